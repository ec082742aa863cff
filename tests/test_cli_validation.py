"""Every bad input a careless user types is one line on stderr and exit status 2, found before the
run (issue 11): each case below was a traceback, a silently wrong or endless run, or exit 1."""

import json
import os

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import mcusim
from mcusim.cli import main


def _usage_error(capsys, argv, *needles):
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2, (rc, err)
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for n in needles:
        assert n in err, err
    return err


@pytest.mark.parametrize("board, key, needle", [
    # were ZeroDivisionError tracebacks: periods, tick rates and baud rates must be positive
    ("nucleo-f746", "firmware.pid_period_ms=0", "firmware.pid_period_ms = 0: must be from 1 to 1000 ms"),
    ("pro-mini", "firmware.sample_ms=0", "firmware.sample_ms = 0: must be from 1 to 10000 ms"),
    ("ciaa-edu", "firmware.tick_hz=0", "firmware.tick_hz = 0: must be from 100 to 10000 Hz"),
    ("ciaa-edu", "firmware.console_baud=0", "firmware.console_baud = 0: must be from 300 to 3000000 baud"),
    # were ValueError / struct.error tracebacks
    ("pro-mini", "firmware.wire_variant=x", "firmware.wire_variant = 'x': expected one of fixed, core"),
    ("pro-mini", "velocity=1e9", "velocity = 1e+09: must be from -1000 to 1000 rpm"),
    # were accepted, then silently wrong: an endless run, a firmware that does nothing, a runaway
    ("nucleo-f746", "motor1.R=inf", "motor1.R = inf: expected a finite number"),
    ("nucleo-f746", "motor1.R=nan", "motor1.R = nan: expected a finite number"),
    ("nucleo-f746", "motor1.R=0", "motor1.R = 0: must be from 0.001 to 1000 Ω"),
    ("nucleo-f746", "firmware.pid_period_ms=-5", "must be from 1 to 1000 ms"),
    ("nucleo-f746", "firmware.counts_per_turn=0", "firmware.counts_per_turn = 0: must be from 4 to 65536"),
    ("nucleo-f746", "/motor1/set_pos=1e308", "/motor1/set_pos = 1e+308: must be from -1000 to 1000 rad"),
    # was exit 1 from deep inside the I2C model: a 7-bit address is checked where it is given
    ("pro-mini", "firmware.i2c_address=999", "firmware.i2c_address = 999: must be from 8 to 119"),
    ("elementall", "mcm1.firmware.i2c_address=0x80", "i2c_address"),
    # enumerations are listed plainly, not as a Python tuple
    ("nucleo-f746", "firmware.variant=foo", "firmware.variant = 'foo': expected one of correct, thesis"),
    # the key the README used to document is refused, naming the real ones
    ("nucleo-f746", "bridgeA.ocd_threshold=4.0", "I_ocd"),
    ("ciaa-edu", "firmware.critical_v=12", "must be below firmware.low_v"),
    ("elementall", "battery.ocv_full=11", "ocv_full = 11 V must be above ocv_empty"),
    # was a run stopped at t = 2 ms (exit 1): the EDU-CIAA brings out ADC0_0 to ADC0_3 only
    ("ciaa-edu", "firmware.battery_channel=7", "ADC0 channel 7 is not wired on this board (wired: 0, 1, 2, 3)"),
])
def test_values_are_checked_against_their_declared_range(capsys, board, key, needle):
    err = _usage_error(capsys, ["run", board, "--duration", "1ms", "--set", key], needle)
    assert "battery battery" not in err and "(" not in err.split(":", 2)[-1][:1]


@pytest.mark.parametrize("args, needle", [
    (["--duration", "5"], "a duration needs a unit"),                # bare numbers are not seconds
    (["--duration", "1e300s"], "longer than the limit of 600s (raise it with --max-duration)"),
    (["--duration", "0s"], "must be positive"),
    (["--duration=-1ms"], "bad duration"),
    (["--duration", "nan"], "bad duration"),
    (["--duration", "1ps"], "shorter than one base tick"),
    (["--duration", "1ms", "--vcd-sample", "0s", "--vcd", "x.vcd"], "must be positive"),
    (["--duration", "1ms", "--vcd-sample", "1ps", "--vcd", "x.vcd"], "the finest sampling grid is 1us"),
    (["--duration", "1ms", "--sample", "1ns", "--csv", "x.csv"], "the finest sampling grid is 1us"),
    (["--duration", "1ms", "--sample", "1.0000001ms", "--csv", "x.csv"], "--sample 1.0000001ms: not a whole"),
    # times on the command line are exact, as in scenarios (216 MHz: 1.0000001 ms is 216000.0216 ticks)
    (["--duration", "1.0000001ms"], "--duration 1.0000001ms: not a whole number of base ticks"),
    (["--duration", "1ms", "--vcd-sample", "1.0000001us", "--vcd", "x.vcd"], "--vcd-sample 1.0000001us: not a whole"),
    (["--duration", "1ms", "--register-log", "r.jsonl", "--register-log-filter", ""], "is empty"),
    (["--duration", "1ms", "--register-log-filter", "TIM1"], "needs --register-log"),
    (["--duration", "1ms", "--no-firmware", "--set", "/motor1/set_pos=1"], "runs without firmware"),
    (["--duration", "1ms", "--vcd", "x", "--csv", "x"], "--vcd and --csv name the same file x"),
    (["--duration", "1ms", "--vcd", "x.vcd", "--summary", "x.gtkw"], "name the same file x.gtkw"),
    (["--duration", "1ms", "--summary", "."], "is a folder"),
])
def test_command_line_mistakes_are_one_line_and_exit_2(tmp_path, monkeypatch, capsys, args, needle):
    monkeypatch.chdir(tmp_path)
    _usage_error(capsys, ["run", "nucleo-f746", *args], needle)
    assert sorted(os.listdir(tmp_path)) == []             # nothing written, not even a temporary file


def test_bench_refuses_a_duration_off_the_base_tick(capsys):
    _usage_error(capsys, ["bench", "pro-mini", "--duration", "10.00001ms", "--repeat", "1"],
                 "--duration 10.00001ms: not a whole number of base ticks")


def test_a_scenario_duration_off_the_base_tick_is_named_at_its_line(tmp_path, capsys):
    """The file's own duration is checked as its other times are (it used to be blamed on a
    --duration that was never given); a --duration given instead replaces it."""
    sc = tmp_path / "frac.toml"
    sc.write_text('[scenario]\nboard = "nucleo-f746"\nduration = "10.3ns"\n')
    _usage_error(capsys, ["run", "nucleo-f746", "--scenario", str(sc)],
                 "frac.toml:3: [scenario]: duration = 10.3ns is not a whole number of base ticks")
    assert main(["run", "nucleo-f746", "--scenario", str(sc), "--duration", "1ms", "-q"]) == 0


def test_a_register_log_file_is_announced_like_the_other_outputs(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["run", "nucleo-f746", "--duration", "1ms", "--register-log", "r.jsonl"]) == 0
    assert "register log written to r.jsonl" in capsys.readouterr().out


def test_the_duration_limit_can_be_raised_with_a_flag(capsys):
    _usage_error(capsys, ["run", "nucleo-f746", "--duration", "2ms", "--max-duration", "1ms"], "limit of 1ms")
    assert main(["run", "nucleo-f746", "--duration", "2ms", "--max-duration", "1ms", "--max-duration", "1s"]) == 0


def test_a_scenario_longer_than_the_limit_names_its_file_and_line(tmp_path, capsys):
    p = tmp_path / "long.toml"
    p.write_text('[scenario]\nboard = "nucleo-f746"\nduration = "1e400s"\n')
    _usage_error(capsys, ["run", "nucleo-f746", "--scenario", str(p)], f"{p}:3:", "longer than the limit")
    p.write_text('[scenario]\nduration = 2\n')                    # a bare number is not a duration
    _usage_error(capsys, ["run", "nucleo-f746", "--scenario", str(p)], f"{p}:2:", "with a unit")


@pytest.mark.parametrize("what", ["board", "scenario"])
def test_a_binary_file_is_one_line_naming_it(tmp_path, capsys, what):
    p = tmp_path / "x.toml"
    p.write_bytes(b"[board]\n\xff\xfe\x00 binary")
    argv = ["run", str(p)] if what == "board" else ["run", "nucleo-f746", "--scenario", str(p)]
    _usage_error(capsys, argv + ["--duration", "1ms"], f"{p}:2: not a UTF-8 text file")


def test_outputs_that_cannot_be_written_are_refused_before_the_run(tmp_path, capsys):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        if os.access(ro, os.W_OK):            # root writes anywhere: a missing folder instead
            ro = tmp_path / "missing"
        for opt in ("--summary", "--vcd", "--csv", "--plot", "--register-log"):
            target = str(ro / ("x.png" if opt == "--plot" else "x"))
            _usage_error(capsys, ["run", "nucleo-f746", "--duration", "1ms", opt, target], opt)
        assert main(["bench", "nucleo-f746", "--duration", "1ms", "--repeat", "1", "--json", str(ro / "b.json")]) == 2
        assert "--json" in capsys.readouterr().err
    finally:
        (tmp_path / "ro").chmod(0o700)


def test_a_full_device_is_named_with_its_option(capsys):
    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full")
    err = _usage_error(capsys, ["run", "nucleo-f746", "--duration", "1ms", "--vcd", "/dev/full"],
                       "--vcd /dev/full", "No space left on device")
    assert "error: :" not in err
    assert os.path.exists("/dev/full") and not os.path.isfile("/dev/full")   # written in place, not replaced


def test_plot_without_matplotlib_says_how_to_get_it_before_the_run(tmp_path, monkeypatch, capsys):
    import sys
    monkeypatch.setitem(sys.modules, "matplotlib", None)       # as if not installed
    _usage_error(capsys, ["run", "nucleo-f746", "--duration", "1ms", "--plot", str(tmp_path / "p.png")],
                 "pip install 'mcusim[plot]'")
    assert list(tmp_path.iterdir()) == []


def test_a_failing_run_leaves_no_complete_looking_file(tmp_path, monkeypatch, capsys):
    import mcusim.sim
    real_run = mcusim.sim.Simulation.run

    def failing_run(self, **kw):
        real_run(self, seconds="1ms")
        raise KeyboardInterrupt

    monkeypatch.setattr(mcusim.sim.Simulation, "run", failing_run)
    rc = main(["run", "nucleo-f746", "--duration", "5ms", "-q", "--vcd", str(tmp_path / "r.vcd"),
               "--csv", str(tmp_path / "r.csv"), "--summary", str(tmp_path / "s.json")])
    assert rc == 130
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["r.csv.part", "r.vcd.part"], names      # streamed files marked incomplete, no summary
    err = capsys.readouterr().err
    assert "partial output left in" in err and "interrupted" in err


def test_a_completed_run_renames_its_outputs_into_place(tmp_path, capsys):
    rc = main(["run", "nucleo-f746", "--duration", "1ms", "-q", "--vcd", str(tmp_path / "r.vcd"),
               "--csv", str(tmp_path / "r.csv"), "--summary", str(tmp_path / "s.json")])
    assert rc == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.csv", "r.gtkw", "r.vcd", "s.json"]
    assert json.loads((tmp_path / "s.json").read_text())["simulated_s"] == 0.001


def test_an_output_may_not_overwrite_the_scenario(tmp_path, capsys):
    p = tmp_path / "s.toml"
    p.write_text('[scenario]\nduration = "1ms"\n')
    _usage_error(capsys, ["run", "nucleo-f746", "--scenario", str(p), "--summary", str(p)], "input of this run")
    assert p.read_text() == '[scenario]\nduration = "1ms"\n'


def test_set_topics_replace_the_profiles_demo_command_and_parameters_do_not(tmp_path, capsys):
    s = tmp_path / "s.json"
    assert main(["run", "nucleo-f746", "--duration", "1ms", "--set", "/motor1/set_pos=0.5", "--summary", str(s)]) == 0
    motors = json.loads(s.read_text())["motors"]
    assert motors["motor1"]["setpoint_rad"] == 0.5 and motors["motor2"]["setpoint_rad"] == 0.0
    assert main(["run", "nucleo-f746", "--duration", "1ms", "--set", "motor1.R=2.5", "--summary", str(s)]) == 0
    motors = json.loads(s.read_text())["motors"]          # [run.set]: 1.57 and -3.14
    assert motors["motor1"]["setpoint_rad"] == 1.57 and motors["motor2"]["setpoint_rad"] == -3.14


def test_summary_rows_line_up_for_long_motor_names(capsys):
    assert main(["run", "rover-diff", "--duration", "1ms"]) == 0
    lines = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith(("motor ", "left.", "right."))]
    ends = {len(ln) for ln in lines}
    starts = {ln.index("angle") for ln in lines if "angle" in ln}
    assert len(ends) == 1 and lines[2].startswith("right.motor ") and starts, lines


def test_trace_defaults_to_one_millisecond(capsys):
    assert main(["trace", "nucleo-f746", "--filter", "TIM1.CR1"]) == 0
    assert "simulated 0.001000 s" in capsys.readouterr().err


def test_bench_help_describes_every_option_with_its_default(capsys):
    assert main(["bench", "--help"]) == 0
    out = capsys.readouterr().out
    for needle in ("--duration TIME", "(default 1s)", "--repeat N", "(default 3)", "--json FILE"):
        assert needle in out, out


def test_an_empty_output_name_and_a_huge_key_are_one_short_line(capsys):
    _usage_error(capsys, ["run", "nucleo-f746", "--duration", "1ms", "--vcd", ""], "--vcd: an empty file name")
    err = _usage_error(capsys, ["run", "nucleo-f746", "--duration", "1ms", "--set", "a" * 5000 + "=1"])
    assert len(err) <= 620


def test_a_zero_or_unitless_duration_is_named_as_the_user_wrote_it(capsys):
    """The message quotes what was typed ('0ms', not a rewritten '0s'), and a unitless zero is not
    told to try '0s or 0ms', which are refused too."""
    from mcusim.cli import main
    assert main(["run", "nucleo-f746", "--duration", "0ms"]) == 2
    err = capsys.readouterr().err
    assert "0ms: must be positive" in err and "Traceback" not in err
    assert main(["run", "nucleo-f746", "--duration", "0"]) == 2
    err = capsys.readouterr().err
    assert "needs a unit" in err and "0s or 0ms" not in err and "500ms or 2s" in err


def test_the_thesis_arr_of_65536_counts_is_refused_as_the_16_bit_timer_cannot_hold_it(capsys):
    """Was a ZeroDivisionError traceback: the thesis sets ARR = counts per turn, 65536 reads back
    as 0 from TIM3's 16-bit ARR, and its CNT/ARR divides by zero. The correct variant's
    ARR = 65535 fits, and the thesis takes 65535."""
    _usage_error(capsys, ["run", "nucleo-f746", "--duration", "1ms", "--set", "firmware.variant=thesis",
                          "--set", "firmware.counts_per_turn=65536"], "16-bit encoder timers cannot hold")
    for sets in (["firmware.counts_per_turn=65536"], ["firmware.variant=thesis", "firmware.counts_per_turn=65535"]):
        mcusim.load("nucleo-f746", overrides=dict(s.split("=") for s in sets)).run(seconds="1ms")


def test_a_summary_that_cannot_be_written_after_the_run_spares_the_streamed_outputs(tmp_path, capsys):
    """Was "the run did not complete: partial output left in ok.csv.part" and "cannot write --csv
    ok.csv or --summary /dev/full": the run had completed and the CSV was whole. Now the CSV
    gets its name and the message names the summary only."""
    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full")
    csv = tmp_path / "ok.csv"
    err = _usage_error(capsys, ["run", "nucleo-f746", "--duration", "3ms", "--csv", str(csv), "--summary",
                                "/dev/full", "-q"], "--summary /dev/full: No space left on device")
    assert "--csv" not in err and "did not complete" not in err, err
    assert csv.read_text().splitlines()[-1].startswith("0.003,") and not (tmp_path / "ok.csv.part").exists()


def test_an_output_under_a_file_says_the_file_is_not_a_folder(tmp_path, capsys):
    (tmp_path / "out.json").write_text("{}")
    _usage_error(capsys, ["run", "nucleo-f746", "--duration", "1ms", "--csv", str(tmp_path / "out.json" / "x.csv")],
                 f"{tmp_path / 'out.json'} is a file, not a folder")


def test_boards_takes_show_or_kinds_not_both(capsys):
    _usage_error(capsys, ["boards", "--kinds", "--show", "pro-mini"], "give --show BOARD or --kinds, not both")


def test_a_scenario_file_given_as_the_board_suggests_scenario(capsys):
    from pathlib import Path
    sc = Path(__file__).resolve().parent.parent / "scenarios" / "step_response.toml"
    _usage_error(capsys, ["run", str(sc)], "a scenario file? run it with --scenario FILE")


def test_a_module_parameter_set_on_the_rover_as_the_controllers_says_where_it_belongs(capsys):
    """Was a list of about 45 controller parameters: the wheel PID is the modules' firmware."""
    _usage_error(capsys, ["run", "elementall", "--duration", "1ms", "--set", "firmware.kp=1"],
                 "firmware.kp: not a parameter of the main board's firmware; the firmware of mcm1, mcm2, mcm3, "
                 "mcm4 takes it: --set mcm1.firmware.kp=...")


def test_a_time_off_the_base_tick_offers_the_nearest_that_is_on_it(capsys):
    """Was "try 10ms or 2s": 1.0000001 ms at 216 MHz is 216000.0216 ticks, the nearest 1 ms."""
    _usage_error(capsys, ["run", "nucleo-f746", "--duration", "1.0000001ms"],
                 "--duration 1.0000001ms: not a whole number of base ticks", "the nearest is 1ms")
    # 1.00001 ms is 216002.16 ticks: the nearest tick is no short decimal, a whole microsecond is
    # (was "try 10ms or 2s" here, where the 16 MHz pro-mini offered "the nearest is 1ms")
    _usage_error(capsys, ["run", "nucleo-f746", "--duration", "1.00001ms"],
                 "--duration 1.00001ms: not a whole number of base ticks", "the nearest whole microsecond is 1ms")


def test_after_run_files_already_written_stay_when_a_later_one_fails(tmp_path, capsys):
    """From review: the plot and the GTKWave layout were written, then removed without a word
    when the summary after them could not be written."""
    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full")
    png, vcd = tmp_path / "ok.png", tmp_path / "ok.vcd"
    _usage_error(capsys, ["run", "pro-mini", "--duration", "5ms", "--vcd", str(vcd), "--plot", str(png),
                          "--summary", "/dev/full", "-q"], "--summary /dev/full")
    assert png.exists() and vcd.exists() and (tmp_path / "ok.gtkw").exists()


def test_a_users_set_typo_is_not_blamed_on_a_run_set_key_it_starts_with(tmp_path, capsys):
    """From review: --set motor.Rx was reported at the profile's [run.set] "motor.R" line."""
    from mcusim.board import shipped_text
    text = shipped_text("pro-mini").replace("[run.set]\n", '[run.set]\n"motor.R" = 2.0\n', 1)
    p = tmp_path / "rs.toml"
    p.write_text(text)
    err = _usage_error(capsys, ["run", str(p), "--set", "motor.Rx=1", "--duration", "1ms"], "--set motor.Rx")
    assert "[run.set]" not in err, err


def test_the_rover_firmware_hint_gives_way_to_the_full_message_for_several_unknown_keys(capsys):
    err = _usage_error(capsys, ["run", "elementall", "--duration", "1ms", "--set", "firmware.typo=2",
                                "--set", "firmware.kp=1"], "typo")
    assert "--set mcm1.firmware.kp" not in err


@pytest.mark.parametrize("text, shown", [
    ("1e-300s", "1e-300s"), ("1e-20s", "1e-20s"), ("0.5ps", "0.5ps"), ("2.5ms", "2.5ms"), ("90s", "90s")])
def test_a_duration_in_a_message_is_shown_in_a_unit_that_reads(text, shown):
    """Below a thousandth of a picosecond a duration is shown in seconds: --duration 1e-300s was
    echoed as 1e-288ps."""
    from mcusim.params import fmt_duration
    from mcusim.time import parse_duration
    assert fmt_duration(parse_duration(text)) == shown


@settings(max_examples=40, deadline=None)
@given(hz=st.integers(10_000, 1_000_000), unit=st.sampled_from(["Hz", "kHz", "MHz"]))
def test_a_parameter_in_hertz_takes_a_frequency_with_its_unit_as_that_many_hertz(hz, unit):
    """README "Command line": a parameter declared in Hz takes ``400kHz`` as 400000, written
    either way; the value is exact (no float rounding of ``0.4MHz``)."""
    from fractions import Fraction

    from mcusim.params import Param
    scale = {"Hz": 1, "kHz": 1000, "MHz": 1_000_000}[unit]
    text = f"{Fraction(hz, scale).numerator / Fraction(hz, scale).denominator!r}{unit}"
    if Fraction(text[:-len(unit)]) * scale != hz:
        return          # the decimal shown does not hold the value exactly (e.g. 1/3 kHz)
    p = Param(100_000, min=10_000, max=1_000_000, unit="Hz")
    assert p.check(text, "f") == hz == p.check(str(hz), "f")
    assert p.check_file(text, "f") == hz


@pytest.mark.parametrize("value, needle", [
    ("2MHz", "firmware.i2c_frequency = '2MHz': must be from 10000 to 1000000 Hz"),
    ("100.0005kHz", "expected a whole number of hertz"),
    ("fastHz", "bad frequency"),
    ("400kbaud", "expected an integer"),
])
def test_a_frequency_parameter_out_of_range_or_not_whole_is_named_as_written(capsys, value, needle):
    _usage_error(capsys, ["run", "ciaa-edu", "--duration", "10ms", "--set", f"firmware.i2c_frequency={value}"],
                 needle)


def test_the_scl_frequency_given_with_a_unit_sets_the_i2c_clock_registers_as_the_number_does():
    """400kHz reaches NuttX's lpc43_i2c_setfrequency as 400000: above 100 kHz it splits the period
    47:83, SCLH = 204 MHz / 130 * 47 / f = 184 and SCLL = 204 MHz / 130 * 83 / f = 325 (C integer
    arithmetic), read back from I2C0 once the controller has polled the bus."""
    regs = []
    for value in ("400kHz", 400000):
        sim = mcusim.load("ciaa-edu", overrides={"firmware.i2c_frequency": value})
        try:
            sim.run(seconds=0.05)
            i2c0 = next(p for p in sim.peripherals() if p.name == "I2C0")
            regs.append((i2c0.value["SCLH"], i2c0.value["SCLL"]))
        finally:
            sim.close()
    assert regs[0] == regs[1] == (204_000_000 // 130 * 47 // 400_000, 204_000_000 // 130 * 83 // 400_000)


HUGE = "9" * 400


@pytest.mark.parametrize("board, key", [("nucleo-f746", "motor1.R"), ("nucleo-f746", "encoder1.counts_per_rev"),
                                        ("nucleo-f746", "/motor1/set_pos"), ("nucleo-f746", "firmware.pid_period_ms"),
                                        ("pro-mini", "velocity")])
def test_an_integer_beyond_the_float_range_is_a_usage_error_naming_its_key(capsys, board, key):
    """400 nines were read as one integer and overflowed where a model met a float (exit 1)."""
    _usage_error(capsys, ["run", board, "--duration", "1ms", "--set", f"{key}={HUGE}"],
                 f"{key} = 9.99999e+399: too large")


@pytest.mark.parametrize("line", [f'torque = {{ motor = "motor1", nm = {HUGE} }}',
                                  f'publish = {{ "/motor1/set_pos" = {HUGE} }}'], ids=["torque", "publish"])
def test_an_integer_beyond_the_float_range_in_a_scenario_is_named_at_its_line(tmp_path, capsys, line):
    sc = tmp_path / "s.toml"
    sc.write_text(f'[scenario]\nboard = "nucleo-f746"\nduration = "10ms"\n\n[[at]]\ntime = "1ms"\n{line}\n')
    _usage_error(capsys, ["run", "nucleo-f746", "--scenario", str(sc)], f"{sc}:7:", "too large")


@pytest.mark.parametrize("argv, needle", [
    (["run", "nucleo-f746", "--duration", "1" * 5000 + "ms"], "too many digits (5000)"),
    (["run", "nucleo-f746", "--duration", "1ms", "--sample", "1" * 5000 + "ms"], "too many digits (5000)"),
    (["run", "nucleo-f746", "--duration", "1ms", "--gdb", "1" * 5000], "expected a TCP port number"),
    (["bench", "nucleo-f746", "--repeat", "1" * 5000], "expected a whole number from 1 to 100"),
], ids=["duration", "sample", "gdb", "repeat"])
def test_a_number_with_thousands_of_digits_is_one_short_line(capsys, argv, needle):
    """Python refuses to read an integer of more than 4300 digits: that was an internal error, or
    argparse's 'invalid _duration value' echoing 5 KB."""
    err = _usage_error(capsys, argv, needle)
    assert len(err) < 300


def test_a_peripheral_placed_past_the_end_of_the_address_space_is_refused_at_its_line(tmp_path, capsys):
    text = mcusim.board.shipped_text("nucleo-f746")
    assert "base = 0x40000400" in text          # TIM3
    bad = tmp_path / "b.toml"
    bad.write_text(text.replace("base = 0x40000400", "base = 0xFFFFFFF0"))
    _usage_error(capsys, ["run", str(bad), "--duration", "1ms"], "TIM3 at 0xfffffff0", "past the end of the 4 GiB")


def test_a_huge_key_is_cut_in_the_message_and_the_list_after_it_stays(tmp_path, capsys):
    """A 100,000-character topic in a scenario: the message names it in 60 characters and keeps
    the inputs the firmware takes; a long file path stays whole."""
    sc = tmp_path / ("d" * 120) / "s.toml"
    sc.parent.mkdir()
    sc.write_text(f'[scenario]\nboard = "nucleo-f746"\nduration = "5ms"\n\n[[at]]\ntime = "1ms"\n'
                  f'publish = {{ "/{"x" * 100_000}" = 1 }}\n')
    err = _usage_error(capsys, ["run", "nucleo-f746", "--scenario", str(sc)], f"{sc}:7:", "/motor2/enable")
    assert len(err) < 700 and "x" * 61 not in err


@pytest.mark.parametrize("cmd", ["run", "bench"])
def test_a_duration_off_the_tick_by_less_than_twelve_digits_show_is_shown_with_all_its_digits(capsys, cmd):
    """'--duration 1ms: not a whole number of base ticks; the nearest is 1ms' contradicted itself."""
    _usage_error(capsys, [cmd, "nucleo-f746", "--duration", "1.0000000000000000000000001ms"],
                 "--duration 1.0000000000000000000000001ms: not a whole number of base ticks")


def test_a_mavlink_link_without_firmware_says_no_firmware_is_the_reason(capsys):
    _usage_error(capsys, ["run", "ciaa-edu", "--no-firmware", "--mavlink", "udpout:127.0.0.1:14550",
                          "--duration", "1ms"], "runs without firmware (--no-firmware)")


def test_boards_show_takes_a_toml_path_as_every_command_takes_a_board(tmp_path, capsys):
    """docs/boards.md: a .toml path works wherever a board name does."""
    text = mcusim.board.shipped_text("pro-mini")
    p = tmp_path / "mine.toml"
    p.write_text(text)
    assert main(["boards", "--show", str(p)]) == 0
    assert capsys.readouterr().out == text
    p.write_text(text.replace("[firmware]", "[firmwear]"))
    _usage_error(capsys, ["boards", "--show", str(p)], "mine.toml")


@pytest.mark.parametrize("word, want", [("estop", "an estop"), ("8-bit", "an 8-bit"), ("16-bit", "a 16-bit"),
                                        ("motor", "a motor"), ("18-bit", "an 18-bit"), ("1-bit", "a 1-bit")])
def test_messages_put_the_article_a_reader_says(word, want):
    from mcusim.params import a_or_an
    assert a_or_an(word) == want


def test_a_scenario_value_of_the_wrong_type_is_shown_as_toml_writes_it(tmp_path, capsys):
    sc = tmp_path / "f.toml"
    sc.write_text('[scenario]\nboard = "nucleo-f746"\nduration = "5ms"\n\n[[at]]\ntime = "1ms"\n'
                  'fault = { encoder = "encoder1", kind = "missing_edges", count = true }\n')
    _usage_error(capsys, ["run", "nucleo-f746", "--scenario", str(sc)], "fault.count = true: expected a whole number")


def test_numbers_past_pythons_4300_digit_limit_are_named_in_files_and_the_api(tmp_path, capsys):
    """TOML and str() refuse integers of more than 4300 digits with a ValueError: that was an
    internal error from a board or scenario file, and a raw ValueError from the API."""
    sc = tmp_path / "s.toml"
    sc.write_text('[scenario]\nboard = "pro-mini"\nduration = "5ms"\n\n[set]\nvelocity = ' + "9" * 5000 + "\n")
    _usage_error(capsys, ["run", "pro-mini", "--scenario", str(sc)], f"{sc}:6: a number of more than 4300 digits")
    with pytest.raises(mcusim.ConfigError, match="motor.R = an integer of about 5000 digits: too large"):
        mcusim.load("pro-mini", overrides={"motor.R": 10 ** 5000})
    with pytest.raises(mcusim.ConfigError, match="cmd_rate_hz = '1e400Hz': too large"):
        mcusim.load("ciaa-edu", overrides={"firmware.cmd_rate_hz": "1e400Hz"})
