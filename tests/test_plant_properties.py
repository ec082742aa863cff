"""Hypothesis properties of the exact plant: encoder edges are located to the tick, guards are found
at their first firing tick, and the closed form equals the matrix exponential."""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.linalg import expm

from mcusim.kernel import Kernel
from mcusim.plant import pwl
from mcusim.plant.dcmotor import DcMotor
from mcusim.plant.encoder import QuadratureEncoder
from mcusim.plant.l6206 import L6206Bridge
from mcusim.signals import Net
from mcusim.time import TimeBase

FS = 216_000_000
STATES = {"fwd": (1, 1, 0), "rev": (1, 0, 1), "brake_lo": (1, 0, 0), "brake_hi": (1, 1, 1), "off": (0, 0, 0)}
QUAD = [(0, 0), (1, 0), (1, 1), (0, 1)]

segments = st.lists(st.tuples(st.sampled_from(sorted(STATES)), st.integers(1, 3000)), min_size=1, max_size=10)


@pytest.mark.heavy
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(segments, st.floats(-600, 600), st.floats(-3, 3), st.floats(-2.0, 2.0))
def test_encoder_count_equals_floor_difference_and_each_edge_brackets_its_threshold(seq, w0, i0, th0):
    tb = TimeBase([FS])
    k = Kernel(tb)
    in1, in2, en, a, b = (Net(n) for n in ("IN1", "IN2", "EN", "A", "B"))
    m = DcMotor(k, "motor1", current=i0, speed=w0, angle=th0)
    L6206Bridge(k, m, in1=in1, in2=in2, en=en, name="bridgeA")
    enc = QuadratureEncoder(k, m, a=a, b=b, counts_per_rev=64, name="encoder1")
    step = 2 * math.pi / 64
    pos0 = math.floor(th0 * 64 / (2 * math.pi))
    assert (a.level, b.level) == QUAD[pos0 % 4]
    log = []

    def on_edge(net):
        t = k.now
        log.append((t, a.level, b.level, m.state_at(t - 1)[2], m.angle))
    a.listen(on_edge)
    b.listen(on_edge)
    t = 0
    for name, us in seq:
        e, i1, i2 = STATES[name]
        in1.set("mcu", i1)
        in2.set("mcu", i2)
        en.set("mcu", e)
        t += us * 216
        k.run_until(t)
    th_end = m.angle
    expect = math.floor(th_end * 64 / (2 * math.pi)) - pos0
    assert enc.count == expect
    pos, prev = pos0, QUAD[pos0 % 4]
    for tick, la, lb, th_before, th_at in log:
        q = QUAD.index((la, lb))
        d = (q - QUAD.index(prev)) % 4
        assert d in (1, 3)
        if d == 1:      # up: threshold (pos+1)·step with θ(t−1) < thr ≤ θ(t)
            thr = (pos + 1) * step
            assert th_before < thr <= th_at, (tick, th_before, thr, th_at)
            pos += 1
        else:           # down: θ(t−1) ≥ thr > θ(t)
            thr = pos * step
            assert th_before >= thr > th_at, (tick, th_before, thr, th_at)
            pos -= 1
        prev = (la, lb)
    assert pos - pos0 == expect


@settings(max_examples=50, deadline=None)
@given(st.floats(-5e4, -10.0), st.floats(-5e4, -10.0), st.floats(-3, 3), st.floats(-3, 3), st.floats(-3, 3),
       st.floats(-5e4, 5e4), st.booleans())
def test_first_fire_finds_the_first_tick_a_brute_force_scan_finds(l1, l2, d1, d2, a0, b0, strict):
    # f(t) = a0 + b0·t + d1 e^{l1 t} + d2 e^{l2 t} sampled every 1 µs "tick" over 400 ticks
    inv = 1e-6

    def f(n):
        t = n * inv
        return a0 + b0 * t + d1 * math.exp(l1 * t) + d2 * math.exp(l2 * t)
    m2 = abs(d1) * l1 * l1 + abs(d2) * l2 * l2
    h0 = f(0)
    if (h0 < 0) if strict else (h0 <= 0):
        return  # the guard is taken as not fired at the start
    brute = next((n for n in range(1, 401) if ((f(n) < 0) if strict else (f(n) <= 0))), None)
    got = pwl.first_fire(f, m2, 0, 400, h0, f(400), strict, inv)
    assert got == brute


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 5000), st.floats(-3.0, 3.0), st.floats(0.0, 6.0), st.integers(-20, 5020), st.booleans(),
       st.booleans())
def test_monotone_search_finds_the_first_fired_tick_a_scan_finds(nb, curve, power, root, strict, at_root):
    """first_fire_monotone: for any guard decreasing over (0, nb] (linear, or bent as far as a
    power law or an exponential bends it), the first fired tick, or None, exactly as a scan finds
    it; a guard that is nearly linear (an encoder threshold inside one PWM piece) takes at most
    four evaluations besides the two ends (two when the secant lands on the crossing)."""
    def h(n):
        x = (n - root) / max(nb, 1)
        bent = math.copysign(abs(x) ** (1.0 + power), x) if curve >= 0 else math.expm1(-curve * x)
        return -(x + abs(curve) * bent) if not at_root else float(root - n)
    calls = []

    def h_at(n):
        calls.append(n)
        return h(n)
    fired = (lambda v: v < 0.0) if strict else (lambda v: v <= 0.0)
    h0 = h(0)
    if fired(h0):
        return                      # the guard is taken as not fired at the start
    brute = next((n for n in range(1, nb + 1) if fired(h(n))), None)
    assert pwl.first_fire_monotone(h_at, 0, nb, h0, h(nb), strict) == brute
    if at_root or curve == 0.0:     # linear: the secant lands on the crossing
        assert len(calls) <= 4, calls


@settings(max_examples=40, deadline=None)
@given(st.floats(0.1, 5.0), st.floats(1e-4, 1e-1), st.floats(1e-3, 0.2), st.floats(1e-7, 1e-3),
       st.floats(0.0, 1e-3), st.floats(-20, 20), st.floats(-50, 50), st.floats(1e-5, 5e-2))
def test_closed_form_equals_matrix_exponential(R, L, K, J, b, v, tq, t):
    A = (-R / L, -K / L, K / J, -b / J)
    u = (v / L, -tq / J)
    x0 = (0.7, -30.0, 0.25)
    tr = pwl.affine2(pwl.eig2(*A), A, u, x0)
    M = np.array([[A[0], A[1], 0, u[0]], [A[2], A[3], 0, u[1]], [0, 1, 0, 0], [0, 0, 0, 0]])
    ref = expm(M * t) @ np.array([x0[0], x0[1], x0[2], 1.0])
    got = tr.eval(t)
    tol = 1e-8 * max(1.0, float(np.abs(ref).max()))
    for g, r in zip(got, ref[:3]):
        assert abs(g - r) <= tol, (got, ref)
