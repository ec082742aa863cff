"""RM0385 rules of the STM32F7 timers a review found missing (each test fails on the old model),
in both engines: reading CCRx of a capture channel clears CCxIF; CCxE = 0 resets the capture
prescaler; CMS cannot go centre-aligned while the counter runs edge-aligned, nor with encoder
mode."""

import pytest

import mcusim
from mcusim.errors import UnsupportedConfiguration

TIM3, GPIOB = 0x40000400, 0x40020400
CR1, SMCR, SR, EGR, CCMR1, CCER, CNT, PSC, ARR, CCR1 = 0x00, 0x08, 0x10, 0x14, 0x18, 0x20, 0x24, 0x28, 0x2C, 0x34
FWD = [(1, 0), (1, 1), (0, 1), (0, 0)]


def _encoder(engine, icpsc=0):
    """TIM3 in encoder mode 3 on PB4/PB5 (AF2), both channels capturing (CC1S = CC2S = 01)."""
    sim = mcusim.load("nucleo-f746", firmware=False, engine=engine)
    m = sim.mcu
    a, b = sim.pin("PB4"), sim.pin("PB5")
    a.drive(0)
    b.drive(0)
    m.write32(GPIOB, (m.read32(GPIOB) & ~(0xF << 8)) | (0xA << 8))           # PB4, PB5: alternate
    m.write32(GPIOB + 0x20, (m.read32(GPIOB + 0x20) & ~(0xFF << 16)) | (0x22 << 16))   # AF2
    m.write32(TIM3 + ARR, 99)
    m.write32(TIM3 + EGR, 1)
    m.write32(TIM3 + SR, 0)
    m.write32(TIM3 + SMCR, 3)
    m.write32(TIM3 + CCMR1, 0x0101 | (icpsc << 2) | (icpsc << 10))
    m.write32(TIM3 + CCER, 0x11)
    m.write32(TIM3 + CNT, 10)
    m.write32(TIM3 + CR1, 1)

    def move(steps):
        for lv_a, lv_b in steps:
            a.drive(lv_a)
            b.drive(lv_b)
            sim.run(cycles=40)
    return sim, m, move


@pytest.mark.parametrize("engine", ["reference", "fast"])
def test_reading_ccr1_of_a_capture_channel_clears_cc1if_and_no_overcapture_follows(engine):
    """RM0385, CC1IF with channel 1 as input: "cleared by software or by reading TIMx_CCR1". An
    ISR that takes the capture by reading CCR1 must not see CC1OF at the next capture."""
    sim, m, move = _encoder(engine)
    for step in FWD * 2:
        move([step])
        if m.read32(TIM3 + SR) & 2:
            m.read32(TIM3 + CCR1)
            assert not m.read32(TIM3 + SR) & 2
    assert not m.read32(TIM3 + SR) & (1 << 9)     # CC1OF
    sim.close()


@pytest.mark.parametrize("engine", ["reference", "fast"])
def test_clearing_cc1e_resets_the_capture_prescaler(engine):
    """RM0385, IC1PSC: "the prescaler is reset as soon as CC1E=0". With IC1PSC = 01 (a capture
    every 2 events), one rising edge, CC1E off and on, one more rising edge: no capture."""
    sim, m, move = _encoder(engine, icpsc=1)
    move(FWD)
    assert m.read32(TIM3 + CCR1) == 0
    m.write32(TIM3 + CCER, m.read32(TIM3 + CCER) & ~1)
    sim.run(cycles=5)
    m.write32(TIM3 + CCER, m.read32(TIM3 + CCER) | 1)
    move(FWD)
    assert m.read32(TIM3 + CCR1) == 0 and not m.read32(TIM3 + SR) & 2
    sim.close()


def test_centre_aligned_mode_cannot_be_set_while_the_counter_runs_edge_aligned_or_in_encoder_mode():
    """RM0385, CR1.CMS: "It is not allowed to switch from edge-aligned mode to center-aligned
    mode as long as the counter is enabled (CEN=1)"; encoder mode with CMS != 00 is not modelled.
    Stopped first, the switch is accepted."""
    sim = mcusim.load("nucleo-f746", firmware=False)
    m = sim.mcu
    m.write32(TIM3 + ARR, 99)
    m.write32(TIM3 + CR1, 1)
    with pytest.raises(UnsupportedConfiguration, match="CMS = 0x1 set while the counter runs edge-aligned"):
        m.write32(TIM3 + CR1, 0x21)
    assert m.read32(TIM3 + CR1) & 0x60 == 0
    m.write32(TIM3 + CR1, 0)
    m.write32(TIM3 + CR1, 0x21)                   # stopped, then centre-aligned and started: fine
    m.write32(TIM3 + CR1, 0)
    m.write32(TIM3 + CR1, 0x20)
    with pytest.raises(UnsupportedConfiguration, match="SMS = 0x3 with a centre-aligned counter"):
        m.write32(TIM3 + SMCR, 3)
    sim.close()


# --- centre-aligned counter writes and a frozen OCxREF (a model review) ------------------------

def _centre_rig(engine, cnt_first=10):
    from tim_oracle import Rig
    r = Rig("TIM3", 108, engine=engine)
    r.w("ARR", 99)
    r.w("CR1", 1 << 5)                  # CMS = 01
    r.w("EGR", 1)
    r.w("SR", 0)
    r.w("CR1", (1 << 5) | 1)
    r.run(cnt_first)
    return r


@pytest.mark.parametrize("engine", ["reference", "fast"])
def test_a_centre_aligned_counter_written_above_arr_keeps_counting_up(engine):
    """RM "Hints on using center-aligned mode" (RM0008, RM0016): "The direction is not updated if
    you write in the counter a value greater than the auto-reload value. For example, if the
    counter was counting up, it continues to count up." The model had turned it down at once.
    Our choice [INF] for what follows: it rolls over from 0xFFFF to 0 with no update event and
    overflows at ARR as usual."""
    r = _centre_rig(engine)
    assert (r.r("CR1") >> 4) & 1 == 0
    r.w("CNT", 200)
    seq = []
    for _ in range(3):
        r.run(1)
        seq.append(r.r("CNT"))
    assert seq == [201, 202, 203] and (r.r("CR1") >> 4) & 1 == 0
    r.run(0xFFFF - 203)
    assert r.r("CNT") == 0xFFFF and r.r("SR") & 1 == 0
    r.run(1)
    assert r.r("CNT") == 0 and r.r("SR") & 1 == 0 and (r.r("CR1") >> 4) & 1 == 0   # no UEV
    r.run(99)
    assert r.r("CNT") == 99 and r.r("SR") & 1 == 1 and (r.r("CR1") >> 4) & 1 == 1   # overflow at ARR
    r.run(1)
    assert r.r("CNT") == 98


@pytest.mark.parametrize("engine", ["reference", "fast"])
@pytest.mark.parametrize("written, dir_after, next_cnt", [(99, 1, 98), (0, 0, 1)])
def test_writing_arr_or_zero_into_a_centre_aligned_counter_sets_the_direction_without_an_update(
        engine, written, dir_after, next_cnt):
    """Same hint: "The direction is updated if you write 0 or write the TIMx_ARR value in the
    counter but no Update Event UEV is generated"."""
    r = _centre_rig(engine, 150)        # counting down from ARR at CNT 48
    r.w("SR", 0)
    r.w("CNT", written)
    assert (r.r("CR1") >> 4) & 1 == dir_after and r.r("SR") & 1 == 0
    r.run(1)
    assert r.r("CNT") == next_cnt


@pytest.mark.parametrize("engine", ["reference", "fast"])
@pytest.mark.parametrize("advanced", [False, True])
def test_frozen_mode_keeps_the_comparison_level_of_an_output_that_was_not_driven(engine, advanced):
    """OCxREF comes from the comparison whatever CCxE (and MOE) say; they only gate the pin. Frozen
    mode keeps OCxREF as it is: PWM1 with CNT = 70 >= CCR1 = 50 has it inactive, so enabling the
    output after the switch to frozen shows 0. The model kept the level of the last time it had
    planned (active) because a channel not driven gets no match events."""
    from tim_oracle import Rig
    r = Rig("TIM1" if advanced else "TIM3", 108, engine=engine)
    r.w("ARR", 99)
    r.w("EGR", 1)
    r.w("SR", 0)
    r.w("CCR1", 50)
    r.w("CCMR1", 0x60)                  # PWM1
    if advanced:
        r.w("CCER", 1)                  # CC1E set, MOE = 0: not driven either
    r.w("CR1", 1)
    r.run(70)
    r.w("CCMR1", 0x00)                  # frozen
    r.w("CCER", 1)
    if advanced:
        r.w("BDTR", 1 << 15)
    assert r.tim.oc[1].value == 0
