"""The pytest plugin (mcusim.pytest_plugin) and the helpers of mcusim.testing.

The helpers are tested directly on a bare pro-mini (16 MHz: one base tick is one CPU cycle), with
Timer1 in CTC mode toggling OC1A (PB1) every 100 ticks and pins driven by kernel events at known
ticks. The plugin is tested through pytester: small user test files run in-process, outcomes and
output checked, and the complete example of docs/pytest.md run, as it is written there, in a
pytest subprocess.
"""

import importlib.metadata
import re
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import mcusim
from mcusim.errors import McusimError, TimeError
from mcusim.pytest_plugin import vcd_filename
from mcusim.testing import SimTimeout, describe_condition, run_for, wait_for_pin, wait_until

pytest_plugins = ["pytester"]

DOCS = Path(__file__).resolve().parents[1] / "docs" / "pytest.md"
TCCR1A, TCCR1B, OCR1AL, OCR1AH, DDRB = 0x80, 0x81, 0x88, 0x89, 0x24


def bare():
    return mcusim.load("pro-mini", firmware=False)


def ctc(sim):
    """Timer1 CTC, TOP = OCR1A = 99, clk/1, toggle OC1A: PB1 edges at ticks 100, 200, 300..."""
    mcu = sim.mcu
    mcu.write8(DDRB, 1 << 1)
    mcu.write8(OCR1AH, 0)
    mcu.write8(OCR1AL, 99)
    mcu.write8(TCCR1A, 1 << 6)
    mcu.write8(TCCR1B, 1 << 3 | 1)
    return sim


# ------------------------------------------------------------------ installation, import cost
def test_plugin_is_registered_as_a_pytest11_entry_point():
    eps = {ep.name: ep.value for ep in importlib.metadata.entry_points(group="pytest11")}
    assert eps.get("mcusim") == "mcusim.pytest_plugin"


def test_importing_the_plugin_imports_no_models_and_no_numpy():
    code = ("import sys, mcusim.pytest_plugin; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('numpy', 'scipy', 'vcd') "
            "or m.startswith(('mcusim.periph', 'mcusim.fw', 'mcusim.plant'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


# ------------------------------------------------------------------ wait_for_pin
def test_wait_for_pin_returns_the_exact_tick_of_each_edge():
    sim = ctc(bare())
    listeners = len(sim.pin("PB1")._listeners)
    assert wait_for_pin(sim, "PB1", 1, timeout="1ms") == 100 / 16e6
    assert sim.now == 100
    assert wait_for_pin(sim, "PB1", 0, timeout="1ms") == 200 / 16e6
    assert sim.now == 200
    assert len(sim.pin("PB1")._listeners) == listeners      # its listener is gone again


def test_wait_for_pin_waits_for_an_edge_not_a_level():
    sim = ctc(bare())
    wait_for_pin(sim, "PB1", 1)
    assert sim.pin("PB1").level == 1
    wait_for_pin(sim, "PB1", 1)                              # already high: the next rising edge
    assert sim.now == 300


def test_wait_for_pin_accepts_a_net():
    sim = ctc(bare())
    wait_for_pin(sim, sim.pin("PB1"), 1)
    assert sim.now == 100


def test_wait_for_pin_timeout_names_the_pin_and_leaves_the_time_at_the_timeout():
    sim = ctc(bare())
    with pytest.raises(SimTimeout, match=r"an edge of pin PB2 to 1.*reached 5e-05 s") as exc:
        wait_for_pin(sim, "PB2", 1, timeout="50us")
    assert sim.now == 800
    assert exc.value.time_s == 50e-6 and exc.value.start_s == 0


# ------------------------------------------------------------------ wait_until
def test_wait_until_stops_at_the_event_that_makes_the_condition_true():
    sim = ctc(bare())                                       # events every 100 ticks around it
    sim.kernel.at(12345, sim.pin("PD2").drive, 1)
    t = wait_until(sim, lambda: sim.pin("PD2").level == 1, timeout="1ms")
    assert sim.now == 12345 and t == 12345 / 16e6
    assert sim.wall_s > 0                                   # accounted as sim.run does
    # PB1 toggled 123 times by 12300 (high); the next toggle, at 12400, takes it low
    assert wait_until(sim, lambda: sim.pin("PB1").level == 0) == 12400 / 16e6
    assert sim.now == 12400


def test_wait_until_with_poll_checks_only_on_the_poll_grid():
    sim = bare()
    sim.kernel.at(1000, sim.pin("PD2").drive, 1)
    calls = []

    def high():
        calls.append(sim.now)
        return sim.pin("PD2").level == 1

    assert wait_until(sim, high, timeout="1ms", poll="1us") == 1008 / 16e6   # 1 µs = 16 ticks
    assert sim.now == 1008
    assert calls == list(range(0, 1009, 16))


def test_wait_until_returns_at_once_when_the_condition_already_holds():
    sim = ctc(bare())
    run_for(sim, "10us")
    events = sim.kernel.events
    assert wait_until(sim, lambda: True) == 10e-6
    assert sim.now == 160 and sim.kernel.events == events


def test_wait_until_timeout_is_an_assertion_error_naming_condition_timeout_and_time():
    sim = ctc(bare())
    run_for(sim, "100us")

    def pb2_high():
        return sim.pin("PB2").level == 1

    with pytest.raises(SimTimeout) as exc:
        wait_until(sim, pb2_high, timeout="500us")
    assert isinstance(exc.value, AssertionError)
    msg = str(exc.value)
    assert "pb2_high" in msg and "500us" in msg and "reached 0.0006 s" in msg and "began at 0.0001 s" in msg
    assert sim.now == 16 * 600                              # at start + timeout

    with pytest.raises(SimTimeout, match=re.escape('lambda: sim.pin("PB2").level == 1')):
        wait_until(sim, lambda: sim.pin("PB2").level == 1, timeout=0.0001)
    with pytest.raises(SimTimeout, match=r"after 0.0001 s .*waiting for the brake to engage \(simulated"):
        wait_until(sim, pb2_high, timeout=0.0001, message="the brake to engage")
    with pytest.raises(SimTimeout, match=r"after 50us .*waiting for PB2 high \(simulated time reached"):
        wait_until(sim, pb2_high, timeout="50us", poll="10us", message="PB2 high")


def test_wait_until_rejects_bad_durations():
    sim = bare()
    with pytest.raises(TimeError):
        wait_until(sim, lambda: False, timeout="soon")
    with pytest.raises(McusimError, match="poll interval"):
        wait_until(sim, lambda: False, timeout="1ms", poll=0)


def test_run_for_is_run_seconds():
    sim = bare()
    assert run_for(sim, "1.5ms") is sim
    run_for(sim, 0.0005)
    assert sim.now == 16 * 2000


def test_describe_condition():
    def motor_at_speed():
        return True

    class Check:
        def __call__(self):
            return True

        def __repr__(self):
            return "Check()"

    assert describe_condition(motor_at_speed).endswith("motor_at_speed")
    assert describe_condition(lambda: 1 + 1 == 2) == "lambda: 1 + 1 == 2"
    assert describe_condition(Check()) == "Check()"


def test_describe_condition_picks_the_lambda_among_several_on_its_line():
    """Was the whole line (or the function's repr): a condition made by a lambda that returns a
    lambda, or one of several lambdas on a line."""
    above = lambda k: (lambda: k > 3)
    assert describe_condition(above(2)) == "lambda: k > 3"
    pair = [lambda x: x + 1, lambda y: y * 2]
    assert describe_condition(pair[1]) == "lambda y: y * 2"
    assert describe_condition(pair[0]) == "lambda x: x + 1"


def test_vcd_filename():
    assert vcd_filename("tests/test_fw.py::test_step[10]") == "tests_test_fw.py__test_step_10.vcd"
    assert vcd_filename("test_a.py::TestX::test_b[a-c]", 2) == "test_a.py__TestX__test_b_a-c-2.vcd"
    long = [vcd_filename("t.py::test[" + "x" * 300 + tail + "]") for tail in ("1", "2")]
    assert long[0] != long[1] and all(len(n) < 200 for n in long)


@settings(max_examples=300, deadline=None)
@given(params=st.lists(st.text(st.characters(codec="utf-8", exclude_categories=("Cs",)), max_size=6),
                       min_size=2, max_size=6, unique=True))
def test_different_parameter_ids_of_a_test_never_share_a_vcd_file(params):
    """Two ids mapped alike (``[a b]`` and ``[a_b]``, ``[+1]`` and ``[1]``, ``[..]`` and ``[]``) had
    shared one file, the later test's trace overwriting the earlier's without a word."""
    ids = ["tests/test_m.py::test_a[" + p + "]" for p in params] + ["tests/test_m.py::test_a"]
    names = [vcd_filename(i) for i in ids]
    assert len(set(names)) == len(names), list(zip(ids, names))
    assert all(re.fullmatch(r"[A-Za-z0-9._-]+\.vcd", n) for n in names)


# ------------------------------------------------------------------ the plugin, through pytester
@pytest.fixture(scope="module")
def models_imported():
    """pytester drops the modules an in-process run imported; import the models here first so
    that the inner runs and the rest of the session share one copy of each (numpy, for one,
    cannot be imported a second time in a process)."""
    import mcusim.trace
    mcusim.load("pro-mini").discard()


@pytest.fixture
def run_inner(pytester, monkeypatch, models_imported):
    """An in-process pytest run in pytester's directory with this plugin and no other third-party
    one (hypothesis, xdist, benchmark... would slow it down or warn about the outer session).
    Its test files are named test_inner_*: in the default import mode a basename that is also a
    module of tests/ would clash."""
    monkeypatch.setenv("PYTEST_DISABLE_PLUGIN_AUTOLOAD", "1")

    def run(*args, in_subprocess=False):
        args = ("-p", "mcusim.pytest_plugin", "-p", "no:cacheprovider", *args)
        return pytester.runpytest_subprocess(*args) if in_subprocess else pytester.runpytest(*args)
    return run


USER_TESTS = '''
    from mcusim.testing import wait_for_pin, wait_until

    def test_edge(mcusim_sim):
        sim = mcusim_sim("pro-mini", firmware=False)
        sim.mcu.write8(0x24, 2); sim.mcu.write8(0x89, 0); sim.mcu.write8(0x88, 99)
        sim.mcu.write8(0x80, 0x40); sim.mcu.write8(0x81, 0x09)
        assert wait_for_pin(sim, "PB1", 1, timeout="1ms") == 100 / 16e6

    def test_never(mcusim_sim):
        sim = mcusim_sim("pro-mini", firmware=False)
        wait_until(sim, lambda: sim.pin("PB2").level == 1, timeout="100us")
'''


def test_user_test_file_passes_and_a_timeout_fails_with_its_message(pytester, run_inner):
    pytester.makepyfile(test_inner_user=USER_TESTS)
    result = run_inner()
    result.assert_outcomes(passed=1, failed=1)                # a failure, not an error
    result.stdout.fnmatch_lines([
        ('*SimTimeout: timed out after 100us of simulated time waiting for '
         'lambda: sim.pin("PB2").level == 1 (simulated time reached 0.0001 s*'),
        "FAILED test_inner_user.py::test_never*",
    ])
    result.stdout.no_fnmatch_line("*mcusim/testing.py*")     # the helpers' frames are hidden


def test_fixture_closes_every_simulation_and_discards_those_never_run(pytester, run_inner):
    pytester.makepyfile(test_inner_teardown='''
        import inspect
        SIMS, CLOSED = {}, []

        def recording(name, close):
            def wrapper():
                CLOSED.append(name)
                close()
            return wrapper

        def test_make(mcusim_sim):
            idle = mcusim_sim("pro-mini")
            ran = mcusim_sim("pro-mini")
            ran.run(seconds=0.001)
            for name, sim in (("idle", idle), ("ran", ran)):
                SIMS[name] = sim
                sim.close = recording(name, sim.close)
            assert mcusim_sim.simulations == [idle, ran]

        def test_after():
            assert sorted(CLOSED) == ["idle", "ran"]
            def states(sim):
                return {t.coro and inspect.getcoroutinestate(t.coro) for t in sim.mcu.rtos.tasks}
            assert states(SIMS["idle"]) == {None}      # never started: no coroutine was made
    ''')
    run_inner().assert_outcomes(passed=2)


def test_vcd_option_writes_one_file_per_simulation_named_after_the_test(pytester, run_inner):
    pytester.makepyfile(test_inner_traces='''
        import pytest

        @pytest.mark.parametrize("x", ["a-b"])
        def test_two(mcusim_sim, x):
            first = mcusim_sim("pro-mini", firmware=False)
            first.mcu.write8(0x24, 2)
            first.pin("PB1").drive(1)
            first.run(seconds=0.0001)
            mcusim_sim("pro-mini", firmware=False)
    ''')
    run_inner().assert_outcomes(passed=1)
    assert not (pytester.path / "out").exists()

    result = run_inner("--mcusim-vcd", "out")
    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines([f"mcusim: VCD traces to {pytester.path / 'out'}"])
    files = sorted(p.name for p in (pytester.path / "out").iterdir())
    # the second simulation never ran: it is discarded, and leaves no VCD of a header alone
    assert files == ["test_inner_traces.py__test_two_a-b.vcd"]
    first = (pytester.path / "out" / "test_inner_traces.py__test_two_a-b.vcd").read_text()
    assert "$var wire 1 ! PB1 $end" in first and "$enddefinitions" in first
    assert "\n1!\n" in first                               # PB1's edge, written at close


def test_the_example_of_the_docs_passes(pytester, run_inner):
    text = DOCS.read_text()
    m = re.search(r"<!-- example: test_firmware\.py.*?-->\n```python\n(.*?)```", text, re.DOTALL)
    assert m, "the example block of docs/pytest.md"
    pytester.makepyfile(test_inner_docs_example=m.group(1))
    # in a process of its own: nested in this session's call stack, the simulation's hot calls can
    # straddle a CPython frame-stack chunk boundary and run at half speed (an mmap per call)
    run_inner(in_subprocess=True).assert_outcomes(passed=4)



def test_mcusim_engine_option_sets_the_fixtures_engine(pytester, run_inner):
    """Issue 9: the engine is selectable in the pytest fixture too (--mcusim-engine)."""
    pytester.makepyfile(test_inner_engine='''
        def test_engine(mcusim_sim, request):
            sim = mcusim_sim("nucleo-f746", firmware=False)
            assert sim.kernel.engine == (request.config.getoption("mcusim_engine") or "fast")
            assert mcusim_sim("nucleo-f746", firmware=False, engine="fast").kernel.engine == "fast"
    ''')
    run_inner().assert_outcomes(passed=1)
    run_inner("--mcusim-engine", "reference").assert_outcomes(passed=1)
