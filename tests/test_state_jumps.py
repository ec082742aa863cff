"""A jump of a motor's state (``motor.set_state(angle=...)``) mid-run, under both engines.

Edge by edge, the motor's next segment is screened from the jumped state: an encoder threshold
that the jump put behind the shaft is taken as not fired at the segment start and fires at the next
tick, whichever way the shaft turns, or if it stands still held by static friction (only a shaft
at rest with no current moving skips the screening). The encoder then emits one edge per threshold
between its old position and the new angle at that tick. The fast engine used to locate encoder
thresholds only ahead of a moving shaft, so a jump while holding, or backwards while turning
forwards, was never counted: the firmware's position, and everything it then did, differed.
"""

from __future__ import annotations

import math

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from test_served_edges import _close, snapshot

import mcusim

BOARDS = {
    # the nucleo's motor 1 moves to 3π, its motor 2 holds; the pro-mini turns at 20 rpm or holds
    ("nucleo-f746", True): {"/motor1/set_pos": 3 * math.pi, "/motor2/set_pos": -math.pi / 2},
    ("nucleo-f746", False): {},
    ("pro-mini", True): {"velocity": 20},
    ("pro-mini", False): {},
}


def _snap(sim) -> dict:
    out = snapshot(sim)
    for mname, m in sim.members.items():
        for pname, p in m["mcu"].periph.items():
            if type(p).__name__ == "Tim":         # the counter as the firmware reads it
                reg = next(r for r in p.REGISTERS if r.name == "CNT")
                out[f"{mname}: {pname} CNT read"] = p.bus_read(reg.offset, 4, reg.offset)
                out.pop(f"{mname}: {pname} registers", None)   # stored values settle lazily
    return out


def _run_both(board, moving, t_ms, jumps, until_ms, step_ms=2):
    sims = {}
    for engine in ("reference", "fast"):
        sim = mcusim.load(board, overrides=BOARDS[board, moving], engine=engine)
        for name, dtheta, speed in jumps:
            motor = sim.part(name)

            def jump(motor=motor, dtheta=dtheta, speed=speed):
                motor.set_state(angle=motor.angle + dtheta, speed=speed)
            sim.kernel.at(sim.timebase.base_hz * t_ms // 1000, jump)
        sims[engine] = sim
    ref, fast = sims["reference"], sims["fast"]
    for _ in range(until_ms // step_ms):
        ref.run(seconds=step_ms / 1000)
        fast.run(seconds=step_ms / 1000)
        a, b = _snap(ref), _snap(fast)
        bad = [k for k in a if not _close(a[k], b[k])]
        assert not bad, (f"at {fast.time_s:.6f} s the engines differ in {bad}: reference "
                         f"{[a[k] for k in bad][:2]}, fast {[b[k] for k in bad][:2]}")
    return ref, fast


@pytest.mark.parametrize("board,motor,encoder", [("nucleo-f746", "motor2", "encoder2"),
                                                 ("pro-mini", "motor", "encoder")])
def test_a_jump_of_a_held_shaft_is_counted_at_the_next_tick_in_both_engines(board, motor, encoder):
    """A shaft held by static friction is turned back one radian at once: both engines' encoders
    reach the position of the new angle (one count per threshold, the position being
    floor(θ / step)), and the firmware sees the same counter from then on."""
    ref, fast = _run_both(board, False, 20, [(motor, -1.0, None)], until_ms=32)
    for sim in (ref, fast):
        enc = sim.part(encoder)
        assert enc.position == math.floor(sim.part(motor).angle / enc.step)
        assert enc.position <= math.floor(-1.0 / enc.step) + 1


@settings(max_examples=8, deadline=None)
# a chunk starting at the jump's tick (a counted run once served the edges left behind)
@example(board="pro-mini", moving=True, t_ms=16, dtheta=1.0, speed=None)
@given(board=st.sampled_from(["nucleo-f746", "pro-mini"]), moving=st.booleans(), t_ms=st.integers(3, 60),
       dtheta=st.floats(-3.0, 3.0).filter(lambda d: abs(d) > 1e-9), speed=st.sampled_from([None, 0.0]))
def test_engines_agree_after_a_jump_of_the_shaft_angle(board, moving, t_ms, dtheta, speed):
    """Jumps of either sign, shorter or longer than one encoder step, while turning or holding,
    with the speed kept or stopped: the engines' states agree every 2 ms for 30 ms after."""
    motor = "motor1" if board == "nucleo-f746" else "motor"
    _run_both(board, moving, t_ms, [(motor, dtheta, speed)], until_ms=t_ms + 30)


@pytest.mark.parametrize("dtheta", [1.0, -0.5])
def test_a_jump_on_the_tick_of_a_pwm_edge_while_turning_is_not_counted_as_spread_out_edges(dtheta):
    """The pro-mini turning at 20 rpm, its shaft turned on the tick of a PWM edge, where the fast
    engine starts a chunk at once: the thresholds the jump left behind all come at the next tick,
    edge by edge, and the handlers lose most of them. A counted run of served edges, which takes
    the crossings from the shaft angle as spaced by its speed, once served all of them there."""
    sim = mcusim.load("pro-mini", overrides=BOARDS["pro-mini", True])
    sim.run(seconds=0.016)
    bridge = sim.part("ibt2")
    t_edge = min(n.wave.next_edge(sim.kernel.now)[0] for n in (bridge.rpwm, bridge.lpwm) if n.wave is not None)
    snaps = []
    for engine in ("reference", "fast"):
        run = mcusim.load("pro-mini", overrides=BOARDS["pro-mini", True], engine=engine)
        motor = run.part("motor")
        run.kernel.at(t_edge, lambda motor=motor: motor.set_state(angle=motor.angle + dtheta))
        run.run(seconds=0.02)
        snaps.append(_snap(run))
    ref, fast = snaps
    assert sum(ref["pro-mini: EXINT edges lost"]) > 0      # the burst: edges lost edge by edge
    assert [k for k in ref if not _close(ref[k], fast[k])] == []
