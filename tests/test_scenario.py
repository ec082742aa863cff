"""Scenarios (mcusim.scenario): parsing with file:line errors, exact action timing, the fault
kinds, expectations and the shipped examples (run with shorter durations)."""

import textwrap
from pathlib import Path

import pytest

from mcusim.cli import main
from mcusim.errors import ConfigError
from mcusim.scenario import load_scenario, run_scenario, scenario_names

EXAMPLES = Path(__file__).resolve().parent.parent / "scenarios"


def write(tmp_path, text, name="s.toml"):
    p = tmp_path / name
    p.write_text(textwrap.dedent(text).lstrip("\n"))
    return p


def error_of(fn, *args):
    with pytest.raises(ConfigError) as info:
        fn(*args)
    return str(info.value)


HEAD = """
[scenario]
board = "nucleo-f746"
duration = "20ms"
"""


# --- every mistake: one message naming the file, the line and the problem --------------------------
@pytest.mark.parametrize("body, line, problem", [
    # unknown key in an [[at]] table (line 7)
    ('[[at]]\ntime = "1ms"\ntorq = { motor = "motor1", nm = 0.1 }\n', 6, "unknown key 'torq'"),
    # bad unit
    ('[[at]]\ntime = "5xs"\npublish = { "/motor1/set_pos" = 1.0 }\n', 5, "bad duration '5xs'"),
    # time out of order: the second [[at]] is earlier than the first
    (('[[at]]\ntime = "10ms"\npublish = { "/motor1/set_pos" = 1.0 }\n\n'
      '[[at]]\ntime = "2ms"\npublish = { "/motor1/set_pos" = 0.5 }\n'), 9, "time order"),
    # unknown fault kind, inline table: the line of the fault key
    ('[[at]]\ntime = "1ms"\nfault = { kind = "gremlins", motor = "motor1" }\n', 6, "unknown fault kind 'gremlins'"),
    # unknown fault kind in a sub-table: the line of kind itself
    ('[[at]]\ntime = "1ms"\n[at.fault]\nmotor = "motor1"\nkind = "gremlins"\n', 8, "unknown fault kind 'gremlins'"),
    # missing field
    ('[[at]]\ntime = "1ms"\nturn = { motor = "motor1" }\n', 6, "missing angle"),
    # unknown key in an [[expect]] after several [[at]]
    (('[[at]]\ntime = "1ms"\npublish = { "/motor1/set_pos" = 1.0 }\n[[expect]]\ntopic = "/motor1/get_pos"\n'
      'approx = 1.0\ntoll = 0.1\n'), 10, "unknown key 'toll'"),
    # an expectation without a check
    ('\n[[expect]]\npart = "motor1"\nattr = "output_angle"\n', 5, "give one check"),
    # an action after the end of the run
    ('[[at]]\ntime = "1s"\npublish = { "/motor1/set_pos" = 1.0 }\n', 5, "after the end of the run"),
    # unknown table
    ('[scenaro]\nboard = "x"\n', 4, "unknown table or key 'scenaro'"),
])
def test_bad_input_names_file_line_and_problem(tmp_path, body, line, problem):
    p = write(tmp_path, HEAD + body, "bad.toml")
    msg = error_of(load_scenario, p)
    assert f"bad.toml:{line}:" in msg, msg
    assert problem in msg, msg
    assert "\n" not in msg


def test_malformed_toml_names_file_and_line(tmp_path):
    p = write(tmp_path, HEAD + '[[at]]\ntime = "1ms"\npublish = { "/motor1/set_pos" = }\n', "broken.toml")
    msg = error_of(load_scenario, p)
    assert "broken.toml:6:" in msg and "invalid TOML" in msg


def test_missing_scenario_table_and_duration(tmp_path):
    assert "no-head.toml:1:" in error_of(load_scenario, write(tmp_path, '[set]\n"motor1.R" = 2.0\n', "no-head.toml"))
    msg = error_of(load_scenario, write(tmp_path, '\n[scenario]\nboard = "pro-mini"\n', "no-dur.toml"))
    assert "no-dur.toml:1:" in msg and "missing duration" in msg


def test_unknown_part_is_reported_at_apply_with_its_line(tmp_path):
    p = write(tmp_path, HEAD + '[[at]]\ntime = "1ms"\ntorque = { motor = "motor9", nm = 0.1 }\n', "part.toml")
    sc = load_scenario(p)
    sim = sc.build(firmware=False)
    msg = error_of(sc.apply, sim)
    assert "part.toml:6:" in msg and "no part 'motor9'" in msg and "motor1" in msg
    # a part of the wrong kind
    p = write(tmp_path, HEAD + '[[at]]\ntime = "1ms"\ntorque = { motor = "encoder1", nm = 0.1 }\n', "kind.toml")
    msg = error_of(load_scenario(p).apply, sim)
    assert "kind.toml:6:" in msg and "not a motor" in msg


def test_unknown_topic_is_reported_at_apply_with_its_line(tmp_path):
    p = write(tmp_path, HEAD + '[[at]]\ntime = "0s"\npublish = { "/motor3/set_pos" = 1.0 }\n'
              '[[expect]]\ntopic = "/motor1/get_pos"\napprox = 0\ntol = 1\n', "topic.toml")
    sc = load_scenario(p)
    sim = sc.build()
    msg = error_of(sc.apply, sim)
    assert "topic.toml:6:" in msg and "/motor3/set_pos" in msg
    sim.discard()
    p = write(tmp_path, HEAD + '[[expect]]\ntopic = "/motor1/speed"\nmax = 1\n', "out.toml")
    sc = load_scenario(p)
    sim = sc.build()
    msg = error_of(sc.apply, sim)
    assert "out.toml:5:" in msg and "/motor1/speed" in msg
    sim.discard()


def test_bad_set_key_names_its_line(tmp_path):
    p = write(tmp_path, HEAD + '\n[set]\n"motor1.load_inertia" = 2e-5\n"motor9.R" = 2.0\n', "set.toml")
    msg = error_of(load_scenario(p).build)
    assert "set.toml:7:" in msg and "motor9" in msg
    p = write(tmp_path, HEAD + '\n[set]\nmotor1.Rx = 2.0\n', "param.toml")
    msg = error_of(load_scenario(p).build)
    assert "param.toml:6:" in msg and "'Rx'" in msg


def test_board_mismatch(tmp_path):
    sc = load_scenario(write(tmp_path, HEAD, "b.toml"))
    msg = error_of(sc.build, "pro-mini")
    assert "b.toml:2:" in msg and "nucleo-f746" in msg and "pro-mini" in msg


# --- timing ---------------------------------------------------------------------------------------
def test_action_runs_at_its_exact_tick(tmp_path):
    p = write(tmp_path, HEAD + '[[at]]\ntime = "1ms"\ntorque = { motor = "motor1", nm = 0.05 }\n', "t.toml")
    sc = load_scenario(p)
    sim = sc.build(firmware=False)
    sc.apply(sim)
    t = sim.timebase.ticks("1ms")
    motor = sim.part("motor1")
    sim.kernel.run_until(t - 1)
    assert motor.params.load_torque == 0.0 and sc.log == []
    sim.kernel.run_until(t)
    assert motor.params.load_torque == 0.05
    assert sc.log == [(t, "torque motor1 0.05 N·m")]


def test_time_not_on_a_tick_is_an_error(tmp_path):
    # 1/216 MHz base tick: 1 ns is not a whole number of ticks
    p = write(tmp_path, HEAD + '[[at]]\ntime = "1ns"\ntorque = { motor = "motor1", nm = 0.05 }\n', "ns.toml")
    sc = load_scenario(p)
    msg = error_of(sc.apply, sc.build(firmware=False))
    assert "ns.toml:5:" in msg and "base ticks" in msg


# --- actions and faults ---------------------------------------------------------------------------
def test_turn_moves_the_shaft_continuously_and_the_encoder_counts_every_edge(tmp_path):
    p = write(tmp_path, HEAD + '[[at]]\ntime = "1ms"\nturn = { motor = "motor1", angle = 0.2, over = "10ms" }\n'
              '[[at]]\ntime = "12ms"\nfault = { kind = "missing_edges", encoder = "encoder1", count = 5 }\n'
              '[[at]]\ntime = "13ms"\nturn = { motor = "motor1", angle = 0.0, over = "5ms" }\n', "turn.toml")
    sc = load_scenario(p)
    sim = sc.build(firmware=False)
    sc.apply(sim)
    motor, enc = sim.part("motor1"), sim.part("encoder1")
    sim.run(seconds="12ms")
    assert motor.output_angle == pytest.approx(0.2, abs=1e-4) and motor.speed == 0.0
    counts = round(0.2 * 30 * 64 / (2 * 3.141592653589793))        # 61 counts at the motor shaft
    assert enc.position == enc.edges == counts
    sim.run(seconds="8ms")
    assert motor.output_angle == pytest.approx(0.0, abs=1e-4)
    assert enc.position == 0 and enc.dropped == 5 and enc.edges == 2 * counts - 5


def test_encoder_glitch_is_a_pulse_of_the_given_width(tmp_path):
    p = write(tmp_path, HEAD + '[[at]]\ntime = "2ms"\n'
              'fault = { kind = "encoder_glitch", encoder = "encoder2", channel = "B", width = "2us" }\n', "g.toml")
    sc = load_scenario(p)
    sim = sc.build(firmware=False)
    sc.apply(sim)
    net, seen = sim.pin("PD13"), []
    net.listen(lambda n: seen.append((sim.now, n.level)))
    sim.run(seconds="3ms")
    t = sim.timebase.ticks("2ms")
    assert seen == [(t, 1), (t + sim.timebase.ticks("2us"), 0)]


def test_stall_holds_the_shaft_until_cleared(tmp_path):
    p = write(tmp_path, HEAD.replace("20ms", "200ms") +
              '[[at]]\ntime = "0s"\npublish = { "/motor1/set_pos" = 1.57 }\n'
              '[[at]]\ntime = "40ms"\nfault = { kind = "stall", motor = "motor1" }\n'
              '[[at]]\ntime = "80ms"\nfault = { kind = "stall", motor = "motor1", clear = true }\n', "stall.toml")
    sc = load_scenario(p)
    sim = sc.build()
    sc.apply(sim)
    motor = sim.part("motor1")
    sim.run(seconds="40ms")
    jammed = motor.output_angle
    assert jammed > 0.05
    sim.run(seconds="39ms")
    assert motor.output_angle == jammed and motor.stuck and abs(motor.current) > 1.0
    sim.run(seconds="40ms")
    assert motor.output_angle > jammed + 0.1
    assert motor.params.tau_s == 5.0e-3


def test_overtemperature_on_the_pro_mini(tmp_path):
    p = write(tmp_path, '[scenario]\nboard = "pro-mini"\nduration = "30ms"\n'
              '[[at]]\ntime = "0s"\npublish = { velocity = 10 }\n'
              '[[at]]\ntime = "10ms"\nfault = { kind = "overtemperature", bridge = "ibt2", side = "R" }\n', "ot.toml")
    sim, sc = run_scenario(p)
    assert sim.part("ibt2").overtemp
    assert [text for _, text in sc.log] == ["publish velocity = 10", "fault overtemperature ibt2"]


def test_rover_faults_battery_estop_and_a_silent_module(tmp_path):
    p = write(tmp_path, '[scenario]\nboard = "elementall"\nduration = "4ms"\n'
              '[[at]]\ntime = "1ms"\nfault = { kind = "battery_sag", battery = "battery", soc = 0.2, amps = 30 }\n'
              '[[at]]\ntime = "1ms"\nfault = { kind = "estop", estop = "estop" }\n'
              '[[at]]\ntime = "2ms"\nfault = { kind = "i2c_silent", board = "mcm2" }\n'
              '[[expect]]\ntime = "3ms"\npart = "estop"\nattr = "pressed"\nequals = true\n'
              '[[expect]]\npart = "battery"\nattr = "soc"\nmax = 0.2\n', "rover.toml")
    sim, sc = run_scenario(p)
    twi = sim.members["mcm2"]["mcu"].periph["TWI"]
    assert twi not in twi.bus.slaves and sim.members["mcm1"]["mcu"].periph["TWI"] in twi.bus.slaves
    assert sim.part("battery").current >= 30 and sim.part("battery").voltage() < 12.0
    assert not sc.failed, sc.format_results()
    with pytest.raises(ConfigError, match="rover.toml:.*no board 'mcm9'"):
        p.write_text(p.read_text().replace('"mcm2"', '"mcm9"'))
        run_scenario(p)
    # the controller is the bus master (its I2C0's slave mode is not modelled): nothing to silence
    with pytest.raises(ConfigError, match="rover.toml:12: .*board 'rcm' has no I2C slave interface"):
        p.write_text(p.read_text().replace('"mcm9"', '"rcm"'))
        run_scenario(p)


# --- expectations ---------------------------------------------------------------------------------
def test_failing_expectation_sets_failed(tmp_path):
    p = write(tmp_path, HEAD + '[[at]]\ntime = "0s"\npublish = { "/motor1/set_pos" = 1.57 }\n'
              '[[expect]]\nname = "there already"\npart = "motor1"\nattr = "output_angle"\napprox = 1.57\ntol = 0.01\n'
              '[[expect]]\nname = "moving"\ntime = "10ms"\npart = "motor1"\nattr = "output_angle"\nmin = 0.001\n',
              "fail.toml")
    sim, sc = run_scenario(p)
    first, second = sc.results
    assert first.name == "there already" and not first.passed and first.time == pytest.approx(0.02)
    assert first.expected == "1.57 ± 0.01" and first.got == sim.part("motor1").output_angle and first.line == 7
    assert second.passed and second.time == pytest.approx(0.01)
    assert sc.failed
    entry = sc.report_entries()["scenario"]
    assert entry["passed"] is False and entry["expectations"][0]["passed"] is False


def test_expectation_after_a_shortened_run_is_not_reached_and_fails(tmp_path):
    p = write(tmp_path, HEAD + '[[expect]]\ntime = "15ms"\npart = "motor1"\nattr = "output_angle"\nmax = 1\n', "short.toml")
    _, sc = run_scenario(p, duration="5ms")
    (r,) = sc.results
    assert r.time is None and r.got is None and not r.passed and sc.failed


# --- the shipped examples (shorter runs) ------------------------------------------------------------
def test_examples_are_shipped():
    assert {"thesis_master_slave", "step_response", "promini_velocity_load", "mavlink_drive"} <= set(scenario_names())


@pytest.mark.parametrize("name, duration", [
    ("step_response", "500ms"),
    ("thesis_master_slave", "1s"),
    ("promini_velocity_load", "1.1s"),
    ("mavlink_drive", "1.2s"),
])
@pytest.mark.heavy
def test_example_passes_its_expectations(name, duration):
    sc = load_scenario(EXAMPLES / f"{name}.toml")
    sc.duration = duration
    sim, sc = run_scenario(sc)
    assert sim.time_s == pytest.approx(float(sc.duration))
    assert not sc.failed, "\n".join(sc.format_results())
    if name == "thesis_master_slave":
        f = sc.report["follow"]
        assert f["samples"] == 951 and 0 < f["max_abs_error_rad"] <= 0.5
        assert sc.report_entries()["scenario"]["report"]["follow"] == f


@pytest.mark.parametrize("attr", ["glitch", "apply_load_torque", "set_state"])
def test_an_expectation_only_reads_a_method_that_acts_or_needs_arguments_is_refused(tmp_path, attr):
    """Was a TypeError from inside the run (a method needing arguments) or, for ``glitch``, an
    encoder glitch injected by reading it: an expectation reads values only. The refusal names
    the line of ``attr`` and what can be read."""
    part = "encoder1" if attr == "glitch" else "motor1"
    p = write(tmp_path, HEAD + f'[[expect]]\ntime = "10ms"\npart = "{part}"\nattr = "{attr}"\nmin = 0\n', "m.toml")
    msg = error_of(run_scenario, p)
    assert "m.toml:7:" in msg and f"{attr!r} is a method, not a value to read" in msg, msg
    assert "position" in msg or "output_angle" in msg, msg


def test_a_part_that_declares_a_method_as_a_value_is_read_through_it(tmp_path):
    """The battery's ``voltage()`` is a value (``READERS``), read at the expectation's time."""
    p = write(tmp_path, '[scenario]\nboard = "elementall"\nduration = "3ms"\n'
              '[[expect]]\ntime = "2ms"\npart = "battery"\nattr = "voltage"\nmin = 11.0\nmax = 14.0\n', "v.toml")
    _, sc = run_scenario(p)
    assert not sc.failed and 11.0 < sc.results[0].got < 14.0, sc.format_results()


def test_a_scenario_for_a_board_that_does_not_exist_says_so(tmp_path):
    """Said only that the scenario was meant for 'nucleo-f999', not for the board given."""
    p = write(tmp_path, HEAD.replace('"nucleo-f746"', '"nucleo-f999"'))
    msg = error_of(load_scenario(p).check_board, "nucleo-f746")
    assert "s.toml:2: the scenario is meant for board 'nucleo-f999', not 'nucleo-f746'" in msg
    assert "no shipped board is called 'nucleo-f999'" in msg and "nucleo-f746" in msg
    assert "no shipped board" not in error_of(load_scenario(write(tmp_path, HEAD, "t.toml")).check_board, "pro-mini")


def test_a_stall_fault_on_the_promini_ends_in_the_driver_fault_as_docs_scenarios_says(tmp_path):
    """docs/scenarios.md: a jammed pro-mini motor's current trips the BTS7960's current sense (the
    sketch's driver fault) within tens of milliseconds, long before its 500 ms stall timer."""
    sc = tmp_path / "jam.toml"
    sc.write_text('[scenario]\nboard = "pro-mini"\nduration = "600ms"\n[[at]]\ntime = "0s"\n'
                  'publish = { velocity = 10 }\n[[at]]\ntime = "500ms"\n'
                  'fault = { kind = "stall", motor = "motor" }\n'
                  '[[expect]]\nsummary = "firmware.faults"\ncontains = "driver"\n')
    assert main(["run", "pro-mini", "--scenario", str(sc), "-q"]) == 0


def test_a_longer_duration_given_on_the_command_line_admits_the_files_later_times(tmp_path, capsys):
    """docs/scenarios.md: --duration shortens or lengthens the run. An expectation after the
    file's own end is refused as a mistake in the file, unless the run is given a duration that
    reaches it; a shorter one leaves later expectations not reached (exit 1)."""
    sc = tmp_path / "late.toml"
    sc.write_text('[scenario]\nboard = "nucleo-f746"\nduration = "100ms"\n'
                  '[[expect]]\ntime = "200ms"\npart = "motor1"\nattr = "output_angle"\napprox = 0.0\ntol = 1.0\n')
    assert main(["run", "nucleo-f746", "--scenario", str(sc), "-q"]) == 2
    assert "after the end of the run (duration 100ms)" in capsys.readouterr().err
    assert main(["run", "nucleo-f746", "--scenario", str(sc), "--duration", "300ms", "-q"]) == 0
    assert "PASS" in capsys.readouterr().out


def test_run_scenario_with_a_longer_duration_admits_the_later_times_as_the_cli_does(tmp_path):
    from mcusim.scenario import run_scenario
    sc = tmp_path / "s.toml"
    sc.write_text('[scenario]\nboard = "pro-mini"\nduration = "10ms"\n[[at]]\ntime = "30ms"\n'
                  'publish = { velocity = 5 }\n')
    _sim, scn = run_scenario(sc, duration="40ms")
    assert any("velocity" in text for _, text in scn.log)      # the action at 30 ms ran


def test_a_scenario_may_come_through_a_pipe(tmp_path):
    import os
    import threading
    fifo = tmp_path / "s.fifo"
    os.mkfifo(fifo)
    body = '[scenario]\nboard = "pro-mini"\nduration = "5ms"\n'
    writer = threading.Thread(target=lambda: fifo.write_text(body))
    writer.start()
    sc = load_scenario(str(fifo))
    writer.join()
    assert sc.board == "pro-mini"


def test_a_number_check_of_a_topic_that_is_a_table_is_a_usage_error_naming_its_fields(tmp_path, capsys):
    """Found by a new user: approx on the rover's odometry topic (a table x, y, yaw) failed as
    'FAIL ... {x: 0.0, ...}' with exit 1, though every field was within tolerance. A number check
    needs a number: the scenario is refused before the run, naming the fields and the summary
    path that reads one."""
    sc = tmp_path / "odo.toml"
    sc.write_text('[scenario]\nboard = "elementall"\nduration = "20ms"\n'
                  '[[expect]]\ntopic = "odometry"\napprox = 0.0\ntol = 1\n')
    assert main(["run", "elementall", "--scenario", str(sc), "-q"]) == 2
    err = capsys.readouterr().err
    assert "odo.toml:5" in err and "odometry is a table (x, y, yaw)" in err and 'summary = "odometry.x"' in err
    sc.write_text(sc.read_text().replace('topic = "odometry"', 'summary = "odometry.x"'))
    assert main(["run", "elementall", "--scenario", str(sc), "-q"]) == 0


@pytest.mark.parametrize("source, needle", [
    ('summary = "firmware.motors_enabled"', "firmware.motors_enabled is true or false, and min needs a number"),
    ('summary = "pose"', "pose is a table (x, y, yaw), and min needs a number"),
])
def test_a_number_check_of_a_summary_flag_or_table_is_a_usage_error(tmp_path, capsys, source, needle):
    """As for topics: False >= 0 holds as numbers, so the run FAILed a check that read as wrong
    (exit 1) where the scenario asked a flag or a table for a number."""
    sc = tmp_path / "flag.toml"
    sc.write_text(f'[scenario]\nboard = "elementall"\nduration = "20ms"\n[[expect]]\n{source}\nmin = 0\n')
    assert main(["run", "elementall", "--scenario", str(sc), "-q"]) == 2
    err = capsys.readouterr().err
    assert "flag.toml:5" in err and needle in err


def test_run_scenario_refuses_a_run_longer_than_its_limit_as_the_command_line_does():
    """docs/scenarios.md: a scenario's duration may be at most 600 s unless the limit is raised
    (``mcusim run --max-duration``; ``max_duration=`` here)."""
    with pytest.raises(ConfigError, match=r"duration 700s is longer than the limit of 600s \(raise it with max_duration=\)"):
        run_scenario("step_response", duration="700s")
    with pytest.raises(ConfigError, match="limit of 1ms"):
        run_scenario("step_response", duration="2ms", max_duration="1ms")
    sim, _ = run_scenario("step_response", duration="2ms", max_duration="1s")
    assert sim.time_s == pytest.approx(0.002)


def test_an_unknown_system_input_lists_the_boards_whose_own_inputs_a_scenario_may_give(tmp_path, capsys):
    """'mcm2.velocity' is taken, so the message about 'mcm9.velocity' names that form and the
    boards, not only the controller's inputs; a module's unknown --set input keeps its board."""
    sc = tmp_path / "in.toml"
    sc.write_text('[scenario]\nboard = "elementall"\nduration = "5ms"\n[[at]]\ntime = "1ms"\n'
                  'publish = { "mcm9.velocity" = 5 }\n')
    assert main(["run", "elementall", "--scenario", str(sc), "-q"]) == 2
    err = capsys.readouterr().err
    assert "in.toml:6:" in err and "a board's own input as <board>.<input>, boards: mcm1, mcm2, mcm3, mcm4" in err
    assert main(["run", "elementall", "--duration", "1ms", "-q", "--set", "mcm2.nope=1"]) == 2
    assert capsys.readouterr().err.startswith("mcusim: error: --set mcm2.nope: no input 'nope'")


def test_a_file_that_starts_with_a_byte_order_mark_is_read(tmp_path):
    """Windows editors put a byte-order mark at the start of a UTF-8 file; it was 'invalid TOML:
    Invalid statement (column 1)'. Scenarios and board profiles skip it."""
    p = tmp_path / "bom.toml"
    p.write_bytes(b"\xef\xbb\xbf" + (HEAD + '[[at]]\ntime = "0s"\npublish = { "/motor1/set_pos" = 1.0 }\n').encode())
    sim, sc = run_scenario(p)
    assert sc.log and sim.time_s > 0
    board = tmp_path / "board.toml"
    import mcusim
    from mcusim.board import shipped_text
    board.write_bytes(b"\xef\xbb\xbf" + shipped_text("pro-mini").encode())
    mcusim.load(str(board)).close()
