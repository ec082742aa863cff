"""The Python API answers a wrong argument with an mcusim error that names it, never with a
TypeError or AttributeError from deep inside, and never by doing something else silently (a
review found each of these)."""

import pytest

import mcusim
from mcusim.errors import ConfigError, McusimError
from mcusim.scenario import load_scenario, run_scenario
from mcusim.testing import wait_until


@pytest.fixture(scope="module")
def bare():
    sim = mcusim.load("nucleo-f746", firmware=False)
    yield sim
    sim.close()


@pytest.mark.parametrize("kw, words", [
    ({"seconds": True}, "expected a number of seconds"),
    ({"seconds": "0.01"}, "as the command line and scenarios take it"),     # a bare number as text
    ({"until": False}, "expected a number of seconds"),
    ({"seconds": 1e300}, "beyond the last tick"),
    ({"seconds": 1e-12}, "shorter than half a base tick"),
    ({"seconds": 0.001, "stop": 5}, "stop is a function"),
    ({"cycles": "x"}, "expected a whole number of cycles"),
    ({"cycles": float("nan")}, "expected a whole number of cycles"),
    ({"cycles": float("inf")}, "expected a whole number of cycles"),
    ({"cycles": True}, "expected a whole number of cycles"),
])
def test_run_refuses_a_time_it_would_not_run_as_asked(bare, kw, words):
    now = bare.kernel.now
    with pytest.raises(McusimError, match=words):
        bare.run(**kw)
    assert bare.kernel.now == now


def test_run_of_zero_seconds_is_no_time_and_no_error(bare):
    now = bare.kernel.now
    bare.run(seconds=0)
    assert bare.kernel.now == now


def test_wait_until_needs_a_function():
    sim = mcusim.load("nucleo-f746", firmware=False)
    with pytest.raises(McusimError, match="function to call"):
        wait_until(sim, True)


@pytest.mark.parametrize("kw, words", [
    ({"firmware": 5}, "firmware=5"),
    ({"overrides": {5: 1}}, "key 5 is not text"),
])
def test_load_refuses_arguments_of_the_wrong_kind(kw, words):
    with pytest.raises(ConfigError, match=words):
        mcusim.load("nucleo-f746", **kw)


@pytest.mark.parametrize("call, words", [
    (lambda m: m.write32(0x40010034, -1), "bus value -1"),
    (lambda m: m.write32(0x40010034, 1.5), "bus value 1.5"),
    (lambda m: m.write32(0x40010034, 1 << 32), "32-bit write"),
    (lambda m: m.write8(0x40010034, None), "bus value None"),
    (lambda m: m.read32("TIM1"), "bus address 'TIM1'"),
])
def test_bus_access_from_a_test_checks_its_address_and_value(bare, call, words):
    with pytest.raises(McusimError, match=words):
        call(bare.mcu)


def test_a_written_register_reads_back_through_the_checked_api(bare):
    bare.mcu.write32(0x40010034, 0x1234)     # TIM1.CCR1 (preload off after reset)
    assert bare.mcu.read32(0x40010034) == 0x1234


@pytest.mark.parametrize("call, words", [
    (lambda s, d: s.trace_vcd(d / "x.vcd", sample=0), "at least one base tick"),
    (lambda s, d: s.trace_vcd(d / "x.vcd", sample="1ps"), "at least one base tick"),
    (lambda s, d: s.trace_vcd(d / "x.vcd", sample="soon"), "bad duration"),
    (lambda s, d: s.trace_vcd(d / "x.vcd", sample="50"), "a duration with a unit"),     # not 50 s
    (lambda s, d: s.trace_csv(d / "x.csv", sample="1"), "a duration with a unit"),
    (lambda s, d: s.trace_vcd(d), "is a folder"),
    (lambda s, d: s.trace_vcd(d / "no" / "x.vcd"), "cannot write it"),
    (lambda s, d: s.trace_csv(d / "no" / "x.csv"), "cannot write it"),
    (lambda s, d: s.trace_registers(None), "not a file name"),
    (lambda s, d: s.trace_registers(d / "r.jsonl", filter=5), "give names as text"),
])
def test_a_trace_with_a_bad_path_or_sample_is_refused_naming_it(tmp_path, call, words):
    sim = mcusim.load("nucleo-f746", firmware=False)
    with pytest.raises(ConfigError, match=words):
        call(sim, tmp_path)
    sim.close()


def test_connect_serial_refuses_an_unknown_endpoint_word_and_member():
    sim = mcusim.load("ciaa-edu")
    with pytest.raises(ConfigError, match='"pty", "buffer" or an object'):
        sim.connect_serial("USART2", "tcp")
    with pytest.raises(ConfigError, match="no such board"):
        sim.connect_serial("USART2", "buffer", member="x")
    ep = sim.connect_serial("USART2", "buffer")     # the line is still free after the refusals
    sim.run(seconds="1ms")
    sim.close()
    assert ep.usart is not None


@pytest.mark.parametrize("data", [300, "abc", [300], None, [True]])
def test_feed_takes_bytes_not_a_count_or_text(data):
    sim = mcusim.load("ciaa-edu")
    ep = sim.connect_serial("USART2", "buffer")
    with pytest.raises(McusimError, match="give bytes"):
        ep.feed(data)
    ep.feed([0x41, 0x42])               # a list of byte values is bytes
    ep.feed(bytearray(b"C"))
    sim.close()


def test_feed_takes_any_byte_buffer_and_load_takes_none_for_no_firmware():
    import array

    import numpy as np
    sim = mcusim.load("ciaa-edu")
    ep = sim.connect_serial("USART2", "buffer")
    ep.feed(np.array([1, 2, 3], dtype=np.uint8))
    ep.feed(array.array("B", [4]))
    sim.close()
    sim = mcusim.load("nucleo-f746", firmware=None)
    assert sim.firmware is None
    sim.close()


def test_a_simulation_loaded_and_dropped_without_running_leaves_no_warning():
    """Each firmware's tasks are given as functions (xTaskCreate's pvTaskCode): their coroutines
    are made at their first step, so dropping a simulation that never ran leaves no "coroutine
    ... was never awaited" (it did for every board, and failed tests run with -W error)."""
    import subprocess
    import sys
    code = ("import gc, mcusim\n"
            "for b in ('nucleo-f746', 'pro-mini', 'ciaa-edu', 'elementall'):\n"
            "    s = mcusim.load(b)\n"
            "    del s\n"
            "    gc.collect()\n")
    out = subprocess.run([sys.executable, "-W", "error", "-c", code], check=False, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0 and "never awaited" not in out.stderr, out.stderr


@pytest.mark.parametrize("call", [
    lambda s, tmp: s.publish("/motor1/set_pos", 1.0),
    lambda s, tmp: s.trace_vcd(tmp / "late.vcd"),
    lambda s, tmp: s.trace_csv(tmp / "late.csv"),
    lambda s, tmp: s.trace_registers(tmp / "late.jsonl"),
    lambda s, tmp: s.connect_serial("USART3", "buffer"),
])
def test_a_closed_simulation_refuses_commands_traces_and_links_as_run_does(tmp_path, call):
    """After close() a command, a trace or a link would never be seen (nothing runs on): refused
    as run() refuses, and no empty file is left behind."""
    sim = mcusim.load("nucleo-f746")
    sim.close()
    with pytest.raises(McusimError, match="was closed"):
        call(sim, tmp_path)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("call, words", [
    (lambda: mcusim.load(5), "board = 5: expected a board name or the path"),
    (lambda: mcusim.load(["nucleo-f746"]), "expected a board name or the path"),
    (lambda: mcusim.load("nucleo-f746", overrides={"motor1.R": 10 ** 400}), "too large"),
])
def test_load_names_a_board_or_a_number_of_the_wrong_kind(call, words):
    with pytest.raises(ConfigError, match=words):
        call()


@pytest.mark.parametrize("call, words", [
    (lambda: run_scenario("step_response", overrides="x"), "overrides = 'x': expected a mapping"),
    (lambda: load_scenario(None), r"load_scenario\(None\): expected the path"),
    (lambda: load_scenario(5), r"load_scenario\(5\): expected the path"),
    (lambda: load_scenario(""), "expected the path of a scenario file"),
])
def test_the_scenario_api_names_a_wrong_argument(call, words):
    with pytest.raises(ConfigError, match=words):
        call()


@pytest.mark.parametrize("value, shown", [(0.0, "= 0.0:"), (1.0, "= 1.0:"), (0.5, "= 0.5:")])
def test_a_switch_refuses_a_float_showing_it_as_given(value, shown):
    """/motor1/enable = 0.0 had been refused as '= 0: expected true or false', a value the same
    switch takes: a float is no switch position (a follow from a position to a switch is refused
    by it), and the message now shows it as given."""
    from mcusim.params import Param
    assert Param(True).check(0, "/motor1/enable") is False and Param(True).check(1, "/motor1/enable") is True
    with pytest.raises(ConfigError, match=f"/motor1/enable {shown} expected true or false"):
        Param(True).check(value, "/motor1/enable")


@pytest.mark.parametrize("call, words", [
    (lambda: run_scenario("step_response", duration="1"), "duration = '1': expected a number of seconds"),
    (lambda: setattr(load_scenario("step_response"), "duration", True), "duration = True"),
])
def test_a_scenario_duration_without_a_unit_is_refused_as_run_refuses_it(call, words):
    """scenarios.md: a plain number 'is refused rather than taken as seconds'; run_scenario and the
    duration setter had taken "1" as one second."""
    with pytest.raises(ConfigError, match=words):
        call()


def test_a_ground_stations_wait_without_a_unit_is_refused_as_run_refuses_it():
    from mcusim.mavlink import MavlinkClient
    sim = mcusim.load("ciaa-edu")
    try:
        gcs = MavlinkClient(sim, "USART3")
        with pytest.raises(ConfigError, match=r"recv_match\(timeout='2'\)"):
            gcs.recv_match("HEARTBEAT", timeout="2")
        assert sim.time_s == 0
    finally:
        sim.close()


@pytest.mark.parametrize("helper", ["wait_until", "wait_for_pin", "run_for"])
def test_the_testing_helpers_name_a_sim_that_is_not_one(helper):
    import mcusim.testing as t
    args = {"wait_until": (lambda: True,), "wait_for_pin": ("PB1", 1), "run_for": ("1ms",)}[helper]
    with pytest.raises(McusimError, match=f"{helper}\\(sim, ...\\): sim = None is not a simulation"):
        getattr(t, helper)(None, *args)
