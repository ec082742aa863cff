"""The command line: listing, running with VCD and JSON summary, and one-line errors with exit 2."""

import json
import subprocess
import sys
from fractions import Fraction

import pytest
from vcd.reader import TokenKind, tokenize

from mcusim.cli import main


def test_boards_lists_nucleo(capsys):
    assert main(["boards"]) == 0
    assert "nucleo-f746" in capsys.readouterr().out


def test_run_writes_summary_json_and_vcd(tmp_path, capsys):
    vcd, js = tmp_path / "t.vcd", tmp_path / "s.json"
    rc = main(["run", "nucleo-f746", "--duration", "20ms", "--set", "/motor1/set_pos=0.05",
               "--vcd", str(vcd), "--summary", str(js)])
    assert rc == 0
    out = capsys.readouterr().out
    assert "motor1" in out and "real time" in out
    s = json.loads(js.read_text())
    assert s["simulated_s"] == 0.02
    assert set(s) >= {"simulated_s", "wall_s", "realtime_factor", "events", "motors"}
    assert set(s["motors"]["motor1"]) >= {"angle_rad", "setpoint_rad", "peak_current_a"}
    assert s["motors"]["motor1"]["setpoint_rad"] == 0.05
    # the VCD names pins as on the chip in a scope named after the board, IRQ lines and plant reals
    scopes, names, changes = [], set(), 0
    with open(vcd, "rb") as f:
        for tok in tokenize(f):
            if tok.kind is TokenKind.SCOPE:
                scopes.append(tok.scope.ident)
            elif tok.kind is TokenKind.VAR:
                names.add((tok.var.reference, tok.var.type_.value))
            elif tok.kind is TokenKind.CHANGE_SCALAR:
                changes += 1
    assert "nucleo-f746" in scopes
    for pin in ("PE9", "PE11", "PA5", "PA3", "PB4", "PB5", "PD12", "PD13", "PF15", "PF5"):
        assert (pin, "wire") in names
    assert ("TIM3", "wire") in names and ("TIM1_UP", "wire") in names
    assert ("motor1.angle_rad", "real") in names and ("motor1.current_a", "real") in names
    # a 0.05 rad step asks for 20 % duty at first (Kp = 400 %/rad): PE9 carries 50 kHz PWM, two
    # edges per 20 µs period, until the motor nears the set point
    assert changes > 500


def test_bad_unit_is_one_line_and_exit_2(capsys):
    assert main(["run", "nucleo-f746", "--duration", "2 parsecs"]) == 2
    err = capsys.readouterr().err
    assert "bad duration '2 parsecs'" in err and "Traceback" not in err


def test_unknown_board_exit_2(capsys):
    assert main(["run", "nucleo-f4"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("mcusim: error: unknown board 'nucleo-f4'") and "\n" not in err


def test_unknown_set_key_exit_2(capsys):
    assert main(["run", "nucleo-f746", "--duration", "1ms", "--set", "motor1.banana=3"]) == 2
    assert "banana" in capsys.readouterr().err
    assert main(["run", "nucleo-f746", "--duration", "1ms", "--set", "/motor3/set_pos=1"]) == 2
    assert "/motor3/set_pos" in capsys.readouterr().err


def test_console_entry_point_runs_without_traceback():
    r = subprocess.run([sys.executable, "-m", "mcusim", "run", "nucleo-f746", "--duration", "1ms",
                        "--set", "firmware.variant=bogus"], capture_output=True, text=True, check=False)
    assert r.returncode == 2
    assert "firmware.variant = 'bogus': expected one of correct, thesis" in r.stderr and "Traceback" not in r.stderr


def test_run_pro_mini_with_velocity_prints_module_summary(tmp_path, capsys):
    js = tmp_path / "s.json"
    assert main(["run", "pro-mini", "--set", "velocity=10", "--duration", "200ms", "--summary", str(js)]) == 0
    out = capsys.readouterr().out
    assert "velocity_setpoint_rpm = 10.000" in out and "faults = []" in out
    s = json.loads(js.read_text())
    # the set point travels as whole counts/s: round(10·50·2048/60) = 17067 -> 10.0002 rpm
    assert abs(s["firmware"]["velocity_setpoint_rpm"] - 10.0) < 60 / (50 * 2048)
    assert s["motors"]["motor"]["speed_rpm"] > 1.0  # accelerating


def test_unknown_module_input_names_the_inputs(capsys):
    assert main(["run", "pro-mini", "--set", "speed=10", "--duration", "1ms"]) == 2
    err = capsys.readouterr().err
    assert "no input 'speed'" in err and "velocity" in err


def test_run_elementall_summary_reports_odometry_pose_battery_and_a_removed_module(tmp_path, capsys):
    js = tmp_path / "s.json"
    rc = main(["run", "elementall", "--set", "cmd_vel.linear=0.5", "--set", "cmd_vel.angular=0.2",
               "--set", "mcm3.present=false", "--set", "battery.count=3", "--duration", "0.3s",
               "--summary", str(js)])
    assert rc == 1                                         # the controller reports the missing module
    captured = capsys.readouterr()
    out = captured.out
    assert "odometry" in out and "true pose" in out and "battery" in out
    assert captured.err == "mcusim: the firmware reported: modules_missing\n"
    s = json.loads(js.read_text())
    assert set(s["odometry"]) == set(s["pose"]) == {"x", "y", "yaw"}
    assert s["battery_v"] == 11.65 + 1.10 * 1.0          # no load: the open-circuit voltage
    assert s["firmware"]["modules_missing"] == ["0x0a"] and not s["firmware"]["motors_enabled"]
    assert set(s["motors"]) == {"mcm1.motor", "mcm2.motor", "mcm3.motor", "mcm4.motor"}


def test_system_set_mistakes_are_one_line_and_exit_2(capsys):
    for args, msg in ((["--set", "battery.count=9"], "from 1 to 8"),
                      (["--set", "mcm9.present=false"], "boards: rcm, mcm1"),
                      (["--set", "rcm.present=false"], "main board"),
                      (["--set", "mcm1.present=maybe"], "expected true or false")):
        assert main(["run", "elementall", "--duration", "1ms", *args]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and msg in err, err


class _Tty:
    def __init__(self):
        self.text = ""

    def isatty(self):
        return True

    def write(self, s):
        self.text += s

    def flush(self):
        pass


def test_progress_bar_draws_on_a_terminal_only_and_slicing_does_not_change_the_run():
    import mcusim
    from mcusim.progress import run_with_progress

    def run(stream, quiet=False):
        sim = mcusim.load("nucleo-f746", overrides={"/motor1/set_pos": 0.3})
        run_with_progress(sim, "20ms", quiet=quiet, stream=stream, after=0.0)
        m = sim.part("motor1")   # (the event count is a cost, which slices may change; the run is not)
        return m.current, m.speed, m.angle, sim.part("encoder1").edges, sim.kernel.now

    tty = _Tty()
    sliced = run(tty)
    assert "100.0%" in tty.text and tty.text.endswith("\n") and "real time" in tty.text
    quiet = _Tty()
    assert run(quiet, quiet=True) == sliced and quiet.text == ""
    import io
    pipe = io.StringIO()
    assert run(pipe) == sliced and pipe.getvalue() == ""


def test_every_subcommand_help_has_examples(capsys):
    for cmd in ("boards", "run", "trace", "bench"):
        assert main([cmd, "--help"]) == 0
        assert "examples:" in capsys.readouterr().out


@pytest.mark.parametrize("expect, rc", [
    ('summary = "firmware.faults"\ncontains = "modules_missing"\n', 0),    # the fault is the point
    ('summary = "firmware.faults"\nequals = []\n', 1),                     # no fault wanted: FAIL
    ('summary = "firmware.modules_missing"\ncontains = "0x0a"\n', 1),     # faults not checked
    ('time = "1ms"\nsummary = "firmware.faults"\nequals = []\n', 1),     # checked before the fault came
])
def test_a_scenario_that_checks_the_firmware_faults_decides_the_exit_status(tmp_path, capsys, expect, rc):
    """Was exit 1 whatever the scenario said: a fault-injection scenario expecting the fault could
    not pass. A scenario checking ``firmware.faults`` now decides; one that does not leaves a
    reported fault failing the run as before."""
    sc = tmp_path / "ce.toml"
    sc.write_text('[scenario]\nduration = "300ms"\n[[expect]]\n' + expect)
    assert main(["run", "ciaa-edu", "--scenario", str(sc)]) == rc
    err = capsys.readouterr().err
    assert "the firmware reported: modules_missing" in err


def test_version_prints_the_installed_version(capsys):
    from importlib.metadata import version
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"mcusim {version('mcusim')}"


def test_an_unknown_option_points_at_the_help_of_its_command(capsys):
    assert main(["bench", "nucleo-f746", "--foo"]) == 2
    assert capsys.readouterr().err == "mcusim: error: unrecognized arguments: --foo (see mcusim bench --help)\n"


def test_bench_shows_its_runs_on_a_terminal_and_not_with_quiet(monkeypatch, capsys):
    """Was silent for the whole bench (13.6 s for three reference runs of 3 s)."""
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    assert main(["bench", "pro-mini", "--duration", "10ms", "--repeat", "2"]) == 0
    assert "bench run 2/2 (fast engine, 10ms simulated)" in capsys.readouterr().err
    assert main(["bench", "pro-mini", "--duration", "10ms", "--repeat", "2", "-q"]) == 0
    assert "bench run" not in capsys.readouterr().err


def test_the_bench_progress_line_is_cleared_before_an_error(monkeypatch, capsys):
    """From review: the error was printed after the progress text on the same line."""
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    assert main(["bench", "pro-mini", "--duration", "1.0000001ms", "--repeat", "2"]) == 2
    err = capsys.readouterr().err
    assert err.split("\r")[-1].startswith("mcusim: error: --duration"), repr(err)


@pytest.mark.parametrize("argv, hint", [
    (["-q", "run", "pro-mini"], "options of a command go after its name: mcusim run -q ..."),
    (["--bogus", "boards"], "see mcusim boards --help"),
])
def test_an_option_before_the_command_is_pointed_after_it_if_the_command_takes_it(capsys, argv, hint):
    assert main(argv) == 2
    assert hint in capsys.readouterr().err


def test_bench_of_a_run_whose_firmware_faults_exits_1_and_says_so(tmp_path, capsys):
    """A bench command that drives the pro-mini into its driver fault (a set point far above
    ~20 rpm from standstill draws the BTS7960's current limit: README) reported a normal
    real-time factor with exit status 0, for a motor that stopped after the first milliseconds."""
    from mcusim.board import shipped_text
    text = shipped_text("pro-mini")
    start = text.index("[bench.set]")
    line_end = text.index("velocity = ", start)
    p = tmp_path / "pm.toml"
    p.write_text(text[:line_end] + "velocity = 60" + text[text.index("\n", line_end):])
    out = tmp_path / "b.json"
    assert main(["bench", str(p), "--duration", "200ms", "--repeat", "1", "--json", str(out)]) == 1
    err = capsys.readouterr().err
    assert "the firmware reported: driver" in err and "exit status 1" in err
    assert json.loads(out.read_text())["faults"] == ["driver"]
    assert main(["bench", "pro-mini", "--duration", "50ms", "--repeat", "1", "-q"]) == 0


@pytest.mark.parametrize("engine", ["fast", "both"])
def test_bench_figures_are_those_of_one_median_run(monkeypatch, engine):
    """--help: 'the figures are the median run's'. With an even --repeat the wall time had been
    the mean of the two middle runs, and with --engine both events_per_wall_s came from another run
    than the median one (517 events 'at 34,507 per wall s' where 517 / median gave 40,330)."""
    import mcusim.bench as b
    walls = iter([0.5, 0.1, 0.4, 0.2, 0.3, 0.6, 0.7, 0.8])
    monkeypatch.setattr(b, "_warm_up", lambda *a: None)
    real = b.time.perf_counter
    clock = {"t": 0.0}

    def fake():
        return clock["t"]
    monkeypatch.setattr(b.time, "perf_counter", fake)
    import mcusim.sim as s
    run = s.Simulation.run

    def timed(self, **kw):
        out = run(self, **kw)
        clock["t"] += next(walls)
        return out
    monkeypatch.setattr(s.Simulation, "run", timed)
    try:
        got = b.bench("nucleo-f746", Fraction(1, 100), repeat=2, engine=engine)
    finally:
        monkeypatch.setattr(b.time, "perf_counter", real)
    fast_walls = [0.5, 0.1] if engine == "fast" else [0.5, 0.4]     # ("both": fast, reference alternate)
    assert got["wall_s_median"] == pytest.approx(min(fast_walls))   # the lower middle: a run that happened
    assert got["events_per_wall_s"] == got["events"] / got["wall_s_median"]
    assert got["realtime_factor"] == got["simulated_s"] / got["wall_s_median"]


def test_bench_warms_each_engine_up_outside_the_timing(monkeypatch):
    """The first engine timed had carried the process's first imports alone: --repeat 1 --engine
    both on ciaa-edu for 100 ms gave a speedup of 0.3x. Each engine now has an untimed run first."""
    import mcusim.bench as b
    warmed = []
    monkeypatch.setattr(b, "_warm_up", lambda board, sc, engine, fw: warmed.append(engine))
    b.bench("nucleo-f746", Fraction(1, 100), repeat=2, engine="both")
    assert warmed == ["fast", "reference"]
