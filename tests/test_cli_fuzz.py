"""Property: whatever a user types — arguments, --set values, scenario files, board files — the
command line answers with exit status 0, 1 or 2, no traceback, at most a few lines on stderr, no
"coroutine never awaited" warning, and in bounded time (issue 11).

Runs are kept short: every command gets ``--max-duration 2ms`` last, so a valid run lasts at most
2 ms of simulated time and a longer duration is refused as a usage error; examples are limited."""

import contextlib
import gc
import io
import os
import string
import tempfile
import time
import warnings

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mcusim.board import board_names, read_profile
from mcusim.cli import main

BOARDS = board_names()
SHIPPED_TEXT = {name: read_profile(name)[1] for name in BOARDS}
WALL_BOUND = 30.0                     # seconds a single command may take (a 2 ms run takes < 2 s)
SETTINGS = settings(max_examples=30, deadline=None, derandomize=True, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def _invoke(argv) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    t0 = time.monotonic()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), \
            warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rc = main(argv)
        gc.collect()                     # a coroutine dropped unawaited warns here
    wall = time.monotonic() - t0
    text = err.getvalue()
    assert rc in (0, 1, 2), (argv, rc, text)
    assert "Traceback" not in text and "internal error" not in text, (argv, text)
    if not (argv[:1] == ["trace"] and rc != 2):      # trace writes its run summary on stderr
        assert text.count("\n") <= 3, (argv, text)
    assert not [w for w in caught if "never awaited" in str(w.message)], (argv, [str(w.message) for w in caught])
    assert wall < WALL_BOUND, (argv, wall)
    return rc, out.getvalue(), text


# --- generated arguments ------------------------------------------------------------------------------
_junk = st.text(alphabet=string.printable + "µ€\u00a0", max_size=12)
_numbers = st.one_of(
    st.sampled_from(["0", "-0", "1", "-1", "1e9", "-1e9", "1e308", "1e400", "inf", "-inf", "nan", "0x10",
                     "999", "1.5", "true", "false", "", "abc", "1e-300", "5.0", "256", "-5"]),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(min_value=-10**20, max_value=10**20).map(str))
_durations = st.one_of(st.sampled_from(["1ms", "500us", "2ms", "0s", "1ps", "5", "1e300s", "1e400s", "nan s",
                                        "-1ms", "1 parsec", "10 ms", "1min", "0.5ms", "1e-3s", ""]), _junk)
_keys = st.one_of(st.sampled_from([
    "/motor1/set_pos", "/motor2/enable", "/motor3/set_pos", "velocity", "pid_enable", "clear_faults",
    "cmd_vel.linear", "cmd_vel.angular", "cmd_vel.lateral", "cmd_vel.stream", "motor1.R", "motor1.L",
    "motor1.J", "motor1.preset", "motor.load_torque", "bridgeA.I_ocd", "bridgeA.V_th", "ibt2.R_IS",
    "encoder1.counts_per_rev", "battery.count", "battery.soc", "battery.step", "body.mass", "body.sides",
    "mcm1.present", "mcm2.motor.R", "mcm1.firmware.i2c_address", "firmware.kp", "firmware.variant",
    "firmware.pid_period_ms", "firmware.counts_per_turn", "firmware.sample_ms", "firmware.i2c_address",
    "firmware.wire_variant", "firmware.tick_hz", "firmware.console_baud", "firmware.modules",
    "firmware.layout", "firmware.i2c_frequency", "firmware.nope", "nope.x", "motor1.", ".x", "="]), _junk)
_sets = st.tuples(_keys, _numbers).map(lambda kv: ["--set", f"{kv[0]}={kv[1]}"])
_names = st.sampled_from(["a.vcd", "a.csv", "a.png", "a.json", "a.gtkw", "b.svg", "c.gif", "sub/x.vcd", ".",
                          "/dev/null", "-", ""])
_options = st.one_of(
    _sets,
    st.tuples(st.sampled_from(["--duration", "--sample", "--vcd-sample", "--max-duration"]), _durations).map(list),
    st.tuples(st.sampled_from(["--vcd", "--csv", "--plot", "--summary", "--register-log", "--json"]),
              _names).map(list),
    st.tuples(st.sampled_from(["--register-log-filter", "--filter", "--repeat", "--scenario"]),
              st.one_of(st.sampled_from(["TIM1", "", "TIM33", "GPIO*", "mcm1.TWI", "0", "-3", "1", "101",
                                         "step_response", "nope"]), _junk)).map(list),
    st.sampled_from([["--strict"], ["--no-firmware"], ["-q"], ["--help"], ["--bogus"]]),
)
_argv = st.tuples(
    st.sampled_from(["run", "trace", "bench", "boards", "runn", ""]),
    st.one_of(st.sampled_from(BOARDS), _junk),
    st.lists(_options, max_size=5),
).map(lambda t: [t[0], t[1], *[x for opt in t[2] for x in opt]])


@SETTINGS
@given(_argv)
def test_generated_command_lines_get_one_clean_answer(argv):
    with tempfile.TemporaryDirectory() as d:
        cwd = os.getcwd()
        os.chdir(d)
        try:
            if argv[0] in ("run", "trace", "bench"):
                argv = [*argv, "--max-duration", "2ms"]
                if argv[0] == "bench":
                    argv += ["--repeat", "1"]
            _invoke(argv)
        finally:
            os.chdir(cwd)


# --- generated scenario files ---------------------------------------------------------------------------
_values = st.one_of(
    st.sampled_from(['"1ms"', '"0s"', '"2ms"', '"1e400s"', '"5"', "1", "0.5", "nan", "inf", "-1", "true",
                     '"motor1"', '"encoder1"', '"nope"', '"/motor1/set_pos"', "[]", "{}", '{ "/motor1/set_pos" = 1 }',
                     '{ motor = "motor1", nm = 1e9 }', '{ motor = "motor1", angle = 1e6, over = "1ms" }',
                     '{ kind = "stall", motor = "motor1" }', '{ kind = "missing_edges", encoder = "encoder1", count = 1e9 }',
                     '{ from = "/motor1/get_pos", to = "/motor2/set_pos", period = "1ns" }',
                     '{ kind = "battery_sag", battery = "battery", amps = 1e9 }']),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    _junk.map(lambda s: '"' + s.replace("\\", "").replace('"', "") + '"'))
_scenario_keys = st.sampled_from(["time", "duration", "board", "publish", "torque", "turn", "follow", "fault",
                                  "part", "attr", "min", "max", "approx", "tol", "equals", "topic", "summary",
                                  "name", "description", "motor1.R", '"firmware.kp"', "velocity", "bogus"])
_tables = st.sampled_from(["[scenario]", "[[at]]", "[[expect]]", "[set]", "[report]", "[bogus]", "[scenario"])
_scenario_text = st.lists(st.one_of(_tables, st.tuples(_scenario_keys, _values).map(lambda kv: f"{kv[0]} = {kv[1]}")),
                          max_size=14).map(lambda lines: '[scenario]\nduration = "1ms"\n' + "\n".join(lines) + "\n")


@SETTINGS
@given(st.one_of(_scenario_text.map(lambda t: t.encode("utf-8")), st.binary(max_size=64)),
       st.sampled_from(["nucleo-f746", "pro-mini"]))
def test_generated_scenario_files_get_one_clean_answer(data, board):
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "s.toml")
        with open(path, "wb") as f:
            f.write(data)
        _invoke(["run", board, "--scenario", path, "--max-duration", "2ms", "-q"])


# --- generated board files: a shipped profile with one line changed ------------------------------------
def _lines(board):
    from importlib.resources import files
    return (files("mcusim.boards") / f"{board}.toml").read_text().splitlines()


_profile_values = st.sampled_from(['"mcusim.periph.stm32.tim:Tim"', '"os:system"', "0xFFFFFFFFF", "-1", "99999", '"1Hz"',
                                  '"0MHz"', '"216.5MHz"', "[1, 2]", '"stm32-gpio"', '"avr-twi"', '"l6206"'])


@st.composite
def _board_files(draw):
    board = draw(st.sampled_from(BOARDS))
    lines = _lines(board)
    i = draw(st.integers(min_value=0, max_value=len(lines) - 1))
    how = draw(st.sampled_from(["value", "delete", "insert", "key"]))
    if how == "delete":
        lines.pop(i)
    elif how == "insert":
        lines.insert(i, draw(st.tuples(_scenario_keys | st.sampled_from(["class", "kind", "irq", "base"]),
                                       _values).map(lambda kv: f"{kv[0]} = {kv[1]}") | _tables))
    elif "=" in lines[i]:
        key, _, _ = lines[i].partition("=")
        if how == "value":
            lines[i] = f"{key}= {draw(_values | _profile_values)}"
        else:
            lines[i] = f"{draw(_scenario_keys)} = {lines[i].partition('=')[2]}"
    return board, "\n".join(lines) + "\n"


@SETTINGS
@given(_board_files())
def test_generated_board_files_get_one_clean_answer(case):
    board, text = case
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, f"{board}-x.toml")
        with open(path, "w", encoding="utf-8") as f:
            f.write(text)
        _invoke(["run", path, "--duration", "1ms", "--max-duration", "2ms", "-q"])
