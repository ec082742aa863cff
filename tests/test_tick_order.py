"""What an action sees and does at the very tick of a plant event, in both engines (found by an
adversarial review of the fast engine).

Edge by edge, an encoder threshold crossing is the motor's event at ``PRIO_PLANT``: an event earlier
in the same tick (a scenario's fault or input, a test's ``kernel.at``) still sees the position
before it, and a fault injected there (a glitch, dropped edges) acts on that position, the crossing
coming after it. The fast engine counts the nucleo's encoders from the shaft angle; it now asks the
kernel where in the tick it is (``Kernel.early_in_tick``) and, ending a lazy stretch early in the
tick, leaves the crossing to come at the plant's priority.

A BTS7960 checks its switches' current limits at an input edge (a switch turning on over its limit
trips there); a rebuild of the motor for another reason (a parameter, a jump of the state) leaves
the trip to the new segment's screening, which finds the limit passed at the next tick. The fast
engine used to check at every rebuild and trip one tick early.
"""

from __future__ import annotations

import pytest
from test_served_edges import _close, snapshot

import mcusim

NUCLEO = {"/motor1/set_pos": 3.0, "/motor2/set_pos": -1.5}


def _cnt(sim, name):
    tim = sim.mcu.periph[name]
    reg = next(r for r in tim.REGISTERS if r.name == "CNT")
    return tim.bus_read(reg.offset, 4, reg.offset)


@pytest.fixture(scope="module")
def crossing_ticks():
    """Ticks at which encoder 1's A output (PB5) changes, edge by edge, between 60 and 75 ms."""
    sim = mcusim.load("nucleo-f746", overrides=NUCLEO, engine="reference")
    ticks = []
    sim.pin("PB5").listen(lambda net: ticks.append(sim.kernel.now))
    sim.run(seconds=0.075)
    lo = sim.timebase.base_hz * 60 // 1000
    found = [t for t in ticks if t >= lo]
    assert len(found) >= 3
    return found[:: max(1, len(found) // 3)][:3]


@pytest.mark.parametrize("action", ["read", "glitch", "drop"])
def test_an_action_at_a_crossing_tick_acts_before_the_crossing_in_both_engines(crossing_ticks, action):
    for T in crossing_ticks:
        out = {}
        for engine in ("reference", "fast"):
            sim = mcusim.load("nucleo-f746", overrides=NUCLEO, engine=engine)
            enc, seen = sim.part("encoder1"), []

            def act(enc=enc, seen=seen, sim=sim):
                seen.append((enc.position, enc.edges, sim.pin("PB5").level))
                if action == "glitch":
                    enc.glitch("A", 2)
                elif action == "drop":
                    enc.drop_edges(1)
            sim.kernel.at(T, act)
            sim.run(until_tick=T + sim.timebase.base_hz // 10_000)      # 100 µs on
            out[engine] = (seen[0], _cnt(sim, "TIM3"), enc.position, enc.dropped)
        assert out["reference"] == out["fast"], (T, out)
        # the action saw the position before the crossing of its tick
        assert out["reference"][0][0] == out["reference"][2] - 1 or action == "read"


@pytest.mark.parametrize("how", ["params between runs", "current jump in an event"])
def test_a_current_limit_passed_off_an_input_edge_trips_at_the_next_tick_in_both_engines(how):
    """pro-mini at 23 ms (about 27.6 A while it starts): limits lowered to 0.3/0.2 A between two
    runs, or the current set to 70 A by an event; neither is an input edge, so the trip comes
    at the next tick, and everything after agrees."""
    T = 16_000_000 * 23 // 1000
    sims = {}
    for engine in ("reference", "fast"):
        sim = mcusim.load("pro-mini", overrides={"velocity": 20}, engine=engine)
        if how == "params between runs":
            sim.run(until_tick=T)
            sim.part("ibt2").set_params(I_CLH=0.3, I_CLL=0.2)
        else:
            motor = sim.part("motor")
            sim.kernel.at(T, lambda m=motor: m.set_state(current=70.0))
        sims[engine] = sim
    for sim in sims.values():
        sim.run(until_tick=T + 10)
        trips = [t for t in sim.part("ibt2").trip_log if t[0] >= T]
        assert trips and trips[0][0] == T + 1, trips
    for _ in range(5):
        for sim in sims.values():
            sim.run(seconds=0.001)
        a, b = snapshot(sims["reference"]), snapshot(sims["fast"])
        bad = [k for k in a if not _close(a[k], b[k])]
        assert not bad, (bad, [a[k] for k in bad][:2], [b[k] for k in bad][:2])
    assert list(sims["reference"].part("ibt2").trip_log) == list(sims["fast"].part("ibt2").trip_log)


@pytest.fixture(scope="module")
def pwm_edge_ticks():
    """Ticks of the pro-mini's PWM edges on RPWM/LPWM (PB1, PB2) just after 23 ms, edge by edge."""
    T0 = 16_000_000 * 23 // 1000
    sim = mcusim.load("pro-mini", overrides={"velocity": 20}, engine="reference")
    edges = []
    for pin in ("PB1", "PB2"):
        sim.pin(pin).listen(lambda net: edges.append(sim.kernel.now))
    sim.run(until_tick=T0 + 16_000)
    return sorted({t for t in edges if t >= T0})[:3]


@pytest.mark.parametrize("when", ["after the edge, between runs", "before the edge, in an input event"])
def test_a_limit_lowered_at_a_pwm_edge_tick_trips_as_the_edge_sees_it(pwm_edge_ticks, when):
    """Edge by edge the edge checks the limits of the switches on after it with the limits it sees:
    lowered after it (between runs), the trip waits for the next tick's screening; lowered by an
    event before it in the same tick (PRIO_INPUT), the edge sees the new limits (the fast engine's
    rebuild stands for the edge then)."""
    from mcusim.kernel import PRIO_INPUT
    for T in pwm_edge_ticks:
        out = {}
        for engine in ("reference", "fast"):
            sim = mcusim.load("pro-mini", overrides={"velocity": 20}, engine=engine)
            bridge = sim.part("ibt2")
            if when.startswith("after"):
                sim.run(until_tick=T)
                bridge.set_params(I_CLH=0.3, I_CLL=0.2)
            else:
                sim.kernel.at(T, lambda b=bridge: b.set_params(I_CLH=0.3, I_CLL=0.2), prio=PRIO_INPUT)
            sim.run(until_tick=T + 10)
            out[engine] = [t for t in bridge.trip_log if t[0] >= T][:2]
        assert out["reference"] == out["fast"], (T, out)
        assert out["reference"]
        if when.startswith("after"):
            assert out["reference"][0][0] == T + 1


@pytest.mark.parametrize("action", ["glitch", "drop"])
def test_a_fault_after_a_motor_rebuild_at_a_crossing_tick_sees_the_crossing(crossing_ticks, action):
    """Edge by edge, any rebuild of the motor at a tick (here a load change by an input event)
    advances it there and fires the encoder crossing due then: a fault injected after it acts on
    the position after the crossing."""
    from mcusim.kernel import PRIO_INPUT
    for T in crossing_ticks:
        out = {}
        for engine in ("reference", "fast"):
            sim = mcusim.load("nucleo-f746", overrides=NUCLEO, engine=engine)
            enc, motor = sim.part("encoder1"), sim.part("motor1")

            def act(enc=enc, motor=motor):
                motor.set_params(load_torque=motor.params.load_torque + 1e-6)
                enc.glitch("A", 2) if action == "glitch" else enc.drop_edges(1)
            sim.kernel.at(T, act, prio=PRIO_INPUT)
            sim.run(until_tick=T + sim.timebase.base_hz // 200)          # 5 ms on
            out[engine] = (_cnt(sim, "TIM3"), enc.position, enc.dropped)
        assert out["reference"] == out["fast"], (T, out)
