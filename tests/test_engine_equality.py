"""The fast engine gives the reference engine's results (issue: one model, two engines).

Every check runs one command line under both engines and compares the VCD signals, the register
log and the summary (:mod:`engine_compare`): digital changes identical tick for tick, plant values
within 1e-9 relative. The cases are the shipped scenarios, the benches' fixed commands, and
hypothesis-generated runs of the nucleo-f746 (set-point steps and reversals, load torques, motors
driven into the L6206 over-current trip, saturated duty, stiff and light shafts).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from engine_compare import differences
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"


def _agree(tmp_path, argv):
    problems = differences(tmp_path, argv)
    assert not problems, "the engines disagree:\n" + "\n".join(problems[:20])


@pytest.mark.parametrize("board,name,duration", [("nucleo-f746", "step_response", "0.3s"),
                                                 ("nucleo-f746", "thesis_master_slave", "0.3s"),
                                                 ("pro-mini", "promini_velocity_load", "0.1s")])
def test_engines_agree_on_shipped_scenario(tmp_path, board, name, duration):
    _agree(tmp_path, [board, "--scenario", str(SCENARIOS / f"{name}.toml"), "--duration", duration])


def test_engines_agree_on_the_nucleo_bench_command(tmp_path):
    _agree(tmp_path, ["nucleo-f746", "--duration", "0.3s", "--set", "/motor1/set_pos=9.42477796076938",
                      "--set", "/motor2/set_pos=-1.5707963267948966"])


@pytest.mark.parametrize("board,duration", [("pro-mini", "50ms"), ("elementall", "20ms")])
def test_engines_agree_on_other_boards(tmp_path, board, duration):
    _agree(tmp_path, [board, "--duration", duration])


def test_engines_agree_through_over_current_trips(tmp_path):
    """A low L6206 threshold trips OCD during the PWM drive: the trip tick and the EN recharge
    release must be the same in both engines (a guard inside a chunk of periods)."""
    _agree(tmp_path, ["nucleo-f746", "--duration", "0.15s", "--set", "bridgeA.I_ocd=1.5",
                      "--set", "bridgeB.I_ocd=2.0", "--set", "/motor1/set_pos=3", "--set", "/motor2/set_pos=-2"])


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(p1=st.floats(-12.0, 12.0), p2=st.floats(-12.0, 12.0), load=st.floats(-0.3, 0.3),
       j_scale=st.sampled_from([0.5, 1.0, 4.0]), i_ocd=st.sampled_from([2.5, 5.6]),
       ms=st.integers(40, 120))
def test_engines_agree_on_generated_nucleo_runs(tmp_path_factory, p1, p2, load, j_scale, i_ocd, ms):
    tmp = tmp_path_factory.mktemp("eq")
    _agree(tmp, ["nucleo-f746", "--duration", f"{ms}ms", "--set", f"/motor1/set_pos={p1!r}",
                 "--set", f"/motor2/set_pos={p2!r}", "--set", f"motor1.load_torque={load!r}",
                 "--set", f"motor2.J={5e-6 * j_scale!r}", "--set", f"bridgeA.I_ocd={i_ocd!r}"])
