"""The motor's angle is an integral: every re-base of a segment (an input change, a piece end, a
chunk end) adds the angle turned to the angle so far. Added plainly, each addition rounds at the
scale of |θ|, the errors random-walk with the number of segments (about 40 k a second under PWM),
and two engines that re-base at different ticks part by ~1e-13 rad after a few seconds: enough to
put an encoder edge on the other side of a tick boundary. ``DcMotor._advance`` keeps the rounding
error of the sum (two-sum) and adds the increments, summed from small terms (``Traj.dtheta``,
``ChunkTraj.dtheta``): the angle does not depend on how often the trajectory was re-based, to a few
units in the last place."""

import math
import random
from types import SimpleNamespace

from hypothesis import given, settings
from hypothesis import strategies as st

import mcusim
from mcusim.kernel import Kernel
from mcusim.plant import pwl
from mcusim.plant.dcmotor import DcMotor
from mcusim.plant.l6206 import L6206Bridge
from mcusim.signals import Net
from mcusim.time import TimeBase

FS = 216_000_000


def _drive(engine="reference"):
    k = Kernel(TimeBase([FS]), engine=engine)
    in1, in2, en = (Net(n) for n in ("IN1", "IN2", "EN"))
    m = DcMotor(k, "motor1", angle=1000.0)      # far from 0: an ulp of θ is 1.1e-13 rad
    L6206Bridge(k, m, in1=in1, in2=in2, en=en, name="bridgeA")
    for net, v in ((in1, 1), (in2, 0), (en, 1)):
        net.set("mcu", v)
    return SimpleNamespace(k=k, m=m)


def _ulps(a, b):
    return abs(a - b) / math.ulp(max(abs(a), abs(b)))


@settings(max_examples=4, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), mean_us=st.sampled_from([7, 25, 60]))
def test_the_angle_does_not_depend_on_how_often_the_segment_is_rebased(seed, mean_us):
    """The same drive for 0.2 s, once re-based only where the engine wants, once also at thousands
    of random ticks (an input change that changes nothing): the angles agree to a few ulps. Added
    plainly, the rebased one would be off by tens of ulps (the random walk of one rounding per
    re-base)."""
    plain, forced = _drive(), _drive()
    end = FS // 5
    plain.k.run_until(end)
    rng, t, n = random.Random(seed), 0, 0
    while True:
        t += 1 + int(rng.expovariate(1.0 / (mean_us * FS / 1e6)))
        if t >= end:
            break
        forced.k.run_until(t)
        forced.m.input_changed()
        n += 1
    forced.k.run_until(end)
    assert n > 2000
    a, b = plain.m.angle, forced.m.angle
    assert abs(a - 1000.0) > 100.0                  # the shaft turned
    assert _ulps(a, b) <= 4, (a, b, n)


def test_a_segment_adds_to_its_start_angle_what_its_increment_says():
    """``eval`` and ``dtheta`` are one expression: x3(t) = x3(0) + (dtheta(t) + lo), in one
    rounding, ``lo`` being what the motor's accumulated angle holds beyond x3(0), for each kind of
    closed form met (two real exponentials, a complex pair, one exponential, free)."""
    d = _drive()
    seen = set()
    for step in range(1, 40):
        d.k.run_until(step * FS // 200)
        tr = d.m._traj
        if tr is None or tr.kind == "chunk":
            continue
        seen.add((tr.kind, tr.cplx))
        for t in (1e-7, 3e-5, 1e-3):
            assert tr.eval(t)[2] == tr.x0[2] + (tr.dtheta(t) + tr.lo)
        assert tr.eval(0.0) == tr.x0 and tr.dtheta(0.0) == 0.0
    assert seen


def test_the_static_closed_form_turns_no_angle():
    tr = pwl.static((0.0, 0.0, 12.5))
    assert tr.dtheta(0.3) == 0.0 and tr.eval(0.3)[2] == 12.5


def test_the_fast_engine_angle_does_not_depend_on_extra_rebases_of_its_chunks():
    """pro-mini at its bench speed (TimerOne PWM in whole-period chunks): 0.5 s as it runs, and
    with a re-base forced every 0.25 ms (a mid-piece segment, then new chunks): the same angle to a
    few ulps."""
    def run(force):
        sim = mcusim.load("pro-mini", overrides={"velocity": 20})
        motor = sim.part("motor")
        if force:
            for j in range(1, 2000):
                sim.run(seconds=0.00025)
                motor.input_changed()
            sim.run(seconds=0.00025)
        else:
            sim.run(seconds=0.5)
        return motor.angle
    a, b = run(False), run(True)
    assert abs(a) > 10.0
    assert _ulps(a, b) <= 8, (a, b)


def _slow_crossing(engine, th0, w, seed, ticks):
    """A frictionless shaft at ``th0`` turning at ``w`` (so slowly that θ gains about an ulp per
    tick) across one threshold of a 64-line encoder, its segment re-based every 1 to 6 ticks:
    the encoder's (tick, position) changes."""
    from mcusim.plant.encoder import QuadratureEncoder
    k = Kernel(TimeBase([FS]), engine=engine)
    m = DcMotor(k, "m", speed=w, angle=th0, tau_c=0.0, tau_s=0.0, b=0.0)
    enc = QuadratureEncoder(k, m, Net("A"), Net("B"), 64, "e")
    log, out = [], enc._out

    def logged():
        out()
        log.append((k.now, enc._pos))
    enc._out = logged
    rng, t = random.Random(seed), 0
    while True:
        t += rng.randint(1, 6)
        if t >= ticks:
            break
        k.run_until(t)
        m.input_changed()
    k.run_until(ticks)
    return log


@settings(max_examples=40, deadline=None)
@given(per_tick=st.sampled_from([0.05, 0.2, 0.45, 0.8, 1.3, 3.0]), below=st.sampled_from([7, 20]),
       seed=st.integers(0, 2**32 - 1))
def test_a_slow_shaft_crossing_a_threshold_between_rebases_makes_one_edge_in_both_engines(per_tick, below,
                                                                                          seed):
    """Found by review: where the re-base took the accumulated sum rather than the angle the
    segment had given, the new segment could start an ulp back across the threshold just crossed
    (edge up, down, up: a pair of extra edges, in the reference engine more often than in the
    fast one). A segment's angles include what the sum holds beyond its start, so the re-base takes
    exactly the angle the old segment gave: one edge, at the same tick in both engines."""
    step = 2 * math.pi / 64
    thr = math.ceil(1000 / step) * step
    u = math.ulp(thr)
    th0, w = thr - below * u, per_tick * u * FS
    ticks = int(3 * below / per_tick) + 50
    ref = _slow_crossing("reference", th0, w, seed, ticks)
    fast = _slow_crossing("fast", th0, w, seed, ticks)
    assert len(ref) == 1 and ref == fast, (ref, fast)


def test_a_shaft_held_by_static_friction_reports_the_angle_it_holds_whatever_the_carried_low_part():
    """The low part the accumulated angle carries joins the angle only where the shaft turns: a
    held shaft (here below breakaway, with a low part of three quarters of an ulp carried, as a chunk can leave) reports the
    same angle at every tick, in both engines, so an encoder resting next to a threshold sees no
    edge from the bookkeeping."""
    for engine in ("reference", "fast"):
        k = Kernel(TimeBase([FS]), engine=engine)
        in1, in2, en = (Net(n) for n in ("IN1", "IN2", "EN"))
        m = DcMotor(k, "motor1", angle=1000.0)
        L6206Bridge(k, m, in1=in1, in2=in2, en=en, name="bridgeA", Vs=1.0)   # below breakaway
        m._th_lo = 0.75 * math.ulp(1000.0)
        for net, v in ((in1, 1), (in2, 0), (en, 1)):
            net.set("mcu", v)
        for t in (1, 17, 2000, FS // 1000, FS // 20):
            k.run_until(t)
            m.input_changed()
            assert m.speed == 0.0 and m.angle == 1000.0, (engine, t, m.angle)
        assert m._th_lo == 0.75 * math.ulp(1000.0)      # carried, not lost
