"""Plant physics: DC motor, L6206 bridge, quadrature encoder (docs/plants.md §1–3, §5).

Every expected value is computed here from the equations of docs/plants.md (closed-form algebra, scipy's
ODE solver or matrix exponential), never copied from the model's output.
"""

import math
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm
from scipy.optimize import brentq

from mcusim.errors import ConfigError
from mcusim.kernel import Kernel
from mcusim.plant.dcmotor import DcMotor, MotorParams
from mcusim.plant.encoder import QuadratureEncoder
from mcusim.plant.l6206 import L6206Bridge, L6206Params
from mcusim.signals import Net
from mcusim.time import TimeBase

FS = 216_000_000
P = MotorParams()
BR = L6206Params()
R_DRIVE = P.R + BR.R_HS + BR.R_LS  # 2.8 Ω


def rig(state=(0.0, 0.0, 0.0), encoder=False, motor_kw=None, bridge_kw=None, bridge=(0, 0, 0)):
    tb = TimeBase([FS])
    k = Kernel(tb)
    in1, in2, en, a, b = (Net(n) for n in ("IN1", "IN2", "EN", "A", "B"))
    m = DcMotor(k, "motor1", current=state[0], speed=state[1], angle=state[2], **(motor_kw or {}))
    br = L6206Bridge(k, m, in1=in1, in2=in2, en=en, name="bridgeA", **(bridge_kw or {}))
    s = SimpleNamespace(tb=tb, k=k, m=m, br=br, in1=in1, in2=in2, en=en, a=a, b=b, enc=None)
    if encoder:
        s.enc = QuadratureEncoder(k, m, a=a, b=b, counts_per_rev=64, name="encoder1")
    set_bridge(s, *bridge)
    return s


def set_bridge(s, en, in1, in2):
    s.in1.set("mcu", in1)
    s.in2.set("mcu", in2)
    s.en.set("mcu", en)


def ode(v0, r_loop, sgn, p=P, load_m=0.0):
    """Right-hand side of §1.1 for a fixed mode: v_m = v0 − R_br·i, friction sign sgn."""
    J = p.J_eq

    def f(t, x):
        i, w, _th = x
        return [(v0 - r_loop * i - p.K * w) / p.L, (p.K * i - p.b * w - p.tau_c * sgn - load_m) / J, w]
    return f


def compare_to_ivp(s, f, x0, t_end, n=9, rtol=2e-8):
    sol = solve_ivp(f, (0, t_end), x0, method="DOP853", rtol=1e-12, atol=1e-12, dense_output=True)
    t0 = s.k.now
    for j in range(1, n + 1):
        tick = t0 + round(j * t_end / n * FS)
        s.k.run_until(tick)
        ref = sol.sol((tick - t0) / FS)
        got = (s.m.current, s.m.speed, s.m.angle)
        for g, r, scale in zip(got, ref, (1.0, 100.0, 1.0)):
            assert abs(g - r) <= rtol * max(abs(r), scale), (j, got, ref)


# ---- closed form vs an independent ODE solver ----------------------------------------------------

def test_drive_segment_matches_ode_solver():
    x0 = (1.0, 500.0, 0.3)
    s = rig(state=x0, bridge=(1, 1, 0))
    compare_to_ivp(s, ode(BR.Vs, R_DRIVE, +1), x0, 5e-3)


def test_brake_high_segment_matches_ode_solver():
    x0 = (0.5, 1000.0, 0.0)
    s = rig(state=x0, bridge=(1, 1, 1))
    compare_to_ivp(s, ode(0.0, P.R + 2 * BR.R_HS, +1), x0, 3e-3)


def test_brake_low_reverse_speed_matches_ode_solver():
    x0 = (-0.5, -800.0, 0.0)
    s = rig(state=x0, bridge=(1, 0, 0))
    compare_to_ivp(s, ode(0.0, P.R + 2 * BR.R_LS, -1), x0, 3e-3)


def test_complex_eigenvalue_segment_matches_ode_solver():
    # small R, large K: (R/L)²/4 < K²/(L·J) -> complex eigenvalues (underdamped)
    kw = {"R": 0.5, "L": 5e-3, "K": 0.1, "J": 1e-4, "tau_s": 2e-3, "tau_c": 1e-3}
    p = MotorParams.from_mapping(kw)
    rl = p.R + BR.R_HS + BR.R_LS
    assert (rl / p.L) ** 2 / 4 < p.K ** 2 / (p.L * p.J_eq)
    x0 = (0.0, 50.0, 0.0)
    s = rig(state=x0, motor_kw=kw, bridge=(1, 1, 0))
    compare_to_ivp(s, ode(BR.Vs, rl, +1, p), x0, 20e-3)


def test_diode_segment_then_discontinuous_conduction_matches_ode_solver():
    x0 = (2.0, 800.0, 0.0)
    vd = BR.Vs + 2 * BR.V_D  # all-off, i > 0: v_m = −(Vs + 2V_D) − 2 r_D·i
    f1 = ode(-vd, P.R + 2 * BR.r_D, +1)

    def hit_zero(t, x):
        return x[0]
    hit_zero.terminal, hit_zero.direction = True, -1
    sol1 = solve_ivp(f1, (0, 1e-3), x0, method="DOP853", rtol=1e-12, atol=1e-13, events=hit_zero,
                     dense_output=True)
    tz = sol1.t_events[0][0]
    xz = sol1.y_events[0][0]
    # DCM: i ≡ 0, J dω/dt = −b ω − τc
    sol2 = solve_ivp(lambda t, x: [0.0, (-P.b * x[1] - P.tau_c) / P.J_eq, x[1]], (tz, 50e-3),
                     [0.0, xz[1], xz[2]], method="DOP853", rtol=1e-12, atol=1e-12, dense_output=True)
    s = rig(state=x0, bridge=(0, 0, 0))
    for frac in (0.2, 0.5, 0.9):
        t = round(frac * tz * FS)
        s.k.run_until(t)
        ref = sol1.sol(t / FS)
        assert s.m.current == pytest.approx(ref[0], rel=1e-8, abs=1e-9)
        assert s.m.speed == pytest.approx(ref[1], rel=1e-9)
    s.k.run_until(math.floor(tz * FS) - 1)
    assert s.m.current > 0
    s.k.run_until(math.ceil(tz * FS) + 1)
    assert s.m.current == 0.0 and s.m.mode.startswith("dcm")
    for t_s in (1e-3, 10e-3, 50e-3):
        s.k.run_until(round(t_s * FS))
        ref = sol2.sol(t_s)
        assert s.m.current == 0.0
        assert s.m.speed == pytest.approx(ref[1], rel=1e-9)
        assert s.m.angle == pytest.approx(ref[2], rel=1e-9)


# ---- steady states --------------------------------------------------------------------------------

def no_load_steady(v=BR.Vs, r=R_DRIVE, p=P):
    # 0 = v − r i − K ω ; 0 = K i − b ω − τc
    A = np.array([[r, p.K], [p.K, -p.b]])
    i, w = np.linalg.solve(A, [v, p.tau_c])
    return float(i), float(w)


def test_no_load_speed_at_12V_equals_analytic_steady_state():
    i_ss, w_ss = no_load_steady()
    s = rig(bridge=(1, 1, 0))     # from rest: breaks away, accelerates, settles (τm ≈ 0.12 s)
    s.k.run_until(3 * FS)
    assert s.m.speed == pytest.approx(w_ss, rel=1e-7)
    assert s.m.current == pytest.approx(i_ss, rel=1e-6)
    # sanity against the datasheet: ≈ 10,000 rpm no-load at 12 V less the bridge drop
    assert 9_500 < w_ss * 60 / (2 * math.pi) < 10_100
    assert s.m.output_angle == pytest.approx(s.m.angle / 30)


def test_stall_current_is_supply_over_loop_resistance_when_load_holds_the_shaft():
    # 1.2 N·m on the output holds the shaft for every i in [3 A, i_stall]:
    # K·i − τ_out/(Nη) ≤ τs (no forward breakaway) and K·i − τ_out·η/N ≥ −τs (no back-driving).
    # (From i = 0 no constant load can do both: 1.2 N·m alone would back-drive the motor.)
    tau_out, i0 = 1.2, 3.0
    i_stall = BR.Vs / R_DRIVE
    for i in (i0, i_stall):
        assert P.K * i - tau_out / (30 * 0.78) <= P.tau_s
        assert P.K * i - tau_out * 0.78 / 30 >= -P.tau_s
    s = rig(state=(i0, 0.0, 0.0), motor_kw={"load_torque": tau_out}, bridge=(1, 1, 0))
    for t in (1e-3, 5e-3, 30e-3):
        s.k.run_until(round(t * FS))
        assert s.m.speed == 0.0 and s.m.angle == 0.0 and s.m.stuck
    assert s.m.current == pytest.approx(BR.Vs / R_DRIVE, rel=1e-12)   # 4.2857 A
    assert s.br.ocd_trips == 0 and s.m.peak_current < BR.I_ocd


# ---- stiction -------------------------------------------------------------------------------------

def test_voltage_below_breakaway_never_moves_the_shaft():
    v = 1.0
    assert P.K * v / R_DRIVE < P.tau_s
    s = rig(bridge_kw={"Vs": v}, bridge=(1, 1, 0))
    for t in (1e-3, 10e-3, 200e-3):
        s.k.run_until(round(t * FS))
        assert s.m.speed == 0.0 and s.m.angle == 0.0
    assert s.m.current == pytest.approx(v / R_DRIVE, rel=1e-12)


def test_voltage_above_breakaway_breaks_away_at_the_analytic_time():
    v = 2.0
    assert P.K * v / R_DRIVE > P.tau_s
    # stuck: i(t) = (v/R)(1 − e^{−tR/L}); breakaway when K·i = τs
    tb = -(P.L / R_DRIVE) * math.log(1 - P.tau_s * R_DRIVE / (P.K * v))
    s = rig(bridge_kw={"Vs": v}, bridge=(1, 1, 0))
    s.k.run_until(math.floor(tb * FS) - 1)
    assert s.m.stuck and s.m.speed == 0.0
    s.k.run_until(math.ceil(tb * FS) + 1)
    assert not s.m.stuck and s.m.speed > 0.0
    s.k.run_until(round(2.0 * FS))
    assert s.m.speed == pytest.approx(no_load_steady(v)[1], rel=1e-6)


# ---- coast (EN low) -------------------------------------------------------------------------------

def test_coast_after_enable_low_current_goes_to_exactly_zero_and_shaft_coasts_on_friction():
    i0, w0 = no_load_steady()
    s = rig(state=(i0, w0, 0.0), bridge=(0, 0, 0))
    s.k.run_until(round(1e-3 * FS))
    assert s.m.current == 0.0 and s.m.mode == "dcm,w>0"
    t_r, w_r = s.k.now, s.m.speed
    J, b, tc = P.J_eq, P.b, P.tau_c
    for t in (0.01, 0.3, 1.0, 2.0):
        s.k.run_until(t_r + round(t * FS))
        expect = (w_r + tc / b) * math.exp(-b * t / J) - tc / b
        assert s.m.current == 0.0
        assert s.m.speed == pytest.approx(expect, rel=1e-9)
    t_stop = t_r + (J / b) * math.log(1 + b * w_r / tc) * FS
    s.k.run_until(math.floor(t_stop) - 2)
    assert s.m.speed > 0
    s.k.run_until(math.ceil(t_stop) + 2)
    assert s.m.speed == 0.0 and s.m.stuck and s.m.current == 0.0
    assert s.br.ocd_trips == 0


# ---- OCD on reversal ------------------------------------------------------------------------------

def test_reversal_at_full_speed_trips_ocd_and_bridge_reenables_after_t_release():
    i0, w0 = no_load_steady()
    s = rig(state=(i0, w0, 0.0), bridge=(1, 1, 0))
    trips = []
    s.br.ocd.listen(lambda n: trips.append((s.k.now, n.level, s.m.current, s.br.legs)))
    set_bridge(s, 1, 0, 1)   # reverse: v = −12 V against E ≈ +11.4 V
    # oracle: x' = A x + u, v = −12, friction sign +, until i = −5.6 A
    A = np.array([[-R_DRIVE / P.L, -P.K / P.L, 0], [P.K / P.J, -P.b / P.J, -P.tau_c / P.J], [0, 0, 0]])
    A[0, 2] = -BR.Vs / P.L
    x0 = np.array([i0, w0, 1.0])
    t_trip = brentq(lambda t: (expm(A * t) @ x0)[0] + BR.I_ocd, 0, 5e-3, xtol=1e-15)
    s.k.run_until(round(3e-3 * FS))
    assert len(trips) >= 2
    t1, lvl, i_trip, legs = trips[0]
    assert lvl == 1 and legs == ("Z", "Z")
    assert abs(t1 - t_trip * FS) <= 1.5
    assert -BR.I_ocd - 1e-3 < i_trip < -BR.I_ocd     # |i| just above 5.6 A at the located tick
    t_rel = BR.R_EN * BR.C_EN * math.log(3.3 / (3.3 - 1.8))
    assert t_rel == pytest.approx(0.4415e-3, rel=1e-3)
    t2, lvl2, _, legs2 = trips[1]
    assert lvl2 == 0 and t2 - t1 == round(t_rel * FS) and legs2 == ("L", "H")
    assert s.br.ocd_trips >= 2      # ω is still ≈ 1000 rad/s: reversing again trips again
    assert BR.I_ocd < s.m.peak_current < BR.I_ocd + 1e-3
    # 0.60 ms: 12 V + E across 2.8 Ω heads for −8.4 A with τe = 0.54 ms
    assert 0.55e-3 < t_trip < 0.65e-3


def test_ocd_is_not_sensed_with_only_low_sides_on():
    # brake low at full speed: i → −E/(R+2R_LS) ≈ −4.2 A... use a faster shaft to exceed 5.6 A
    s = rig(state=(0.0, 2000.0, 0.0), bridge=(1, 0, 0))
    s.k.run_until(round(2e-3 * FS))
    assert s.m.peak_current > BR.I_ocd and s.br.ocd_trips == 0


# ---- encoder --------------------------------------------------------------------------------------

QUAD_UP = {(0, 0): (1, 0), (1, 0): (1, 1), (1, 1): (0, 1), (0, 1): (0, 0)}


def record_edges(s):
    edges = []

    def on(net):
        edges.append((s.k.now, s.a.level, s.b.level))
    s.a.listen(on)
    s.b.listen(on)
    return edges


@pytest.mark.parametrize("sign", [+1, -1])
def test_encoder_edges_at_analytic_crossing_times_and_a_leads_b_forward(sign):
    x0 = (0.5 * sign, 300.0 * sign, 0.01)
    s = rig(state=x0, encoder=True)
    step = 2 * math.pi / 64
    k0 = math.floor(x0[2] / step)
    assert (s.a.level, s.b.level) == [(0, 0), (1, 0), (1, 1), (0, 1)][k0 % 4]
    edges = record_edges(s)
    prev = (s.a.level, s.b.level)
    set_bridge(s, 1, 1, 0) if sign > 0 else set_bridge(s, 1, 0, 1)
    t_end = 30e-3
    s.k.run_until(round(t_end * FS))
    sol = solve_ivp(ode(BR.Vs * sign, R_DRIVE, sign), (0, t_end), x0, method="DOP853", rtol=1e-13,
                    atol=1e-12, dense_output=True)
    th_end = s.m.angle
    assert th_end == pytest.approx(sol.sol(t_end)[2], rel=1e-9)
    assert len(edges) == abs(math.floor(th_end * 64 / (2 * math.pi)) - k0) > 100
    assert s.enc.count == math.floor(th_end * 64 / (2 * math.pi)) - k0
    pos = k0
    for tick, a, b in edges:
        if sign > 0:
            assert QUAD_UP[prev] == (a, b)            # A leads B
            pos += 1
            thr = pos * step
        else:
            assert QUAD_UP[(a, b)] == prev            # B leads A
            thr = pos * step
            pos -= 1
        prev = (a, b)
        t_cross = brentq(lambda t, thr=thr: sol.sol(t)[2] - thr, 0, t_end, xtol=1e-16)
        assert abs(tick - t_cross * FS) <= 1.0, (tick, t_cross * FS)


def test_encoder_counts_through_reversal():
    # spinning forward, driven back (|i| stays below the OCD threshold from 200 rad/s)
    s = rig(state=(0.0, 200.0, 0.0), encoder=True, bridge=(1, 0, 1))
    edges = record_edges(s)
    s.k.run_until(round(80e-3 * FS))
    assert s.m.speed < 0 and s.m.angle < -1.0
    step = 2 * math.pi / 64
    k_end = math.floor(s.m.angle / step)
    assert s.enc.count == k_end
    pos, prev, ups, downs = 0, (0, 0), 0, 0
    for _, a, b in edges:
        if QUAD_UP[prev] == (a, b):
            pos, ups = pos + 1, ups + 1
        else:
            assert QUAD_UP[(a, b)] == prev
            pos, downs = pos - 1, downs + 1
        prev = (a, b)
    assert pos == k_end and ups > 10 and downs > ups and s.br.ocd_trips == 0


# ---- configuration ---------------------------------------------------------------------------------

@pytest.mark.parametrize("cpr", [1, 2, 10, 63, 2047])
def test_encoder_counts_per_rev_is_four_per_disc_cycle_so_other_counts_raise_naming_it(cpr):
    # docs/plants.md §3.1: A and B make n_cyc cycles per revolution, C4 = 4·n_cyc counts; a count
    # that is not a multiple of 4 is no quadrature disc (the A/B state at θ and θ + 2π would differ)
    k = Kernel(TimeBase([FS]))
    m = DcMotor(k, "m")
    with pytest.raises(ConfigError, match=rf"encoder e: counts_per_rev = {cpr}\b.*multiple of 4"):
        QuadratureEncoder(k, m, Net("A"), Net("B"), counts_per_rev=cpr, name="e")
    for ok in (4, 48, 64, 2048):
        assert QuadratureEncoder(k, DcMotor(k, f"m{ok}"), Net("A"), Net("B"), counts_per_rev=ok,
                                 name="e").counts_per_rev == ok


def test_unknown_parameter_names_raise_config_error_naming_the_key():
    tb = TimeBase([FS])
    k = Kernel(tb)
    with pytest.raises(ConfigError, match="Rx"):
        DcMotor(k, "m", Rx=1.0)
    with pytest.raises(ConfigError, match="bogus"):
        MotorParams.from_mapping({"bogus": 1})
    with pytest.raises(ConfigError, match="R_XX"):
        L6206Params.from_mapping({"R_XX": 1})
    with pytest.raises(ConfigError, match="tau_s"):
        MotorParams.from_mapping({"tau_s": 1e-4})
    m = DcMotor(k, "m", {"gear_ratio": 50}, R=3.0)
    assert m.params.gear_ratio == 50 and m.params.R == 3.0 and m.params.efficiency == 0.78


def test_load_inertia_is_reflected_through_the_gear_squared():
    p = MotorParams.from_mapping({"load_inertia": 2.3e-6 * 900})
    assert p.J_eq == pytest.approx(5e-6 + 2.3e-6)
    p = MotorParams.from_mapping({"load_torque": 0.78})
    assert p.load_reflected(+1) == pytest.approx(0.78 / (30 * 0.78))
    assert p.load_reflected(-1) == pytest.approx(0.78 * 0.78 / 30)


def test_runtime_load_torque_advances_first_and_changes_the_steady_state():
    i_ss, w_ss = no_load_steady()
    s = rig(state=(i_ss, w_ss, 0.0), bridge=(1, 1, 0))
    s.k.run_until(round(1e-3 * FS))
    th_before = s.m.angle
    s.m.apply_load_torque(0.3)
    assert s.m.angle == th_before
    s.k.run_until(round(2 * FS))
    tl = 0.3 / (30 * 0.78)
    i2, w2 = np.linalg.solve([[R_DRIVE, P.K], [P.K, -P.b]], [BR.Vs, P.tau_c + tl])
    assert s.m.speed == pytest.approx(w2, rel=1e-6)
    assert s.m.current == pytest.approx(i2, rel=1e-6)


@pytest.mark.parametrize("engine", ["reference", "fast"])
def test_a_motor_given_a_current_without_a_driver_drops_it_to_zero_and_coasts(engine):
    """Open terminals carry no current (dcmotor's docstring); a state given one before any bridge
    attaches turned every variable into NaN (the open circuit's infinite voltages)."""
    k = Kernel(TimeBase([16_000_000]), engine)
    m = DcMotor(k, "m", current=1.0, speed=100.0)
    k.run_until(16_000)
    assert m.current == 0.0 and 0.0 < m.speed < 100.0 and math.isfinite(m.angle)
    m.set_state(current=-0.5)
    k.run_until(32_000)
    assert m.current == 0.0 and math.isfinite(m.speed) and m.speed > 0.0


def test_an_encoder_glitch_lasts_its_width_whatever_crosses_meanwhile():
    """glitch(): the channel shows the wrong level for ``width`` ticks. A threshold crossing of the
    other channel used to rewrite both outputs, ending the glitch early and changing A and B at one
    tick (an illegal quadrature step)."""
    from mcusim.plant.encoder import _QUAD
    k = Kernel(TimeBase([1_000_000]))
    m = DcMotor(k, "m", speed=50.0)          # no driver: coasting from 50 rad/s
    a, b = Net("A"), Net("B")
    enc = QuadratureEncoder(k, m, a, b, counts_per_rev=64, name="e")
    changes, wrong = [], []
    a.listen(lambda n: changes.append((k.now, "A")))
    b.listen(lambda n: changes.append((k.now, "B")))
    k.run_until(1_000)
    t0, width = k.now, 6_000                 # about three crossings long (~2 ms each at 50 rad/s)
    enc.glitch("B", width)
    for t in range(t0 + 500, t0 + width, 500):   # B against its true level inside the glitch
        k.at(t, lambda: wrong.append(b.level != _QUAD[enc.position & 3][1]))
    k.run_until(t0 + width + 3_000)
    assert any(ch == "A" and t0 < t < t0 + width for t, ch in changes)     # A crossed meanwhile
    assert wrong and all(wrong)              # wrong for the whole width
    ticks = [t for t, _ in changes]
    assert len(ticks) == len(set(ticks))     # never both channels at one tick
    assert b.level == _QUAD[enc.position & 3][1]      # the true level again after it
