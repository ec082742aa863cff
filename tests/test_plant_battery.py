"""Lead-acid bank (docs/plants.md §4, §4.1) and the BTS7960 supply coupling (§2.1, §2.3, §5.1).

Expected values come from the equations of docs/plants.md (the Thevenin ECM, OCV ≈ 11.65 + 1.10·SOC, the
motor/bridge steady state) or from an independent numerical integration, never from the model's
own output.
"""

import itertools
import math
from types import SimpleNamespace

import numpy as np
import pytest

from mcusim.errors import ConfigError
from mcusim.kernel import PRIO_HW, PRIO_OBSERVE, PRIO_PLANT, Kernel
from mcusim.plant.battery import ConstantLoad, LeadAcidBank, VoltageDivider
from mcusim.plant.bts7960 import Bts7960Bridge, Bts7960Params
from mcusim.plant.dcmotor import DcMotor, MotorParams
from mcusim.plant.presets import motor_preset
from mcusim.signals import AnalogNet, Net
from mcusim.time import TimeBase

FS = 16_000_000
MS = FS // 1000
PRESET = "openrover-100w-50"
P = MotorParams.from_mapping(motor_preset(PRESET))
BR = Bts7960Params()


def kernel():
    return Kernel(TimeBase([FS]))


def bank_with_load(amps, **kw):
    k = kernel()
    load = ConstantLoad(k, amps)
    bank = LeadAcidBank(k, loads=[load], **kw)
    return k, bank, load


def ocv_rule(soc):                                   # §4.1: OCV ≈ 11.65 + 1.10·SOC
    return 11.65 + 1.10 * soc


# ---- OCV, instant sag, RC relaxation, SOC ---------------------------------------------------------------

@pytest.mark.parametrize("soc, volts", [(0.0, 11.65), (0.5, 12.20), (1.0, 12.75)])
def test_open_circuit_voltage_follows_the_recommended_sla_table(soc, volts):
    k = kernel()
    bank = LeadAcidBank(k, soc=soc)
    assert bank.ocv == pytest.approx(volts, abs=1e-12)
    assert bank.voltage() == pytest.approx(volts, abs=1e-12)          # at rest: v_t = OCV
    k.run_until(10 * MS)                                              # no load: stays at OCV
    assert bank.voltage() == pytest.approx(volts, abs=1e-12) and bank.current == 0.0
    # the linear rule is within 30 mV of the §4.1 table at 25 % and 75 %
    assert abs(ocv_rule(0.25) - 11.95) < 0.03 and abs(ocv_rule(0.75) - 12.45) < 0.03


@pytest.mark.parametrize("n, r0_bank", [(1, 0.020), (2, 0.010)])
def test_instant_sag_is_r0_over_n_times_the_current(n, r0_bank):
    i = 20.0
    k, bank, load = bank_with_load(i, count=n, r1=0.0, wiring_r=0.0, peukert_k=1.0)
    k.run_until(MS)                                                  # first step: I = 20 A held
    assert bank.current == pytest.approx(i, rel=1e-12)
    soc = 1.0 - i * 1e-3 / (3600 * 9.0 * n)
    assert bank.voltage() == pytest.approx(ocv_rule(soc) - r0_bank * i, abs=1e-12)
    assert load.supply == bank.voltage()                              # handed to the load
    assert bank.ocv - bank.voltage() == pytest.approx(r0_bank * i, rel=1e-9)   # 0.4 V / 0.2 V


def test_two_batteries_halve_the_instant_drop_of_one_and_wiring_adds_in_series():
    drops = []
    for n in (1, 2):
        k, bank, _ = bank_with_load(40.0, count=n, r1=0.0, wiring_r=0.0)
        k.run_until(MS)
        drops.append(bank.ocv - bank.voltage())
    assert drops[1] == pytest.approx(drops[0] / 2, rel=1e-9)
    assert drops[0] == pytest.approx(0.8, rel=1e-9)                   # 1 × 20 mΩ · 40 A (§4.1: "0.88 V")
    k, bank, _ = bank_with_load(40.0, count=2, r1=0.0, wiring_r=0.010)
    k.run_until(MS)
    assert bank.ocv - bank.voltage() == pytest.approx((0.010 + 0.010) * 40.0, rel=1e-9)


@pytest.mark.parametrize("n", [1, 2])
def test_rc_pair_relaxes_with_tau1_to_the_full_thevenin_drop_and_recovers(n):
    i, tau1, r0, r1, w = 10.0, 0.5, 0.020, 0.015, 0.010
    k, bank, load = bank_with_load(i, count=n, tau1=tau1, r0=r0, r1=r1, wiring_r=w, peukert_k=1.0)
    for t in (tau1, 3 * tau1, 10 * tau1):
        k.run_until(round(t * FS))
        soc = 1.0 - i * t / (3600 * 9.0 * n)
        v1 = r1 / n * i * -math.expm1(-t / tau1)
        assert bank.voltage() == pytest.approx(ocv_rule(soc) - v1 - (r0 / n + w) * i, abs=1e-9)
    # v_t -> OCV − (R0/n + wiring + R1/n)·I
    assert bank.ocv - bank.voltage() == pytest.approx((r0 / n + w + r1 / n) * i, rel=1e-4)
    # load off: the ohmic drop vanishes at once, v1 decays with the same τ1
    t_off = k.now
    v1_off = bank.v1
    load.set(0.0)
    k.run_until(t_off + MS + 1)
    v1 = v1_off * math.exp(-1e-3 / tau1)
    assert bank.ocv - bank.voltage() == pytest.approx(v1, rel=1e-9)
    k.run_until(t_off + round(tau1 * FS))
    assert bank.ocv - bank.voltage() == pytest.approx(v1_off * math.exp(-1.0), rel=1e-9)


def test_soc_falls_by_charge_over_bank_capacity_without_peukert():
    i, t, n = 9.0, 2.0, 2
    k, bank, _ = bank_with_load(i, count=n, peukert_k=1.0)
    k.run_until(round(t * FS))
    assert bank.soc == pytest.approx(1.0 - i * t / (3600 * 9.0 * n), rel=1e-12)
    assert bank.charge_ah == pytest.approx(i * t / 3600, rel=1e-12)


def test_peukert_shrinks_the_capacity_above_the_20_hour_rate_only():
    i, t, n, kp = 20.0, 1.0, 2, 1.15
    k, bank, load = bank_with_load(i, count=n, peukert_k=kp)
    k.run_until(round(t * FS))
    q_eff = 9.0 * (0.45 / (i / n)) ** (kp - 1)                        # §4.1, per battery
    assert q_eff == pytest.approx(5.65, abs=0.01)                      # 9 Ah shrinks to ≈5.7 Ah at 10 A
    assert 1.0 - bank.soc == pytest.approx(i * t / (3600 * q_eff * n), rel=1e-9)
    # at or below the 20 h rate (0.45 A per battery) the rated capacity holds
    load.set(0.8)                                                      # 0.4 A per battery
    soc0, t0 = bank.soc, k.now
    k.run_until(t0 + FS)
    assert soc0 - bank.soc == pytest.approx(0.8 * 1.0 / (3600 * 9.0 * n), rel=1e-9)
    # charge returned counts at the rated capacity too, and SOC never exceeds 1
    load.set(-5.0)
    soc0, t0 = bank.soc, k.now
    k.run_until(t0 + FS // 10)
    assert bank.soc - soc0 == pytest.approx(5.0 * 0.1 / (3600 * 9.0 * n), rel=1e-9)
    k2, full, _ = bank_with_load(-5.0)
    k2.run_until(10 * MS)
    assert full.soc == 1.0 and full.voltage() > full.ocv             # charging lifts v_t above OCV


@pytest.mark.parametrize("count", [0, 9, -1, 2.5, "two", True, None])
def test_battery_count_outside_1_to_8_is_rejected_with_a_clear_message(count):
    with pytest.raises(ConfigError, match="count .*1 to 8"):
        LeadAcidBank(kernel(), count=count)


def test_bad_parameters_are_config_errors():
    k = kernel()
    with pytest.raises(ConfigError, match="soc"):
        LeadAcidBank(k, soc=1.5)
    with pytest.raises(ConfigError, match="ocv_full"):
        LeadAcidBank(k, ocv_full=11.0)
    with pytest.raises(ConfigError, match="step"):
        LeadAcidBank(k, step="1.00000001ms")                          # not a whole number of ticks
    with pytest.raises(ConfigError, match="r0"):
        LeadAcidBank(k, r0=-0.1)
    with pytest.raises(ConfigError, match="cannot be a load"):
        LeadAcidBank(k).connect(object())


def test_voltage_at_a_past_tick_is_the_value_held_then_and_min_voltage_is_the_lowest():
    k, bank, load = bank_with_load(10.0, r1=0.0, wiring_r=0.0, peukert_k=1.0)
    k.run_until(3 * MS)
    v_loaded = bank.voltage()
    load.set(0.0)
    k.run_until(5 * MS)
    assert bank.voltage(0) == pytest.approx(12.75)                    # before the first step
    assert bank.voltage(MS - 1) == pytest.approx(12.75)
    assert bank.voltage(3 * MS + 5) == v_loaded                       # held from the 3 ms step on
    assert bank.voltage() > v_loaded
    assert bank.min_voltage == v_loaded                               # SOC only falls under load
    assert bank.net.voltage() == bank.voltage()


def test_voltage_divider_scales_the_bank_voltage_for_the_adc():
    k = kernel()
    bank = LeadAcidBank(k)
    div = VoltageDivider(bank.voltage, 100e3, 22e3)
    assert div.voltage() == pytest.approx(12.75 * 22 / 122, rel=1e-12)
    adc_in = AnalogNet("CH1")                                         # the CIAA's CH1, as an ADC sees it
    adc_in.source = VoltageDivider(bank.net.voltage, 33e3, 6.8e3).voltage
    assert adc_in.voltage(k.now) == pytest.approx(12.75 * 6.8 / 39.8, rel=1e-12)
    k2, loaded, _ = bank_with_load(10.0, r1=0.0)
    k2.run_until(2 * MS)
    div = VoltageDivider(loaded.voltage, 33e3, 6.8e3)
    assert div.voltage() == pytest.approx(loaded.voltage() * 6.8 / 39.8, rel=1e-12)
    assert div.voltage(MS // 2) == pytest.approx(12.75 * 6.8 / 39.8, rel=1e-12)   # held value then
    with pytest.raises(ConfigError, match="r_bottom"):
        VoltageDivider(bank.voltage, 1e3, 0.0)


# ---- BTS7960 supply coupling --------------------------------------------------------------------------

def rig(motor_kw=None, bridge_kw=None, en=True):
    k = kernel()
    rpwm, lpwm = Net("RPWM"), Net("LPWM")
    r_en, l_en = (Net("R_EN"), Net("L_EN")) if en else (None, None)
    m = DcMotor(k, "motor", preset=PRESET, **(motor_kw or {}))
    br = Bts7960Bridge(k, m, rpwm, lpwm, r_en, l_en, name="ibt2", **(bridge_kw or {}))
    if en:
        r_en.set("mcu", 1)
        l_en.set("mcu", 1)
    return SimpleNamespace(k=k, m=m, br=br, rpwm=rpwm, lpwm=lpwm, r_en=r_en, l_en=l_en)


def test_set_supply_changes_the_drive_voltage_from_now_and_ignores_an_unchanged_value():
    s = rig(motor_kw={"tau_s": 10.0}, bridge_kw={"I_CLH": 1e3, "I_CLL": 1e3})   # locked, no limit
    s.rpwm.set("mcu", 1)
    r_drive = P.R + BR.R_HS + BR.R_LS
    s.k.run_until(20 * MS)                                            # ≈ 12 τe: at 12 V / R
    assert s.m.current == pytest.approx(12.0 / r_drive, rel=1e-4)
    segs = s.m.segments
    s.br.set_supply(12.0)
    assert s.m.segments == segs                                       # unchanged: nothing to do
    i0, t0 = s.m.current, s.k.now
    s.br.set_supply(10.0)
    assert s.br.drive_state()[0] == pytest.approx(10.0)
    s.k.run_until(t0 + MS)
    tau = P.L / r_drive
    i_ref = 10.0 / r_drive + (i0 - 10.0 / r_drive) * math.exp(-1e-3 / tau)
    assert s.m.current == pytest.approx(i_ref, rel=1e-9)
    with pytest.raises(ConfigError, match="supply"):
        s.br.set_supply(float("nan"))


def supply_current(legs, i):
    """§2.1 by definition: the current out of B+ is the current out of each leg connected to Vs
    (H: the high-side FET, either direction; Z: the high-side body diode when the current out of
    the leg is negative). Leg A (M+) carries i out, leg B (M−) carries −i out."""
    total = 0.0
    for leg, j in zip(legs, (i, -i), strict=True):
        if leg == "H" or (leg == "Z" and j < 0.0):
            total += j
    return total


def test_supply_charge_under_pwm_matches_a_fine_numerical_integration():
    """20 kHz drive/brake-low (regenerating: E above the mean drive voltage), EN-PWM drive/coast (fast decay returns
    charge; discontinuous conduction), a supply step, brake high and reverse drive. The model's exact
    supply charge against the trapezoid rule on the motor's exact current sampled every 0.5 µs."""
    w0 = 200.0                                                        # motor rad/s: E ≈ 9.9 V
    s = rig(motor_kw={"horizon": 50e-6}, bridge_kw={"I_CLH": 1e3, "I_CLL": 1e3})
    s.m.set_state(current=0.0, speed=w0)
    period = FS // 20_000                                             # 800 ticks
    k = s.k
    phase = {"pin": s.rpwm, "on": 480}

    def edge(level, t):
        pin, on = phase["pin"], phase["on"]
        if pin is not None:
            pin.set("mcu", level)
        nxt = t + (on if level else period - on)
        k.at(nxt, edge, 1 - level, nxt, prio=PRIO_HW)
    k.at(0, edge, 1, 0, prio=PRIO_HW)

    def to_coast():                                                   # sign-magnitude on EN: drive/coast
        s.rpwm.set("mcu", 1)
        s.lpwm.set("mcu", 0)
        phase["pin"], phase["on"] = _EnPair(s), 200

    def to_brake_high():
        phase["pin"] = None
        s.r_en.set("mcu", 1)
        s.l_en.set("mcu", 1)
        s.rpwm.set("mcu", 1)
        s.lpwm.set("mcu", 1)

    def to_reverse():
        s.rpwm.set("mcu", 0)
    k.at(10 * MS, to_coast, prio=PRIO_HW)
    k.at(15 * MS, s.br.set_supply, 11.0, prio=PRIO_HW)
    k.at(20 * MS, to_brake_high, prio=PRIO_HW)
    k.at(22 * MS, to_reverse, prio=PRIO_HW)
    t_end = 25 * MS
    dt = 8                                                            # 0.5 µs: every edge is a sample
    samples = []

    def sample(t):
        samples.append((s.br.legs, s.m.state_at(t), s.br.params.Vs))
        if t + dt <= t_end:
            k.at(t + dt, sample, t + dt, prio=PRIO_OBSERVE)
    k.at(0, sample, 0, prio=PRIO_OBSERVE)
    per_ms = []
    k.at(MS, _every_ms, k, s.br, per_ms, prio=PRIO_PLANT)
    k.run_until(t_end)
    q_model = sum(per_ms) + s.br.supply_charge()
    h = dt / FS
    q_ref = 0.0
    drawn = returned = 0.0
    crossings = 0
    for (legs, (i_a, w_a, _), vs), (_, (i_b, _, _), _) in itertools.pairwise(samples):   # legs constant
        if legs == ("Z", "Z") and i_a > 0.0 and i_b == 0.0:
            # the current reaches 0 inside the interval and stays there (DCM): integrate the
            # supply current up to the crossing only, from the slope of §1.1/§2.1
            # (L·di/dt = −(Vs + 2V_D) − R·i − K·ω with i > 0 on both body diodes)
            slope = (-(vs + 2 * BR.V_D) - P.R * i_a - P.K * w_a) / P.L
            q = 0.5 * supply_current(legs, i_a) * (i_a / -slope)
            crossings += 1
        else:
            q = 0.5 * h * (supply_current(legs, i_a) + supply_current(legs, i_b))
        q_ref += q
        drawn += max(q, 0.0)
        returned += min(q, 0.0)
    assert drawn > 0.05 and returned < -0.02                          # both directions exercised
    assert crossings > 50                                             # DCM entries were exercised
    # the trapezoid's own error here is ≈ h²/12·|i''|·t ≈ 1e-8 A·s (h = 0.5 µs, |i''| ≈ 2e7 A/s²)
    assert q_model == pytest.approx(q_ref, abs=2e-7 * (drawn - returned))
    assert s.br.charge_total == pytest.approx(q_model, rel=1e-12)


class _EnPair:
    """Drives both EN nets with the PWM level (sign-magnitude with coast in the off phase)."""

    def __init__(self, s):
        self.s = s

    def set(self, who, level):
        self.s.r_en.set(who, level)
        self.s.l_en.set(who, level)


def _every_ms(k, br, out):
    out.append(br.supply_charge())
    k.after(MS, _every_ms, k, br, out, prio=PRIO_PLANT)


def test_supply_current_is_the_motor_current_in_drive_zero_in_brake_and_returned_in_coast():
    s = rig(motor_kw={"tau_s": 10.0}, bridge_kw={"I_CLH": 1e3, "I_CLL": 1e3})
    s.m.set_state(current=20.0)
    r_fast = P.R                                                      # ZZ: only the motor's R in the loop
    for pins, en, sign in (((1, 0), (1, 1), +1), ((0, 0), (1, 1), 0), ((1, 1), (1, 1), 0),
                           ((1, 0), (0, 0), -1)):
        s.rpwm.set("mcu", pins[0])
        s.lpwm.set("mcu", pins[1])
        s.r_en.set("mcu", en[0])
        s.l_en.set("mcu", en[1])
        s.br.supply_charge()
        s.m.set_state(current=20.0)
        t0 = s.k.now
        n = 160                                                       # 10 µs
        s.k.run_until(t0 + n)
        q = s.br.supply_charge()
        if sign == 0:
            assert q == 0.0
            continue
        legs = s.br.legs
        if legs == ("H", "L"):                                        # ∫ 20 A → I∞ exponential
            r, v = P.R + BR.R_HS + BR.R_LS, 12.0
        else:                                                         # ZZ, i > 0: v_m = −(Vs + 2V_D)
            r, v = r_fast, -(12.0 + 2 * BR.V_D)
        tau, i_inf, t = P.L / r, v / r, n / FS
        integral = i_inf * t + (20.0 - i_inf) * tau * -math.expm1(-t / tau)
        assert q == pytest.approx(sign * integral, rel=1e-9)


def test_full_duty_motor_on_one_battery_settles_at_the_analytic_current_and_bus_voltage():
    """§1.4 motor with an output load of 15 N·m at full forward duty from one 12 V 9 Ah battery:
    with R_bat = R0 + wiring + R1 (v1 settled) the steady state solves
        OCV − (R_bat + R + R_HS + R_LS)·i − K·ω = 0,   K·i − b·ω − τc − τ_out/(N·η) = 0,
    and the bus is OCV − R_bat·i."""
    tau_out = 15.0
    s = rig(motor_kw={"load_torque": tau_out}, en=False)
    # τ1 shortened to 20 ms and the capacity made huge so that v1 settles and the OCV stays put
    # within the run (with 9 Ah the OCV falls ≈ 0.5 mV/s at 8.5 A, which the motor follows ≈ 30 ms
    # late: a 7e-6 relative offset from the frozen-OCV steady state)
    bank = LeadAcidBank(s.k, count=1, tau1=0.02, capacity_ah=1e5, loads=[s.br])
    s.rpwm.set("mcu", 1)
    s.k.run_until(round(0.8 * FS))                                     # slow mode ≈ 30 ms
    r_bat = 0.020 + 0.010 + 0.015
    r_all = r_bat + P.R + BR.R_HS + BR.R_LS
    tl = P.tau_c + tau_out / (P.gear_ratio * P.efficiency)
    i, w = np.linalg.solve([[r_all, P.K], [P.K, -P.b]], [bank.ocv, tl])
    assert 8.0 < i < 9.0                                             # ≈ (0.035 + 0.375)/K + viscous
    assert s.m.current == pytest.approx(i, rel=1e-9)
    assert s.m.speed == pytest.approx(w, rel=1e-9)
    assert bank.current == pytest.approx(i, rel=1e-9)                 # forward drive: I_s = i
    assert bank.voltage() == pytest.approx(bank.ocv - r_bat * i, rel=1e-10)
    assert s.br.params.Vs == bank.voltage()
    # a hard start from rest sagged the bus far more than the steady state
    assert bank.min_voltage < bank.voltage() - 0.5


def test_locked_motor_current_and_sag_with_two_batteries_vs_one():
    """Locked rotor at 30 % duty (drive/brake-low, 20 kHz): average current ≈ D·V/R_loop is well
    under the current limit; the bank sees D·i, the sag halves (R0 part) with two batteries."""
    out = {}
    for n in (1, 2):
        s = rig(motor_kw={"tau_s": 10.0}, en=False)
        bank = LeadAcidBank(s.k, count=n, r1=0.0, wiring_r=0.0, loads=[s.br])
        period, on = 800, 240

        def edge(level, t, s=s, on=on, period=period):
            s.rpwm.set("mcu", level)
            nxt = t + (on if level else period - on)
            s.k.at(nxt, edge, 1 - level, nxt, prio=PRIO_HW)
        s.k.at(0, edge, 1, 0, prio=PRIO_HW)
        s.k.run_until(round(0.05 * FS))
        out[n] = (bank.ocv - bank.voltage(), bank.current, s.m.current)
    (d1, i1, _), (d2, i2, _) = out[1], out[2]
    # average motor current ≈ D·V_bus/R_loop (ripple-free in the mean for brake-low)
    r_loop = P.R + BR.R_HS + BR.R_LS
    assert i1 == pytest.approx(0.3 * 0.3 * (12.75 - d1) / r_loop, rel=0.02)  # bank current = D·i_avg
    assert d1 == pytest.approx(0.020 * i1, rel=1e-9)
    assert d2 == pytest.approx(0.010 * i2, rel=1e-9)
    assert d2 / d1 == pytest.approx(0.5, rel=0.01)
