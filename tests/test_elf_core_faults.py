"""Faults of the instruction stream and of device accesses, with tests/elf_src/corefaults.c (a call
through the pointer `target` the host sets, or an unaligned peripheral access, chosen by `which`)
and tests/elf_src/itcm.c. References: Armv7-M Architecture Reference Manual (ARM DDI 0403E) B3.1
(the default memory map: which regions are Execute Never), A7.3.1 and B1.4.2 (EPSR.T, INVSTATE),
A3.2.1 (unaligned accesses); Cortex-M7 TRM (unaligned accesses to Device memory fault)."""

from __future__ import annotations

import sys

import pytest
from elf_build import BIN

import mcusim
from mcusim.elf.core import CoreFault


def run(which, target=0, seconds="50us", image="corefaults"):
    sim = mcusim.load("nucleo-f746", firmware=str(BIN / f"{image}.elf"),
                      overrides={"/which": which, "/target": target} if image == "corefaults" else {})
    sim.run(seconds=seconds)
    return sim


def fault(which, target=0, seconds="50us"):
    with pytest.raises(CoreFault) as info:
        run(which, target, seconds)
    return str(info.value)


# --- B3.1: Peripheral, Device and System regions are Execute Never ------------------------------------
@pytest.mark.parametrize("target, region", [(0x40000401, "Peripheral"), (0xE000E011, "System"),
                                            (0xA0000001, "Device")])
def test_a_branch_into_an_execute_never_region_is_a_fault_at_the_fetch_address(target, region):
    text = fault(1, target)
    assert f"instruction fetch from {target - 1:#010x}, in the {region} region" in text
    assert "Execute Never" in text and f"at PC {target - 1:#010x}" in text


def test_a_branch_to_an_address_with_no_memory_is_a_fault_at_the_fetch_address():
    text = fault(1, 0x60000001)
    assert "instruction fetch from unmapped memory at 0x60000000" in text and "at PC 0x60000000" in text


# --- B3.1: code may run from any executable memory, address 0 (the ITCM RAM) included -------------------
def test_code_in_itcm_ram_at_address_0_runs():
    sim = run(0, image="itcm")
    assert sim.mcu.cpu.state == "sleep"
    assert sim.mcu.read32(sim.firmware.symbols["calls"]) == 3
    assert sim.firmware.symbols["fast"] & ~1 == 0


def test_a_branch_to_an_address_with_no_memory_near_0_is_a_fault_at_that_address():
    text = fault(1, 0x00004001)
    assert "instruction fetch from unmapped memory at 0x00004000" in text and "at PC 0x00004000" in text


# --- running off the end of a memory: the fault is the fetch where the memory ends ----------------------
def test_a_call_to_address_0_runs_what_the_itcm_ram_holds_and_faults_at_its_end():
    """A call to 0x00000001 (Thumb, address 0): the ITCM RAM holds zeros (MOVS r0, r0), the core
    runs them up to the end of the 16 KB, where the fetch from no memory is the fault, naming that
    address. (A call through a NULL pointer is another fault: bit 0 clear, see below.)"""
    text = fault(1, 1, seconds="200us")
    assert "instruction fetch from unmapped memory at 0x00004000" in text and "at PC 0x00004000" in text


def test_running_off_the_end_of_the_flash_is_a_fault_at_the_first_address_past_it():
    text = fault(1, 0x080FFF01)
    assert "instruction fetch from unmapped memory at 0x08100000" in text and "at PC 0x08100000" in text


# --- A7.3.1, B1.4.2: a branch with bit 0 clear clears EPSR.T; the next instruction is an INVSTATE fault --
@pytest.mark.parametrize("target", ["landing", 0x20000000, 0])
def test_a_branch_to_an_even_address_is_an_invalid_state_fault_naming_the_caller(target):
    """Bit 0 clear: to a function's own address, to RAM, and a call through a NULL pointer (which
    on a Cortex-M is this fault, whatever memory is at 0)."""
    if isinstance(target, str):
        sim = mcusim.load("nucleo-f746", firmware=str(BIN / "corefaults.elf"))
        target = sim.firmware.symbols[target]
        sim.close()
    address = target & ~1
    text = fault(1, address)
    assert "invalid state" in text and "INVSTATE" in text and f"at PC {address:#010x}" in text
    assert "(call_target+0x" in text                     # LR: the caller, after its BLX
    assert "undefined instruction" not in text


# --- A3.2.1: unaligned accesses to Device memory fault (Cortex-M7 TRM); not split into two ------------
@pytest.mark.parametrize("which, what, function", [(2, "unaligned 32-bit read of 0x40000402 (TIM3)", "unaligned_read"),
                                                   (3, "unaligned 16-bit write to 0x40000405 (TIM3)", "unaligned_write")])
def test_an_unaligned_peripheral_access_is_a_fault_naming_address_size_and_block(which, what, function, tmp_path):
    from mcusim.reglog import load_logged
    path = tmp_path / "regs.jsonl"
    sim, _ = load_logged("nucleo-f746", str(path), firmware=str(BIN / "corefaults.elf"),
                         overrides={"/which": which})
    with pytest.raises(CoreFault) as info:
        sim.run(seconds="50us")
    sim.close()
    assert what in str(info.value) and f"({function}+0x" in str(info.value)
    assert "TIM3" not in path.read_text()              # no register of the block was accessed


@pytest.mark.parametrize("address, kind, hint", [
    (0x40084004, "cortex-m4", "Peripheral region: a peripheral this board does not model"),   # LPC TIMER0
    (0x4000480C, "cortex-m7", "Peripheral region: a peripheral this board does not model"),   # STM32 USART3
    (0x22002014, "cortex-m4", "a bit-band alias: bit-banding is not modelled"),
    (0x42000000, "cortex-m4", "a bit-band alias"),
    (0x22002014, "cortex-m7", ""),          # the Cortex-M7 has no bit-banding: just unmapped
    (0xE0001000 + 0x200, "cortex-m7", "a Cortex-M system register mcusim does not model"),
    (0x60000000, "cortex-m7", ""),          # external RAM region: no guess
])
def test_an_unmapped_access_says_what_the_default_memory_map_has_there(address, kind, hint):
    """Armv7-M B3.1: 0x40000000-0x5FFFFFFF is the Peripheral region, 0xE0000000-0xE00FFFFF the
    private peripheral bus; the Cortex-M4 maps bit-band aliases at 0x22000000 and 0x42000000. A
    review's images writing LPC TIMER0, STM32 USART3 or a bit-band alias had been told only
    "unmapped memory", which points at the user's pointer rather than at the model."""
    from mcusim.elf.faults import unmapped_hint
    got = unmapped_hint(address, kind)
    assert (hint in got and got) if hint else got == ""


# --- fault traps the core cannot honour: refused where the image sets them, not a fault of it -----------
@pytest.mark.parametrize("value, field", [(0x210, "DIV_0_TRP"), (0x208, "UNALIGN_TRP")])
def test_setting_a_fault_trap_stops_the_run_naming_the_bit_and_the_writer_not_as_a_hardfault(value, field):
    """SCB.CCR DIV_0_TRP and UNALIGN_TRP (Armv7-M B3.2.8) would make a division by zero or an
    unaligned access a UsageFault; the core cannot trap either without a hook on every instruction,
    so the write is refused as an unsupported configuration naming the bit, its reason and the
    instruction that wrote it. (It had been reported as a 'HardFault' of the image.)"""
    from mcusim.errors import UnsupportedConfiguration
    code = bytes.fromhex("0248" "0349" "0160" "7047" "00bf" "00bf") + (0xE000ED14).to_bytes(4, "little") \
        + value.to_bytes(4, "little")   # ldr r0,=CCR; ldr r1,=value; str r1,[r0]; bx lr
    sim = mcusim.load("nucleo-f746", firmware=str(BIN / "corefaults.elf"), overrides={"/which": 1, "/target": 0x3001})
    sim.firmware.core.write(0x3000, code)          # into the ITCM RAM, where code may run
    with pytest.raises(UnsupportedConfiguration) as info:
        sim.run(seconds="50us")
    text = str(info.value)
    assert f"SCB.CCR.{field} = 0x1 is not modelled (the core cannot trap" in text
    assert "(the access at PC 0x00003004" in text and "HardFault" not in text


# --- B3.2: the System Control Space is for privileged software -------------------------------------------
def test_an_unprivileged_read_of_the_system_control_space_is_a_bus_fault():
    """Armv7-M B3.2: 'unprivileged access to the SCS ... causes a BusFault'. Thread mode after
    CONTROL.nPRIV = 1 read SCB->CPUID (and wrote SysTick) as if privileged."""
    code = bytes.fromhex("0120" "80f31488" "bff36f8f" "0149" "0a68" "7047") + (0xE000ED00).to_bytes(4, "little")
    # movs r0,#1; msr CONTROL,r0; isb; ldr r1,=SCB->CPUID; ldr r2,[r1]; bx lr
    sim = mcusim.load("nucleo-f746", firmware=str(BIN / "corefaults.elf"), overrides={"/which": 1, "/target": 0x3001})
    sim.firmware.core.write(0x3000, code)
    with pytest.raises(CoreFault) as info:
        sim.run(seconds="50us")
    text = str(info.value)
    assert "unprivileged 32-bit read of 0xe000ed00, in the System Control Space" in text
    assert "at PC 0x0000300c" in text


def test_a_signal_raised_in_a_device_read_ends_the_run_without_a_stray_traceback(capfd):
    """Ctrl-C or SIGTERM while the core reads a peripheral: the exception comes out of the run, and
    Python prints no 'Exception ignored on converting result of ctypes callback function' (a read
    callback must give ctypes a number; unicorn's own catch gave None)."""
    sim = mcusim.load("nucleo-f746", firmware=str(BIN / "armv7m.elf"), overrides={"/which": 10})
    bus, calls = sim.firmware.core.bus, []     # (case 10: a loop reading TIM2.CNT)
    read = bus.read

    def interrupted(address, size):
        calls.append(address)
        raise KeyboardInterrupt
    sim.run(seconds="1ms")
    bus.read, unraisable = interrupted, []
    hook, sys.unraisablehook = sys.unraisablehook, unraisable.append
    try:
        with pytest.raises(KeyboardInterrupt):
            sim.run(seconds="5ms")
    finally:
        bus.read, sys.unraisablehook = read, hook
    assert calls and not unraisable and "Exception ignored" not in capfd.readouterr().err


def test_a_model_refusing_an_access_stops_the_run_naming_the_access_not_as_a_hardfault():
    """A peripheral model's refusal (a chip limit under --strict, a configuration refused where a
    block starts) is no fault of the image: the run stops with the model's line and the access
    that raised it, not 'HardFault at ...'; a bus fault stays the image's HardFault."""
    from mcusim.errors import BusFault, McusimError
    sim = mcusim.load("nucleo-f746", firmware=str(BIN / "armv7m.elf"), overrides={"/which": 10})
    bus = sim.firmware.core.bus
    sim.run(seconds="1ms")
    read = bus.read

    def refused(address, size):
        raise McusimError("TIM2: a limit of the chip")
    bus.read = refused
    try:
        with pytest.raises(McusimError) as info:
            sim.run(seconds="1ms")
    finally:
        bus.read = read
    assert not isinstance(info.value, CoreFault)
    assert str(info.value).startswith("TIM2: a limit of the chip (the access at PC 0x")

    sim = mcusim.load("nucleo-f746", firmware=str(BIN / "armv7m.elf"), overrides={"/which": 10})
    bus = sim.firmware.core.bus
    sim.run(seconds="1ms")

    def faulting(address, size):
        raise BusFault(address, size)
    bus.read = faulting
    with pytest.raises(CoreFault, match="HardFault at t = .*bus fault"):
        sim.run(seconds="1ms")
