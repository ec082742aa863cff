"""IBT-2 (2 × BTS7960) bridge, the 100 W OpenRover motor preset and the AMT10 encoder
(docs/plants.md §0, §1.4, §2.1, §2.3, §3.2, §5.2).

Every expected value is computed here from the equations of docs/plants.md (closed-form algebra or scipy's
matrix exponential), never copied from the model's output.
"""

import math
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.linalg import expm

from mcusim.errors import ConfigError
from mcusim.kernel import PRIO_HW, PRIO_OBSERVE, Kernel
from mcusim.plant.bts7960 import Bts7960Bridge, Bts7960Params
from mcusim.plant.dcmotor import DcMotor, MotorParams
from mcusim.plant.encoder import QuadratureEncoder
from mcusim.plant.presets import MOTOR_PRESETS, motor_preset
from mcusim.signals import AnalogNet, Net
from mcusim.time import TimeBase

FS = 16_000_000                     # Arduino Pro Mini base clock (system b)
PRESET = "openrover-100w-50"
P = MotorParams.from_mapping(motor_preset(PRESET))
BR = Bts7960Params()
R_DRIVE = P.R + BR.R_HS + BR.R_LS   # 0.176 Ω
LOCKED = {"tau_s": 10.0}           # breakaway far above any motor torque: locked rotor


def rig(state=(0.0, 0.0, 0.0), motor_kw=None, bridge_kw=None, en=True, pins=(0, 0)):
    k = Kernel(TimeBase([FS]))
    rpwm, lpwm = Net("RPWM"), Net("LPWM")
    r_en, l_en = (Net("R_EN"), Net("L_EN")) if en else (None, None)
    m = DcMotor(k, "motor1", preset=PRESET, current=state[0], speed=state[1], angle=state[2],
                **(motor_kw or {}))
    br = Bts7960Bridge(k, m, rpwm, lpwm, r_en, l_en, name="ibt2", **(bridge_kw or {}))
    s = SimpleNamespace(k=k, m=m, br=br, rpwm=rpwm, lpwm=lpwm, r_en=r_en, l_en=l_en)
    if en:
        set_en(s, 1, 1)
    set_pwm(s, *pins)
    return s


def set_pwm(s, r, l):
    s.rpwm.set("mcu", r)
    s.lpwm.set("mcu", l)


def set_en(s, r, l):
    s.r_en.set("mcu", r)
    s.l_en.set("mcu", l)


def steady(v=BR.Vs, r=R_DRIVE, p=P):
    # 0 = v − r·i − K·ω ; 0 = K·i − b·ω − τc
    i, w = np.linalg.solve([[r, p.K], [p.K, -p.b]], [v, p.tau_c])
    return float(i), float(w)


def aug(v0, r_loop, sgn, p=P):
    """4×4 augmented matrix of §5.1 for x = (i, ω, θ, 1) with v_m = v0 − r_loop·i, friction sign sgn."""
    J = p.J_eq
    return np.array([[-r_loop / p.L, -p.K / p.L, 0.0, v0 / p.L],
                     [p.K / J, -p.b / J, 0.0, -p.tau_c * sgn / J],
                     [0.0, 1.0, 0.0, 0.0],
                     [0.0, 0.0, 0.0, 0.0]])


def v_is(i_forward, p=BR):
    return min(min(max(i_forward, 0.0) / p.k_ILIS, p.I_IS_lim) * p.R_IS, p.Vcc)


# ---- presets ---------------------------------------------------------------------------------------

def test_pololu_preset_equals_the_motor_defaults_and_openrover_preset_matches_the_sheet():
    assert MotorParams.from_mapping(motor_preset("pololu-37d-12v-30")) == MotorParams()
    p = P
    assert (p.R, p.L, p.K, p.J, p.gear_ratio) == (0.16, 0.3e-3, 0.0496, 1.2e-4, 50.0)
    assert p.tau_c + p.b * (2279 * 2 * math.pi / 60) == pytest.approx(p.K * 1.0, rel=0.02)  # τf0 = K·I_0
    assert 1.5 * p.tau_c <= p.tau_s <= 2 * p.tau_c
    # loaded rover, §1.4: 12.5 kg at r = 0.195 m plus a 2 kg disc wheel, reflected through 50²
    assert p.J_eq == pytest.approx(1.2e-4 + (12.5 + 1.0) * 0.195 ** 2 / 50 ** 2, rel=1e-3)
    assert 3.2e-4 < p.J_eq < 3.4e-4
    # the recommended row of §1.4: no-load ≈ 2,279 rpm, stall ≈ 75 A at 12 V (motor alone)
    assert steady(12.0, p.R)[1] * 60 / (2 * math.pi) == pytest.approx(2279, rel=2e-3)
    assert 12.0 / p.R == pytest.approx(75.0)


def test_unknown_preset_raises_config_error_listing_the_presets_and_overrides_apply_on_top():
    with pytest.raises(ConfigError, match="openrover-100w-50.*pololu-37d-12v-30"):
        motor_preset("nope")
    k = Kernel(TimeBase([FS]))
    with pytest.raises(ConfigError, match="pololu"):
        DcMotor(k, "m", preset="nope")
    m = DcMotor(k, "m", {"efficiency": 0.5}, preset=PRESET, R=0.2)
    assert (m.params.R, m.params.efficiency, m.params.K) == (0.2, 0.5, 0.0496)
    with pytest.raises(ConfigError, match="not both"):
        DcMotor(k, "m2", MotorParams(), preset=PRESET)
    motor_preset(PRESET)["R"] = 99.0            # a copy: the table is not modified
    assert MOTOR_PRESETS[PRESET]["R"] == 0.16


# ---- truth table (§2.1, §2.3 IBT-2 state table) -----------------------------------------------------

VS, RH, RL, VD = BR.Vs, BR.R_HS, BR.R_LS, BR.V_D


@pytest.mark.parametrize("en, pins, legs, vp, vn, rbr, diode", [
    ((1, 1), (1, 0), ("H", "L"), VS, VS, RH + RL, False),                 # forward drive
    ((1, 1), (0, 1), ("L", "H"), -VS, -VS, RL + RH, False),               # reverse drive
    ((1, 1), (0, 0), ("L", "L"), 0.0, 0.0, 2 * RL, False),                # brake low
    ((1, 1), (1, 1), ("H", "H"), 0.0, 0.0, 2 * RH, False),                # brake high
    ((0, 0), (1, 0), ("Z", "Z"), -(VS + 2 * VD), VS + 2 * VD, 0.0, True),  # coast, fast decay
    ((1, 0), (1, 0), ("H", "Z"), -VD, VS + VD, RH, True),                 # A=H, B=Z: −(V_D + i·R_HS)
    ((1, 0), (0, 0), ("L", "Z"), -(VS + VD), 0.0 + VD, RL, True),         # A=L, B=Z: −(Vs + V_D + i·R_LS)
])
def test_leg_truth_table_gives_the_sheet_motor_voltage_in_each_state(en, pins, legs, vp, vn, rbr, diode):
    s = rig()
    set_en(s, *en)
    set_pwm(s, *pins)
    assert s.br.legs == legs
    got = s.br.drive_state()
    assert got[0] == pytest.approx(vp, abs=1e-12) and got[1] == pytest.approx(vn, abs=1e-12)
    assert got[2] == pytest.approx(rbr, abs=1e-15) and got[3] == diode


def test_enable_none_means_inh_tied_high_and_coast_gives_discontinuous_conduction():
    s = rig(en=False, pins=(1, 0))
    assert s.br.legs == ("H", "L")
    set_pwm(s, 0, 1)
    assert s.br.legs == ("L", "H")
    # coast from the no-load steady state: i decays through the diodes to exactly 0 (DCM)
    i0, w0 = steady()
    s = rig(state=(i0, w0, 0.0), pins=(1, 0))
    set_en(s, 0, 0)
    # i·L/(Vs + 2V_D + E) ≈ 1 A · 0.3 mH / 24 V ≈ 12 µs
    s.k.run_until(round(100e-6 * FS))
    assert s.m.current == 0.0 and s.m.mode == "dcm,w>0"
    assert s.br.is_r.voltage() == 0.0 and s.br.is_l.voltage() == 0.0


@pytest.mark.parametrize("i0, pins, v_r, v_l", [
    (10.0, (1, 0), v_is(10.0), 0.0),    # forward drive: R high side sources i
    (10.0, (0, 0), 0.0, 0.0),           # brake low: no high side on
    (10.0, (1, 1), v_is(10.0), 0.0),    # brake high, i > 0: the M+ high side sources
    (-10.0, (1, 1), 0.0, v_is(10.0)),   # brake high, i < 0: the M− high side sources
    (-10.0, (1, 0), 0.0, 0.0),          # R high side on, but the current is reverse: no sense
])
def test_is_pins_follow_the_ibt2_state_table(i0, pins, v_r, v_l):
    s = rig(state=(i0, 100.0 * np.sign(i0), 0.0), pins=pins)
    assert s.br.is_r.voltage(s.k.now) == pytest.approx(v_r, rel=1e-15)
    assert s.br.is_l.voltage(s.k.now) == pytest.approx(v_l, rel=1e-15)
    assert v_is(10.0) == pytest.approx(10.0 / 8.5, rel=1e-12)       # §2.3: V_IS = I_L/8.5 A


# ---- steady states with both R_ON in the loop ---------------------------------------------------------

def test_locked_rotor_stall_current_at_12V_is_supply_over_motor_plus_both_r_on():
    # current limit lifted out of the way to see the bare stall current
    s = rig(motor_kw=LOCKED, bridge_kw={"I_CLH": 1e3, "I_CLL": 1e3}, pins=(1, 0))
    i_inf = BR.Vs / R_DRIVE                       # 68.18 A (75 A for the motor alone, §1.4)
    tau = P.L / R_DRIVE
    for t in (0.5e-3, 2e-3, 40e-3):
        s.k.run_until(round(t * FS))
        assert s.m.speed == 0.0 and s.m.stuck
        assert s.m.current == pytest.approx(i_inf * -math.expm1(-t / tau), rel=1e-9)
    assert s.m.current == pytest.approx(i_inf, rel=1e-9)
    assert 68.0 < i_inf < 68.4 and s.br.cl_trips == 0
    # IS saturates at the analog ceiling I_IS(lim)·R_IS = 4.5 V (normal reading above ≈38 A)
    assert s.br.is_r.voltage() == pytest.approx(BR.I_IS_lim * BR.R_IS) == pytest.approx(4.5)


def test_no_load_speed_from_a_hard_start_equals_the_analytic_steady_state():
    i_ss, w_ss = steady()
    s = rig(pins=(1, 0))
    s.k.run_until(round(0.6 * FS))                # τ ≈ 21 ms for the loaded rover (§1.6)
    assert s.m.speed == pytest.approx(w_ss, rel=1e-7)
    assert s.m.current == pytest.approx(i_ss, rel=1e-6)
    rpm = w_ss * 60 / (2 * math.pi)
    assert 2260 < rpm < 2279                      # §1.4: 2,279 rpm for the motor alone, less 16 mΩ
    # §1.4: a full-duty start reaches the limit in ≈1.1–1.5 ms and is current-limited
    assert s.br.cl_trips_l > 0 and s.br.cl_trips_r == 0
    t1 = s.br.trip_log[0][0] / FS
    assert 1.1e-3 < t1 < 2.2e-3
    assert BR.I_CLL < s.m.peak_current < BR.I_CLL + 0.01


# ---- IS under 20 kHz PWM --------------------------------------------------------------------------------

def test_is_voltage_follows_the_exact_current_in_the_on_phase_and_is_zero_in_the_brake_phase():
    period, on = FS // 20_000, FS // 40_000       # 800 ticks, D = 0.5: drive / brake low
    s = rig(pins=(0, 0))

    def edge(level, t):
        s.rpwm.set("mcu", level)
        s.k.at(t + (on if level else period - on), edge, 1 - level, t + (on if level else period - on),
               prio=PRIO_HW)
    s.k.at(0, edge, 1, 0, prio=PRIO_HW)
    n_per = 4000                                   # 0.2 s: well into the periodic steady state
    t0 = n_per * period
    s.k.run_until(t0)
    assert s.m.speed > 0 and s.m.current > 0 and s.br.legs == ("H", "L")
    x0 = np.array([*s.m.state_at(t0), 1.0])
    samples = {}

    def sample(t):
        samples[t] = (s.br.is_r.voltage(t), s.br.is_l.voltage(t))
    ticks = [t0 + d for d in (1, 100, 250, 399, 400, 401, 600, 799, 800 + 1)]
    for t in ticks:
        s.k.at(t, sample, t, prio=PRIO_OBSERVE)
    s.k.run_until(t0 + period + 10)
    A_on, A_off = aug(BR.Vs, R_DRIVE, +1), aug(0.0, P.R + 2 * BR.R_LS, +1)
    x_on_end = expm(A_on * on / FS) @ x0
    for t in ticks:
        d = t - t0
        if d < on:                                 # drive: R high side conducts i
            i_ref = (expm(A_on * d / FS) @ x0)[0]
            assert samples[t][0] == pytest.approx(i_ref / BR.k_ILIS * BR.R_IS, rel=1e-9)
            assert samples[t][0] > 0.05
        elif d < period:                           # brake low: no high side on
            assert samples[t][0] == 0.0
            assert (expm(A_off * (d - on) / FS) @ x_on_end)[0] > 0      # current still flows
        assert samples[t][1] == 0.0                # L high side never on
    # next on-phase, and past ticks read back after the fact (history + previous segment)
    x_per = expm(A_off * (period - on) / FS) @ x_on_end
    i_801 = (expm(A_on * 1 / FS) @ x_per)[0]
    assert samples[t0 + 801][0] == pytest.approx(i_801 / BR.k_ILIS * BR.R_IS, rel=1e-9)
    assert s.br.is_r.voltage(t0 + 805) == pytest.approx((expm(A_on * 5 / FS) @ x_per)[0] / BR.k_ILIS * BR.R_IS,
                                                        rel=1e-9)
    assert s.br.is_r.voltage(t0 + 600) == 0.0
    # ripple per §2.3: Δi ≈ V·D(1−D)·T/L ≈ 0.5 A (a few 10 mV on IS)
    di = samples[t0 + 399][0] - samples[t0 + 1][0]
    assert di * BR.k_ILIS / BR.R_IS == pytest.approx(BR.Vs * 0.25 / 20e3 / P.L, rel=0.15)


def test_is_voltage_at_a_past_tick_of_the_segment_uses_the_exact_state_there():
    s = rig(motor_kw=LOCKED, pins=(1, 0))
    s.k.run_until(round(0.2e-3 * FS))
    t_past = s.k.now - 777
    i_inf, tau = BR.Vs / R_DRIVE, P.L / R_DRIVE
    i_ref = i_inf * -math.expm1(-t_past / FS / tau)
    assert s.br.is_r.voltage(t_past) == pytest.approx(i_ref / BR.k_ILIS * BR.R_IS, rel=1e-9)


# ---- current limitation (§2.3, §5.2 item 7) ---------------------------------------------------------

@pytest.mark.parametrize("case", ["low side of M-", "high side of M+"])
def test_current_limit_trips_at_i_cl_and_reenables_after_t_cls(case):
    if case == "low side of M-":                   # forward current into leg M−: I_CLL = 43 A first
        kw, i_cl, side, switch, fault_legs, r_fault = {}, BR.I_CLL, "L", "L", ("H", "H"), 2 * BR.R_HS
    else:                                          # lift I_CLL: the M+ high side trips at I_CLH = 60 A
        kw, i_cl, side, switch, fault_legs, r_fault = {"I_CLL": 100.0}, BR.I_CLH, "R", "H", ("L", "L"), 2 * BR.R_LS
    s = rig(motor_kw=LOCKED, bridge_kw=kw, pins=(1, 0))
    i_inf, tau = BR.Vs / R_DRIVE, P.L / R_DRIVE
    t_trip = -tau * math.log(1 - i_cl / i_inf)                   # i(t) = I∞(1 − e^{−t/τ}) = I_CL
    s.k.run_until(math.floor(t_trip * FS) - 1)
    assert not s.br.fault and s.br.cl_trips == 0 and s.m.current < i_cl
    s.k.run_until(math.ceil(t_trip * FS) + 1)
    assert s.br.fault and s.br.cl_trips == 1
    tick1, side1, sw1 = s.br.trip_log[0]
    assert (side1, sw1) == (side, switch)
    assert abs(tick1 - t_trip * FS) <= 1.0
    i_trip = s.m.state_at(tick1)[0]
    assert i_cl < i_trip < i_cl + 0.01                           # first tick above the limit
    # during t_CLS: the tripped switch is off and the other switch of that half bridge is on
    assert s.br.legs == fault_legs
    # IS of the faulted half bridge carries the fault current I_IS(lim)·R_IS = 4.5 V
    v_fault = s.br.is_l.voltage() if side == "L" else s.br.is_r.voltage()
    assert v_fault == pytest.approx(BR.I_IS_lim * BR.R_IS)
    # IN changes of the faulted half bridge are ignored during t_CLS
    pin = s.lpwm if side == "L" else s.rpwm
    level = pin.level
    pin.set("mcu", 1 - level)
    assert s.br.legs == fault_legs
    pin.set("mcu", level)
    cls = round(BR.t_CLS * FS)
    assert s.br.cls_ticks == cls == 1840
    s.k.run_until(tick1 + cls - 1)
    assert s.br.fault and s.br.legs == fault_legs
    # slow decay through both switches of the faulted side's type: i = i_trip·e^{−t(R + 2R_on)/L}
    s.k.run_until(tick1 + cls)
    i_rel = i_trip * math.exp(-(cls / FS) * (P.R + r_fault) / P.L)
    assert s.m.current == pytest.approx(i_rel, rel=1e-9) and i_rel < i_cl
    assert not s.br.fault and s.br.legs == ("H", "L")
    # drive again from i_rel: the next trip at the analytic time
    t2 = -tau * math.log((i_inf - i_cl) / (i_inf - i_rel))
    s.k.run_until(tick1 + cls + math.ceil(t2 * FS) + 1)
    assert s.br.cl_trips == 2
    assert abs(s.br.trip_log[1][0] - (tick1 + cls + t2 * FS)) <= 1.0
    # the switched-mode limit holds the locked-rotor current below the limit for good
    s.k.run_until(round(20e-3 * FS))
    assert s.m.peak_current < i_cl + 0.01 and s.br.cl_trips > 10


def test_current_limit_cl_action_off_leaves_the_half_bridge_open_on_its_diodes():
    k = Kernel(TimeBase([FS]))
    rpwm, lpwm = Net("RPWM"), Net("LPWM")
    m = DcMotor(k, "m", preset=PRESET, **LOCKED)
    is_r, is_l = AnalogNet("A0"), AnalogNet("A1")
    br = Bts7960Bridge(k, m, rpwm, lpwm, cl_action="off", is_r=is_r, is_l=is_l)
    assert br.is_r is is_r and br.is_l is is_l
    rpwm.set("mcu", 1)
    k.run_until(round(3e-3 * FS), stop=lambda: br.fault)
    assert br.cl_trips_l == 1
    t1 = br.trip_log[0][0]
    assert k.now == t1
    i1 = m.current
    k.run_until(t1 + 10)
    assert br.legs == ("H", "Z") and br.fault_l
    assert is_l.voltage(k.now) == pytest.approx(BR.I_IS_lim * BR.R_IS)
    # A=H, B=Z (§2.1): v_m = −(V_D + i·R_HS) while i > 0 (one FET + the M− high-side diode)
    k.run_until(t1 + br.cls_ticks - 1)
    rt = P.R + BR.R_HS + BR.r_D
    t = (br.cls_ticks - 1) / FS
    i_ref = -BR.V_D / rt + (i1 + BR.V_D / rt) * math.exp(-t * rt / P.L)
    assert m.current == pytest.approx(i_ref, rel=1e-9)
    with pytest.raises(ConfigError, match="cl_action"):
        Bts7960Bridge(k, DcMotor(k, "m3"), Net("a"), Net("b"), cl_action="latch")


def test_is_voltage_is_clamped_at_vcc():
    # fault current 4.5 mA into a 2 kΩ R_IS would be 9 V: the pin clamps at Vcc = 5 V
    s = rig(motor_kw=LOCKED, bridge_kw={"R_IS": 2000.0}, pins=(1, 0))
    s.k.run_until(round(3e-3 * FS), stop=lambda: s.br.fault)
    s.k.run_until(s.k.now + 1)
    assert s.br.fault_l and s.br.is_l.voltage() == 5.0
    # 20 A forward in the R high side: 20/8500 · 2 kΩ = 4.71 V, below the clamp
    s = rig(state=(20.0, 0.0, 0.0), motor_kw=LOCKED, bridge_kw={"R_IS": 2000.0}, pins=(1, 0))
    assert s.br.is_r.voltage() == pytest.approx(20.0 / 8500 * 2000, rel=1e-12)


# ---- AMT10 encoder on the motor shaft (§3.2) ---------------------------------------------------------

def test_amt10_2048_counts_per_motor_rev_edge_count_and_edge_times_vs_angle():
    i_ss, w_ss = steady()
    th0 = 0.123
    s = rig(state=(i_ss, w_ss, th0), pins=(1, 0))
    a, b = Net("ENC_A"), Net("ENC_B")
    enc = QuadratureEncoder(s.k, s.m, a, b, counts_per_rev=2048, name="amt10")
    edges = []
    a.listen(lambda n: edges.append(s.k.now))
    b.listen(lambda n: edges.append(s.k.now))
    t_end = 5e-3
    s.k.run_until(round(t_end * FS))
    step = 2 * math.pi / 2048
    th_end = th0 + w_ss * t_end                  # steady state: ω constant, θ linear
    assert s.m.angle == pytest.approx(th_end, rel=1e-9)
    k0 = math.floor(th0 / step)
    assert enc.count == len(edges) == math.floor(th_end / step) - k0
    for j, tick in enumerate(edges, start=1):     # edge j at θ = (k0 + j)·step
        t_cross = ((k0 + j) * step - th0) / w_ss * FS
        assert 0 <= tick - t_cross < 1.0 + 1e-6
    assert 2048 * s.m.angle / (2 * math.pi) == pytest.approx(k0 + enc.count, abs=1.0)


def test_full_speed_edge_rate_from_the_simulated_no_load_speed_is_about_77_8k_counts_per_s():
    s = rig(pins=(1, 0))
    s.k.run_until(round(0.6 * FS))                # from rest to the no-load speed (current-limited start)
    w = s.m.speed
    a, b = Net("ENC_A"), Net("ENC_B")
    enc = QuadratureEncoder(s.k, s.m, a, b, counts_per_rev=2048, name="amt10")
    a_edges = []
    a.listen(lambda n: a_edges.append(s.k.now))
    t_win = 20e-3
    s.k.run_until(s.k.now + round(t_win * FS))
    rate = enc.count / t_win
    assert rate == pytest.approx(w * 2048 / (2 * math.pi), abs=1 / t_win)
    assert rate == pytest.approx(77.8e3, rel=0.005)              # §3.2: ≈77.8 k counts/s at ≈2,280 rpm
    f_a = len(a_edges) / 2 / t_win                               # A: 2 edges per cycle
    assert f_a == pytest.approx(19.4e3, rel=0.01)                # §3.2: 19.4 kHz per channel


def test_overtemperature_turns_the_half_bridge_off_and_shows_the_fault_current():
    """§2.3: on thermal shutdown both switches are off and IS sources I_IS(lim) (4.5 mA into 1 kΩ:
    4.5 V); the latch holds until an INH low pulse resets it."""
    from mcusim.kernel import Kernel
    from mcusim.plant.bts7960 import Bts7960Bridge
    from mcusim.plant.dcmotor import DcMotor
    from mcusim.signals import Net
    from mcusim.time import TimeBase
    k = Kernel(TimeBase([16_000_000]))
    m = DcMotor(k, "m", preset="openrover-100w-50")
    rpwm, lpwm, r_en = Net("RPWM"), Net("LPWM"), Net("R_EN")
    r_en.set("mcu", 1)
    rpwm.set("mcu", 1)
    b = Bts7960Bridge(k, m, rpwm, lpwm, r_en=r_en)
    k.run_until(16_000)                       # 1 ms of forward drive
    assert b.legs == ("H", "L") and m.current > 1.0
    b.overtemperature("R")
    assert b.legs == ("Z", "L") and b.overtemp
    assert b.is_voltage("R") == 4.5
    k.run_until(16_000 * 50)
    assert m.current == 0.0                   # decayed through the diodes, then blocked
    r_en.set("mcu", 0)                        # INH low pulse resets the latch
    r_en.set("mcu", 1)
    assert not b.overtemp and b.legs == ("H", "L")


@pytest.mark.parametrize("at", [16_100, 16_500, 17_333])     # in an INH-high phase, at a falling edge, low
def test_an_inh_waveform_resets_the_thermal_latch_at_its_next_low_edge_in_both_engines(at):
    """A review found the fast engine never reset the latch while INH carried a timer waveform (its
    edges reach the bridge as waveform edges, not as pin changes): the half bridge stayed off for
    good. §2.3: an INH low pulse resets it; both engines now do so at the waveform's next falling
    edge, and agree on the legs, the latch and IS at every tick sampled and on the motor's end."""
    from mcusim.engine.waveform import Waveform
    P, W, end = 800, 400, 16_000 * 5            # INH at 20 kHz, 50 %, for 5 ms

    def run(engine):
        k = Kernel(TimeBase([FS]), engine)
        m = DcMotor(k, "m", preset="openrover-100w-50")
        rpwm, lpwm, r_en, l_en = Net("RPWM"), Net("LPWM"), Net("R_EN"), Net("L_EN")
        rpwm.set("mcu", 1)
        lpwm.set("mcu", 0)
        l_en.set("mcu", 1)
        r_en.set("mcu", 0)
        b = Bts7960Bridge(k, m, rpwm, lpwm, r_en, l_en)
        wave = Waveform(k, 0, P, W)
        if engine == "fast":
            k.at(0, lambda: r_en.set_wave("mcu", wave), prio=PRIO_HW)
        else:
            k.at(0, r_en.set, "mcu", wave.level_at(0), prio=PRIO_HW)
            for t, level in wave.edges(0, end):
                k.at(t, r_en.set, "mcu", level, prio=PRIO_HW)
        k.at(at, b.overtemperature, "R", prio=PRIO_HW)
        seen = []
        for t in (at + 1, at + 399, at + 401, at + 800, 16_000 * 3, end - 1):
            k.at(t, lambda t=t: seen.append((t, b.overtemp, b.legs, b.is_voltage("R"))), prio=PRIO_OBSERVE)
        k.run_until(end)
        return seen, m.current, m.speed

    ref, fast = run("reference"), run("fast")
    assert [x[:3] for x in fast[0]] == [x[:3] for x in ref[0]]      # digital: exactly
    assert [x[3] for x in fast[0]] == pytest.approx([x[3] for x in ref[0]], rel=1e-9)     # IS: analog
    assert not ref[0][-1][1] and ref[1] > 1.0       # the latch was reset and the motor drives again
    assert fast[1] == pytest.approx(ref[1], rel=1e-9) and fast[2] == pytest.approx(ref[2], rel=1e-9)
