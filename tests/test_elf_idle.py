"""The core's fast-forward through idle loops (mcusim.elf.idle): at a branch to itself it retires
the rest of the quantum at once instead of spinning it instruction by instruction. The results
must be the same as spinning, byte for byte: every interrupt entered at the same tick (the DWT
CYCCNT each SysTick handler reads is in the register log), the same pin edges in the VCD, the same
instruction count. tests/elf_src/idle.c; its `/which` topic chooses the loop."""

from __future__ import annotations

import pytest
from elf_build import BIN

import mcusim
from mcusim.elf import idle
from mcusim.reglog import load_logged


def run_both(tmp_path, which, skip, monkeypatch):
    """One run of 3 ms with the fast-forward on or off: (register log bytes, VCD bytes, the core's
    and the image's state at the end)."""
    monkeypatch.setattr(idle, "IDLE_SKIP", skip)
    log, vcd = tmp_path / f"regs{which}{skip}.jsonl", tmp_path / f"wave{which}{skip}.vcd"
    sim, _ = load_logged("nucleo-f746", str(log), firmware=str(BIN / "idle.elf"), overrides={"/which": which})
    sim.trace_vcd(str(vcd))
    sim.run(seconds="3ms")
    cpu, syms = sim.mcu.cpu, sim.firmware.symbols
    state = (cpu.instructions, cpu.cpu_time, cpu.pc, cpu.busy_ticks, cpu.read(syms["stamp"], 256),
             sim.mcu.read32(syms["ticks"]), sim.mcu.read32(syms["tim2_count"]), dict(cpu.isr_count))
    sim.close()
    return log.read_bytes(), vcd.read_bytes(), state


@pytest.mark.parametrize("which", [1, 2, 3, 4])
def test_idle_skip_gives_the_same_register_log_vcd_and_core_state_as_spinning(tmp_path, which, monkeypatch):
    skips, spinning = [], idle.spinning
    monkeypatch.setattr(idle, "spinning", lambda core, pc: spinning(core, pc) and not skips.append(pc))
    on = run_both(tmp_path, which, True, monkeypatch)
    off = run_both(tmp_path, which, False, monkeypatch)
    assert on[0] == off[0] and on[1] == off[1]
    assert on[2] == off[2]                         # instructions, time, busy ticks, CYCCNT stamps
    assert len(skips) > 10                         # the fast-forward did run (the first time)
    assert on[0].count(b"SysTick_Handler") >= (0 if which == 2 else 25)   # the handlers did run
    ticks, tim2 = on[2][5], on[2][6]
    assert (ticks, tim2) == ((0, 0) if which == 2 else (29, 0 if which == 4 else 12))


def test_idle_skip_retires_an_idle_loop_a_quantum_at_a_time(monkeypatch):
    """PRIMASK set, nothing can wake the core: 100 ms of `b .` (21.6 million instructions) is
    retired by one skip per quantum (a quantum ends at each kernel event), not by 21.6 million
    block hooks."""
    skips, spinning = [], idle.spinning
    monkeypatch.setattr(idle, "spinning", lambda core, pc: spinning(core, pc) and not skips.append(pc))
    monkeypatch.setattr(idle, "IDLE_SKIP", True)
    sim = mcusim.load("nucleo-f746", firmware=str(BIN / "idle.elf"), overrides={"/which": 2})
    sim.run(seconds="100ms")
    assert sim.mcu.cpu.instructions > 21_000_000
    assert 0 < len(skips) and len(skips) * 1000 < sim.mcu.cpu.instructions
