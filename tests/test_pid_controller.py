"""pid_controller.c: the discrete law, anti-windup and the recovery bound it buys.

Law: u[k] = Kp·(e[k] + τD·(e[k]−e[k−1])/T + (T/τI)·Σe), Σe clamped to ±W, u clamped to ±100.
Recovery bound (analytic): once the error has held one value e for two samples (derivative term
0), u has the sign of e whenever |e| > (T/τI)·W, whatever happened before, because the integral
term is at most Kp·(T/τI)·W in magnitude. Without the clamp a long saturation can hold the output
in the wrong direction for as many samples as it took to wind up.
"""

import math

from hypothesis import given, settings
from hypothesis import strategies as st
from mcusim.fw.controlmotor.pid_controller import BRIDGE_A, BRIDGE_B, PidController

T = 0.005


def make(kp=400.0, kd=0.02, ki=0.25, w=2.0):
    c = PidController()
    c.pid_set_parameters(BRIDGE_A, kp, kd, ki, w)
    c.pid_set_period(BRIDGE_A, T)
    c.pid_reset(BRIDGE_A)
    return c


def test_parameter_order_is_kp_kd_ki_windup():
    c = PidController()
    c.pid_set_parameters(BRIDGE_B, 1.0, 2.0, 3.0, 4.0)
    p = c.pids[BRIDGE_B]
    assert (p.kp, p.kd, p.ki, p.windup_limit) == (1.0, 2.0, 3.0, 4.0)


def test_law_matches_formula_when_unsaturated():
    """The law, to float32's precision (the C computes in float: rel 1e-6)."""
    c = make(kp=2.0, kd=0.01, ki=0.5, w=100.0)
    c.pid_set_point(BRIDGE_A, 1.0)
    u1 = c.pid_apply(BRIDGE_A, 0.2)          # e = 0.8, first sample: no derivative kick
    assert math.isclose(u1, 2.0 * (0.8 + (T / 0.5) * 0.8), rel_tol=1e-6)
    u2 = c.pid_apply(BRIDGE_A, 0.5)          # e = 0.5
    assert math.isclose(u2, 2.0 * (0.5 + 0.01 * (0.5 - 0.8) / T + (T / 0.5) * 1.3), rel_tol=1e-6)


def test_pid_apply_rounds_every_operation_to_float32_in_the_cs_order():
    """pid_controller.c computes in float: error = sp − y, then kd·(e − e_prev)/T, (T/ki)·Σe and
    kp·(e + d + i), each operation rounded to binary32, compared with the same expression evaluated
    in numpy.float32 step by step (the port had computed in binary64)."""
    import numpy as np
    f = np.float32
    c = make(kp=400.0, kd=0.05, ki=0.25, w=2.0)
    c.pid_set_point(BRIDGE_A, 1.57)
    kp, kd, ki, wl, per, sp = f(400.0), f(0.05), f(0.25), f(2.0), f(T), f(1.57)
    prev, s = None, f(0)
    for k in range(300):
        y = 1.57 * (1 - math.exp(-k / 60.0)) + 0.001 * math.sin(k)
        e = sp - f(y)
        prev = e if prev is None else prev
        s = min(max(s + e, -wl), wl)
        u = kp * (e + kd * (e - prev) / per + (per / ki) * s)
        prev = e
        want = float(min(max(u, f(-100)), f(100)))
        assert c.pid_apply(BRIDGE_A, y) == want, k


def test_output_saturates_at_100_percent():
    c = make()
    c.pid_set_point(BRIDGE_A, 10.0)
    assert c.pid_apply(BRIDGE_A, 0.0) == 100.0
    c.pid_set_point(BRIDGE_A, -10.0)
    assert c.pid_apply(BRIDGE_A, 0.0) == -100.0


measurements = st.lists(st.floats(min_value=-50, max_value=50, allow_nan=False), min_size=1, max_size=200)


@settings(max_examples=80)
@given(measurements, st.floats(min_value=-50, max_value=50), st.floats(min_value=0.01, max_value=20))
def test_integral_never_exceeds_windup_limit(ys, sp, w):
    c = make(w=w)
    c.pid_set_point(BRIDGE_A, sp)
    for y in ys:
        u = c.pid_apply(BRIDGE_A, y)
        assert abs(c.pids[BRIDGE_A].error_sum) <= w
        assert -100.0 <= u <= 100.0


@settings(max_examples=80)
@given(measurements, st.floats(min_value=0.01, max_value=5), st.floats(min_value=1.0, max_value=10.0),
       st.sampled_from([-1, 1]))
def test_loop_recovers_within_two_samples_after_error_reverses(history, w, margin, sign):
    """After any saturating history, a held error beyond (T/τI)·W drives the output its way."""
    c = make(w=w)
    c.pid_set_point(BRIDGE_A, 0.0)
    for y in history:
        c.pid_apply(BRIDGE_A, y)
    e = sign * margin * (T / 0.25) * w
    c.pid_apply(BRIDGE_A, -e)               # error e, derivative term still active
    u = c.pid_apply(BRIDGE_A, -e)           # same error: derivative term 0
    assert u * sign > 0


def test_without_clamp_windup_holds_output_in_wrong_direction():
    """The contrast: with a huge windup limit the same situation stays saturated the wrong way."""
    c = make(w=1e9)
    c.pid_set_point(BRIDGE_A, 0.0)
    for _ in range(400):
        c.pid_apply(BRIDGE_A, -5.0)         # error +5 for 2 s: Σe = 2000
    e = -0.5
    c.pid_apply(BRIDGE_A, -e)
    assert c.pid_apply(BRIDGE_A, -e) == 100.0  # still full forward although the error is negative
