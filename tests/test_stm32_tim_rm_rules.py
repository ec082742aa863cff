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
