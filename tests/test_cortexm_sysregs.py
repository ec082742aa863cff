"""System registers a compiled image's start-up and HAL code touch: SCB (Armv7-M ARM B3.2), DWT,
and the STM32F7's RCC ready flags, PLL, flash ACR and PWR (RM0385 §3.7, §4.4, §5.3)."""

from __future__ import annotations

from pathlib import Path

import pytest

import mcusim
from mcusim.errors import UnsupportedConfiguration
from mcusim.irq import PENDSV

TICKS = str(Path(__file__).parent / "elf_bin" / "ticks.elf")


@pytest.fixture
def sim():
    s = mcusim.load("nucleo-f746", firmware=TICKS)
    yield s
    s.close()


def test_cpuid_is_the_stm32f746s_cortex_m7_r0p1(sim):
    """ES0290: the STM32F74x/75x embed Cortex-M7 r0p1: CPUID 0x410FC271 (implementer 0x41,
    variant 0, architecture 0xF, part 0xC27, revision 1), the value FreeRTOS's ARM_CM4F port
    asserts against on these parts. It had read 0x411FC270 (r1p0)."""
    assert sim.mcu.read32(0xE000ED00) == 0x410FC271


def test_vtor_resets_to_the_boot_address_and_moves_the_vector_table(sim):
    assert sim.mcu.read32(0xE000ED08) == 0x00200000
    sim.mcu.write32(0xE000ED08, 0x08000000)
    assert sim.mcu.cpu.exc.vtor == 0x08000000


def test_aircr_needs_its_key_and_sets_prigroup(sim):
    sim.mcu.write32(0xE000ED0C, 5 << 8)                       # no VECTKEY: ignored
    assert sim.mcu.read32(0xE000ED0C) == 0xFA05_0000
    sim.mcu.write32(0xE000ED0C, (0x05FA << 16) | (5 << 8))
    assert sim.mcu.read32(0xE000ED0C) == 0xFA05_0500 and sim.mcu.cpu.exc.prigroup == 5
    with pytest.raises(UnsupportedConfiguration, match="SYSRESETREQ"):
        sim.mcu.write32(0xE000ED0C, (0x05FA << 16) | 4)


def test_prigroup_splits_group_and_subpriority(sim):
    exc = sim.mcu.cpu.exc
    sim.mcu.nvic.set_priority(0, 0b0110)     # 4 bits: 0x60
    exc.prigroup = 4                          # group = bits [7:5]: 0x60 >> 5 = 3
    assert exc.group(0b0110) == 3
    exc.prigroup = 6                          # group = bit 7 only
    assert exc.group(0b0110) == 0


def test_icsr_pends_and_clears_pendsv(sim):
    sim.mcu.write32(0xE000ED04, 1 << 28)
    assert PENDSV in sim.mcu.nvic.pending and sim.mcu.read32(0xE000ED04) & (1 << 28)
    sim.mcu.write32(0xE000ED04, 1 << 27)
    assert PENDSV not in sim.mcu.nvic.pending


def test_shpr3_sets_the_priorities_of_pendsv_and_systick(sim):
    sim.mcu.write32(0xE000ED20, (0xF0 << 16) | (0x30 << 24) | 0xFFFF)
    assert sim.mcu.nvic.priority[-2] == 0xF and sim.mcu.nvic.priority[-1] == 0x3
    # 4 implemented bits keep the top nibble; byte 1 (exception 13) is reserved and reads 0
    assert sim.mcu.read32(0xE000ED20) == (0xF0 << 16) | (0x30 << 24) | 0xF0


def test_dwt_cyccnt_counts_core_cycles_only_while_enabled(sim):
    sim.mcu.write32(0xE000EDFC, 1 << 24)                      # DEMCR.TRCENA powers the DWT
    sim.mcu.write32(0xE0001000, 1)
    sim.run(cycles=1000)
    assert sim.mcu.read32(0xE0001004) == 1000
    sim.mcu.write32(0xE0001000, 0)
    sim.run(cycles=500)
    assert sim.mcu.read32(0xE0001004) == 1000


def test_rcc_ready_flags_follow_their_enables(sim):
    cr = sim.mcu.read32(0x40023800)
    assert cr & (1 << 25) and cr & (1 << 17)                  # PLLRDY, HSERDY: as SystemClock_Config left them
    sim.mcu.write32(0x40023800, cr & ~(1 << 24))              # PLLON = 0
    assert not sim.mcu.read32(0x40023800) & (1 << 25)


def test_the_pll_may_be_programmed_only_to_the_boards_sysclk(sim):
    # RM0385 §5.3.2: f = src / PLLM * PLLN / PLLP; HSE 8 MHz / 8 * 432 / 2 = 216 MHz
    sim.mcu.write32(0x40023804, 8 | (432 << 6) | (1 << 22) | (9 << 24))
    with pytest.raises(UnsupportedConfiguration, match="PLLCFGR.*200 MHz"):
        sim.mcu.write32(0x40023804, 8 | (400 << 6) | (1 << 22) | (9 << 24))


def test_flash_acr_and_pwr_ready_flags(sim):
    assert sim.mcu.read32(0x40023C00) & 0xF == 7              # 7 wait states at 216 MHz
    sim.mcu.write32(0x40023C00, 0x307)                        # PRFTEN, ARTEN
    assert sim.mcu.read32(0x40023C00) == 0x307
    assert sim.mcu.read32(0x40007004) == (1 << 14) | (1 << 16) | (1 << 17)
    sim.mcu.write32(0x40007000, 0b11 << 14)                   # over-drive off
    assert sim.mcu.read32(0x40007004) == 1 << 14
