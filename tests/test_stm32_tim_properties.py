"""Hypothesis properties of the STM32 timer model against the per-tick oracle (tests/tim_oracle.py)
and against the closed-form rules of the reference sheet (§2.3, §3.2, §4.2-§4.3)."""

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcusim.periph.stm32.tim_input import RESYNC_CYCLES, filter_timing
from test_stm32_tim import (
    ARPE,
    CEN,
    DIR,
    OC1PE,
    PWM1,
    PWM2,
    enc_rig,
    high_ticks,
    level_at,
    pwm_rig,
    uif_times,
)
from tim_oracle import Rig, TimOracle

from mcusim.kernel import PRIO_CPU

SETTINGS = settings(max_examples=int(__import__("os").environ.get("TIM_EXAMPLES", 60)), deadline=None, suppress_health_check=[HealthCheck.too_slow])


@st.composite
def pwm_configs(draw, writes=True):
    name = draw(st.sampled_from(["TIM1", "TIM3"]))
    arr = draw(st.integers(1, 24))
    cms = draw(st.integers(0, 3))
    cfg = {
        "name": name, "psc": draw(st.integers(0, 3)), "arr": arr, "ccr": draw(st.integers(0, arr + 2)),
        "mode": draw(st.sampled_from([PWM1, PWM2])), "pol": draw(st.integers(0, 1)), "cms": cms,
        "down": draw(st.booleans()) if cms == 0 else False, "arpe": draw(st.booleans()),
        "ocpe": draw(st.booleans()), "rcr": draw(st.integers(0, 3)) if name == "TIM1" else 0}
    cfg["writes"] = []
    if writes:
        arr_written = False
        for _ in range(draw(st.integers(0, 3))):
            cyc = draw(st.integers(1, 150))
            reg = draw(st.sampled_from(["CCR1", "PSC", "ARR"]))
            if reg == "ARR":
                if arr_written:
                    continue
                arr_written = True
                # ARPE=0 with ARR below CNT is open question 6 of the sheet: only raise ARR then
                v = draw(st.integers(1, 30)) if cfg["arpe"] else draw(st.integers(arr, 30))
            elif reg == "PSC":
                v = draw(st.integers(0, 3))
            else:
                v = draw(st.integers(0, 32))
            cfg["writes"].append((cyc, reg, v))
        cfg["writes"].sort(key=lambda w: w[0])
    return cfg


def start_model(cfg, engine="reference"):
    cr1 = (cfg["cms"] << 5) | (DIR if cfg["down"] else 0) | (ARPE if cfg["arpe"] else 0)
    mhz = 216 if cfg["name"] == "TIM1" else 108
    rig, edges, t0 = pwm_rig(cfg["name"], mhz, arr=cfg["arr"], ccr=cfg["ccr"], mode=cfg["mode"],
                             pol=cfg["pol"], psc=cfg["psc"], cr1=cr1, ocpe=OC1PE if cfg["ocpe"] else 0,
                             rcr=cfg["rcr"], engine=engine)
    return rig, edges, t0


def oracle_of(cfg):
    return TimOracle(psc=cfg["psc"], arr=cfg["arr"], ccr=cfg["ccr"], mode=cfg["mode"] >> 4, pol=cfg["pol"],
                     cms=cfg["cms"], down=cfg["down"], rcr=cfg["rcr"], arpe=cfg["arpe"], ocpe=cfg["ocpe"])


def oracle_pins(cfg):
    """(oracle, cycles, pin level at every cycle) of the per-tick oracle running cfg's writes."""
    orc = oracle_of(cfg)
    n = 4 * (cfg["psc"] + 1) * 2 * 31
    writes = {}
    for cyc, reg, v in cfg["writes"]:
        writes.setdefault(cyc, []).append((reg, v))
    want = [orc.pin()]
    for _ in range(n):
        orc.step()
        for reg, v in writes.get(orc.cycle, ()):
            {"CCR1": orc.write_ccr, "ARR": orc.write_arr, "PSC": orc.write_psc}[reg](v)
        want.append(orc.pin())
    return orc, n, want


@SETTINGS
@given(pwm_configs())
def test_pwm_matches_per_tick_oracle_edge_for_edge(cfg):
    rig, edges, t0 = start_model(cfg)
    P = rig.P
    uif = uif_times(rig, 1)
    ccif = uif_times(rig, 1 << 1)
    for cyc, reg, v in cfg["writes"]:
        rig.kernel.at(t0 + cyc * P, rig.w, reg, v, prio=PRIO_CPU)
    orc, n, want = oracle_pins(cfg)
    rig.kernel.run_until(t0 + n * P)
    init = level_at(edges, t0)
    got = [level_at(edges, t0 + c * P, init) for c in range(n + 1)]
    assert got == want
    assert [(t - t0) // P for t in uif] == orc.uif_cycles
    assert [(t - t0) // P for t in ccif] == orc.ccif_cycles


@SETTINGS
@given(pwm_configs(), st.lists(st.integers(1, 4 * 4 * 2 * 31), max_size=4))
def test_steady_waveform_matches_per_tick_oracle_in_fast_engine(cfg, reads):
    """Fast engine, no interrupt enabled: the timer publishes steady waveforms (the edges come from
    the descriptor through the port's expander) and sets CCxIF/UIF lazily. Pin levels at every
    cycle and the SR flags seen by reads (which clear them, as firmware would) match the oracle."""
    rig, edges, t0 = start_model(cfg, engine="fast")
    P = rig.P
    writes = {}
    for cyc, reg, v in cfg["writes"]:
        rig.kernel.at(t0 + cyc * P, rig.w, reg, v, prio=PRIO_CPU)
        writes.setdefault(cyc, []).append((reg, v))
    seen = []
    for cyc in sorted(set(reads)):
        def read(cyc=cyc):
            sr = rig.r("SR") & 0x3
            seen.append((cyc, sr))
            rig.w("SR", ~sr & 0xFFFF_FFFF)
        rig.kernel.at(t0 + cyc * P, read, prio=PRIO_CPU + 1)
    orc, n, want = oracle_pins(cfg)
    rig.kernel.run_until(t0 + n * P)
    init = level_at(edges, t0)
    got = [level_at(edges, t0 + c * P, init) for c in range(n + 1)]
    assert got == want
    last = 0
    for cyc, sr in seen:   # a flag is seen iff its event happened since the previous read
        if cyc > n:
            break
        uif = any(last < c <= cyc for c in orc.uif_cycles)
        ccif = any(last < c <= cyc for c in orc.ccif_cycles)
        assert sr == (1 if uif else 0) | (2 if ccif else 0), (cyc, sr, uif, ccif)
        last = cyc


def rule_high(cfg):
    """§3.2: high counter ticks of the pin per counter period, and the period."""
    arr, ccr = cfg["arr"], cfg["ccr"]
    if cfg["cms"]:
        period, high = 2 * arr, 2 * min(ccr, arr)
    elif cfg["down"]:
        period, high = arr + 1, min(ccr + 1, arr + 1)
    else:
        period, high = arr + 1, min(ccr, arr + 1)
    if (cfg["mode"] == PWM2) ^ cfg["pol"]:
        high = period - high
    return high, period


@SETTINGS
@given(pwm_configs(writes=False))
def test_pwm_high_time_per_period_follows_rule(cfg):
    rig, edges, t0 = start_model(cfg)
    high, period = rule_high(cfg)
    tick = (cfg["psc"] + 1) * rig.P
    rig.kernel.run_until(t0 + 3 * period * tick)
    for k in range(3):
        a = t0 + k * period * tick
        assert high_ticks(edges, a, a + period * tick, level_at(edges, a)) == high * tick
    assert rig.tim.pwm_waveform(1) == (high * tick, period * tick)


@SETTINGS
@given(st.sampled_from(["TIM2", "TIM3"]), st.data())
def test_counter_wraparound_with_uif_for_any_arr_and_start(name, data):
    bits = 32 if name == "TIM2" else 16
    arr = data.draw(st.one_of(st.integers(1, 50), st.integers((1 << bits) - 50, (1 << bits) - 1)))
    start = data.draw(st.integers(0, arr))
    down = data.draw(st.booleans())
    m = data.draw(st.integers(0, 300))
    rig = Rig(name, 216)
    rig.w("ARR", arr)
    rig.w("CR1", DIR if down else 0)
    rig.w("EGR", 1)
    rig.w("SR", 0)
    rig.w("CNT", start)
    uif = uif_times(rig)
    rig.w("CR1", (DIR if down else 0) | CEN)
    rig.run(m)
    if down:
        want_cnt = (start - m) % (arr + 1)
        wraps = 0 if m <= start else (m - start - 1) // (arr + 1) + 1
    else:
        want_cnt = (start + m) % (arr + 1)
        wraps = (start + m) // (arr + 1)
    assert rig.r("CNT") == want_cnt
    assert len(uif) == wraps


GRAY = [(0, 0), (1, 0), (1, 1), (0, 1)]  # forward quadrature: A (TI1) leads B (TI2)


@SETTINGS
@given(st.data())
def test_encoder_count_equals_quarter_steps_mod_arr_plus_one(data):
    arr = data.draw(st.integers(1, 40))
    start = data.draw(st.integers(0, arr))
    sms = data.draw(st.sampled_from([3, 3, 1, 2]))
    pol1, pol2 = data.draw(st.integers(0, 1)), data.draw(st.integers(0, 1))
    icf = data.draw(st.integers(0, 15))
    ckd = data.draw(st.integers(0, 2))
    moves = data.draw(st.lists(st.sampled_from([1, -1]), min_size=1, max_size=60))
    rig = enc_rig(sms=sms, arr=arr, cnt=start, pol1=pol1, pol2=pol2, icf=icf)
    rig.w("CR1", (ckd << 8) | CEN)
    uif = uif_times(rig)
    ps, n = filter_timing(icf, ckd, rig.P)
    settle = ps * (n + 1) + (RESYNC_CYCLES + 1) * rig.P
    sign = -1 if pol1 ^ pol2 else 1  # inverting one input reverses the direction (§4.3)
    phase, cnt, wraps = 0, start, 0
    for mv in moves:
        new_phase = (phase + mv) % 4
        a_toggles = GRAY[phase][0] != GRAY[new_phase][0]
        phase = new_phase
        a, b = GRAY[phase]
        rig.tim.ti[1].set("enc", a)
        rig.tim.ti[2].set("enc", b)
        extra = data.draw(st.integers(0, 3 * rig.P))
        rig.kernel.run_until(rig.kernel.now + settle + extra)
        counts = sms == 3 or (sms == 1) == a_toggles
        if counts:
            step = mv * sign
            cnt += step
            if cnt > arr:
                cnt, wraps = 0, wraps + 1
            elif cnt < 0:
                cnt, wraps = arr, wraps + 1
    assert rig.r("CNT") == cnt
    assert len(uif) == wraps
    if sms == 3:
        q = sum(moves) * sign
        assert cnt == (start + q) % (arr + 1)
