"""STM32F746 TIM1-5/8 model: the reference sheet's test vectors (§6) through the bus, and the model's
pinned choices. Sheet: ST RM0385 (project timer notes)."""

import pytest
from mcusim.periph.stm32.tim_input import RESYNC_CYCLES
from tim_oracle import Rig

from mcusim.errors import UnsupportedConfiguration
from mcusim.kernel import PRIO_CPU

CEN, UDIS, URS, OPM, DIR, ARPE, UIFREMAP = 1, 2, 4, 8, 16, 128, 1 << 11
PWM1, PWM2 = 0x60, 0x70
OC1PE = 1 << 3
MOE = 1 << 15


def pwm_rig(name="TIM1", mhz=216, arr=4319, ccr=2160, mode=PWM1, pol=0, psc=0, cr1=0, moe=True, ocpe=0,
            rcr=0, engine="reference"):
    """HAL-like PWM init on CH1 (TIM_Base_SetConfig, TIM_OC1_SetConfig, PWM_Start); returns (rig, edges, t0)."""
    rig = Rig(name, mhz, engine=engine)
    edges = rig.record(1)
    rig.w("CR1", cr1)
    rig.w("ARR", arr)
    rig.w("PSC", psc)
    if rig.tim.advanced:
        rig.w("RCR", rcr)
    rig.w("EGR", 1)
    rig.w("SR", 0)
    rig.w("CCR1", ccr)
    rig.w("CCMR1", mode | ocpe)
    rig.w("CCER", 1 | (pol << 1))
    if rig.tim.advanced and moe:
        rig.w("BDTR", MOE)
    t0 = rig.kernel.now
    rig.w("CR1", cr1 | CEN)
    return rig, edges, t0


def high_ticks(edges, t_from, t_to, initial):
    """Base ticks at level 1 in [t_from, t_to) given the port edges and the level at t_from."""
    level, t, total = initial, t_from, 0
    for te, v in edges:
        if te <= t_from:
            continue
        if te >= t_to:
            break
        if level == 1:
            total += te - t
        level, t = v, te
    if level == 1:
        total += t_to - t
    return total


def level_at(edges, t, initial=None):
    v = initial
    for te, lv in edges:
        if te <= t:
            v = lv
    return v


def uif_times(rig, mask=1):
    """Times at which SR flags in ``mask`` are raised. An 'ISR' at CPU priority (same tick, after the
    hardware) records the flags it finds and clears them, so every later set raises the line again."""
    times = []
    rig.w("DIER", rig.r("DIER") | mask)

    def isr():
        if rig.tim.value["SR"] & mask:
            times.append(rig.kernel.now)
            rig.w("SR", ~mask & 0xFFFF_FFFF)

    def on_line(irqn, level):
        if level and irqn in (rig.tim._irq_up, rig.tim._irq_cc):
            rig.kernel.at(rig.kernel.now, isr, prio=PRIO_CPU)
    rig.nvic.line_listeners.append(on_line)
    return times


# ------------------------------------------------------------------ §6 vectors: PWM
def test_v1_pwm1_edge_aligned_50khz():
    rig, edges, t0 = pwm_rig()
    ccif = uif_times(rig, 1 << 1)
    rig.run(2159)
    assert rig.r("CNT") == 2159 and rig.r("SR") & 2 == 0
    rig.run(1)
    assert rig.r("CNT") == 2160 and ccif == [t0 + 2160]
    rig.run(2159)
    assert rig.r("CNT") == 4319 and rig.r("SR") & 1 == 0
    rig.run(1)
    assert rig.r("CNT") == 0 and rig.r("SR") & 1 == 1
    assert [e for e in edges if e[0] > t0] == [(t0 + 2160, 0), (t0 + 4320, 1)]
    assert high_ticks(edges, t0, t0 + 4320, 1) == 2160
    assert rig.tim.pwm_waveform(1) == (2160, 4320)
    assert rig.tb.seconds(4320 * rig.P) == pytest.approx(20e-6)


@pytest.mark.parametrize("ccr,high", [(0, 0), (4319, 4319), (4320, 4320), (0xFFFF, 4320)])
def test_v2_v3_v4_pwm1_duty_edge_cases(ccr, high):
    rig, edges, t0 = pwm_rig(ccr=ccr)
    rig.run(3 * 4320)
    for k in range(3):
        start = t0 + k * 4320
        assert high_ticks(edges, start, start + 4320, level_at(edges, start)) == high
    if ccr == 4319:  # low only while CNT = ARR
        assert level_at(edges, t0 + 4319) == 0 and level_at(edges, t0 + 4318) == 1


def test_v5_pwm2_is_complement():
    rig, edges, t0 = pwm_rig(mode=PWM2)
    rig.run(4320)
    assert level_at(edges, t0) == 0 and level_at(edges, t0 + 2159) == 0
    assert level_at(edges, t0 + 2160) == 1 and level_at(edges, t0 + 4319) == 1
    assert high_ticks(edges, t0, t0 + 4320, 0) == 2160


def test_v6_ccxp_inverts_pin_not_ref():
    rig, edges, t0 = pwm_rig(ccr=1000, pol=1)
    rig.run(4320)
    assert level_at(edges, t0 + 999) == 0 and level_at(edges, t0 + 1000) == 1
    assert high_ticks(edges, t0, t0 + 4320, 0) == 3320
    assert rig.tim._ref[1] == 1  # OCxREF unchanged: high at CNT 0


def test_v7_moe_zero_output_not_driven():
    rig, edges, t0 = pwm_rig(moe=False)
    assert rig.tim.oc[1].value is None
    uif = uif_times(rig)
    rig.run(4320 * 2)
    assert edges == [] and rig.tim.oc[1].value is None
    assert uif == [t0 + 4320, t0 + 8640]
    assert rig.tim._ref[1] == 1  # OC1REF still toggles internally
    rig.w("BDTR", MOE)
    assert rig.tim.oc[1].value == 1


@pytest.mark.parametrize("ccr,high", [(4, 5), (0, 1), (9, 9)])
def test_v8_down_counting_pwm1(ccr, high):
    rig, edges, t0 = pwm_rig("TIM3", 108, arr=8, ccr=ccr, cr1=DIR)
    P = rig.P
    assert rig.r("CNT") == 8
    uif = uif_times(rig)
    seq = []
    for _ in range(9):
        rig.run(1)
        seq.append(rig.r("CNT"))
    assert seq == [7, 6, 5, 4, 3, 2, 1, 0, 8]
    assert uif == [t0 + 9 * P]  # UIF on the 0 -> 8 step
    assert high_ticks(edges, t0, t0 + 9 * P, level_at(edges, t0)) == high * P


@pytest.mark.parametrize("ccr,high", [(4, 8), (0, 0), (7, 14), (8, 16), (9, 16)])
def test_v9_centre_aligned_pwm1(ccr, high):
    rig, edges, t0 = pwm_rig(arr=8, ccr=ccr, cr1=1 << 5)
    uif = uif_times(rig)
    seq = [rig.r("CNT")]
    dirs = [rig.r("CR1") & DIR]
    for _ in range(16):
        rig.run(1)
        seq.append(rig.r("CNT"))
        dirs.append(rig.r("CR1") & DIR)
    assert seq == [0, 1, 2, 3, 4, 5, 6, 7, 8, 7, 6, 5, 4, 3, 2, 1, 0]
    assert dirs == [0] * 8 + [DIR] * 8 + [0]
    assert high_ticks(edges, t0, t0 + 16, level_at(edges, t0)) == high
    assert uif == [t0 + 8, t0 + 16]  # UEV at CNT reaching ARR and at CNT reaching 0 (RCR=0)
    rig.w("CR1", rig.r("CR1") | DIR)  # DIR is read-only in centre-aligned mode
    assert rig.r("CR1") & DIR == 0


def test_v10_prescaler_one_mhz():
    rig, _edges, t0 = pwm_rig(psc=215, arr=999)
    uif = uif_times(rig)
    rig.run(215)
    assert rig.r("CNT") == 0
    rig.run(1)
    assert rig.r("CNT") == 1
    rig.run(216 * 999 - 1)
    assert rig.r("CNT") == 999
    rig.kernel.run_until(t0 + 216_000 * 5)
    assert uif == [t0 + 216_000 * k for k in range(1, 6)]


def test_v11_psc_is_buffered_until_uev():
    rig, _edges, t0 = pwm_rig("TIM3", 108, arr=99, ccr=0)
    P = rig.P
    rig.run(10)
    assert rig.r("CNT") == 10
    rig.w("PSC", 3)
    rig.run(89)
    assert rig.r("CNT") == 99
    rig.run(1)
    assert rig.r("CNT") == 0 and rig.r("SR") & 1
    rig.run(3)
    assert rig.r("CNT") == 0
    rig.run(1)
    assert rig.r("CNT") == 1
    assert rig.kernel.now == t0 + 104 * P


def test_v12_arpe_preload_and_immediate():
    rig, _edges, _t0 = pwm_rig("TIM3", 108, arr=199, ccr=0, cr1=ARPE)
    rig.run(150)
    rig.w("ARR", 99)
    assert rig.r("ARR") == 99
    rig.run(49)
    assert rig.r("CNT") == 199
    rig.run(1)
    assert rig.r("CNT") == 0
    rig.run(99)
    assert rig.r("CNT") == 99
    rig.run(1)
    assert rig.r("CNT") == 0
    # ARPE=0: the write at CNT=50 governs the current period
    rig2, _, _ = pwm_rig("TIM3", 108, arr=199, ccr=0)
    rig2.run(50)
    rig2.w("ARR", 99)
    rig2.run(49)
    assert rig2.r("CNT") == 99 and rig2.r("SR") & 1 == 0
    rig2.run(1)
    assert rig2.r("CNT") == 0 and rig2.r("SR") & 1


def test_v13_ocxpe_preload():
    rig, edges, t0 = pwm_rig("TIM3", 108, arr=999, ccr=500, ocpe=OC1PE)
    P = rig.P
    rig.run(300)
    rig.w("CCR1", 100)
    assert rig.r("CCR1") == 100
    rig.run(1000)
    assert level_at(edges, t0 + 499 * P) == 1 and level_at(edges, t0 + 500 * P) == 0
    assert level_at(edges, t0 + 1099 * P) == 1 and level_at(edges, t0 + 1100 * P) == 0
    assert high_ticks(edges, t0 + 1000 * P, t0 + 2000 * P, 1) == 100 * P


def ug_rig(cr1=0, name="TIM2"):
    rig = Rig(name, 216)
    rig.w("ARR", 0xFFFF_FFFF if rig.tim.bits == 32 else 9999)
    rig.w("EGR", 1)
    rig.w("SR", 0)
    rig.w("CR1", cr1 | CEN)
    rig.run(1234)
    assert rig.r("CNT") == 1234
    return rig


def test_v14_ug_resets_counter_loads_shadows_sets_uif():
    rig = ug_rig()
    rig.w("PSC", 7)
    rig.w("EGR", 1)
    assert rig.r("CNT") == 0 and rig.r("SR") & 1 and rig.r("EGR") == 0
    assert rig.tim._psc == 7
    rig.run(7)
    assert rig.r("CNT") == 0
    rig.run(1)
    assert rig.r("CNT") == 1  # prescaler counter restarted from 0 at the UG


def test_v15_urs_blocks_uif_on_ug():
    rig = ug_rig(URS)
    rig.w("PSC", 3)
    rig.w("EGR", 1)
    assert rig.r("CNT") == 0 and rig.r("SR") & 1 == 0 and rig.tim._psc == 3


def test_v16_udis_blocks_shadow_load_but_ug_resets():
    rig = ug_rig(UDIS | ARPE)
    rig.w("ARR", 100)
    rig.w("PSC", 1)
    rig.w("EGR", 1)
    assert rig.r("CNT") == 0 and rig.r("SR") & 1 == 0
    assert rig.tim._arr == 0xFFFF_FFFF and rig.tim._psc == 0
    rig.run(200)
    assert rig.r("CNT") == 200  # old ARR still governs, prescaler unchanged


def test_v17_ug_in_down_mode_loads_arr():
    rig = Rig("TIM3", 108)
    rig.w("ARR", 99)
    rig.w("CR1", DIR)
    rig.w("CNT", 5)
    rig.w("EGR", 1)
    assert rig.r("CNT") == 99


def test_v18_sr_is_rc_w0():
    rig, _edges, _t0 = pwm_rig(ccr=10, arr=99)
    rig.w("DIER", 0)
    rig.w("SR", 0)
    rig.run(100)
    assert rig.r("SR") & 3 == 3
    rig.w("SR", 0b1)
    assert rig.r("SR") & 3 == 1
    rig.w("SR", 0xFFFF_FFFE)
    assert rig.r("SR") & 3 == 0


def test_v19_32bit_wrap_and_uifremap():
    rig = Rig("TIM2", 216)
    rig.w("ARR", 0xFFFF_FFFF)
    rig.w("EGR", 1)
    rig.w("SR", 0)
    rig.w("CNT", 0xFFFF_FFFF)
    rig.w("CR1", CEN)
    assert rig.r("CNT") == 0xFFFF_FFFF
    rig.run(1)
    assert rig.r("CNT") == 0 and rig.r("SR") & 1
    rig.w("CR1", CEN | UIFREMAP)
    rig.run(5)
    assert rig.r("CNT") == 0x8000_0005  # bit 31 reads UIF, not the counter MSB
    rig.w("SR", 0)
    assert rig.r("CNT") == 0x0000_0005
    t3 = Rig("TIM3", 108)
    t3.w("ARR", 0xFFFF)
    t3.w("CR1", UIFREMAP)
    t3.w("CNT", 0x1234)
    t3.w("EGR", 1)
    t3.w("CNT", 0x1234)
    assert t3.r("CNT") == 0x8000_1234


def test_v20_repetition_counter():
    rig, edges, t0 = pwm_rig(arr=99, ccr=50, rcr=3)
    uif = uif_times(rig)
    rig.run(800)
    assert uif == [t0 + 400, t0 + 800]
    rises = [t for t, v in edges if v == 1 and t > t0]
    assert rises == [t0 + 100 * k for k in range(1, 9)]


# ------------------------------------------------------------------ §6 vectors: encoder
def enc_rig(sms=3, arr=99, cnt=10, pol1=0, pol2=0, icf=0, psc=0, name="TIM3"):
    """HAL_TIM_Encoder_Init + Encoder_Start, TI nets at 0."""
    rig = Rig(name, 108)
    rig.w("ARR", arr)
    rig.w("PSC", psc)
    rig.w("EGR", 1)
    rig.w("SR", 0)
    rig.w("SMCR", sms)
    rig.w("CCMR1", 0x0101 | (icf << 4) | (icf << 12))
    rig.w("CCER", (pol1 << 1) | (pol2 << 5))
    rig.w("CCER", rig.r("CCER") | 0x11)
    rig.run(1100)  # a CCxP change is a TIxFPx edge: let it pass the filter and synchroniser before CEN
    rig.w("CNT", cnt)
    rig.w("CR1", CEN)
    return rig


def move(rig, seq, settle=10):
    for a, b in seq:
        rig.tim.ti[1].set("enc", a)
        rig.tim.ti[2].set("enc", b)
        rig.run(settle)


FWD = [(1, 0), (1, 1), (0, 1), (0, 0)]
BWD = [(0, 1), (1, 1), (1, 0), (0, 0)]


def test_v21_encoder_x4_forward():
    rig = enc_rig()
    move(rig, FWD)
    assert rig.r("CNT") == 14 and rig.r("CR1") & DIR == 0 and rig.r("SR") & 1 == 0


def test_v22_encoder_x4_backward():
    rig = enc_rig()
    move(rig, BWD)
    assert rig.r("CNT") == 6 and rig.r("CR1") & DIR == DIR


def test_v23_encoder_overflow_wraps_with_uif():
    rig = enc_rig(cnt=99)
    move(rig, [(1, 0)])
    assert rig.r("CNT") == 0 and rig.r("SR") & 1 and rig.r("CR1") & DIR == 0


def test_v24_encoder_underflow_wraps_with_uif():
    rig = enc_rig(cnt=0)
    move(rig, [(0, 1)])
    assert rig.r("CNT") == 99 and rig.r("SR") & 1 and rig.r("CR1") & DIR == DIR


@pytest.mark.parametrize("sms", [1, 2])
def test_v25_encoder_x2_counts_one_input_hal_reading(sms):
    rig = enc_rig(sms=sms)
    cnts = []
    for step in FWD:
        move(rig, [step])
        cnts.append(rig.r("CNT"))
        assert rig.r("CR1") & DIR == 0  # the other input's edges refresh DIR too
    assert rig.r("CNT") == 12
    # SMS=001 counts TI1 edges (steps 1 and 3), SMS=010 TI2 edges (steps 2 and 4)
    assert cnts == ([11, 11, 12, 12] if sms == 1 else [10, 11, 11, 12])


def test_v26_encoder_jitter_cancels():
    rig = enc_rig()
    cnts = []
    for a in (1, 0, 1, 0):
        move(rig, [(a, 0)])
        cnts.append(rig.r("CNT"))
    assert cnts == [11, 10, 11, 10] and rig.r("CR1") & DIR == DIR


@pytest.mark.parametrize("p1,p2,final", [(1, 0, 6), (1, 1, 14)])
def test_v27_encoder_polarity_inversion(p1, p2, final):
    rig = enc_rig(pol1=p1, pol2=p2)
    # CCxP=1 inverts TIx: the idle (0,0) pins read as TIxFPx=1, so start from the pins' idle state
    move(rig, FWD)
    assert rig.r("CNT") == final


def test_v28_input_filter_rejects_short_pulse():
    rig = enc_rig(icf=0b0011)  # fCK_INT, N=8
    P = rig.P
    rig.run(1)
    t = rig.kernel.now
    rig.tim.ti[1].set("enc", 1)
    rig.run(7)
    rig.tim.ti[1].set("enc", 0)
    rig.run(50)
    assert rig.r("CNT") == 10 and rig.r("CR1") & DIR == 0
    t = rig.kernel.now
    rig.tim.ti[1].set("enc", 1)
    rig.run(8 + RESYNC_CYCLES - 1)
    assert rig.r("CNT") == 10
    rig.run(1)
    assert rig.r("CNT") == 11  # 8 samples (t+P .. t+8P) + 2 cycles resync
    assert rig.kernel.now == t + (8 + RESYNC_CYCLES) * P


def test_v29_encoder_prescaler_counter_is_up_only():
    rig = enc_rig(psc=1)
    move(rig, FWD[:2])
    assert rig.r("CNT") == 11 and rig.tim._pscc == 0
    move(rig, [(1, 0)])  # reverse one edge: the prescaler counter still counts up
    assert rig.tim._pscc == 1 and rig.r("CNT") == 11
    move(rig, [(0, 0)])
    assert rig.tim._pscc == 0 and rig.r("CNT") == 10


def test_v30_old_hal_init_leaves_uif_and_fires_irq():
    rig = Rig("TIM3", 108)
    # HAL_TIM_Base_Init (pre-v1.3.1 HAL: no UIF clear after UG)
    rig.w("CR1", 0)
    rig.w("ARR", 999)
    rig.w("PSC", 107)
    rig.w("EGR", 1)
    assert rig.r("SR") & 1 == 1
    # HAL_TIM_Base_Start_IT: UIE then CEN -> immediate update interrupt
    rig.w("DIER", 1)
    assert 29 in rig.nvic.pending
    rig.w("CR1", CEN)
    # HAL >= v1.3.1 clears it: no immediate IRQ
    rig2 = Rig("TIM3", 108)
    rig2.w("ARR", 999)
    rig2.w("EGR", 1)
    if rig2.r("SR") & 1:
        rig2.w("SR", ~1 & 0xFFFF_FFFF)
    rig2.w("DIER", 1)
    assert 29 not in rig2.nvic.pending


# ------------------------------------------------------------------ pinned choices
def test_arr_reset_default_is_zero_per_rm0090_unverified():
    rig = Rig("TIM3", 108)
    assert rig.r("ARR") == 0
    rig.w("CR1", CEN)
    rig.run(100)
    assert rig.r("CNT") == 0  # ARR=0 blocks the counter
    assert Rig("TIM2", 108, arr_reset=0xFFFF_FFFF).r("ARR") == 0xFFFF_FFFF


def test_cen_starts_counter_one_cycle_after_write():
    rig = Rig("TIM3", 108)  # P = 2 base ticks
    rig.w("ARR", 99)
    rig.kernel.run_until(5)  # write between CK_INT edges (edges at even ticks)
    rig.w("CR1", CEN)
    rig.kernel.run_until(7)
    assert rig.r("CNT") == 0
    rig.kernel.run_until(8)  # first CK_INT edge at or after 5 + 2
    assert rig.r("CNT") == 1
    rig2 = Rig("TIM1", 216)
    rig2.w("ARR", 99)
    rig2.w("CR1", CEN)
    rig2.run(1)
    assert rig2.r("CNT") == 1


def test_encoder_resync_delay_is_two_cycles_after_next_edge():
    rig = enc_rig()
    P = rig.P
    rig.kernel.run_until(rig.kernel.now + 1)  # odd tick: between CK_INT edges
    t = rig.kernel.now
    rig.tim.ti[1].set("enc", 1)
    s1 = (t // P + 1) * P
    rig.kernel.run_until(s1 + RESYNC_CYCLES * P - 1)
    assert rig.r("CNT") == 10
    rig.kernel.run_until(s1 + RESYNC_CYCLES * P)
    assert rig.r("CNT") == 11
    assert RESYNC_CYCLES == 2


def test_simultaneous_ti_edges_count_nothing():
    rig = enc_rig()
    move(rig, [(1, 1)])  # both inputs change in the same sample
    assert rig.r("CNT") == 10 and rig.r("CR1") & DIR == 0
    move(rig, [(0, 1)])  # later single edges count normally from the new levels
    assert rig.r("CNT") == 11


def test_centre_ccif_direction_by_cms():
    for cms, expect in ((1, [12]), (2, [4]), (3, [4, 12])):
        rig, _edges, t0 = pwm_rig(arr=8, ccr=4, cr1=cms << 5)
        times = uif_times(rig, 1 << 1)
        rig.run(16)
        assert [t - t0 for t in times] == expect


def test_opm_clears_cen_at_update():
    rig, _edges, _t0 = pwm_rig(arr=9, ccr=5, cr1=OPM)
    rig.run(30)
    assert rig.r("CR1") & CEN == 0 and rig.r("CNT") == 0 and rig.r("SR") & 1


def test_shared_and_separate_irq_lines():
    rig, _, _t0 = pwm_rig(arr=9, ccr=5)
    rig.w("DIER", 0b10)
    rig.run(5)
    assert rig.nvic.lines.get(27) and not rig.nvic.lines.get(25)
    rig2, _, _ = pwm_rig("TIM2", arr=9, ccr=5)
    rig2.w("DIER", 0b11)
    rig2.run(10)
    assert rig2.nvic.lines.get(28)
    rig2.w("SR", ~0b10 & 0xFFFF)
    assert rig2.nvic.lines.get(28)  # UIF still holds the shared line
    rig2.w("SR", 0)
    assert not rig2.nvic.lines.get(28)


def test_frozen_and_forced_modes():
    rig, _edges, _t0 = pwm_rig(arr=99, ccr=50)
    rig.run(10)
    rig.w("CCMR1", 0x50)  # force active
    assert rig.tim.oc[1].value == 1
    rig.w("CCMR1", 0x40)  # force inactive
    assert rig.tim.oc[1].value == 0
    rig.w("CCMR1", 0x00)  # frozen: holds
    rig.run(200)
    assert rig.tim.oc[1].value == 0


@pytest.mark.parametrize("reg,value", [
    ("CR2", 0x10), ("SMCR", 0x4), ("SMCR", 0x7), ("SMCR", 1 << 16), ("SMCR", 1 << 14), ("SMCR", 0x10),
    ("DIER", 1 << 8), ("DIER", 1 << 9), ("DIER", 1 << 6), ("EGR", 0b10), ("CCMR1", 0x10), ("CCMR1", 0x30),
    ("CCMR1", 1 << 16), ("CCMR1", 0x80), ("CCMR1", 0x3), ("CCER", 1 << 2), ("BDTR", 0x10), ("BDTR", 1 << 12),
    ("DCR", 1), ("OR", 1), ("CCR5", 1), ("CR1", 3 << 8),
])
def test_unsupported_configuration_raises(reg, value):
    rig = Rig("TIM1", 216)
    before = rig.r(reg) if reg not in ("EGR",) else 0
    with pytest.raises(UnsupportedConfiguration) as e:
        rig.w(reg, value)
    assert e.value.periph == "TIM1" and e.value.register == reg
    assert rig.r(reg) == before


def test_input_capture_outside_encoder_mode_raises():
    rig = Rig("TIM3", 108)
    rig.w("CCMR1", 0x01)
    with pytest.raises(UnsupportedConfiguration):
        rig.w("CCER", 1)
    assert rig.r("CCER") == 0
    enc = enc_rig()
    with pytest.raises(UnsupportedConfiguration):
        enc.w("SMCR", 0)
    assert enc.r("SMCR") == 3


def test_encoder_capture_into_ccr1():
    rig = enc_rig()
    move(rig, FWD[:2])
    assert rig.r("SR") & 0b10
    assert rig.r("CCR1") == 11 and not rig.r("SR") & 0b10   # reading CCR1 clears CC1IF (RM0385)
    rig.w("CCR1", 5)  # read-only in input mode
    assert rig.r("CCR1") == 11


def test_counter_property_has_no_side_effects():
    rig, _edges, _t0 = pwm_rig(arr=99, ccr=50)
    rig.run(42)
    state = (rig.tim._cnt, rig.tim._tb, rig.r("SR"))
    assert rig.tim.counter == 42
    assert (rig.tim._cnt, rig.tim._tb, rig.r("SR")) == state


def test_set_kernel_clock_changes_rate():
    rig, _edges, _t0 = pwm_rig("TIM3", 108, arr=999, ccr=0)
    rig.run(10)
    rig.tim.set_kernel_clock(rig.tb.clock("fast", 216_000_000))
    c = rig.r("CNT")
    rig.kernel.run_until(rig.kernel.now + 101)
    assert rig.r("CNT") == c + 101  # one tick per 216 MHz cycle from the next edge on


def test_pwm_costs_constant_events_per_period():
    rig, _edges, _t0 = pwm_rig()
    n0 = rig.kernel.events
    rig.run(4320 * 100)
    assert rig.kernel.events - n0 <= 2 * 100 + 2
