"""``Simulation.run``: one clear error for an end that cannot be reached, never a silent no-op."""

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import mcusim
from mcusim.errors import McusimError


@pytest.fixture(scope="module")
def sim():
    s = mcusim.load("pro-mini")
    s.run(seconds="1ms")
    return s


@pytest.mark.parametrize("kw", [{"until_tick": 5}, {"until": "0.5ms"}, {"until_tick": -1}])
def test_an_absolute_end_before_now_is_an_error_not_a_silent_no_op(sim, kw):
    now = sim.now
    with pytest.raises(McusimError, match="before now"):
        sim.run(**kw)
    assert sim.now == now


@pytest.mark.parametrize("tick", [1.5, True, "16000"])
def test_until_tick_takes_a_whole_number_of_base_ticks(sim, tick):
    with pytest.raises(McusimError, match="whole number of base ticks"):
        sim.run(until_tick=tick)


@settings(max_examples=20, deadline=None)
@given(ahead=st.integers(0, 2000))
def test_until_tick_now_or_later_ends_exactly_there(sim, ahead):
    end = sim.now + ahead
    sim.run(until_tick=float(end) if ahead % 2 else end)
    assert sim.now == end


@pytest.mark.parametrize("level", [2, -1, 0.5, "1", None])
def test_a_pin_is_driven_to_0_or_1_only(sim, level):
    """Was taken silently as level 1 (2, -1) or 0 (None): a digital level is 0 or 1."""
    with pytest.raises(McusimError, match="a digital level is 0 or 1"):
        sim.pin("PD3").drive(level)


def test_wait_for_pin_takes_a_level_of_0_or_1(sim):
    """Was a wait until the timeout for a level a pin can never have."""
    from mcusim.testing import wait_for_pin
    with pytest.raises(McusimError, match="a digital level is 0 or 1"):
        wait_for_pin(sim, "PB1", 2)


def test_overrides_are_a_mapping_not_a_list_of_set_strings():
    from mcusim.errors import ConfigError
    with pytest.raises(ConfigError, match="expected a mapping of --set keys"):
        mcusim.load("nucleo-f746", overrides=["motor1.R=2"])


def test_a_simulation_dropped_before_it_ran_leaves_no_never_awaited_warning():
    """Was "RuntimeWarning: coroutine 'OpenRoverMcm.main' was never awaited" at exit for every
    simulation loaded and not run (the test suite ended with one)."""
    import subprocess
    import sys
    code = "import mcusim\nmcusim.load('elementall')\ns = mcusim.load('pro-mini')\ndel s\n"
    out = subprocess.run([sys.executable, "-c", code], check=False, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and "never awaited" not in out.stderr, out.stderr


def test_a_run_stopped_before_a_task_took_its_first_step_leaves_no_warning_either():
    """From review: a task marked started but whose first step was still queued when the run
    stopped left the warning (its coroutine counted as awaited too early)."""
    import subprocess
    import sys
    code = ("import mcusim\nsim = mcusim.load('ciaa-edu')\nn = [0]\n"
            "def stop():\n    n[0] += 1\n    return n[0] >= 1\nsim.run(seconds='1ms', stop=stop)\n")
    out = subprocess.run([sys.executable, "-c", code], check=False, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and "never awaited" not in out.stderr, out.stderr


@pytest.mark.parametrize("word", ["off", "OFF", "no", "false"])
def test_a_set_word_that_reads_as_false_is_the_one_choice_spelled_so(word):
    # --set ibt2.cl_action=off was refused with "expected a string": off had been read as false
    sim = mcusim.load("pro-mini", overrides={"ibt2.cl_action": word})
    assert sim.part("ibt2").cl_action == "off"


@given(text=st.text(alphabet="abcdefxyz0123456789.,-[] ", max_size=12), quote=st.sampled_from(["'", '"']))
def test_a_quoted_set_value_is_the_text_inside_the_quotes(text, quote):
    from mcusim.board import parse_value
    assert parse_value(f"{quote}{text}{quote}") == text


def test_a_simulation_stopped_by_a_refused_register_configuration_refuses_to_run_on(tmp_path):
    """An error raised inside an event leaves the models where it happened: run() goes no further
    (an ADC whose sketch selects AVcc while a voltage is on AREF, ATmega328P datasheet ADMUX)."""
    import mcusim
    from mcusim.board import shipped_text
    from mcusim.errors import McusimError, UnsupportedConfiguration
    text = shipped_text("pro-mini").replace('name = "ADC"\n', 'name = "ADC"\naref = 3.0\n', 1)
    prof = tmp_path / "aref.toml"
    prof.write_text(text)
    sim = mcusim.load(str(prof))
    with pytest.raises(UnsupportedConfiguration, match="REFS"):
        sim.run(seconds="50ms")
    with pytest.raises(McusimError, match="stopped at t = .* on an error .*REFS.*cannot run on"):
        sim.run(seconds="1ms")


def test_a_closed_or_discarded_simulation_refuses_to_run_on():
    """Ran on silently after close(), with its firmware's tasks already ended."""
    import mcusim
    from mcusim.errors import McusimError
    for end in ("close", "discard"):
        sim = mcusim.load("pro-mini")
        sim.run(seconds="1ms")
        getattr(sim, end)()
        with pytest.raises(McusimError, match="cannot run on"):
            sim.run(seconds="1ms")
        assert sim.summary()["simulated_s"] == pytest.approx(1e-3)     # the state stays readable
