"""Armv7-M rules a review of the compiled-firmware core found broken, each pinned with
tests/elf_src/armv7m.c (the case is chosen through its `/which` topic; results land in res[]).
References: Armv7-M Architecture Reference Manual (ARM DDI 0403E) B1.5 (exception model), B3.2
(SCB), C1.8 (DWT); the Cortex-M7 TRM for FPCCR."""

from __future__ import annotations

import shutil
import struct

import pytest
from elf_build import BIN
from hypothesis import example, given, settings
from hypothesis import strategies as st

import mcusim
from mcusim.cli import main
from mcusim.errors import ConfigError


def run(which, seconds="200us"):
    sim = mcusim.load("nucleo-f746", firmware=str(BIN / "armv7m.elf"), overrides={"/which": which})
    sim.run(seconds=seconds)
    return sim


def res(sim, n=16):
    return struct.unpack(f"<{n}I", sim.mcu.cpu.read(sim.firmware.symbols["res"], 4 * n))


def sym(sim, name):
    return sim.firmware.symbols[name]


# --- B1.5.6, B1.5.8: entry and return stack on the SP in use, whatever the privilege --------------------
@pytest.mark.parametrize("which, control_after", [(1, 0), (2, 1)])
def test_exception_entry_and_return_with_unprivileged_thread_mode_keep_the_stack(which, control_after):
    """which 1: SVC from unprivileged thread mode (CONTROL.nPRIV = 1), the handler makes it
    privileged; which 2: the handler makes thread mode unprivileged for the return. Either way the
    8-word frame is pushed on MSP (SPSEL = 0) right below the thread's SP, it holds the address
    after the SVC, the return pops it (SP as before) and CONTROL.nPRIV is what the handler left."""
    sim = run(which)
    r = res(sim)
    sp_before, sp_after, handler_msp, stacked_pc = r[2], r[3], r[0], r[1]
    assert sim.mcu.cpu.state == "run"
    assert handler_msp == (sp_before - 32) & ~7
    assert stacked_pc == sym(sim, "svc_next")
    assert sp_after == sp_before
    assert r[4] == control_after


# --- B1.5.8 DeActivate(): FAULTMASK clears on return from any exception but NMI -------------------------
def test_faultmask_is_cleared_by_exception_return():
    r = res(run(3))
    assert r[7] == 1            # the handler ran (and did CPSID f)
    assert r[6] == 0            # FAULTMASK read back in thread mode


# --- B1.5.18 WFE, SEV, YIELD ----------------------------------------------------------------------------
def test_wfe_after_sev_goes_on_and_the_next_wfe_sleeps_until_an_interrupt():
    """SysTick interrupts every 1000 cycles. SEV sets the event register: the first WFE clears it
    and goes on at once; the second sleeps until the SysTick exception (a wake-up event).
    YIELD is a hint that executes as a NOP (not an undefined instruction)."""
    r = res(run(4))
    assert r[7] == 0x600d
    assert r[5] <= 4                    # CYCCNT across SEV; WFE: a few cycles, no sleep
    assert r[8] == 0 and r[9] == 1      # no tick before the first WFE returned; one after the second
    assert 900 < r[6] <= 1000 + 12 + 40  # the second WFE slept until the tick (then the handler ran)


# --- B1.5.6 a frame is pushed in RAM; RAM is DTCM and SRAM1 back to back ----------------------------------
def test_an_exception_frame_across_the_dtcm_sram1_seam_is_stacked():
    sim = run(5)
    r = res(sim)
    assert sim.mcu.cpu.state == "run" and r[7] == 0x600d
    assert r[9] == 0x20010010 - 32      # PendSV's MSP: the frame spans 0x2000fff0..0x2001000f


# --- B1.5.4: preemption is decided by group priority, which AIRCR.PRIGROUP sets --------------------------
def test_changing_prigroup_lets_a_pending_exception_preempt_at_once():
    """IRQ2 (0x70) runs, pends IRQ1 (0x40): with PRIGROUP 5 both are group 1, so IRQ1 waits; the
    handler sets PRIGROUP 3 (groups 4 and 7): IRQ1 preempts before IRQ2's next instruction."""
    sim = run(6)
    log = struct.unpack("<3I", sim.mcu.cpu.read(sym(sim, "olog"), 12))
    assert log == (0xB0, 0xA, 0xB1)


# --- B3.2.13 SHCSR: active bits of the system handlers -----------------------------------------------------
def test_shcsr_pendsvact_reads_1_inside_pendsv_and_0_after():
    r = res(run(7))
    assert r[10] == 1 << 10 and r[12] == 0


def test_shcsr_enable_bits_are_stored_and_a_write_changing_active_state_is_refused():
    sim = run(7)
    sim.mcu.write32(0xE000ED24, 1 << 18)                     # USGFAULTENA
    assert sim.mcu.read32(0xE000ED24) == 1 << 18
    with pytest.raises(mcusim.errors.UnsupportedConfiguration, match="SHCSR"):
        sim.mcu.write32(0xE000ED24, 1 << 10)                  # PENDSVACT while PendSV is not active


# --- C1.8.8: the DWT counts only while DEMCR.TRCENA = 1 ----------------------------------------------------
def test_cyccnt_stands_still_while_demcr_trcena_is_0():
    r = res(run(8))
    assert r[5] == 0 and r[6] > 10


# --- FPCCR.ASPEN (Cortex-M7 TRM, Armv7-M B1.5.7): no automatic FP context, no FP frame --------------------
def test_the_fp_frame_follows_fpccr_aspen():
    r = res(run(9))
    assert r[13] == 0xFFFFFFE9          # ASPEN = 1 after an FP instruction: extended frame
    assert r[14] == 0xFFFFFFF9          # ASPEN = 0: basic frame


# --- review finding 3: a peripheral read answers with its own instant's value ------------------------------
def test_a_loop_reading_one_register_sees_it_change_and_keeps_no_growing_record():
    sim = run(10, "100us")
    for _ in range(3):
        sim.run(seconds="500us")
        prev, last = res(sim, 2)
        cnt = sim.mcu.read32(0x40000024)
        # TIM2 at 108 MHz, a loop of a few instructions (the run may end between its two stores)
        assert 0 <= last - prev <= 8 and 0 <= cnt - last <= 8 and last > 1000
        assert len(sim.mcu.cpu._acc) <= 2


# --- B1.5.19 WFI: sleeps until an interrupt, also as the last instruction of a quantum ----------------------
def test_wfi_sleeps_also_as_the_last_instruction_of_a_quantum():
    """No interrupt is enabled, so the WFI never wakes. A run that ends right after the WFI (the
    run's end ends the quantum) must still leave the core asleep: runs of every length around
    the WFI's instant."""
    first = run(11, "20us")
    assert first.mcu.cpu.state == "sleep"
    n = first.mcu.cpu.instructions                 # the WFI is the n-th instruction (1 cycle each)
    for k in range(n - 3, n + 4):
        sim = mcusim.load("nucleo-f746", firmware=str(BIN / "armv7m.elf"), overrides={"/which": 11})
        sim.run(cycles=k)
        sim.run(cycles=100)
        assert sim.mcu.read32(sym(sim, "wakes")) == 0, k
        assert sim.mcu.cpu.state == "sleep"


# --- review finding 5: an f32 topic reads back as the value published -------------------------------------
@pytest.fixture(scope="module")
def ticks_sim():
    sim = mcusim.load("nucleo-f746", firmware=str(BIN / "ticks.elf"))
    sim.run(seconds="20us")          # past main: a publish is a store at once
    return sim


@settings(max_examples=60, deadline=None)
@given(st.floats(width=32, allow_nan=False, allow_infinity=False))
@example(3.4025001647762064e+38)     # its short decimals round past the largest float32
def test_an_f32_topic_reads_back_as_the_float32_published(ticks_sim, x):
    sim = ticks_sim
    sim.firmware.publish("/set_point", x)
    got = sim.firmware.topic("/set_point")
    assert struct.pack("<f", got) == struct.pack("<f", x)       # the same float32
    assert len(repr(got)) <= len(repr(x))                       # and its shortest decimal


@pytest.mark.parametrize("text", ["1.57", "0.1", "-3.14159", "1e-07", "216000000.0"])
def test_a_short_decimal_published_to_an_f32_topic_reads_back_equal(ticks_sim, text):
    ticks_sim.firmware.publish("/set_point", float(text))
    assert ticks_sim.firmware.topic("/set_point") == float(text)


# --- review finding 9: bad topic maps are one clear error ---------------------------------------------------
@pytest.mark.parametrize("body, message", [
    ('symbol = "ticks"\ntype = ["f32"]\ndirection = "pub"', "type = \\['f32'\\]: expected a string"),
    ('symbol = 3\ntype = "u32"\ndirection = "pub"', "symbol = 3: expected a string"),
    ('symbol = "ticks"\ntype = "u32"\ndirection = "sub"\ncount = 1', "count = 1: expected a string"),
    ('symbol = "_estack"\ntype = "u32"\ndirection = "sub"', "not in the board's RAM"),
    ('symbol = "ticks"\ntype = "u32"\ndirection = "sub"\ncount = "_estack"', "count.*not in the board's RAM"),
])
def test_a_bad_topic_map_value_is_a_config_error(tmp_path, capsys, body, message):
    shutil.copy(BIN / "ticks.elf", tmp_path / "app.elf")
    (tmp_path / "app.topics.toml").write_text('[topics."/x"]\n' + body + "\n")
    with pytest.raises(ConfigError, match=message):
        mcusim.load("nucleo-f746", firmware=str(tmp_path / "app.elf"))
    assert main(["run", "nucleo-f746", "--firmware", str(tmp_path / "app.elf"), "-q", "--duration", "1us"]) == 2
    assert "Traceback" not in capsys.readouterr().err


@pytest.mark.skipif(shutil.which("arm-none-eabi-strip") is None, reason="arm-none-eabi-strip is not installed")
def test_a_topic_map_for_a_stripped_image_says_the_symbol_table_is_missing(tmp_path):
    # found by an adversarial test: it said the ELF had no symbol 'set_point', as if misspelt
    import subprocess
    shutil.copy(BIN / "ticks.elf", tmp_path / "app.elf")
    shutil.copy(BIN / "ticks.topics.toml", tmp_path / "app.topics.toml")
    subprocess.run(["arm-none-eabi-strip", str(tmp_path / "app.elf")], check=True)
    with pytest.raises(ConfigError, match="no symbol table \\(stripped\\?\\)"):
        mcusim.load("nucleo-f746", firmware=str(tmp_path / "app.elf"))


# --- review finding 14: the bench's command comes from the profile: the error says so ----------------------
def test_bench_with_an_image_lacking_the_profiles_topics_names_the_bench_set_table(tmp_path, capsys):
    shutil.copy(BIN / "ticks.elf", tmp_path / "my.elf")
    assert main(["bench", "nucleo-f746", "--firmware", str(tmp_path / "my.elf"), "--repeat", "1",
                 "--duration", "1ms"]) == 2
    err = capsys.readouterr().err
    assert "[bench.set]" in err and "/motor1/set_pos" in err and "Traceback" not in err


# --- B1.5.6 late arrival: a more urgent exception during another's entry takes over its frame --------------
def test_late_arrival_takes_the_frame_being_stacked_and_the_first_exception_tail_chains():
    """IRQ0 (priority 0x80) is pended `delay` loop turns after SysTick (priority 0) was started
    to fire 200 cycles later. Whatever the delay, SysTick never finds IRQ0's handler unstarted
    below it (its stacked return address is never IRQ0_Handler's first instruction): arriving
    during IRQ0's entry, it takes IRQ0's frame (the same thread return address), with IRQ0 still
    pending (ICSR.VECTPENDING = 16) and nothing else active (RETTOBASE = 1)."""
    late = 0
    for delay in range(16, 40):
        sim = mcusim.load("nucleo-f746", firmware=str(BIN / "armv7m.elf"), overrides={"/which": 12, "/delay": delay})
        sim.run(seconds="20us")
        irq0_pc, systick_pc, icsr = res(sim, 3)
        assert systick_pc != sym(sim, "IRQ0_Handler"), delay
        if systick_pc == irq0_pc:
            late += 1
            assert icsr & 0x1FF == 15 and (icsr >> 12) & 0x1FF == 16 and icsr & (1 << 11), (delay, hex(icsr))
    assert late >= 1


# --- B1.5.19 SCR.SLEEPONEXIT: sleep on return to thread mode, without unstacking -------------------------------
def test_sleeponexit_sleeps_with_the_frame_still_stacked_and_the_thread_never_runs_again():
    """SysTick every 1000 cycles; thread mode sets SLEEPONEXIT then counts in `wakes`. After the
    first handler returns, the core sleeps on the stacked frame (MSP stays 32 bytes below the
    thread's SP) and each later SysTick tail-chains onto it: the thread counts no more."""
    sim = run(13, "30us")
    thread_sp = res(sim, 4)[3]
    wakes, ticks = sim.mcu.read32(sym(sim, "wakes")), sim.mcu.read32(sym(sim, "ticks"))
    assert ticks >= 5 and sim.mcu.cpu.state == "sleep"
    assert sim.mcu.cpu.reg("msp") == (thread_sp - 32) & ~7
    sim.run(seconds="30us")
    assert sim.mcu.read32(sym(sim, "wakes")) == wakes
    assert sim.mcu.read32(sym(sim, "ticks")) >= ticks + 5
    assert sim.mcu.cpu.reg("msp") == (thread_sp - 32) & ~7
