"""A Cortex-M core running a compiled image (unicorn) on the simulation's kernel and bus.

It implements the CPU interface of :class:`mcusim.firmware.Cpu` that the NVIC drives
(``request_dispatch``): the NVIC says an interrupt may need taking, the core
takes it when the architecture says so. How it runs:

* **Quanta.** The core executes ``emu_start(count=n)`` where n instructions reach up to the next
  scheduled kernel event (or the end of the run). Instruction i of a quantum that starts at tick
  T executes at ``T + i * cpi * period`` (the cycle model: ``cpi`` core cycles per instruction,
  ``[core] cycles_per_instruction``, default 1).
* **MMIO at its instant.** Peripheral pages are mapped with ``mmio_map``; each access goes
  through the bus (the register models) with ``kernel.now`` set to the instant of its
  instruction, counted with a block hook and the exact PC (``count=`` makes the PC exact).
* **Ending a quantum early.** An access that schedules an event before the quantum's end or
  pends an interrupt that can preempt stops the emulation inside the callback. unicorn then
  abandons the instruction and runs it again on resume, so the core *replays* it at once, alone
  (``count=1``), answering its accesses from the record (no second side effect): the quantum
  ends exactly after that instruction.
* **WFI** ends ``emu_start``; the core sleeps (no kernel event at all) until the NVIC reports an
  interrupt that can wake it. A code hook on each WFI of the image tells a WFI that is the
  quantum's last instruction from a quantum that simply ran out.
* **Idle loops**: at a branch to itself the quantum's remaining instructions retire at once
  (:mod:`mcusim.elf.idle`), with the same count and times as spinning them.
* **WFE, YIELD, SEV**: unicorn ends the run on WFE and YIELD (reported as an invalid
  instruction, PC past them) and runs SEV as a NOP (a code hook sets the event register). WFE
  consumes a set event register, else sleeps as WFI.
* **The access record** of the instruction making a peripheral access is keyed by (emu_start
  call, instruction index), so a replay answers from that instruction's own accesses.
* **Exceptions** are the simulator's (unicorn has none): see :mod:`mcusim.elf.exceptions`.
* **Faults** (unmapped or protected access, undefined instruction, a bus fault in a register
  model, an escalated SVC) stop the run with :class:`CoreFault` naming the PC, the function and
  the simulated time.
"""

from __future__ import annotations

import bisect
import ctypes
from typing import ClassVar

from unicorn import Uc, UcError
from unicorn import arm_const as A
from unicorn.unicorn_const import (
    UC_ARCH_ARM,
    UC_ERR_INSN_INVALID,
    UC_HOOK_BLOCK,
    UC_HOOK_CODE,
    UC_HOOK_INTR,
    UC_HOOK_MEM_FETCH_UNMAPPED,
    UC_HOOK_MEM_PROT,
    UC_HOOK_MEM_READ,
    UC_HOOK_MEM_READ_UNMAPPED,
    UC_HOOK_MEM_WRITE,
    UC_HOOK_MEM_WRITE_UNMAPPED,
    UC_MEM_FETCH_UNMAPPED,
    UC_MEM_READ_UNMAPPED,
    UC_MEM_WRITE,
    UC_MEM_WRITE_PROT,
    UC_MEM_WRITE_UNMAPPED,
    UC_MODE_THUMB,
    UC_PROT_ALL,
    UC_PROT_EXEC,
    UC_PROT_READ,
)

from ..errors import BusFault, ConfigError, McusimError, UnsupportedConfiguration
from ..kernel import PRIO_CPU
from . import faults, idle
from .exceptions import ExceptionModel
from .memory import PAGE

MAX_QUANTUM = 1 << 20          # instructions per emu_start at most (the kernel regains control)
# emu_start's "until" address: one no Thumb instruction can have (0 would stop code at address 0,
# the ITCM RAM of a Cortex-M7, before its first instruction)
NO_UNTIL = 0xFFFFFFFF
INTNO_UDEF, INTNO_SWI, INTNO_EXC_EXIT = 1, 2, 8


#: the System Control Space (Armv7-M B3.2): SysTick, NVIC, SCB, the FPU's and debug registers
SCS_BASE, SCS_END = 0xE000E000, 0xE000F000


class CoreFault(McusimError):
    """The firmware faulted (HardFault): an unmapped access, an undefined instruction, ...
    The message names the simulated instant of the faulting instruction (``has_time``)."""

    has_time = True


def _thumb_len(halfword: int) -> int:
    return 4 if (halfword >> 11) in (0b11101, 0b11110, 0b11111) else 2


class CortexMCore:
    """The CPU of an MCU running ``image`` (an :class:`~mcusim.elf.image.ElfImage`)."""

    def __init__(self, mcu, image, memories, kind="cortex-m7", cpi=1, entry_latency=12, boot_address=None):
        self.mcu, self.kernel, self.bus, self.nvic = mcu, mcu.kernel, mcu.bus, mcu.nvic
        self.image, self.memories, self.kind = image, memories, kind
        self.clock = mcu.core_clock
        self.period = mcu.core_clock.period
        self.cpi, self.entry_latency = int(cpi), int(entry_latency)
        self.step_ticks = self.cpi * self.period
        self.stack = []            # Cpu interface (traces look at it); exception numbers are in exc.active
        self.rtos = None
        self.isr_count: dict[int, int] = {}
        self.busy_ticks = 0
        self.instructions = 0      # retired since reset
        self.nvic.cpu = self
        self.uc = uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB)
        uc.ctl_set_cpu_model(A.UC_CPU_ARM_CORTEX_M7 if kind == "cortex-m7" else A.UC_CPU_ARM_CORTEX_M4)
        self._map_memories()
        self._load(image)
        self._map_peripherals()
        uc.hook_add(UC_HOOK_BLOCK, self._on_block)
        self._idle = idle.self_branches(image.segments)
        for addr in sorted(self._idle):      # a branch to itself: fast-forward (after _on_block)
            uc.hook_add(UC_HOOK_BLOCK, self._on_idle, begin=addr, end=addr)
        for addr in sorted(self._unmask):    # after an instruction that may unmask: take what is pending
            uc.hook_add(UC_HOOK_CODE, self._on_unmask, begin=addr, end=addr)
        for addr in sorted(self._wfi):       # a WFI about to execute (even as a quantum's last instruction)
            uc.hook_add(UC_HOOK_CODE, self._on_wfi, begin=addr, end=addr)
        for addr in sorted(self._sev):       # unicorn runs SEV as a NOP: it sets the event register here
            uc.hook_add(UC_HOOK_CODE, self._on_sev, begin=addr, end=addr)
        uc.hook_add(UC_HOOK_INTR, self._on_intr)
        uc.hook_add(UC_HOOK_MEM_READ_UNMAPPED | UC_HOOK_MEM_WRITE_UNMAPPED | UC_HOOK_MEM_FETCH_UNMAPPED
                    | UC_HOOK_MEM_PROT, self._on_bad_access)
        self.exc = ExceptionModel(self)
        self._blocks: dict[int, tuple] = {}
        self._blk_n_cache: dict[tuple, int] = {}
        # run state
        self.state = "run"          # run | sleep (WFI) | fault
        self.cpu_time = 0           # tick of the next instruction
        self._ev = None
        self._in_emu = False
        self._check = False         # an interrupt was pended during an access
        self._stop = None           # why the emulation stopped early
        self._replay = []
        self._held = None           # (pc, IPSR, accesses) of an instruction a watchpoint stopped
        self._interrupted = None    # an exception a signal raised in a device read, raised on return
        self._acc_pc, self._acc, self._acc_key = None, [], None
        self._quantum = 0           # numbers the emu_start calls: an access record is per instruction
        self._wfi_at = None
        self.debug = None           # a gdb server: breakpoints, watchpoints, halts
        self._replaying = False
        self.fault = None
        boot = boot_address if boot_address is not None else 0
        self.exc.reset(boot)
        self._schedule(0)

    # --- loading ---------------------------------------------------------------------------
    def _map_memories(self):
        uc = self.uc
        for m in self.memories:
            perms = (UC_PROT_READ | UC_PROT_EXEC) if m.kind == "flash" else UC_PROT_ALL
            for base in (m.base, *m.aliases):
                uc.mem_map_ptr(base, m.size, perms, ctypes.addressof(m.buffer))

    def _region(self, address, length):
        for m in self.memories:
            off = m.contains(address, length)
            if off is not None:
                return m, off
        return None, None

    def _covered(self, address, length, kinds=("ram",)) -> bool:
        """[address, address+length) lies in memories of these kinds, possibly several adjacent ones
        (an exception frame may straddle the seam between DTCM and SRAM1)."""
        end = address + length
        while address < end:
            for m in self.memories:
                if m.kind in kinds and m.contains(address) is not None:
                    base = next(b for b in (m.base, *m.aliases) if b <= address < b + m.size)
                    address = base + m.size
                    break
            else:
                return False
        return True

    def _load(self, image):
        for seg in image.segments:
            if not self._covered(seg.address, len(seg.data), ("ram", "flash")):
                raise ConfigError(faults.outside(self, image, seg))
            pos = 0
            while pos < len(seg.data):               # region by region (a segment may span two)
                m, off = self._region(seg.address + pos, 1)
                n = min(len(seg.data) - pos, m.size - off)
                m.view[off:off + n] = seg.data[pos:pos + n]
                pos += n
        self._wfi, self._sev, self._unmask = set(), set(), set()
        for seg in image.segments:          # WFI: where the core sleeps; CPSIE/MSR: may unmask
            if not seg.code_addresses:
                continue
            d = seg.data
            for i in range(0, len(d) - 1, 2):
                hw = d[i] | d[i + 1] << 8
                # at the load address and, for code the start-up copies to RAM, where it runs (a
                # match in data never runs: its hook never fires)
                for base in seg.code_addresses:
                    if hw == 0xBF30:
                        self._wfi.add(base + i)
                    elif hw == 0xBF40:
                        self._sev.add(base + i)
                    elif hw & 0xFFF8 == 0xB660:                        # CPSIE i/f
                        self._unmask.add(base + i + 2)
                    elif hw & 0xFFF0 == 0xF380 and i + 3 < len(d) and (d[i + 2] | d[i + 3] << 8) in (
                            0x8810, 0x8811, 0x8812, 0x8813):           # MSR PRIMASK/BASEPRI(_MAX)/FAULTMASK
                        self._unmask.add(base + i + 4)

    def _map_peripherals(self):
        pages = set()
        for base, size, _p in self.bus._entries:
            if any(m.contains(base) is not None for m in self.memories):
                continue
            pages.update(range(base // PAGE, (base + size - 1) // PAGE + 1))
        runs = []
        for page in sorted(pages):
            if runs and runs[-1][1] == page:
                runs[-1][1] = page + 1
            else:
                runs.append([page, page + 1])
        for first, end in runs:
            base = first * PAGE
            self.uc.mmio_map(base, (end - first) * PAGE, self._mmio_read, base, self._mmio_write, base)
            # unicorn splits an unaligned access into aligned ones before _mmio sees it: refuse it here
            self.uc.hook_add(UC_HOOK_MEM_READ | UC_HOOK_MEM_WRITE, self._on_device_access,
                             begin=base, end=end * PAGE - 1)

    # --- symbols -----------------------------------------------------------------------------
    def where(self, pc=None) -> str:
        return self.image.where(self.pc if pc is None else pc)

    def caller(self) -> str | None:
        """The function whose instruction makes the current bus access (the register log)."""
        return self.image.function(self._acc_pc) if self._in_emu and self._acc_pc is not None else None

    @property
    def pc(self) -> int:
        return self.uc.reg_read(A.UC_ARM_REG_PC)

    # --- the CPU interface the NVIC drives -------------------------------------------------
    def request_dispatch(self) -> None:
        if self._in_emu:
            self._check = True
        elif self.state == "sleep" and self.exc.wakes():
            self.state = "run"
            self._schedule(max(self.cpu_time, self._aligned(self.kernel.now)))

    def current_priority(self) -> int:
        return self.exc.execution_priority()

    def _aligned(self, t):
        p = self.period
        return -(-t // p) * p

    def _schedule(self, t):
        if self._ev is not None:
            self._ev.cancel()
        self.cpu_time = t
        self._ev = self.kernel.at(t, self._run, prio=PRIO_CPU)

    # --- running ---------------------------------------------------------------------------
    def _limit(self, t0):
        """The first tick no instruction of a quantum starting at t0 may reach."""
        k = self.kernel
        end = k.end
        limit = end + 1 if end is not None else t0 + MAX_QUANTUM * self.step_ticks
        head = k.peek()
        if head is not None:
            t, prio = head
            if t == t0 and prio > PRIO_CPU:
                t = t0 + 1                 # an observer at this tick sees the instruction at t0
            limit = min(limit, t)
        return limit

    def _run(self):
        self._ev = None
        if self.state != "run":
            return
        dbg = self.debug
        if dbg is not None:
            dbg.before_quantum()            # halted: serve gdb here, simulated time stands still
            if self.state != "run" or self._ev is not None:
                return
        t0 = self.kernel.now
        if self.exc.take_pending(t0):
            if self.debug is not None:
                self.debug.entered()
            return                          # entry scheduled the next run after its latency
        limit = self._limit(t0)
        n = min(MAX_QUANTUM, -(-(limit - t0) // self.step_ticks))
        if n <= 0:
            self._schedule(t0 if limit > t0 else t0 + self.step_ticks)
            return
        if self.debug is not None:
            n = self.debug.budget(n)
        # at a branch to itself the quantum spins to its end (mcusim.elf.idle)
        retired = n if idle.spinning(self, self.pc) else self._emulate(t0, n, limit)
        self.instructions += retired
        self.cpu_time = t = t0 + retired * self.step_ticks
        self.kernel.now = t0
        stop, self._stop = self._stop, None
        debug_stop = None
        if stop is not None:
            kind = stop[0]
            if kind == "fault":
                self._fault(stop[1], stop[2], t)
            elif kind == "wfi" and not self.exc.wakes():
                self.state = "sleep"
            elif kind == "wfe":
                if self.exc.event:
                    self.exc.event = False      # WFE consumes a set event register and goes on
                elif not self.exc.wakes():
                    self.state = "sleep"
            elif kind == "exc_return":
                self.exc.exception_return(stop[1], t)
            elif kind == "svc":
                self.exc.svc(t)
            elif kind == "debug":
                debug_stop = stop[1]
        if self.debug is not None:
            self.debug.after_quantum(debug_stop)
        if self._ev is None and self.state == "run":
            self._schedule(t)

    def _emulate(self, t0, n, limit) -> int:
        """Run up to n instructions from t0; return how many retired."""
        uc = self.uc
        self._q_t0, self._q_limit = t0, limit
        self._q_base, self._blk_addr, self._blk_n, self._blk_size = 0, None, 0, 0
        self._in_emu = True
        self._check = False
        self._quantum += 1
        self._wfi_at = None
        pc = uc.reg_read(A.UC_ARM_REG_PC)
        held = self._held
        if held is not None and held[1] == self._ipsr():
            # (an exception taken at the resume runs first, and returns to the held instruction)
            self._held = None
            if held[0] == pc:           # not moved by the debugger: it retires as it began
                done = self._replay_one(pc, t0, held[2])
                if self._stop is not None or n == 1:
                    return done
                return done + self._emulate(t0 + self.step_ticks, n - 1, limit)
        if not self._thumb():                # a BX to an even address was a quantum's last instruction
            self._stop = ("fault", pc, faults.invstate(self, pc))
            self._in_emu = False
            return 0
        try:
            uc.emu_start(pc | 1, NO_UNTIL, count=n)
            err = None
        except UcError as exc:
            err = exc
        finally:
            self._in_emu = False
            if self.debug is not None:
                self.debug._skip_bp = None
            self._raise_interrupt()
        pc = uc.reg_read(A.UC_ARM_REG_PC)
        stop = self._stop
        if err is None and stop == ("idle",):
            self._stop = None
            return n                        # reached a branch to itself: it spins to the end
        if err is not None and stop is None and err.errno == UC_ERR_INSN_INVALID:
            hint = {0xBF10: "yield", 0xBF20: "wfe"}.get(self._halfword(pc - 2))
            if hint is not None:
                # unicorn ends the run on YIELD and WFE (QEMU's EXCP_YIELD, reported as an invalid
                # instruction) with PC past them: both are valid hints that retire
                err, self._stop = None, ((hint,) if hint == "wfe" else None)
                return self._retired_to(pc)
        if err is not None and stop is None and not self._thumb():
            self._stop = ("fault", pc, faults.invstate(self, pc))        # EPSR.T = 0: INVSTATE
            return self._retired_to(pc)
        if err is not None and (stop is None or stop[0] != "fault"):
            self._stop = ("fault", pc, faults.uc_error_text(err))
            return self._retired_to(pc)
        if stop is not None and stop[0] == "exc_return":
            return self._q_base + self._blk_n
        if stop is not None and stop[0] == "fault":
            return self._retired_to(stop[1])
        retired = self._retired_to(pc)
        if stop is None and (self._wfi_at == pc - 2 or (retired < n and self._halfword(pc - 2) == 0xBF30)):
            self._stop = ("wfi",)          # (the second test: a WFI in code the image copied to RAM)
        if stop is not None and stop[0] == "watch":
            # a debugger's watchpoint on a peripheral register: the stop comes before the
            # instruction retires, as gdb takes an ARM watchpoint (it steps the instruction
            # itself); the accesses it made are held, answered from the record when it runs again
            self._held = (pc, self._ipsr(), list(stop[1]))
            self._stop = ("debug", stop[2])
        elif stop is not None and stop[0] == "replay":
            self._stop = None
            retired += self._replay_one(pc, t0 + retired * self.step_ticks, stop[1])
        return retired

    def _replay_one(self, pc: int, t: int, record) -> int:
        """Finish alone the instruction at ``pc``, abandoned after its accesses ``record``, answering
        its peripheral accesses from the record (no second side effect): 1, the instruction retired."""
        uc = self.uc
        self._replay = list(record)
        self._in_emu = self._replaying = True
        self._q_t0 = t
        self._q_base, self._blk_addr, self._blk_n, self._blk_size = 0, None, 0, 0
        self._quantum += 1
        try:
            uc.emu_start(pc | 1, NO_UNTIL, count=1)
        except UcError as exc:
            self._stop = ("fault", pc, faults.uc_error_text(exc))
        finally:
            self._in_emu = self._replaying = False
            self._replay = []
            self._raise_interrupt()
        return 1

    def _raise_interrupt(self) -> None:
        """Raise what a signal raised inside a device read (:meth:`_mmio_read`), now that the
        emulator has returned."""
        exc, self._interrupted = self._interrupted, None
        if exc is not None:
            raise exc

    def _unprivileged(self) -> bool:
        """Thread mode with CONTROL.nPRIV set."""
        return bool(self.uc.reg_read(A.UC_ARM_REG_CONTROL) & 1) and not self._ipsr()

    def _ipsr(self) -> int:
        return self.uc.reg_read(A.UC_ARM_REG_XPSR) & 0x1FF

    def _thumb(self) -> bool:
        return bool(self.uc.reg_read(A.UC_ARM_REG_XPSR) >> 24 & 1)

    def _halfword(self, address):
        try:
            return int.from_bytes(self.uc.mem_read(address, 2), "little")
        except UcError:
            return None

    def _fault(self, pc, what, t):
        self.kernel.now = t                  # the simulation stands at the faulting instruction
        secs = t / self.kernel.timebase.base_hz
        if isinstance(what, McusimError):
            # (the access that raised it: the write itself, or the one that started a block whose
            # configuration, written earlier, is refused there)
            self.state = "stopped"
            self.fault = (pc, str(what))
            at = f"the access at PC {pc:#010x} ({self.where(pc)})"
            if isinstance(what, UnsupportedConfiguration):
                raise UnsupportedConfiguration(what.periph, what.register, what.field, what.value,
                                               f"{what.why} ({at})")
            try:
                named = type(what)(f"{what} ({at})")
            except TypeError:       # an error class of its own signature
                named = McusimError(f"{what} ({at})")
            raise named from None
        self.state = "fault"
        self.fault = (pc, what)
        raise CoreFault(f"HardFault at t = {float(secs):.9f} s: {what} at PC {pc:#010x} ({self.where(pc)})")

    # --- hooks -----------------------------------------------------------------------------
    def _index(self, addr, pc) -> int:
        """Instructions from a block's start to pc (pc is an instruction boundary in it)."""
        if addr is None:
            return 0
        offs = self._blocks.get(addr)
        if offs is None or (offs and pc > addr + offs[-1]):
            span = max(pc - addr, 0)
            try:
                data = bytes(self.uc.mem_read(addr, span + 4))
            except UcError:                  # the block ends where a memory ends
                data = bytes(self.uc.mem_read(addr, span))
            offs, i = [], 0
            while i < len(data) - 1:
                offs.append(i)
                i += _thumb_len(data[i] | data[i + 1] << 8)
            self._blocks[addr] = offs = tuple(offs)
        return bisect.bisect_left(offs, pc - addr)

    def _retired_to(self, pc) -> int:
        """Instructions of this emu_start retired when the next one is at pc: in the current block,
        those before pc; anywhere else (a fetch that failed after the block's branch), the block."""
        a = self._blk_addr
        if a is not None and not a <= pc <= a + self._blk_size:
            return self._q_base + self._blk_n
        return self._q_base + self._index(a, pc)

    def _on_block(self, uc, address, size, _):
        n = self._blk_n_cache.get((address, size))
        if n is None:
            n = self._blk_n_cache[(address, size)] = self._index(address, address + size)
        self._q_base += self._blk_n
        self._blk_addr, self._blk_n, self._blk_size = address, n, size

    _ACCESS: ClassVar[dict] = {UC_MEM_READ_UNMAPPED: "read of unmapped", UC_MEM_WRITE_UNMAPPED: "write to unmapped",
               UC_MEM_FETCH_UNMAPPED: "instruction fetch from unmapped", UC_MEM_WRITE_PROT: "write to read-only"}

    def _on_bad_access(self, uc, access, address, size, value, _):
        if self._stop is None:
            what = self._ACCESS.get(access, "access not allowed to")
            extra = " (flash is programmed through the flash interface, not by a store)" \
                if access == UC_MEM_WRITE_PROT else ""
            pc = uc.reg_read(A.UC_ARM_REG_PC)
            self._stop = ("fault", address if access == UC_MEM_FETCH_UNMAPPED else pc,
                          f"{8 * size}-bit {what} memory at {address:#010x}{extra}"
                          + (faults.unmapped_hint(address, self.kind)
                             if access in (UC_MEM_READ_UNMAPPED, UC_MEM_WRITE_UNMAPPED) else ""))
        return False

    def _on_idle(self, uc, address, size, _):
        if size == self._idle[address] and self._stop is None and not self._replaying \
                and idle.spinning(self, address):
            self._stop = ("idle",)
            uc.emu_stop()

    def _on_device_access(self, uc, access, address, size, value, _):
        if address % size and self._stop is None:     # Armv7-M A3.2.1; the Cortex-M7 faults it
            hit = self.bus.peripheral_at(address & ~3)
            block = hit[0].name if hit is not None else "no register block"
            op = "write to" if access == UC_MEM_WRITE else "read of"
            what = (f"unaligned {8 * size}-bit {op} {address:#010x} ({block}): peripheral and system "
                    "registers take aligned accesses only (an UNALIGNED UsageFault on the chip)")
            self._stop = ("fault", uc.reg_read(A.UC_ARM_REG_PC), what)
            uc.emu_stop()

    def _on_wfi(self, uc, address, size, _):
        self._wfi_at = address

    def _on_sev(self, uc, address, size, _):
        self.exc.event = True

    def _on_unmask(self, uc, address, size, _):
        if self._in_emu and self._stop is None and not self._replay and self.exc.can_preempt():
            self._stop = ("unmask",)
            uc.emu_stop()

    def _on_intr(self, uc, intno, _):
        if self._stop is not None:
            return
        pc = uc.reg_read(A.UC_ARM_REG_PC)
        if intno == INTNO_EXC_EXIT:
            self._stop = ("exc_return", pc | 1)
        elif intno == INTNO_SWI:
            self._stop = ("svc",)
        elif intno == INTNO_UDEF:
            self._stop = ("fault", pc, "undefined instruction")
        elif intno == 7:                         # EXCP_BKPT
            self._stop = ("debug", "T05") if self.debug is not None else ("fault", pc, faults.bkpt_text(self, pc))
        elif intno == 3:                         # EXCP_PREFETCH_ABORT: PC is the failed fetch
            self._stop = ("fault", pc, faults.fetch_fault(pc))
        else:
            self._stop = ("fault", pc, faults.CPU_EXCEPTIONS.get(intno, f"CPU exception {intno}"))
        uc.emu_stop()


    def _mmio(self, uc, address, size, value):
        """One peripheral access by the firmware; value None for a read. Returns the read value."""
        if self._replaying and self._replay:   # the replayed instruction's recorded accesses
            return self._replay.pop(0)[2]
        pc = uc.reg_read(A.UC_ARM_REG_PC)
        index = self._retired_to(pc)
        key = (self._quantum, index)
        if key != self._acc_key:               # a new instruction: a new record of its accesses
            self._acc_pc, self._acc, self._acc_key = pc, [], key
        if self._stop is not None:
            return 0
        if SCS_BASE <= address < SCS_END and self._unprivileged():
            # Armv7-M B3.2: an unprivileged access to the System Control Space is a BusFault (but
            # a write to STIR with CCR.USERSETMPEND set, which this model refuses to set)
            what = "read of" if value is None else "write to"
            why = (f"bus fault: unprivileged {8 * size}-bit {what} {address:#010x}, in the System Control "
                   "Space (CONTROL.nPRIV = 1 in thread mode; Armv7-M B3.2)")
            self._stop = ("fault", pc, why)
            uc.emu_stop()
            return 0
        k = self.kernel
        k.now = self._q_t0 + index * self.step_ticks
        try:
            if value is None:
                result = self.bus.read(address, size)
            else:
                self.bus.write(address, value, size)
                result = 0
        except BusFault as exc:         # the image's fault: a HardFault report
            self._stop = ("fault", pc, str(exc))
            uc.emu_stop()
            return 0
        except McusimError as exc:
            # not a fault of the image: a configuration the simulator does not model, or a limit
            # of the chip under --strict, named as the Python ports' register accesses name it
            self._stop = ("fault", pc, exc)
            uc.emu_stop()
            return 0
        except Exception as exc:   # noqa: BLE001 (a model bug: stop cleanly, report it)
            self._stop = ("fault", pc, f"{type(exc).__name__} in a register model: {exc}")
            uc.emu_stop()
            return 0
        self._acc.append((address, size, result))
        if self.debug is not None and self.debug.watchpoints and not self._replaying:
            hit = self.debug.watch_hit(address, size, value is not None)
            if hit is not None and not (pc == self.debug._skip_bp and index == 0):
                self._stop = ("watch", list(self._acc), hit)
                uc.emu_stop()
                return result
        if self._replaying:
            return result
        nxt = k.next_time()
        if (nxt is not None and nxt < self._q_limit) or (self._check and self.exc.can_preempt()):
            self._stop = ("replay", list(self._acc))
            uc.emu_stop()
        self._check = False
        return result

    def _mmio_read(self, uc, offset, size, base):
        # unicorn passes the offset within the mapped page
        try:
            return self._mmio(uc, base + offset, size, None)
        except BaseException as exc:    # noqa: BLE001 (Ctrl-C, SIGTERM: raised after emu_start returns)
            # a read callback must return a number to ctypes: unicorn's own catch would return
            # None, and Python would print a stray 'Exception ignored' traceback
            self._interrupted = exc
            uc.emu_stop()
            return 0

    def _mmio_write(self, uc, offset, size, value, base):
        self._mmio(uc, base + offset, size, value & ((1 << (8 * size)) - 1))

    # --- helpers for tests, the debugger and the firmware object ---------------------------------
    def read(self, address: int, length: int) -> bytes:
        return bytes(self.uc.mem_read(address, length))

    def write(self, address: int, data: bytes) -> None:
        self.uc.mem_write(address, bytes(data))

    def reg(self, name: str) -> int:
        return self.uc.reg_read(getattr(A, f"UC_ARM_REG_{name.upper()}"))

    def set_reg(self, name: str, value: int) -> None:
        if name.lower() == "pc":           # unicorn takes EPSR.T from bit 0 of a PC write: keep it
            value = (value & ~1) | self._thumb()
        self.uc.reg_write(getattr(A, f"UC_ARM_REG_{name.upper()}"), value)
