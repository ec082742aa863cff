"""The nucleo-f746 board without firmware: reference-sheet vectors through GPIO pins and RCC clocks."""

import itertools

import pytest

import mcusim
from mcusim.errors import BusFault, ConfigError, UnsupportedConfiguration

TIM1, TIM2 = 0x40010000, 0x40000000
GPIOE, GPIOA = 0x40021000, 0x40020000
RCC = 0x40023800
CR1, CCMR1, CCER, CNT, PSC, ARR, CCR1, BDTR, EGR, SR = 0x00, 0x18, 0x20, 0x24, 0x28, 0x2C, 0x34, 0x44, 0x14, 0x10


def af(sim, port, pin, number):
    reg = port + (0x20 if pin < 8 else 0x24)  # AFR first, then MODER, as HAL_GPIO_Init does
    sh = 4 * (pin % 8)
    sim.mcu.write32(reg, (sim.mcu.read32(reg) & ~(0xF << sh)) | (number << sh))
    sim.mcu.write32(port + 0x00, (sim.mcu.read32(port) & ~(3 << 2 * pin)) | (2 << 2 * pin))


def pwm1(sim, tim, arr, ccr, advanced):
    m = sim.mcu
    m.write32(tim + ARR, arr)
    m.write32(tim + CCR1, ccr)
    m.write32(tim + CCMR1, 0x60)           # OC1M = PWM mode 1
    m.write32(tim + EGR, 1)                # UG
    m.write32(tim + SR, 0)
    m.write32(tim + CCER, 1)               # CC1E
    if advanced:
        m.write32(tim + BDTR, 1 << 15)     # MOE
    m.write32(tim + CR1, 1)                # CEN


def edges(sim, pin, duration_ticks):
    out = []
    sim.pin(pin).listen(lambda n: out.append((sim.now, n.level)))
    sim.run(cycles=duration_ticks // sim.mcu.core_clock.period)
    return out


def test_pe9_carries_tim1_pwm_at_50khz_with_50_percent_duty():
    """Sheet §6 #1 on the board: TIM1 at 216 MHz, ARR=4319, CCR1=2160 -> 20 µs period, 2160 ticks high."""
    sim = mcusim.load("nucleo-f746", firmware=False)
    af(sim, GPIOE, 9, 1)
    pwm1(sim, TIM1, 4319, 2160, advanced=True)
    ev = edges(sim, "PE9", 5 * 4320 + 100)
    rises = [t for t, lv in ev if lv == 1]
    falls = [t for t, lv in ev if lv == 0]
    assert [b - a for a, b in itertools.pairwise(rises)] == [4320] * (len(rises) - 1)
    assert len(rises) >= 4
    highs = [f - r for r, f in zip(rises, [f for f in falls if f > rises[0]])]
    assert set(highs) == {2160}


def test_tim2_counts_at_108mhz_so_arr_4319_gives_25khz():
    """Sheet §2.2: APB1 /4 with TIMPRE=0 -> TIM2 at 2 x 54 MHz; the same ARR halves the frequency."""
    sim = mcusim.load("nucleo-f746", firmware=False)
    af(sim, GPIOA, 5, 1)
    pwm1(sim, TIM2, 4319, 2160, advanced=False)
    rises = [t for t, lv in edges(sim, "PA5", 4 * 8640 + 100) if lv]
    assert {b - a for a, b in itertools.pairwise(rises)} == {8640}  # 40 µs in 1/216 MHz ticks


def test_timpre_makes_apb1_timers_count_at_hclk():
    sim = mcusim.load("nucleo-f746", firmware=False)
    sim.mcu.write32(RCC + 0x8C, 1 << 24)   # DCKCFGR1.TIMPRE
    af(sim, GPIOA, 5, 1)
    pwm1(sim, TIM2, 4319, 2160, advanced=False)
    rises = [t for t, lv in edges(sim, "PA5", 4 * 4320 + 100) if lv]
    assert {b - a for a, b in itertools.pairwise(rises)} == {4320}


def test_counter_readable_through_api_and_advances_per_core_cycles():
    sim = mcusim.load("nucleo-f746", firmware=False)
    sim.mcu.write32(TIM1 + ARR, 0xFFFF)
    sim.mcu.write32(TIM1 + CR1, 1)
    sim.run(cycles=1001)
    # sheet §2.1/§2.8: the first increment comes one CK_INT cycle after CEN is written, then one
    # per cycle (PSC=0, TIM1 at 216 MHz = one core cycle)
    assert sim.mcu.read32(TIM1 + CNT) == 1001


def test_external_stimulus_takes_encoder_pin_from_the_plant():
    sim = mcusim.load("nucleo-f746", firmware=False)
    pin = sim.pin("PB4")
    pin.drive(1)
    assert pin.level == 1
    pin.drive(0)
    assert pin.level == 0


def test_unmapped_address_and_unmodelled_mode_fail_loudly():
    sim = mcusim.load("nucleo-f746", firmware=False)
    with pytest.raises(BusFault, match="0x60000000"):
        sim.mcu.read32(0x6000_0000)
    with pytest.raises(UnsupportedConfiguration, match="TIM3.SMCR"):
        sim.mcu.write32(0x40000400 + 0x08, 0b110)  # SMS = trigger mode


def test_unknown_board_and_bad_override_are_config_errors():
    with pytest.raises(ConfigError, match="unknown board 'nucleo-f4'.*nucleo-f746"):
        mcusim.load("nucleo-f4")
    with pytest.raises(ConfigError, match="no part 'motor9'"):
        mcusim.load("nucleo-f746", overrides={"motor9.J": 1})
    with pytest.raises(ConfigError, match="banana"):
        mcusim.load("nucleo-f746", overrides={"motor1.banana": 1})


def test_uifremap_cnt_write_keeps_bit31_on_32bit_timer():
    """Sheet §1.2: with UIFREMAP bit 31 of CNT becomes write-only (reads give UIFCPY)."""
    sim = mcusim.load("nucleo-f746", firmware=False)
    sim.mcu.write32(TIM2 + ARR, 0xFFFF_FFFF)
    sim.mcu.write32(TIM2 + CR1, 1 << 11)
    sim.mcu.write32(TIM2 + CNT, 0x8000_0005)
    assert sim.mcu.periph["TIM2"].counter == 0x8000_0005
    assert sim.mcu.read32(TIM2 + CNT) == 0x0000_0005  # UIF = 0 reads in bit 31


def test_clearing_arpe_makes_pending_arr_effective_at_once():
    sim = mcusim.load("nucleo-f746", firmware=False)
    m = sim.mcu
    m.write32(TIM1 + CR1, 1 << 7)          # ARPE
    m.write32(TIM1 + ARR, 9)
    m.write32(TIM1 + EGR, 1)
    m.write32(TIM1 + ARR, 4)               # preloaded, not yet active
    m.write32(TIM1 + CR1, 0)               # ARPE = 0: the preload reaches the shadow
    m.write32(TIM1 + SR, 0)
    m.write32(TIM1 + CR1, 1)
    sim.run(cycles=5)
    assert m.read32(TIM1 + SR) & 1          # wrapped at ARR = 4, not 9


def test_open_drain_af_pin_releases_on_one_and_analog_disables_pulls():
    sim = mcusim.load("nucleo-f746", firmware=False)
    m = sim.mcu
    af(sim, GPIOE, 9, 1)
    m.write32(GPIOE + 0x04, 1 << 9)         # OTYPER9 = open drain
    pwm1(sim, TIM1, 4319, 4320, advanced=True)  # CCR > ARR: OC1 constantly 1
    pin = sim.pin("PE9")
    assert "GPIOE" not in pin._drivers       # 1 on an open-drain output: released
    m.write32(GPIOE + 0x0C, 1 << 18)         # PUPDR9 = pull-up
    assert pin.level == 1
    m.write32(GPIOE + 0x00, 3 << 18)         # MODER9 = analog: pulls disabled
    assert pin.pull is None


def test_hal_encoder_reinit_after_counting_down_starts_at_zero():
    """ST's HAL_TIM_Encoder_Init clears SMS before TIM_Base_SetConfig, so UG sees an up-counter."""
    from mcusim.fw.stm32hal import tim as hal
    from mcusim.fw.stm32hal.regs import Stm32f7
    sim = mcusim.load("nucleo-f746", firmware=False)
    dev = Stm32f7(sim.mcu.bus)
    for port, pin in ((0x40020400, 4), (0x40020400, 5)):
        af(sim, port, pin, 2)
    h = hal.TIM_HandleTypeDef(dev.TIM3, hal.TIM_Base_InitTypeDef(Period=99))
    hal.HAL_TIM_Encoder_Init(h, hal.TIM_Encoder_InitTypeDef())
    hal.HAL_TIM_Encoder_Start(h)
    sim.run(cycles=100)
    a, b = sim.pin("PB4"), sim.pin("PB5")
    a.drive(0)
    b.drive(0)
    sim.run(cycles=100)
    b.drive(1)                               # B rises with A low: one step down
    sim.run(cycles=100)
    assert sim.mcu.read32(0x40000400) & (1 << 4)  # DIR = 1
    hal.HAL_TIM_Encoder_Stop(h)
    hal.HAL_TIM_Encoder_Init(h, hal.TIM_Encoder_InitTypeDef())
    assert sim.mcu.read32(0x40000424) == 0


def test_byte_access_to_timer_register_is_a_bus_fault():
    """RM0385: timer registers are accessed by half-words or words."""
    sim = mcusim.load("nucleo-f746", firmware=False)
    with pytest.raises(BusFault, match="TIM1 accepts only 16/32-bit"):
        sim.mcu.write8(TIM1 + ARR, 1)
    sim.mcu.write16(TIM1 + ARR, 0x1234)
    assert sim.mcu.read16(TIM1 + ARR) == 0x1234


def test_an_ahb_prescaler_is_refused_as_the_core_and_systick_do_not_follow_it():
    """RM0385 §5.2: HCLK clocks the core, and SysTick runs on HCLK or HCLK/8. The core and SysTick
    here count SYSCLK, so HPRE = /2 had slowed only the timers (DWT counted twice the cycles a
    review measured against TIM1). It is refused, naming the field, and the register keeps its
    value."""
    sim = mcusim.load("nucleo-f746", firmware=False)
    before = sim.mcu.read32(RCC + 0x08)
    with pytest.raises(UnsupportedConfiguration, match=r"RCC\.CFGR\.HPRE = 0x8 \(AHB prescaler /2\)"):
        sim.mcu.write32(RCC + 0x08, before | (0b1000 << 4))
    assert sim.mcu.read32(RCC + 0x08) == before
    sim.mcu.write32(RCC + 0x08, before | (0b0111 << 4))     # 0xxx is /1 (RM0385 HPRE table)
    sim.close()


def test_every_documented_clock_enable_bit_reads_back_and_reserved_bits_read_zero():
    """RM0385 RCC_xxxENR: HAL's __HAL_RCC_USART2_CLK_ENABLE and __HAL_RCC_PWR_CLK_ENABLE set
    APB1ENR bits 17 and 28, which read back (they had read 0: only the timers' bits were kept);
    bit 10 is reserved. AHB1ENR has DTCMRAMEN (bit 20) set out of reset."""
    sim = mcusim.load("nucleo-f746", firmware=False)
    m = sim.mcu
    assert m.read32(RCC + 0x30) == 0x0010_0000
    m.write32(RCC + 0x40, (1 << 17) | (1 << 28) | (1 << 10))
    assert m.read32(RCC + 0x40) == 0x1002_0000
    m.write32(RCC + 0x44, 0xFFFF_FFFF)
    assert m.read32(RCC + 0x44) == 0x04F7_7F33
    sim.close()


def test_gpio_ports_a_and_b_reset_with_the_debug_pins_in_alternate_function_and_pulled():
    """RM0385 §6.4 reset values: MODER 0xA800_0000 (port A) and 0x0000_0280 (port B), OSPEEDR
    0x0C00_0000 and 0x0000_00C0, PUPDR 0x6400_0000 and 0x0000_0100, 0 for the other ports (every
    register had read 0). The pulls act: PA13 (SWDIO, pull-up) and PA15 read 1 in IDR, PA14
    (SWCLK, pull-down) 0."""
    sim = mcusim.load("nucleo-f746", firmware=False)
    m = sim.mcu
    regs = lambda base: [m.read32(base + off) for off in (0x00, 0x08, 0x0C)]
    assert regs(GPIOA) == [0xA800_0000, 0x0C00_0000, 0x6400_0000]
    assert regs(GPIOA + 0x400) == [0x0000_0280, 0x0000_00C0, 0x0000_0100]
    assert regs(GPIOE) == [0, 0, 0]
    assert m.read32(GPIOA + 0x10) & 0xE000 == 0xA000
    sim.close()
