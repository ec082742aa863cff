"""The LPC4337's system blocks an LPCOpen image's start-up and drivers touch (CGU, CCU1/CCU2, SCU,
CREG, RGU; UM10503), through the bus as the core's loads and stores reach them: reset values (the
state Chip_SetupCoreClock leaves), status bits that follow their enables at once, the core clock
held to the board's 204 MHz, the boot shadow, reset completion."""

from __future__ import annotations

import pytest
from elf_build import BIN, build, gcc

import mcusim
from mcusim.errors import BusFault, UnsupportedConfiguration

CGU, CCU1, CCU2, RGU, SCU, CREG = 0x40050000, 0x40051000, 0x40052000, 0x40053000, 0x40086000, 0x40043000
PLL1_STAT, PLL1_CTRL, BASE_M4_CLK = CGU + 0x40, CGU + 0x44, CGU + 0x6C
PLL1_204_DIRECT = 0x0610_0080          # crystal, M = 17, N = 1, DIRECT


@pytest.fixture
def sim():
    s = mcusim.load("ciaa-edu", firmware=str(BIN / "lpc_ticks.elf"))
    yield s
    s.close()


def rd(sim, a):
    return sim.mcu.bus.read(a, 4)


def wr(sim, a, v):
    sim.mcu.bus.write(a, v, 4)


def test_reset_values_are_the_state_lpcopen_clock_setup_leaves(sim):
    assert rd(sim, CGU + 0x18) == 0x4                    # XTAL_OSC_CTRL: crystal on, no bypass
    assert rd(sim, PLL1_CTRL) == PLL1_204_DIRECT
    assert rd(sim, PLL1_STAT) == 1                       # locked
    assert rd(sim, BASE_M4_CLK) == 0x0900_0800           # PLL1, AUTOBLOCK
    assert rd(sim, CGU + 0x80) >> 24 == 0x09             # BASE_APB1_CLK (I2C0) on PLL1
    assert rd(sim, CGU + 0xA4) >> 24 == 0x09             # BASE_UART2_CLK
    cgu = sim.mcu.periph["CGU"]
    assert cgu.pll1_hz(rd(sim, PLL1_CTRL)) == 204_000_000
    assert rd(sim, CCU1 + 0x410) == 1 and rd(sim, CCU1 + 0x414) == 1     # CLK_M4_GPIO runs
    assert rd(sim, CCU1 + 0x004) == 0 and rd(sim, CCU2 + 0x004) == 0     # BASE_STAT: no base idle
    assert rd(sim, SCU + 0x304) == 0                     # SFSP6_1
    assert rd(sim, CREG + 0x200) == 0x4906002B           # CHIPID: LPC43xx with flash
    assert rd(sim, CREG + 0x100) == 0x1A000000           # M4MEMMAP: flash bank A
    assert rd(sim, RGU + 0x150) == 0xFFFF_FFFF
    assert rd(sim, RGU + 0x154) == 0xFEFF_FFFF           # M0APP held in reset
    assert rd(sim, RGU + 0x100) == 0                     # RESET_CTRL0: write-only


def test_pll1_lock_follows_its_power_down_bit_at_once(sim):
    wr(sim, BASE_M4_CLK, 0x0600_0800)                    # the core on the crystal first, as LPCOpen
    wr(sim, PLL1_CTRL, PLL1_204_DIRECT | 1)
    assert rd(sim, PLL1_STAT) & 1 == 0
    wr(sim, PLL1_CTRL, PLL1_204_DIRECT)
    assert rd(sim, PLL1_STAT) & 1 == 1


def test_pll0_status_reads_locked_once_powered_up(sim):
    assert rd(sim, CGU + 0x1C) == 0                      # PLL0USB_STAT: powered down after reset
    wr(sim, CGU + 0x20, 0x0600_0000)                     # PLL0USB_CTRL: crystal, PD = 0
    assert rd(sim, CGU + 0x1C) == 0b11                   # LOCK, FR
    assert rd(sim, CGU + 0x2C) == 0                      # PLL0AUDIO untouched


def test_a_pll1_setting_that_does_not_give_204_mhz_is_refused_naming_register_and_frequency(sim):
    with pytest.raises(UnsupportedConfiguration, match=r"PLL1_CTRL.*216 MHz.*204 MHz"):
        wr(sim, PLL1_CTRL, 0x0611_0080)                  # M = 18: 216 MHz while BASE_M4_CLK selects PLL1
    assert rd(sim, PLL1_CTRL) == PLL1_204_DIRECT         # a refused write leaves the register
    with pytest.raises(UnsupportedConfiguration, match="PLL1_CTRL"):
        wr(sim, PLL1_CTRL, PLL1_204_DIRECT | 1)          # powering PLL1 down under the core


def test_pll1_is_free_while_the_core_runs_on_another_clock_then_checked_when_selected(sim):
    wr(sim, BASE_M4_CLK, 0x0600_0800)                    # crystal
    wr(sim, PLL1_CTRL, 0x0613_0080)                      # 240 MHz: not selected, stored
    with pytest.raises(UnsupportedConfiguration, match=r"BASE_M4_CLK.*240 MHz"):
        wr(sim, BASE_M4_CLK, 0x0900_0800)
    wr(sim, PLL1_CTRL, 0x0610_0000)                      # DIRECT clear, P = 1: 102 MHz, the ramp step
    wr(sim, BASE_M4_CLK, 0x0900_0800)
    wr(sim, PLL1_CTRL, PLL1_204_DIRECT)
    with pytest.raises(UnsupportedConfiguration, match="BASE_M4_CLK"):
        wr(sim, BASE_M4_CLK, 0x0C00_0800)                # IDIVA (IRC / 1): 12 MHz is not a start-up clock


def test_ccu_branch_status_follows_its_configuration_at_once(sim):
    wr(sim, CCU1 + 0x520, 0)                             # CLK_M4_TIMER0_CFG: off
    assert rd(sim, CCU1 + 0x524) == 0
    wr(sim, CCU1 + 0x520, 0b111)                         # RUN, AUTO, WAKEUP
    assert rd(sim, CCU1 + 0x524) == 0b111
    wr(sim, CCU1 + 0x000, 1)                             # PM.PD: branches with WAKEUP stop
    assert rd(sim, CCU1 + 0x524) == 0b110
    wr(sim, CCU1 + 0x000, 0)
    wr(sim, CCU2 + 0x300, 0)                             # CLK_APB2_USART2: the only branch of BASE_UART2
    assert rd(sim, CCU2 + 0x304) == 0
    assert rd(sim, CCU2 + 0x004) == 1 << 2               # BASE_STAT: UART2's branches all off


def test_scu_pin_configuration_is_stored(sim):
    wr(sim, SCU + 0x304, 0x50)                           # SFSP6_1
    wr(sim, SCU + 0xC84, 0x0808)                         # SFSI2C0
    assert rd(sim, SCU + 0x304) == 0x50 and rd(sim, SCU + 0xC84) == 0x0808
    with pytest.raises(BusFault):
        rd(sim, SCU + 0x008)                             # P0_2 does not exist


def test_creg_boot_shadow_may_not_move(sim):
    wr(sim, CREG + 0x100, 0x1A000000)                    # what the board maps: accepted
    with pytest.raises(UnsupportedConfiguration, match=r"M4MEMMAP.*0x1a000000"):
        wr(sim, CREG + 0x100, 0x10000000)
    wr(sim, CREG + 0x200, 0)                             # CHIPID is read only
    assert rd(sim, CREG + 0x200) == 0x4906002B


def test_rgu_reset_completes_at_once_and_resets_the_modelled_block(sim):
    adc = sim.mcu.periph["ADC0"]
    sim.mcu.bus.write(0x400E3000, 0x0020_0401, 4)        # ADC0 CR: PDN, CLKDIV, SEL
    wr(sim, RGU + 0x104, 1 << (40 - 32))                 # ADC0_RST
    assert rd(sim, RGU + 0x154) & (1 << 8)               # not in reset: Chip_RGU_InReset is false
    assert adc.value["CR"] == 0
    assert (rd(sim, RGU + 0x118) >> 16) & 3 == 0b11      # RESET_STATUS2: reset 40 by software
    wr(sim, RGU + 0x104, 1 << 0)                         # TIMER0_RST: no model, nothing to do
    assert rd(sim, RGU + 0x154) & 1


def test_rgu_refuses_what_it_cannot_reset(sim):
    with pytest.raises(UnsupportedConfiguration, match="USART2_RST"):
        wr(sim, RGU + 0x104, 1 << (46 - 32))
    with pytest.raises(UnsupportedConfiguration, match="I2C0_RST"):
        wr(sim, RGU + 0x104, 1 << (48 - 32))
    with pytest.raises(UnsupportedConfiguration, match="CORE_RST"):
        wr(sim, RGU + 0x100, 1)


@pytest.mark.skipif(gcc() is None, reason="arm-none-eabi-gcc is not installed")
def test_an_lpcopen_like_clock_pin_and_reset_setup_runs_to_the_end_of_main(tmp_path):
    elf = build("lpc_clocks", tmp_path)
    s = mcusim.load("ciaa-edu", firmware=str(elf))
    try:
        s.run(seconds=0.001)
        assert s.mcu.read32(s.firmware.symbols["done"]) == 5
        assert s.mcu.read32(s.firmware.symbols["chipid"]) == 0x4906002B
        assert s.mcu.bus.read(PLL1_CTRL, 4) & 0x80       # DIRECT: 204 MHz
        assert s.mcu.periph["RGU"].reset_count == 2
    finally:
        s.close()


def test_freq_mon_measures_pll1_against_the_irc_at_once(sim):
    wr(sim, CGU + 0x14, (0x09 << 24) | (1 << 23) | 0x1FF)    # PLL1, MEAS, RCNT = 511 IRC cycles
    v = rd(sim, CGU + 0x14)
    assert (v >> 23) & 1 == 0 and v & 0x1FF == 0
    assert (v >> 9) & 0x3FFF == 511 * 17                      # 204 MHz / 12 MHz


# --- the core's clock chain (found by an adversarial test: each was accepted, the core ran on) ---
XTAL_OSC_CTRL, IDIVA_CTRL, FREQ_MON = CGU + 0x18, CGU + 0x48, CGU + 0x14


def test_the_crystal_switched_off_under_the_core_is_refused_directly_and_through_pll1(sim):
    with pytest.raises(UnsupportedConfiguration, match=r"XTAL_OSC_CTRL.*0 MHz from PLL1"):
        wr(sim, XTAL_OSC_CTRL, 0x5)                      # ENABLE = 1 powers it down; PLL1 runs on it
    assert rd(sim, XTAL_OSC_CTRL) == 0x4 and rd(sim, PLL1_STAT) == 1
    wr(sim, BASE_M4_CLK, 0x0600_0800)                    # the core on the crystal itself
    with pytest.raises(UnsupportedConfiguration, match=r"XTAL_OSC_CTRL.*0 MHz from crystal"):
        wr(sim, XTAL_OSC_CTRL, 0x5)


def test_an_integer_divider_feeding_the_core_is_held_to_the_core_clock(sim):
    wr(sim, IDIVA_CTRL, 0x0900_0800)                     # IDIVA = PLL1 / 1: 204 MHz
    wr(sim, BASE_M4_CLK, 0x0C00_0800)                    # the core on IDIVA
    with pytest.raises(UnsupportedConfiguration, match=r"IDIVA_CTRL.*102 MHz from IDIVA"):
        wr(sim, IDIVA_CTRL, 0x0900_0804)                 # / 2
    with pytest.raises(UnsupportedConfiguration, match=r"PLL1_CTRL.*0 MHz"):
        wr(sim, PLL1_CTRL, PLL1_204_DIRECT | 1)          # PLL1 powered down under the divider


@pytest.mark.parametrize("ctrl, cco", [(0x0610_0040, 408), (0x0621_0000, 408), (0x0610_1080, 102)])
def test_pll1_with_its_cco_outside_156_to_320_mhz_is_refused(sim, ctrl, cco):
    # UM10503: the CCO runs from 156 to 320 MHz. Integer mode M = 17, N = 1, P = 1 and non-integer
    # M = 34, N = 1, P = 1 both give 204 MHz out with a 408 MHz CCO; direct M = 17, N = 2 is 102 MHz
    wr(sim, BASE_M4_CLK, 0x0600_0800)                    # off PLL1: only the range decides
    with pytest.raises(UnsupportedConfiguration, match=rf"PLL1_CTRL.*CCO at {cco} MHz.*156-320"):
        wr(sim, PLL1_CTRL, ctrl)
    wr(sim, PLL1_CTRL, 0x0621_1080)                      # direct, M = 34, N = 2: CCO 204 MHz


def test_a_transitional_core_clock_is_refused_once_it_has_lasted_2_ms(sim):
    wr(sim, BASE_M4_CLK, 0x0100_0800)                    # IRC, as LPCOpen while it reprograms PLL1
    sim.run(seconds="1ms")
    wr(sim, BASE_M4_CLK, 0x0900_0800)                    # back on PLL1 in time
    sim.run(seconds="3ms")
    wr(sim, BASE_M4_CLK, 0x0100_0800)
    with pytest.raises(UnsupportedConfiguration, match=r"12 MHz from IRC for 2 ms"):
        sim.run(seconds="3ms")
    assert sim.time_s == pytest.approx(0.006, abs=1e-9)


def test_the_cores_own_branch_clock_cannot_be_stopped(sim):
    with pytest.raises(UnsupportedConfiguration, match="CLK_M4_M4CORE_CFG.*core would stop"):
        wr(sim, CCU1 + 0x448, 0)
    assert rd(sim, CCU1 + 0x448) & 1 and rd(sim, CCU1 + 0x44C) & 1


def test_freq_mon_counts_nothing_from_the_32_khz_oscillator_while_creg0_holds_it_off(sim):
    assert rd(sim, CREG + 0x4) & 0b1100                  # CREG0 after reset: RESET32KHZ, PD32KHZ
    wr(sim, FREQ_MON, (1 << 23) | 0x1FF)                 # CLK_SEL 0: the 32 kHz oscillator
    assert (rd(sim, FREQ_MON) >> 9) & 0x3FFF == 0
    wr(sim, CREG + 0x4, rd(sim, CREG + 0x4) & ~0b1100)
    wr(sim, FREQ_MON, (1 << 23) | 0x1FF)
    assert (rd(sim, FREQ_MON) >> 9) & 0x3FFF == 511 * 32768 // 12_000_000


ADC0, USART3 = 0x400E3000, 0x400C2000


def test_a_peripheral_whose_base_clock_no_longer_gives_its_clock_refuses_to_run(sim):
    """UM10503 clock tables: ADC0/1 run on BASE_APB3_CLK, USART3 on BASE_UART3_CLK. The models run
    at the board's 204 MHz whatever the CGU says; a base clock moved to the 12 MHz crystal (as
    NuttX's lpc4337-ws set-up does for APB3) or powered down had left the ADC converting and the
    USART framing at 204 MHz without a word. The move itself is accepted (a firmware may move the
    clock of a peripheral it does not use); the peripheral refuses when it starts."""
    wr(sim, CGU + 0x84, 0x0600_0800)                      # BASE_APB3_CLK: crystal
    wr(sim, USART3 + 0x00, 0x41)                          # THR: USART3's base clock is still PLL1
    sim.run(seconds="200us")
    with pytest.raises(UnsupportedConfiguration, match=r"CGU\.BASE_APB3_CLK = 0x6000800 selects crystal "
                       r"oscillator, 12 MHz: ADC0 runs on it.*204 MHz"):
        wr(sim, ADC0 + 0x00, (1 << 24) | (1 << 21) | (49 << 8) | 1)   # CR: START now, PDN, channel 0
    assert rd(sim, ADC0 + 0x00) == 0                      # the refused write left CR as it was
    wr(sim, CGU + 0x84, 0x0900_0800)                      # back on PLL1: converts
    sim.mcu.analog["DAC"].set(1.0)                        # (channel 0: nothing is wired to it)
    wr(sim, ADC0 + 0x00, (1 << 24) | (1 << 21) | (49 << 8) | 1)
    sim.run(seconds="50us")
    assert rd(sim, ADC0 + 0x04) >> 31 == 1               # GDR.DONE
    wr(sim, CGU + 0xA8, 0x0900_0801)                      # BASE_UART3_CLK powered down
    with pytest.raises(UnsupportedConfiguration, match=r"BASE_UART3_CLK = 0x9000801 is powered down: USART3"):
        wr(sim, USART3 + 0x00, 0x42)
    assert not sim.mcu.periph["USART3"]._txq               # the byte was not queued either


def test_converting_a_channel_nothing_drives_warns_that_it_reads_0_v(sim):
    """ciaa-edu wires only CH1 (the battery divider); ADC0's channels 0, 2 and 3 are open pins,
    whose reading is undefined on the chip. Converting one warns once (an error with strict) that
    the 0 V it reads stands for nothing; a channel set from Python or wired does not warn."""
    import warnings

    from mcusim.periph.lpc43xx.adc import AdcInputWarning
    wr(sim, ADC0 + 0x00, (1 << 24) | (1 << 21) | (49 << 8) | (1 << 2))
    with pytest.warns(AdcInputWarning, match=r"ADC0: channel 2 \(CH2\) is converted but nothing drives it"):
        sim.run(seconds="20us")
    sim.mcu.analog["CH3"].set(1.5)
    with warnings.catch_warnings():
        warnings.simplefilter("error", AdcInputWarning)
        wr(sim, ADC0 + 0x00, (1 << 24) | (1 << 21) | (49 << 8) | (1 << 3))
        sim.run(seconds="20us")
        wr(sim, ADC0 + 0x00, (1 << 24) | (1 << 21) | (49 << 8) | (1 << 1))   # CH1: the divider
        sim.run(seconds="20us")
