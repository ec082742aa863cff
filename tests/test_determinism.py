"""Invariant 2: the same inputs give the same trace, byte for byte."""

import pytest

import mcusim


def _trace(path):
    sim = mcusim.load("nucleo-f746", overrides={"/motor1/set_pos": 0.3, "/motor2/set_pos": -0.2})
    sim.trace_vcd(path, sample="20us")
    sim.run(seconds=0.03)
    sim.close()
    return path.read_bytes(), sim.kernel.events


def test_same_inputs_give_byte_identical_vcd(tmp_path):
    a, ev_a = _trace(tmp_path / "a.vcd")
    b, ev_b = _trace(tmp_path / "b.vcd")
    assert ev_a == ev_b
    assert a == b
    assert len(a) > 10_000


def _rover_trace(path):
    sim = mcusim.load("elementall", overrides={"cmd_vel.linear": 0.1, "cmd_vel.angular": 0.1})
    sim.trace_vcd(path, sample="1ms")
    sim.run(seconds=0.35)
    sim.close()
    return path.read_bytes(), sim.kernel.events, sim.summary()["pose"]


@pytest.mark.heavy
def test_five_mcus_on_one_queue_give_byte_identical_vcd(tmp_path):
    a, ev_a, pose_a = _rover_trace(tmp_path / "a.vcd")
    b, ev_b, pose_b = _rover_trace(tmp_path / "b.vcd")
    assert ev_a == ev_b and pose_a == pose_b and a == b
    assert len(a) > 10_000
