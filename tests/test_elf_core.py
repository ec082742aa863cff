"""Compiled Cortex-M images on the simulated bus: the load rules, the Cortex-M exception model
(Armv7-M ARM B1.5), the cycle model and fault reports.

The images are built from tests/elf_src by tests/elf_build.py and committed in tests/elf_bin, so
these tests run without the toolchain; test_committed_images_match_their_sources rebuilds them
when arm-none-eabi-gcc is installed.
"""

from __future__ import annotations

import itertools
import json
import shutil
import struct

import pytest
from elf_build import BIN, IMAGES, build, gcc
from hypothesis import given, settings
from hypothesis import strategies as st

import mcusim
from mcusim.cli import main
from mcusim.elf.core import CoreFault
from mcusim.errors import BusFault, ConfigError


def elf(name):
    return str(BIN / f"{name}.elf")


def load(name, board="nucleo-f746", **kw):
    return mcusim.load(board, firmware=elf(name), **kw)


def word(sim, name, index=0):
    return sim.mcu.read32(sim.firmware.symbols[name] + 4 * index)


# --- loading ------------------------------------------------------------------------------------------
def test_segments_load_at_their_load_address_and_symbols_are_kept(tmp_path):
    sim = load("ticks")
    syms = sim.firmware.symbols
    vectors = syms["vectors"]
    assert vectors == 0x08000000
    # the vector table as the image holds it, through the bus, at flash and at its ITCM alias
    sp, reset = sim.mcu.read32(0x08000000), sim.mcu.read32(0x08000004)
    assert sim.mcu.read32(0x00200004) == reset == syms["Reset_Handler"] | 1
    assert sp == 0x20050000                                    # _estack = end of RAM (link.ld)
    assert sim.mcu.cpu.reg("msp") == sp and sim.mcu.cpu.pc == syms["Reset_Handler"]


def test_data_is_copied_by_the_startup_code_from_its_load_address():
    sim = load("exc")
    sim.run(seconds="10us")
    assert word(sim, "r4_after") == 0 and word(sim, "n_trace") > 0   # .bss zeroed, then used


def test_bus_reaches_ram_both_ways():
    sim = load("ticks")
    sim.run(seconds="5ms")
    addr = sim.firmware.symbols["ticks"]
    assert sim.mcu.read32(addr) == sim.firmware.topic("/ticks") > 0
    sim.mcu.write32(addr, 1000)
    sim.run(seconds="1ms")
    assert 1000 < sim.firmware.topic("/ticks") <= 1002


def test_a_store_to_flash_from_the_host_is_refused():
    sim = load("ticks")
    with pytest.raises(BusFault, match="flash"):
        sim.mcu.write32(0x08000000, 0)


def test_not_an_elf_is_one_clear_error(tmp_path):
    bad = tmp_path / "app.elf"
    bad.write_text("hello")
    with pytest.raises(ConfigError, match="not an ELF file"):
        mcusim.load("nucleo-f746", firmware=str(bad))


def test_wrong_machine_is_one_clear_error(tmp_path):
    data = bytearray((BIN / "ticks.elf").read_bytes())
    struct.pack_into("<H", data, 18, 62)            # e_machine = EM_X86_64
    bad = tmp_path / "x86.elf"
    bad.write_bytes(bytes(data))
    with pytest.raises(ConfigError, match="EM_X86_64.*32-bit little-endian ARM"):
        mcusim.load("nucleo-f746", firmware=str(bad))


@pytest.mark.parametrize("size,message", [
    (20, r"a truncated ELF file \(20 bytes; its header alone is 52\)"),
    (1000, r"not a valid ELF file, truncated or corrupt \(1000 bytes; the ELF reader says: .*past EOF"),
])
def test_a_truncated_elf_says_so(tmp_path, size, message):
    """Was "not a valid ELF file: expected 4, found 0" (the ELF reader's words) for 20 bytes."""
    bad = tmp_path / "cut.elf"
    bad.write_bytes((BIN / "ticks.elf").read_bytes()[:size])
    with pytest.raises(ConfigError, match=message):
        mcusim.load("nucleo-f746", firmware=str(bad))


def test_a_big_endian_elf_names_its_machine_read_in_its_own_byte_order(tmp_path):
    """The machine of a big-endian image was read little-endian (machine 10240 for EM_ARM)."""
    data = bytearray((BIN / "ticks.elf").read_bytes())
    data[5] = 2                                     # EI_DATA = ELFDATA2MSB
    struct.pack_into(">H", data, 18, 40)            # e_machine = EM_ARM, big-endian
    bad = tmp_path / "be.elf"
    bad.write_bytes(bytes(data))
    with pytest.raises(ConfigError, match=r"an ELF for EM_ARM \(32-bit, big-endian\).*32-bit little-endian ARM"):
        mcusim.load("nucleo-f746", firmware=str(bad))


def test_a_bad_image_given_to_bench_is_not_blamed_on_the_bench_command(tmp_path, capsys):
    from mcusim.cli import main
    bad = tmp_path / "cut.elf"
    bad.write_bytes((BIN / "ticks.elf").read_bytes()[:20])
    assert main(["bench", "nucleo-f746", "--firmware", str(bad), "--repeat", "1", "--duration", "1ms"]) == 2
    err = capsys.readouterr().err
    assert "a truncated ELF file" in err and "[bench.set]" not in err, err


def test_no_loadable_segment_is_one_clear_error(tmp_path):
    data = bytearray((BIN / "ticks.elf").read_bytes())
    phoff, phentsize, phnum = struct.unpack_from("<I", data, 28)[0], *struct.unpack_from("<HH", data, 42)
    for i in range(phnum):
        struct.pack_into("<I", data, phoff + i * phentsize, 4)      # p_type = PT_NOTE
    bad = tmp_path / "empty.elf"
    bad.write_bytes(bytes(data))
    with pytest.raises(ConfigError, match="no loadable segment"):
        mcusim.load("nucleo-f746", firmware=str(bad))


def test_segment_outside_the_boards_memory_is_one_clear_error():
    with pytest.raises(ConfigError, match="segment \\(.*\\) at 0x08000000.*outside the board's memory"):
        load("ticks", board="ciaa-edu")


def test_a_board_without_a_cortex_m_core_refuses_an_elf():
    with pytest.raises(ConfigError, match="Cortex-M ELF"):
        load("ticks", board="pro-mini")


@pytest.mark.parametrize("argv", [
    ["run", "nucleo-f746", "--firmware", "missing.elf"],
    ["run", "ciaa-edu", "--firmware", elf("ticks")],
    ["run", "nucleo-f746", "--firmware", elf("ticks"), "--no-firmware"],
    ["run", "nucleo-f746", "--gdb", "3333"],
    ["run", "nucleo-f746", "--firmware", elf("ticks"), "--set", "firmware.kp=3"],
])
def test_cli_load_mistakes_exit_2(argv, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("mcusim: error:") and err.count("\n") == 1


def test_cli_runs_an_elf_and_topics_reach_its_globals(capsys):
    assert main(["run", "nucleo-f746", "--firmware", elf("ticks"), "--duration", "20ms",
                 "--set", "/set_point=1.25", "-q"]) == 0
    out = capsys.readouterr().out
    assert "/doubled = 2.500" in out and "/ticks = 19" in out


def test_topic_writes_before_main_survive_the_startup_code_and_count():
    sim = load("ticks", overrides={"/set_point": 0.75})
    sim.run(seconds="2ms")
    assert sim.firmware.topic("/doubled") == 1.5
    assert word(sim, "set_point_count") == 1
    sim.publish("/set_point", -2.0)
    assert word(sim, "set_point_count") == 2
    sim.run(seconds="2ms")
    assert sim.firmware.topic("/doubled") == -4.0


def test_topic_map_mistakes_are_named():
    sim = load("ticks")
    with pytest.raises(ConfigError, match="no subscribed topic '/ticks'"):
        sim.publish("/ticks", 3)
    with pytest.raises(ConfigError, match="expected a finite number"):
        sim.publish("/set_point", "fast")


@pytest.mark.parametrize("value, ok", [(1e40, False), (-1e39, False), (10 ** 400, False),
                                       (3.4028234663852886e38, True), (3.4028235e38, True), (-1e38, True)])
def test_an_f32_topic_takes_what_rounds_to_a_finite_float32_and_refuses_the_rest(value, ok):
    """An f32 topic beyond float32 (1e40) was an internal OverflowError from the packing; a value
    rounding to FLT_MAX (3.4028235e38, as C's printf writes it) is fine."""
    sim = load("ticks")
    if ok:
        sim.publish("/set_point", value)
    else:
        with pytest.raises(ConfigError, match="(out of range for f32|expected a finite number)"):
            sim.publish("/set_point", value)


# --- the exception model ----------------------------------------------------------------------------
def test_nesting_by_priority_and_tail_chaining():
    sim = load("exc")
    sim.run(seconds="1ms")
    trace = [word(sim, "trace", i) for i in range(word(sim, "n_trace"))]
    # IRQ0 (0xC0) runs; IRQ1 (0x40) preempts it at once; IRQ2 (0xE0) waits for IRQ0's end and is
    # tail-chained before thread mode resumes
    assert trace == [0x10, 0x20, 0x11, 0x12, 0x30, 0x01, 0x02]
    assert word(sim, "ipsr_in_irq1") == 16 + 1
    assert word(sim, "lr_in_irq0") == 0xFFFFFFF9          # thread mode, MSP, no FP frame


def test_an_access_that_pends_an_interrupt_ends_the_quantum_after_that_instruction():
    sim = load("exc")
    sim.run(seconds="1ms")
    assert word(sim, "stacked_pc") == sim.firmware.symbols["pend_irq3_next"]


def test_an_access_that_schedules_an_earlier_event_ends_the_quantum():
    """sched.c: CYCCNT is read 2 instructions before the TIM2 CEN write; the update comes 200
    cycles (100 ticks of the 108 MHz timer clock, +1 to reach its edge) after that write; the poll
    loop reads SR every 4 instructions, and CYCCNT is read 4 instructions after the read that sees
    UIF. Had the quantum not ended at the write, the poll would have run past the update unseen."""
    sim = load("sched")
    sim.run(seconds="1ms")
    seen = word(sim, "t_seen") - word(sim, "t_start")
    assert 2 + 200 + 4 <= seen <= 2 + 201 + 4 + 4


def test_basepri_and_primask_mask_by_priority_and_unmasking_takes_the_interrupt_at_once():
    sim = load("masks")
    sim.run(seconds="1ms")
    syms = sim.firmware.symbols
    trace = [word(sim, "trace", i) for i in range(word(sim, "n_trace"))]
    # BASEPRI 0x40: IRQ1 (0x20) is taken, IRQ0 (0x80) waits; PRIMASK: IRQ1 waits too
    assert trace == [0x11, 0x01, 0x10, 0x02, 0x11]
    assert word(sim, "ret_irq0") == syms["after_basepri"]     # right after MSR BASEPRI
    assert word(sim, "ret_irq1") == syms["after_cpsie"]       # right after CPSIE


def test_stacking_with_and_without_the_fp_frame():
    sim = load("fpframe")
    sim.run(seconds="1ms")
    sp_main = word(sim, "sp_main")
    assert word(sim, "lr0") == 0xFFFFFFF9 and word(sim, "sp0") == sp_main - 0x20     # 8 words
    assert word(sim, "control_main") & 4                                          # FPCA after FP use
    assert word(sim, "lr1") == 0xFFFFFFE9 and word(sim, "sp1") == sp_main - 0x68  # 26 words
    assert word(sim, "fp_ok") == 1            # s0, s5, s15 restored after the handler changed them


def test_pendsv_context_switch_between_two_psp_threads():
    sim = load("rtos")
    sim.run(seconds="10ms")
    assert word(sim, "svc_calls") == 1
    ticks, switches = word(sim, "ticks"), word(sim, "switches")
    assert ticks == switches and 95 <= ticks <= 100                   # SysTick every 100 us
    assert word(sim, "count_a") > 1000 and word(sim, "count_b") > 1000
    assert word(sim, "errors") == 0                                    # r4, r5, r11 kept per task
    assert sim.mcu.cpu.reg("control") & 2                              # thread mode runs on PSP


def test_wfi_sleeps_until_the_interrupt_and_costs_no_instructions():
    sim = load("ticks")
    sim.run(seconds="100ms")
    core = sim.mcu.cpu
    assert core.state == "sleep"
    assert core.isr_count == {-1: 99, 28: 100}
    assert core.instructions < 30 * 200       # a few dozen instructions per interrupt, none asleep


# --- the cycle model ---------------------------------------------------------------------------------
def test_one_cycle_per_instruction_between_two_cyccnt_reads():
    sim = load("cycles")
    sim.run(seconds="1ms")
    assert word(sim, "c1") - word(sim, "c0") == 11           # ldr, ten nops: 11 instructions


def test_interrupts_from_wfi_enter_exactly_one_period_apart():
    sim = load("cycles")
    sim.run(seconds="1ms")
    entries = [word(sim, "entries", i) for i in range(word(sim, "n_entries"))]
    assert len(entries) == 8
    assert {b - a for a, b in itertools.pairwise(entries)} == {10000}   # SysTick LOAD + 1


def test_cycles_per_instruction_from_the_profile(tmp_path):
    text = mcusim.board.shipped_text("nucleo-f746").replace("cycles_per_instruction = 1",
                                                             "cycles_per_instruction = 3")
    prof = tmp_path / "slow.toml"
    prof.write_text(text)
    sim = mcusim.load(str(prof), firmware=elf("cycles"))
    sim.run(seconds="1ms")
    assert word(sim, "c1") - word(sim, "c0") == 33


# --- faults ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("which, what, where", [
    (1, "32-bit read of unmapped memory at 0x60000000", "bad_read+0x"),
    (2, "undefined instruction", "bad_insn"),
    (3, "32-bit write to read-only memory at 0x08000100", "flash_write+0x"),
    (4, "SVC executed where SVCall cannot preempt", "svc_masked+0x"),
])
def test_hardfault_is_reported_with_pc_symbol_and_time(which, what, where):
    sim = load("faults", overrides={"/which": which})
    with pytest.raises(CoreFault, match=r"HardFault at t = 0\.0000\d+ s: .*") as info:
        sim.run(seconds="1ms")
    assert what in str(info.value) and f"({where}" in str(info.value)


def test_a_fault_in_the_cli_names_the_simulated_time_once(capsys):
    # review finding 10: the message gave the fault's instant and then the quantum's start
    assert main(["run", "nucleo-f746", "--firmware", elf("faults"), "--set", "/which=1", "-q",
                 "--duration", "1ms"]) == 1
    err = capsys.readouterr().err
    assert "HardFault at t = 0.0000" in err and "bad_read" in err and err.count(" t = ") == 1, err


def test_after_a_fault_the_simulation_stands_at_the_faulting_instruction():
    sim = load("faults", overrides={"/which": 1})
    with pytest.raises(CoreFault) as info:
        sim.run(seconds="1ms")
    said = float(str(info.value).split("t = ")[1].split(" s")[0])
    assert said > 0 and sim.time_s == pytest.approx(said, abs=1e-9)


def test_a_simulation_stopped_by_a_fault_refuses_to_run_on():
    """A second run() after a HardFault returned normally and moved time on with a dead core
    (found by an adversarial test of ELF images)."""
    from mcusim.errors import McusimError
    sim = load("faults", overrides={"/which": 1})
    with pytest.raises(CoreFault):
        sim.run(seconds="1ms")
    stood = sim.time_s
    with pytest.raises(McusimError, match=r"stopped at t = 0\.0000\d+ s on an error \(HardFault.*cannot run on"):
        sim.run(seconds="0.5s")
    assert sim.time_s == stood


# --- the images match their sources ------------------------------------------------------------------
@pytest.mark.skipif(shutil.which("arm-none-eabi-gcc") is None, reason="arm-none-eabi-gcc is not installed")
@pytest.mark.parametrize("name", IMAGES)
def test_committed_images_match_their_sources(name, tmp_path):
    assert gcc() is not None
    assert build(name, tmp_path).read_bytes() == (BIN / f"{name}.elf").read_bytes()


def test_an_access_a_register_model_refuses_is_a_hardfault_with_its_reason():
    sim = load("faults", overrides={"/which": 5})
    with pytest.raises(CoreFault, match=r"no register of TIM2 at offset 0x3f0 at PC 0x[0-9a-f]+ \(main"):
        sim.run(seconds="1ms")


# --- the other board, determinism, the register log --------------------------------------------------
def test_ciaa_edu_runs_an_image_linked_for_its_flash_through_the_boot_shadow():
    sim = load("lpc_ticks", board="ciaa-edu")
    sim.run(seconds="10ms")
    assert sim.mcu.read32(0x0) == 0x10008000                        # SP, seen at the shadow address
    assert word(sim, "ticks") == 9 and word(sim, "base") == 1000    # SysTick at 1 kHz; .data copied
    assert sim.mcu.read32(0xE000ED00) == 0x410FC241                 # a Cortex-M4


@pytest.mark.skipif(shutil.which("arm-none-eabi-gcc") is None, reason="arm-none-eabi-gcc is not installed")
def test_an_image_too_big_for_the_flash_names_its_sections_and_the_overflow(tmp_path):
    """Found by an adversarial test: a 1.1 MB constant table was 'a loadable segment ... outside
    the board's memory', naming neither the sections nor by how much the 1 MB flash overflows."""
    import subprocess

    from elf_build import COMMON, SRC, STM32F746
    (tmp_path / "big.c").write_text("const unsigned char table[1100000] = {1};\n"
                                    "volatile unsigned sink;\n"
                                    "int main(void) { sink = table[sink]; for (;;) {} }\n")
    # linked for a chip with 2 Mbytes of flash (an F767ZI's), so the linker lets it through
    (tmp_path / "link.ld").write_text((SRC / "link.ld").read_text().replace("LENGTH = 1024K", "LENGTH = 2048K"))
    flags = [str(tmp_path / "link.ld") if f == "link.ld" else f for f in STM32F746]
    out = tmp_path / "big.elf"
    subprocess.run([gcc(), *COMMON, *flags, "startup.c", str(tmp_path / "big.c"), "-o", str(out), "-lgcc"],
                   cwd=SRC, check=True, capture_output=True)
    with pytest.raises(ConfigError, match=r"segment \(.*\.text.*\) at 0x08000000 \(\d+ bytes\) overflows "
                                          r"the board's memory by \d+ bytes.*ends at 0x080fffff") as info:
        mcusim.load("nucleo-f746", firmware=str(out))
    size = int(str(info.value).split("(")[2].split(" bytes")[0])
    over = int(str(info.value).split("by ")[1].split(" bytes")[0])
    assert over == size - 0x100000                      # the F746ZG's flash: 1 Mbyte


RAMCODE = """
#include <stdint.h>
#define REG(a) (*(volatile uint32_t *)(a))
volatile uint32_t sink, order[4], n;
void IRQ0_Handler(void) { order[n++] = 0xAA; }
/* copied to RAM by the start-up code with .data (the segment is read-write only) */
__attribute__((section(".data"), noinline, long_call)) void ram_sev_wfe(void) {
  __asm volatile("sev\\n wfe");
  sink = 1;
}
__attribute__((section(".data"), noinline, long_call)) void ram_unmask(void) {
  __asm volatile("cpsie i" ::: "memory");
  order[n++] = 1;
}
int main(void) {
  ram_sev_wfe();
  __asm volatile("cpsid i");
  REG(0xE000E100) = 1;        /* ISER0: IRQ0 */
  REG(0xE000E200) = 1;        /* ISPR0: pend IRQ0 */
  ram_unmask();
  order[n++] = 2;
  for (;;) __asm volatile("wfi");
}
"""


@pytest.mark.skipif(shutil.which("arm-none-eabi-gcc") is None, reason="arm-none-eabi-gcc is not installed")
def test_sev_wfe_and_cpsie_in_code_copied_to_ram_act_as_in_flash(tmp_path):
    """Found by an adversarial test: the core found SEV, WFI and CPSIE by scanning the image at its
    load addresses only, so in a function copied to RAM `sev; wfe` slept (the WFE goes on at once
    after an SEV, B1.5.18) and an interrupt pended under PRIMASK waited past `cpsie i` (it is
    taken right after it, B1.5.4 and the Cortex-M7 TRM)."""
    import subprocess

    from elf_build import COMMON, SRC, STM32F746
    (tmp_path / "ram.c").write_text(RAMCODE)
    out = tmp_path / "ram.elf"
    subprocess.run([gcc(), *COMMON, *STM32F746, "startup.c", str(tmp_path / "ram.c"), "-o", str(out), "-lgcc"],
                   cwd=SRC, check=True, capture_output=True)
    sim = mcusim.load("nucleo-f746", firmware=str(out))
    sim.run(seconds="1ms")
    syms = sim.firmware.symbols
    assert sim.mcu.read32(syms["sink"]) == 1
    assert [sim.mcu.read32(syms["order"] + 4 * k) for k in range(3)] == [0xAA, 1, 2]


@pytest.mark.skipif(shutil.which("arm-none-eabi-gcc") is None, reason="arm-none-eabi-gcc is not installed")
def test_a_semihosting_call_without_a_debugger_is_named_as_such(tmp_path):
    """BKPT 0xAB is Arm's semihosting call (newlib's rdimon); with no debugger it escalates to a
    HardFault. Found by an adversarial test: the report said only 'BKPT with no debugger'."""
    import subprocess

    from elf_build import COMMON, SRC, STM32F746
    (tmp_path / "semi.c").write_text('int main(void) { __asm volatile("bkpt 0xab"); for (;;) {} }\n')
    out = tmp_path / "semi.elf"
    subprocess.run([gcc(), *COMMON, *STM32F746, "startup.c", str(tmp_path / "semi.c"), "-o", str(out), "-lgcc"],
                   cwd=SRC, check=True, capture_output=True)
    sim = mcusim.load("nucleo-f746", firmware=str(out))
    with pytest.raises(CoreFault, match=r"BKPT #0xab, a semihosting call.*nosys\.specs.*\(main\)"):
        sim.run(seconds="1ms")


def test_a_system_profile_refuses_an_elf():
    with pytest.raises(ConfigError, match="system runs its boards' own firmware"):
        mcusim.load("elementall", firmware=elf("ticks"))


def test_the_register_log_names_the_function_of_each_access_and_is_deterministic(tmp_path):
    from mcusim.reglog import load_logged
    logs = []
    for k in range(2):
        path = tmp_path / f"regs{k}.jsonl"
        sim, _ = load_logged("nucleo-f746", str(path), firmware=elf("ticks"))
        sim.run(seconds="3ms")
        sim.close()
        logs.append(path.read_text())
    assert logs[0] == logs[1]
    lines = [json.loads(x) for x in logs[0].splitlines()]
    fns = {(x["reg"], x["op"], x.get("fn")) for x in lines}
    assert ("TIM2.PSC", "write", "main") in fns
    assert ("TIM2.SR", "write", "TIM2_IRQHandler") in fns


# --- priorities, for all inputs ----------------------------------------------------------------------
@settings(max_examples=25, deadline=None)
@given(prios=st.lists(st.integers(0, 15), min_size=4, max_size=4),
       pend=st.sets(st.integers(0, 3), min_size=1), prigroup=st.integers(0, 7))
def test_interrupts_pending_together_run_in_priority_order(prios, pend, prigroup):
    """Armv7-M B1.5.4: of the pending exceptions the one with the lowest group priority, then the
    lowest subpriority, then the lowest number, is taken; one runs to its end before the next
    (none of them can preempt another of the same or lower urgency; tail-chained)."""
    sim = load("order")
    sim.run(seconds="10us")                                   # main enabled the IRQs and sleeps
    sim.mcu.write32(0xE000ED0C, (0x05FA << 16) | (prigroup << 8))
    sim.mcu.write32(0xE000E400, sum(p << (4 + 8 * i) for i, p in enumerate(prios)))
    sim.mcu.write32(0xE000E200, sum(1 << n for n in pend))  # pended at one instant
    sim.run(seconds="20us")
    trace = [word(sim, "trace", i) for i in range(word(sim, "n_trace"))]
    assert trace == sorted(pend, key=lambda n: (prios[n] << 4, n))
    sim.close()


def test_a_shipped_image_runs_by_name_from_any_directory(tmp_path, monkeypatch, capsys):
    """--firmware takes a shipped image's name (as --scenario takes a shipped scenario's), so the
    README's command works in an installed mcusim, away from the repository; an unknown name lists
    the shipped ones."""
    monkeypatch.chdir(tmp_path)
    assert main(["run", "nucleo-f746", "--firmware", "controlmotor", "--duration", "10ms"]) == 0
    assert main(["run", "nucleo-f746", "--firmware", "controlmotor_thesis.elf", "--duration", "10ms"]) == 0
    capsys.readouterr()
    assert main(["run", "nucleo-f746", "--firmware", "controlmotr", "--duration", "10ms"]) == 2
    err = capsys.readouterr().err
    assert "no shipped image of that name" in err and "controlmotor, controlmotor_thesis" in err


def test_a_function_is_named_by_its_strong_symbol_not_a_weak_alias_of_it():
    """Start-up code aliases every unused handler to Default_Handler with weak symbols: a stop in
    it had been named after one of them (UsageFault_Handler for an SVC with no handler), which
    suggests another exception."""
    from elftools.elf.elffile import ELFFile

    from mcusim.elf.image import read_elf
    path = BIN / "corefaults.elf"
    image = read_elf(str(path))
    with open(path, "rb") as f:
        table = ELFFile(f).get_section_by_name(".symtab")
        at = {s.name: (s["st_value"] & ~1, s["st_info"]["bind"]) for s in table.iter_symbols() if s.name}
    start, bind = at["Default_Handler"]
    assert bind == "STB_GLOBAL" and [n for n, (a, b) in at.items() if a == start and b == "STB_WEAK"]
    assert image.function(start) == "Default_Handler" and image.where(start) == "Default_Handler"
