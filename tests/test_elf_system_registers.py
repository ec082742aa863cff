"""The system registers CMSIS start-up and HAL code read and write besides the SCB's exception
registers: cache identification and maintenance (Cortex-M7), MPU, ICTR/ACTLR, ITM, and the
STM32F7's DBGMCU and device signature. Accessed through the bus as the core's loads and stores
reach them (a CubeMX F7 main calls SCB_EnableICache/DCache and often MPU_Config first; USB
descriptors read the unique ID)."""

from __future__ import annotations

import pytest
from elf_build import BIN

import mcusim
from mcusim.errors import BusFault, UnsupportedConfiguration


@pytest.fixture(scope="module")
def bus():
    sim = mcusim.load("nucleo-f746", firmware=str(BIN / "ticks.elf"))
    yield sim.mcu.bus
    sim.close()


def _ccsidr_fields(v):
    return {"sets": ((v >> 13) & 0x7FFF) + 1, "ways": ((v >> 3) & 0x3FF) + 1, "line_bytes": 16 << (v & 7)}


def test_ccsidr_gives_the_stm32f746_l1_caches_as_csselr_selects_them(bus):
    # STM32F74x: 4 KB instruction and 4 KB data cache (RM0385 §1, §2.1); the Cortex-M7's L1 caches
    # have 32-byte lines, the instruction cache 2 ways and the data cache 4 (Cortex-M7 TRM)
    bus.write(0xE000ED84, 0, 4)                       # CSSELR: level 1, data
    d = _ccsidr_fields(bus.read(0xE000ED80, 4))
    assert d == {"sets": 32, "ways": 4, "line_bytes": 32}
    assert d["sets"] * d["ways"] * d["line_bytes"] == 4096
    bus.write(0xE000ED84, 1, 4)                       # InD = 1: the instruction cache
    i = _ccsidr_fields(bus.read(0xE000ED80, 4))
    assert i == {"sets": 64, "ways": 2, "line_bytes": 32}
    bus.write(0xE000ED84, 1 << 1, 4)                  # level 2: none
    assert bus.read(0xE000ED80, 4) == 0
    bus.write(0xE000ED84, 0, 4)


def test_clidr_and_ctr_say_separate_level_1_caches_of_8_word_lines(bus):
    clidr, ctr = bus.read(0xE000ED78, 4), bus.read(0xE000ED7C, 4)
    assert clidr & 7 == 0b011                         # Ctype1: separate instruction and data caches
    assert (clidr >> 24) & 7 == 1 and (clidr >> 27) & 7 == 1    # LoC, LoUU: level 1
    assert ctr >> 29 == 0b100                         # the Armv7 format
    assert ctr & 0xF == 3 and (ctr >> 16) & 0xF == 3  # IminLine, DminLine: log2(8 words)


def test_cache_maintenance_operations_are_write_only_registers_the_set_way_loop_can_write(bus):
    # SCB_EnableDCache: one DCISW write per set and way, from CCSIDR (0xE000EF60); ICIALLU, BPIALL
    bus.write(0xE000ED84, 0, 4)
    f = _ccsidr_fields(bus.read(0xE000ED80, 4))
    for s in range(f["sets"]):
        for w in range(f["ways"]):
            bus.write(0xE000EF60, (s << 5) | (w << 30), 4)
    for address in (0xE000EF50, 0xE000EF78, 0xE000EF70, 0xE000EF68):
        bus.write(address, 0x20000000, 4)


def test_mpu_type_counts_8_regions_and_rbar_with_valid_selects_its_region(bus):
    assert (bus.read(0xE000ED90, 4) >> 8) & 0xFF == 8          # MPU_TYPE.DREGION
    bus.write(0xE000ED98, 2, 4)                                 # RNR = 2
    bus.write(0xE000EDA0, 0x0306002B, 4)                        # RASR of region 2
    bus.write(0xE000ED9C, 0x20010000 | 0x10 | 5, 4)             # RBAR: VALID, REGION = 5
    assert bus.read(0xE000ED98, 4) == 5                         # RNR followed REGION (B3.5.9)
    assert bus.read(0xE000ED9C, 4) == 0x20010000 | 5            # ADDR and the region number
    assert bus.read(0xE000EDA0, 4) == 0                         # region 5's RASR, not region 2's
    bus.write(0xE000ED98, 2, 4)
    assert bus.read(0xE000EDA0, 4) == 0x0306002B
    assert bus.read(0xE000EDA8, 4) == 0x0306002B                # the A1 alias reads the same region
    bus.write(0xE000ED94, 0b101, 4)                             # CTRL: ENABLE, PRIVDEFENA (HAL_MPU_Enable)
    assert bus.read(0xE000ED94, 4) == 0b101
    bus.write(0xE000ED94, 0, 4)


def test_an_mpu_region_number_beyond_the_eight_is_refused_naming_it(bus):
    with pytest.raises(UnsupportedConfiguration, match="RNR.*REGION"):
        bus.write(0xE000ED98, 8, 4)


def test_ictr_counts_the_nvic_lines_in_groups_of_32(bus):
    # nucleo-f746 declares 98 lines: INTLINESNUM = 3 (97 to 128 lines), B3.4.3
    assert bus.read(0xE000E004, 4) & 0xF == 3


def test_itm_stimulus_port_reads_ready_so_itm_sendchar_never_waits(bus):
    bus.write(0xE0000E80, 1, 4)                       # TCR.ITMENA
    bus.write(0xE0000E00, 1, 4)                       # TER: port 0
    assert bus.read(0xE0000E80, 4) == 1
    assert bus.read(0xE0000000, 4) & 1 == 1           # FIFOREADY
    bus.write(0xE0000000, ord("A"), 1)                # the character goes nowhere


def test_dbgmcu_idcode_names_the_stm32f74x_device(bus):
    # RM0385 DBGMCU_IDCODE: DEV_ID 0x449 for the STM32F74xxx/75xxx
    assert bus.read(0xE0042000, 4) & 0xFFF == 0x449


def test_the_device_signature_gives_a_96_bit_unique_id_and_the_flash_size_in_kbytes(bus):
    uid = [bus.read(0x1FF0F420 + 4 * k, 4) for k in range(3)]
    assert any(uid) and uid == [bus.read(0x1FF0F420 + 4 * k, 4) for k in range(3)]
    assert bus.read(0x1FF0F442, 2) == 1024            # STM32F746ZG: 1 Mbyte of flash


def test_a_cortex_m4_has_no_caches_clidr_reads_0_and_no_maintenance_registers():
    sim = mcusim.load("ciaa-edu", firmware=str(BIN / "lpc_ticks.elf"))
    try:
        assert sim.mcu.bus.read(0xE000ED78, 4) == 0
        assert (sim.mcu.bus.read(0xE000ED90, 4) >> 8) & 0xFF == 8    # its MPU has 8 regions
        with pytest.raises(BusFault):
            sim.mcu.bus.write(0xE000EF50, 0, 4)
    finally:
        sim.close()
