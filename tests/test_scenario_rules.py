"""Scenario rules as docs/scenarios.md states them, for inputs the shipped scenarios do not use (a
review wrote its own scenarios; each test failed on the code before its fix)."""

import re
import textwrap

import pytest

import mcusim
from mcusim.cli import main
from mcusim.errors import McusimError
from mcusim.testing import wait_until


def write(tmp_path, text, name="s.toml"):
    p = tmp_path / name
    p.write_text(textwrap.dedent(text).lstrip("\n"))
    return p


def run(tmp_path, text, *args):
    """``mcusim run <the scenario's board> --scenario <text> --quiet *args``: its exit status."""
    board = re.search(r'board = "([^"]+)"', text).group(1)
    return main(["run", board, "--scenario", str(write(tmp_path, text)), "--quiet", *args])


MAVLINK = """
[scenario]
board = "ciaa-edu"
duration = "300ms"

[[expect]]
mavlink = "HEARTBEAT"
"""


def test_a_mavlink_expectation_with_a_firmware_fault_the_scenario_does_not_check_exits_1(tmp_path, capsys):
    """The bench ciaa-edu reports modules_missing after ~0.22 s; a scenario that does not check
    firmware.faults leaves it to the run, which exits 1 (the MAVLink expectation's record had no
    summary source, and the run ended in an internal error)."""
    assert run(tmp_path, MAVLINK) == 1
    err = capsys.readouterr().err
    assert "internal error" not in err and "modules_missing" in err


def test_a_mavlink_expectation_and_a_checked_firmware_fault_pass(tmp_path, capsys):
    """docs/scenarios.md: a scenario that checks ``firmware.faults`` itself passes with 0."""
    text = MAVLINK + '\n[[expect]]\nsummary = "firmware.faults"\ncontains = "modules_missing"\n'
    assert run(tmp_path, text) == 0


@pytest.mark.parametrize("kind", ['["stall"]', "{ a = 1 }", "3"])
def test_a_fault_kind_that_is_not_a_string_is_a_usage_error_at_its_line(tmp_path, capsys, kind):
    text = f"""
    [scenario]
    board = "nucleo-f746"
    duration = "10ms"

    [[at]]
    time = "1ms"
    fault = {{ kind = {kind}, motor = "motor1" }}
    """
    assert run(tmp_path, text) == 2
    err = capsys.readouterr().err
    assert "s.toml:7:" in err and "unknown fault kind" in err and "Traceback" not in err


TURNS = """
[scenario]
board = "nucleo-f746"
duration = "200ms"

[[at]]
time = "0s"
publish = {{ "/motor1/enable" = false }}
turn = {{ motor = "motor1", angle = 3.0, over = "100ms" }}

[[at]]
time = "150ms"
turn = {{ motor = "motor1", angle = {angle}, over = "{over}" }}
"""


def test_a_turn_faster_than_a_hand_is_refused_by_the_distance_it_moves(tmp_path, capsys):
    """docs/scenarios.md: a turn "no faster than 100 rad/s". From 3 rad to -0.5 rad in 10 ms is
    350 rad/s, refused at its line; the check had looked at the target angle alone (0.5 rad in
    10 ms passed it)."""
    assert run(tmp_path, TURNS.format(angle=-0.5, over="10ms")) == 2
    err = capsys.readouterr().err
    assert "s.toml:12:" in err and "350 rad/s, faster than a hand turns a shaft" in err


def test_a_slow_turn_to_a_far_target_from_near_it_is_accepted(tmp_path, capsys):
    """From 3 rad to 3.1 rad in 50 ms is 2 rad/s: accepted, though 3.1 rad in 50 ms from rest
    would be 62 rad/s (the old check, on the target alone, refused a 10 rad target here)."""
    text = TURNS.format(angle=3.1, over="50ms").replace('duration = "200ms"', 'duration = "250ms"')
    assert run(tmp_path, text) == 0


def test_a_systems_motor_is_read_through_a_summary_path_whose_key_holds_a_dot(tmp_path, capsys):
    """docs/scenarios.md: ``summary`` is a dotted path in the run summary; a system's motors are
    keyed ``mcm1.motor`` there, so ``motors.mcm1.motor.speed_rpm`` takes the longest key at each
    level. It had been refused ("summary has no 'motors.mcm1'")."""
    text = """
    [scenario]
    board = "elementall"
    duration = "20ms"

    [[expect]]
    summary = "motors.mcm1.motor.speed_rpm"
    min = 0
    """
    assert run(tmp_path, text) == 0


def test_the_summarys_warnings_can_be_checked_though_the_entry_appears_only_with_a_warning(tmp_path, capsys):
    """README: a specification limit the firmware exceeds is a ``warnings`` entry in the summary.
    It exists only once there is one, so the path had been refused before the run."""
    text = """
    [scenario]
    board = "ciaa-edu"
    duration = "100ms"

    [set]
    "firmware.adc_clkdiv" = 10

    [[expect]]
    summary = "warnings"
    contains = "ADC0: ADC clock 18.545 MHz = PCLK_ADC 204 MHz / (CLKDIV 10 + 1) is above the 4.5 MHz maximum (data sheet Table 37); CLKDIV >= 45 keeps it at or below 4.5 MHz"

    [[expect]]
    summary = "firmware.faults"
    contains = "modules_missing"
    """
    assert run(tmp_path, text, "--duration", "300ms") == 0


def test_a_command_line_set_mistake_is_named_as_the_command_lines(tmp_path, capsys):
    """A --set key that extends a [set] key (firmware.kpp beside firmware.kp) had been reported at
    the [set] line of the file."""
    text = """
    [scenario]
    board = "nucleo-f746"
    duration = "10ms"

    [set]
    firmware.kp = 300
    """
    assert run(tmp_path, text, "--set", "firmware.kpp=1") == 2
    err = capsys.readouterr().err
    assert "firmware.kpp" in err and "s.toml" not in err


def test_set_takes_a_list_as_the_command_lines_8_9(tmp_path, capsys):
    """docs/scenarios.md: [set] takes the keys and values of --set, which reads a list (8,9)."""
    text = """
    [scenario]
    board = "elementall"
    duration = "10ms"

    [set]
    "firmware.modules" = [8, 9, 10, 11]
    """
    assert run(tmp_path, text) == 0
    bad = text.replace("[8, 9, 10, 11]", "[[8]]")
    assert run(tmp_path, bad) == 2


@pytest.mark.parametrize("line", ['duration = "10ms"\ndescription = ""',      # free text, empty too
                                  'duration = "40000\u03bcs"'])                   # the Greek mu
def test_an_empty_description_and_microseconds_in_greek_mu_are_accepted(tmp_path, capsys, line):
    text = '[scenario]\nboard = "nucleo-f746"\n' + line + "\n"
    assert run(tmp_path, text) == 0


@pytest.mark.parametrize("timeout", ["2", True])
def test_a_wait_timeout_without_a_unit_is_refused_as_run_refuses_it(timeout):
    """docs/pytest.md: a number of seconds or a string with a unit; run(seconds="2") is refused,
    and wait_until had taken "2" as 2 s and True as 1 s."""
    sim = mcusim.load("nucleo-f746", firmware=False)
    with pytest.raises(McusimError, match="expected a number of seconds or a duration with a unit"):
        wait_until(sim, lambda: False, timeout=timeout)
    sim.close()


def test_equals_tells_a_boolean_from_a_number(tmp_path, capsys):
    """A boolean equals only a boolean: ``equals = 0`` against the bench controller's
    ``motors_enabled``, false, fails (it had passed: Python's 0 == False); ``equals = false``
    passes."""
    text = """
    [scenario]
    board = "ciaa-edu"
    duration = "10ms"

    [[expect]]
    summary = "firmware.motors_enabled"
    equals = {v}
    """
    assert run(tmp_path, text.format(v="false")) == 0
    assert run(tmp_path, text.format(v="0")) == 1


@pytest.mark.parametrize("source, check, needle", [
    ('part = "motor1"\nattr = "kernel"', "min = 0", "'kernel' is not a value to read"),
    ('part = "encoder1"\nattr = "motor"', "equals = 1", "'motor' is not a value to read"),
    ('summary = "board"', "min = 0", "board is text ('nucleo-f746'), and min needs a number"),
    ('summary = "simulated_s"', 'contains = "a"', "simulated_s is a number, and contains needs text"),
    ('summary = "realtime_factor"', "min = 0", "measured on the machine"),
    ('summary = "wall_s"', "max = 100", "measured on the machine"),
], ids=["part-object", "encoder-motor", "text-min", "number-contains", "realtime", "wall"])
def test_an_expectation_that_cannot_hold_is_a_usage_error_before_the_run(tmp_path, capsys, source, check, needle):
    """A check of the wrong kind for its value, or of an object a part holds, had run and failed
    at the end (exit 1; the object's repr, with a memory address, in the summary); the wall-clock
    entries were None when expectations read them. Each is now refused at its line (exit 2)."""
    rc = run(tmp_path, f"""
        [scenario]
        board = "nucleo-f746"
        duration = "5ms"

        [[expect]]
        {source.replace(chr(10), chr(10) + '        ')}
        {check}
        """)
    err = capsys.readouterr().err
    assert rc == 2 and needle in err and re.search(r"s\.toml:\d+:", err), err


def test_text_and_a_number_are_still_checked_with_the_checks_made_for_them(tmp_path, capsys):
    rc = run(tmp_path, """
        [scenario]
        board = "nucleo-f746"
        duration = "5ms"

        [[expect]]
        summary = "board"
        contains = "nucleo"

        [[expect]]
        summary = "simulated_s"
        approx = 0.005
        tol = 1e-9

        [[expect]]
        part = "encoder1"
        attr = "position"
        equals = 0
        """)
    assert rc == 0, capsys.readouterr()


def test_the_mavlink_link_summary_can_be_checked_though_the_link_is_made_at_the_firmwares_first_step(
        tmp_path, capsys):
    """docs/mavlink.md documents firmware.mavlink in the summary; the check before the run had
    refused it ('summary has no firmware.mavlink'), as the link is made in board_init."""
    rc = run(tmp_path, """
        [scenario]
        board = "ciaa-edu"
        duration = "50ms"

        [[expect]]
        summary = "firmware.mavlink.rx_errors"
        equals = 0

        [[expect]]
        summary = "firmware.mavlink.armed"
        equals = false
        """)
    assert rc == 0, capsys.readouterr()


def test_the_rover_controllers_summary_has_the_same_keys_before_and_after_its_first_step():
    """The load-time check of a summary path reads the summary before the run: its shape must be
    the run's (a key that appears at the first step would be refused, as firmware.mavlink was)."""
    sim = mcusim.load("ciaa-edu")
    try:
        def keys(d, prefix=""):
            return {prefix + k for k in d} | {x for k, v in d.items() if isinstance(v, dict)
                                              for x in keys(v, prefix + k + ".")}
        before = keys(sim.summary()["firmware"])
        sim.run(seconds="0.01s")
        assert keys(sim.summary()["firmware"]) == before
    finally:
        sim.close()


def test_run_scenario_runs_on_the_engine_asked_and_both_give_the_same_results():
    from mcusim.scenario import run_scenario
    got = {}
    for engine in ("fast", "reference"):
        sim, sc = run_scenario("step_response", duration="0.2s", engine=engine)
        assert sim.kernel.engine == engine
        got[engine] = [(r.name, r.got, r.passed) for r in sc.results]
    # plant values agree within 1e-9 relative (docs/engine.md), the verdicts exactly
    assert [(n, p) for n, _, p in got["fast"]] == [(n, p) for n, _, p in got["reference"]]
    assert [g for _, g, _ in got["fast"]] == pytest.approx([g for _, g, _ in got["reference"]], rel=1e-9)


@pytest.mark.parametrize("source, check, needle", [
    ('topic = "wheel_setpoints"', "approx = 0\n        tol = 1", "wheel_setpoints is a list, and approx needs a number"),
    ('summary = "firmware.modules_found"', "min = 0", "firmware.modules_found is a list, and min needs a number"),
    ('topic = "odometry"', 'contains = "x"', "odometry is a table (x, y, yaw), and contains needs text or a list"),
], ids=["list-approx", "list-min", "table-contains"])
def test_a_check_of_a_list_or_a_table_of_the_wrong_kind_is_refused_before_the_run(tmp_path, capsys, source,
                                                                                 check, needle):
    rc = run(tmp_path, f"""
        [scenario]
        board = "ciaa-edu"
        duration = "5ms"

        [[expect]]
        {source}
        {check}
        """)
    err = capsys.readouterr().err
    assert rc == 2 and needle in err, err


CLEAR_AT_50MS = """
        [[at]]
        time = "50ms"
        fault = { kind = "stall", motor = "motor1", clear = true }
"""


@pytest.mark.parametrize("clear, check", [("", "equals = 0.0"), (CLEAR_AT_50MS, "max = 0.01")],
                         ids=["jammed", "cleared-mid-turn"])
def test_a_hand_does_not_turn_a_shaft_a_stall_fault_jams_and_lets_go_of_it(tmp_path, capsys, clear, check):
    """docs/scenarios.md: a stalled shaft stays stuck whatever the current (10^6 N·m of stiction);
    a turn had moved it all the same, setting its speed every millisecond. The hand lets go: once
    the jam clears it does not catch up with its ramp, which would turn the shaft far faster than a
    hand can (the limit a turn is checked against when it starts)."""
    rc = run(tmp_path, f"""
        [scenario]
        board = "nucleo-f746"
        duration = "150ms"

        [[at]]
        time = "0s"
        publish = {{ "/motor1/enable" = false }}
        fault = {{ kind = "stall", motor = "motor1" }}

        [[at]]
        time = "10ms"
        turn = {{ motor = "motor1", angle = 1.0, over = "100ms" }}
        {clear}
        [[expect]]
        part = "motor1"
        attr = "output_angle"
        {check}
        """)
    assert rc == 0, capsys.readouterr()
