"""The fast engine's period maps keep full precision over thousands of PWM periods.

The rule: N periods of a DC motor under a two-piece PWM drive (on at V, then freewheeling), advanced
by the power table, land on the exact solution of the motor's ODE to within a few float roundings of the scale the
closed form rounds at (each piece's steady state: see the test).
The oracle is the exact matrix exponential of the augmented system at 40 significant digits
(mpmath), composed and raised to the N-th power in that precision.

The bug this pins: a period map written as a plain matrix holds the mechanical mode's decay per
period as e^{λτ} ≈ 1 − 1e-4, which keeps only ~12 digits of the change; the same rounding repeated
every period drifted the state by ~1e-11 relative after a few thousand periods. The edge-by-edge
engine does not drift that way, so an encoder threshold crossing could land one tick apart in the
two engines (a generated rover run on CI: one PD3 edge 1 tick late). In delta form (T − I, with
expm1) the drift is gone.
"""

from __future__ import annotations

import mpmath as mp
from hypothesis import example, given, settings
from hypothesis import strategies as st

from mcusim.engine import periodmap as pm
from mcusim.plant import pwl


def _exact(R, L, K, J, b, V, T, t_on, t_off, N):
    with mp.workdps(40):
        def flow(u1, u2, t):
            A = mp.matrix([[-R / L, -K / L, 0, u1], [K / J, -b / J, 0, u2], [0, 1, 0, 0], [0, 0, 0, 0]])
            return mp.expm(A * t)
        M = flow(0, -T / J, t_off) * flow(V / L, -T / J, t_on)
        x = (M ** N) * mp.matrix([0, 0, 0, 1])
        return [float(x[i]) for i in range(3)]


@settings(max_examples=20, deadline=None)
@example(R=4.5, L=0.005, K=0.015625, J=0.0001, b=1e-07, V=1.0, T=0.002, duty=0.05, f_pwm=50000.0, N=256)
@given(R=st.floats(0.3, 5.0), L=st.sampled_from([2e-4, 1e-3, 5e-3]), K=st.floats(0.01, 0.1),
       J=st.sampled_from([2e-6, 2e-5, 1e-4]), b=st.sampled_from([1e-7, 1e-5, 1e-4]),
       V=st.floats(1.0, 24.0), T=st.sampled_from([0.0, 0.002]), duty=st.floats(0.05, 0.95),
       f_pwm=st.sampled_from([20e3, 50e3]), N=st.integers(256, 4096))
def test_period_map_powers_land_on_the_exact_solution_after_thousands_of_periods(R, L, K, J, b, V, T, duty,
                                                                                 f_pwm, N):
    P = 1.0 / f_pwm
    t_on, t_off = duty * P, P - duty * P
    A = (-R / L, -K / L, K / J, -b / J)
    eig = pwl.eig2(*A)
    D = pm.compose([pm.full_flow(eig, A, (V / L, -T / J), t_on), pm.full_flow(eig, A, (0.0, -T / J), t_off)])
    got = pm.PowerTable(D, N).state((0.0, 0.0, 0.0), N)
    want = _exact(R, L, K, J, b, V, T, t_on, t_off, N)
    # Scales of the rounding. The closed form writes a piece's motion about its steady state
    # (current s1, speed s2: -A⁻¹u), so it rounds relative to those: the angle relative to
    # |s2|·t, which exceeds the angle travelled when a slow mode keeps the motor far from its
    # steady speed (CI: a 0.5/s mode, load torque against a 5 % duty, 2.5e-4 rad travelled
    # where |s2|·t is 0.2 rad).
    c = K * K / R + b
    w_ss = max(abs(K * V / R - T) / c, T / c)    # the steady speeds of the on and the off piece
    scale = (V / R, w_ss, N * P * w_ss)
    for g, w, s in zip(got, want, scale):
        # measured worst 1.5e-15 over 7400 generated cases; a plain (non-delta) matrix power
        # exceeds 5e-15 in a quarter of them (up to 9e-14)
        assert abs(g - w) <= 5e-15 * max(abs(w), s), (got, want)


def test_delta_maps_compose_as_the_maps_do():
    """(I + B)(I + A) − I: two pieces composed equal the closed-form segments run one after the
    other, to rounding."""
    A = (-1000.0, -50.0, 2500.0, -0.5)
    eig = pwl.eig2(*A)
    u_on, u_off = (12000.0, -10.0), (0.0, -10.0)
    x0 = (0.5, 30.0, 2.0)
    D = pm.compose([pm.full_flow(eig, A, u_on, 2e-5), pm.full_flow(eig, A, u_off, 3e-5)])
    x1 = pwl.affine2(eig, A, u_on, x0).eval(2e-5)
    x2 = pwl.affine2(eig, A, u_off, x1).eval(3e-5)
    for g, w in zip(pm.apply(D, x0), x2):
        assert abs(g - w) <= 1e-14 * max(abs(w), 1.0)


@settings(max_examples=40, deadline=None)
@given(V1=st.floats(1.0, 24.0), V2=st.floats(1.0, 24.0), T1=st.floats(0.0, 0.01), T2=st.floats(0.0, 0.01),
       duty=st.floats(0.05, 0.95), n=st.integers(1, 300), grow=st.integers(1, 300))
def test_maps_that_differ_only_in_their_inputs_share_powers_and_modes_and_lose_nothing(V1, V2, T1, T2, duty,
                                                                                      n, grow):
    """A supply voltage or a load torque moves only the period map's constant column: its linear
    part, and so its powers (``LinearPowers``) and modes, are those of any other map with that
    part. A table on powers another map built (to another length, in steps) gives the states bit
    for bit as one on powers of its own, and modes taken from the other map are the full build's."""
    from mcusim.engine import modal

    A = (-900.0, -3.1, 156.25, -1e-3)
    eig = pwl.eig2(*A)
    P = 5e-5

    def period(V, T):
        return pm.compose([pm.full_flow(eig, A, (V / 5e-3, -T / 1e-4), duty * P),
                           pm.full_flow(eig, A, (0.0, -T / 1e-4), P - duty * P)])
    D1, D2 = period(V1, T1), period(V2, T2)
    assert D1[:3, :3].tobytes() == D2[:3, :3].tobytes()     # the inputs leave the linear part as it is
    other = pm.PowerTable(D1, 512)
    other.augmented_states((0.1, 2.0, 0.0), grow)           # built by the other map, to its own length
    shared = pm.PowerTable(D2, 512, other.linear)
    own = pm.PowerTable(D2, 512)
    x0 = (0.3, -4.0, 1.5)
    assert shared.augmented_states(x0, n).tobytes() == own.augmented_states(x0, n).tobytes()
    Q1, Q2 = [[[0.0] * 4] * 4, D1.tolist()], [[[0.0] * 4] * 4, D2.tolist()]
    try:
        full = modal.Modes(Q2)
    except ValueError:
        return
    like = modal.Modes(Q2, modal.Modes(Q1))
    for attr in ("ystar", "bounds", "V", "Vi", "mu", "lg", "cplx"):
        assert getattr(like, attr) == getattr(full, attr), attr
