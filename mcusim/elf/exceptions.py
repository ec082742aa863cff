"""The Cortex-M exception model (Armv7-M ARM B1.5), done by the simulator for the unicorn core.

* Priorities: the NVIC's (``nvic.priority``, in implemented bits) for interrupts, SysTick and
  PendSV, the SCB's SHPRx for the other system handlers; Reset -3, NMI -2, HardFault -1. With
  AIRCR.PRIGROUP only the group (preemption) part decides preemption; the whole value orders
  the pending ones (then the lower exception number).
* Execution priority: the most urgent active exception, PRIMASK (0), FAULTMASK (-1), BASEPRI.
* Entry: the frame (r0-r3, r12, lr, return address, xPSR; plus s0-s15 and FPSCR when
  CONTROL.FPCA = 1: eager stacking, no lazy FP state) is pushed on the stack in use (PSP in
  thread mode with CONTROL.SPSEL = 1, else MSP), 8-byte aligned with xPSR bit 9 marking the
  padding; LR = EXC_RETURN, IPSR = the exception number, CONTROL.SPSEL = CONTROL.FPCA = 0,
  PC = the vector at VTOR. The handler's first instruction runs ``entry_latency`` cycles later.
* Return: ``bx lr`` (or ``pop {pc}``, ``ldr pc``) of an EXC_RETURN value in handler mode. If a
  pending exception can preempt the context returned to, it is tail-chained (no unstacking;
  it costs the entry latency); else the frame is popped and the mode, stack and FPCA restored.
* SVC is taken at once if its priority can preempt, else it escalates to a fault (reported).
* Unprivileged thread mode (CONTROL.nPRIV = 1): unicorn hides MSP/PSP and ignores CONTROL
  writes then, so entry borrows handler mode to clear nPRIV first (restored in the frame's
  CONTROL), and return writes the stack pointer before the final CONTROL.
* DeActivate: FAULTMASK clears on return from any exception but NMI; entry and return set the
  event register (WFE). FPCCR.ASPEN = 0: no FP frame.
"""

from __future__ import annotations

import struct

from unicorn import arm_const as A

from .regs import RegBlock

THREAD = 1 << 16
SVCALL, PENDSV_EXC, SYSTICK_EXC = 11, 14, 15
_VALID_RETURNS = {0xFFFFFFF1, 0xFFFFFFF9, 0xFFFFFFFD, 0xFFFFFFE1, 0xFFFFFFE9, 0xFFFFFFED}
_FIXED = {2: -2, 3: -1}                 # NMI, HardFault
_FRAME_REGS = (A.UC_ARM_REG_R0, A.UC_ARM_REG_R1, A.UC_ARM_REG_R2, A.UC_ARM_REG_R3, A.UC_ARM_REG_R12,
               A.UC_ARM_REG_LR)
_S = tuple(getattr(A, f"UC_ARM_REG_S{i}") for i in range(16))
_MASKS = (A.UC_ARM_REG_BASEPRI, A.UC_ARM_REG_PRIMASK, A.UC_ARM_REG_FAULTMASK)
_RETURN = (A.UC_ARM_REG_IPSR, A.UC_ARM_REG_CONTROL, A.UC_ARM_REG_MSP, A.UC_ARM_REG_PSP, A.UC_ARM_REG_FAULTMASK)
_ENTRY = (A.UC_ARM_REG_XPSR, A.UC_ARM_REG_CONTROL, A.UC_ARM_REG_MSP, A.UC_ARM_REG_PSP, A.UC_ARM_REG_PC) + _FRAME_REGS


class ExceptionModel:
    def __init__(self, core):
        self.core, self.uc, self.nvic = core, core.uc, core.nvic
        uc = self.uc
        self._masks = RegBlock(uc, _MASKS)
        self._entry_in = RegBlock(uc, _ENTRY)
        self._entry_out = RegBlock(uc, (A.UC_ARM_REG_CONTROL, A.UC_ARM_REG_XPSR, A.UC_ARM_REG_APSR_NZCV,
                                        A.UC_ARM_REG_LR))
        self._return_in = RegBlock(uc, _RETURN)
        # unicorn ignores MSP/PSP/CONTROL writes (and reads MSP/PSP as 0) while the core is
        # unprivileged (thread mode with CONTROL.nPRIV = 1): on return, CONTROL (nPRIV clear) and
        # the stack pointer are written while still in handler mode, the final CONTROL last
        # (in thread mode, where a change of SPSEL switches the banked SP).
        self._return_out = {psp: RegBlock(uc, (*_FRAME_REGS, A.UC_ARM_REG_CONTROL,
                                               A.UC_ARM_REG_PSP if psp else A.UC_ARM_REG_MSP,
                                               A.UC_ARM_REG_XPSR, A.UC_ARM_REG_APSR_NZCV, A.UC_ARM_REG_CONTROL,
                                               A.UC_ARM_REG_PC)) for psp in (False, True)}
        # entry from unprivileged thread mode: borrow handler mode to clear nPRIV (restored at entry)
        self._privileged = RegBlock(uc, (A.UC_ARM_REG_IPSR, A.UC_ARM_REG_CONTROL, A.UC_ARM_REG_IPSR))
        self._faultmask = RegBlock(uc, (A.UC_ARM_REG_FAULTMASK,))
        self.vtor = 0
        self.prigroup = 0
        self.stkalign = True
        self.sleeponexit = False
        self.active: list[int] = []           # exception numbers, outermost first
        self.event = False                    # the event register (WFE, SEV; B1.5.18)
        self.aspen = True                     # FPCCR.ASPEN: with 0, no FP frame (see enter)
        self._entering = None                 # (exception, tick of its first instruction) during entry
        self.sleep_return = None              # EXC_RETURN of a return that went to sleep (SLEEPONEXIT)

    # --- reset ---------------------------------------------------------------------------------
    def reset(self, boot: int) -> None:
        """Take SP and the reset vector from the vector table at ``boot``."""
        from ..errors import ConfigError
        core = self.core
        m, off = core._region(boot, 8)
        if m is None:
            raise ConfigError(f"{core.image.path}: the vector table at {boot:#010x} is not in the board's memory")
        sp, pc = struct.unpack_from("<II", m.view, off)
        if sp == 0 and pc == 0:
            raise ConfigError(f"{core.image.path}: no vector table at {boot:#010x} (initial SP and reset vector "
                              "are 0): the image is not linked for this board's boot address")
        if not pc & 1 or core._region(pc & ~1, 2)[0] is None:
            raise ConfigError(f"{core.image.path}: the reset vector {pc:#010x} does not point to thumb code "
                              "in the board's memory")
        self.vtor = boot
        uc = self.uc
        uc.reg_write(A.UC_ARM_REG_CONTROL, 0)
        uc.reg_write(A.UC_ARM_REG_MSP, sp & ~3)
        uc.reg_write(A.UC_ARM_REG_PC, pc)      # (bit 0 set: unicorn takes EPSR.T from it)
        self.reset_sp, self.reset_pc = sp & ~3, pc & ~1

    # --- priorities ------------------------------------------------------------------------------
    def priority(self, exc: int) -> int:
        """The group (preemption) priority of exception number ``exc``."""
        if exc in _FIXED:
            return _FIXED[exc]
        return self.group(self.nvic.priority.get(exc - 16, 0))

    def group(self, prio: int) -> int:
        bits = self.nvic.prio_bits
        return ((prio << (8 - bits)) & 0xFF) >> (self.prigroup + 1)

    def execution_priority(self, primask=True) -> int:
        p = THREAD
        for e in self.active:
            p = min(p, self.priority(e))
        base, pm, fm = self._masks.read()
        base &= 0xFF
        if base:
            p = min(p, base >> (self.prigroup + 1))
        if primask and pm & 1:
            p = min(p, 0)
        if fm & 1:
            p = min(p, -1)
        return p

    def _best(self):
        best = self.nvic.best_pending()
        return None if best is None else (self.group(best[0]), best[1] + 16)

    def can_preempt(self) -> bool:
        best = self._best()
        return best is not None and best[0] < self.execution_priority()

    def wakes(self) -> bool:
        """WFI ends on an interrupt that would preempt were PRIMASK clear."""
        best = self._best()
        return best is not None and best[0] < self.execution_priority(primask=False)

    def pending_exception(self):
        best = self._best()
        return None if best is None else best[1]

    # --- entry ---------------------------------------------------------------------------------
    def take_pending(self, t: int) -> bool:
        best = self._best()
        if best is None or best[0] >= self.execution_priority():
            self._entering = None             # the handler's first instruction runs now
            if self.sleep_return is not None:  # woken from SLEEPONEXIT by one that cannot preempt
                ret, self.sleep_return = self.sleep_return, None
                self._unstack(ret, t)
            return False
        if self.sleep_return is not None:      # woken from SLEEPONEXIT: tail-chain onto the frame
            ret, self.sleep_return = self.sleep_return, None
            self.enter(best[1], t, tail_return=ret)
            return True
        entering = self._entering
        if entering is not None and entering[1] == t and self.active and self.active[-1] == entering[0]:
            self._late_arrival(best[1], t)
            return True
        self.enter(best[1], t)
        return True

    def _late_arrival(self, exc: int, t: int) -> None:
        """A more urgent exception became pending while another was being entered (B1.5.6 note;
        Cortex-M7 TRM "late-arriving"): it takes the frame already stacked and runs first; the
        one it displaced stays pending and tail-chains after it."""
        core, nvic = self.core, self.nvic
        old = self.active.pop()
        core.stack.pop()
        nvic.active.discard(old - 16)
        nvic.pending.add(old - 16)
        core.isr_count[old - 16] -= 1
        xpsr, control, _msp, _psp, _pc, *regs = self._entry_in.read()
        self._entry_out.write((control, (xpsr & ~0x1FF) | exc, xpsr & 0xF8000000, regs[5]))
        self._vector(exc, t)
        core._schedule(t)

    def _fault(self, what, t):
        self.core._fault(self.uc.reg_read(A.UC_ARM_REG_PC), what, t)

    def enter(self, exc: int, t: int, tail_return: int | None = None) -> None:
        uc, core = self.uc, self.core
        xpsr, control, msp, psp, ret, *regs = self._entry_in.read()
        if tail_return is None and control & 1 and not xpsr & 0x1FF:
            self._privileged.write((SVCALL, control & ~1, 0))
            xpsr, _, msp, psp, ret, *regs = self._entry_in.read()
        self.event = True                     # exception entry is a WFE wake-up event
        if tail_return is None:
            thread = not self.active and (xpsr & 0x1FF) == 0
            use_psp = thread and bool(control & 2)
            fp = bool(control & 4) and self.aspen   # (unicorn sets FPCA whatever ASPEN says)
            sp = psp if use_psp else msp
            size = 0x68 if fp else 0x20
            new = (sp - size) & 0xFFFFFFFF
            pad = bool(new & 4) and self.stkalign
            new &= ~4 if self.stkalign else ~0
            saved = [*regs, ret, (xpsr & ~(1 << 9)) | (pad << 9) | (1 << 24)]
            frame = struct.pack("<8I", *(v & 0xFFFFFFFF for v in saved))
            if fp:
                frame += struct.pack("<16I", *(v & 0xFFFFFFFF for v in uc.reg_read_batch(_S)))
                frame += struct.pack("<II", uc.reg_read(A.UC_ARM_REG_FPSCR) & 0xFFFFFFFF, 0)
            if not core._covered(new, len(frame)):
                self._fault(f"stacking for exception {exc} at SP {new:#010x} outside RAM (stack overflow?)", t)
            uc.mem_write(new, frame)
            exc_return = 0xFFFFFFE1 | (0 if fp else 0x10) | (8 if thread else 0) | (4 if use_psp else 0)
            uc.reg_write(A.UC_ARM_REG_PSP if use_psp else A.UC_ARM_REG_MSP, new)
        else:
            exc_return = tail_return
        self._entry_out.write((control & ~6, (xpsr & 0xF8000000) | (1 << 24) | exc, xpsr & 0xF8000000,
                               exc_return))
        self._vector(exc, t)
        ticks = core.entry_latency * core.period
        core.busy_ticks += ticks
        self._entering = (exc, t + ticks)
        core._schedule(t + ticks)

    def _vector(self, exc: int, t: int) -> None:
        """PC = the handler of ``exc``; ``exc`` becomes active."""
        uc, core = self.uc, self.core
        m, off = core._region(self.vtor + 4 * exc, 4)
        vector = struct.unpack_from("<I", m.view, off)[0] if m is not None else 0
        if not vector & 1 or core._region(vector & ~1, 2)[0] is None:
            self._fault(f"exception {exc} has no valid vector at VTOR {self.vtor:#010x} + {4 * exc:#x} "
                        f"({vector:#010x})", t)
        uc.reg_write(A.UC_ARM_REG_PC, vector)  # bit 0 (set) is EPSR.T for unicorn
        self.active.append(exc)
        irqn = exc - 16
        self.nvic.acknowledge(irqn)
        core.isr_count[irqn] = core.isr_count.get(irqn, 0) + 1
        core.stack.append(exc)

    def svc(self, t: int) -> None:
        if self.priority(SVCALL) >= self.execution_priority():
            self._fault("SVC executed where SVCall cannot preempt (priority escalation to HardFault)", t)
        self.enter(SVCALL, t)

    # --- return --------------------------------------------------------------------------------
    def exception_return(self, exc_return: int, t: int) -> None:
        core = self.core
        exc, _control, _msp, _psp, faultmask = self._return_in.read()
        exc &= 0x1FF
        self.event = True
        if faultmask & 1 and exc != 2:         # DeActivate(): FAULTMASK clears on return, except from NMI
            self._faultmask.write((0,))
        if exc_return not in _VALID_RETURNS:
            self._fault(f"exception return with invalid EXC_RETURN {exc_return:#010x}", t)
        if not self.active or self.active[-1] != exc:
            self._fault(f"exception return from exception {exc}, which is not the active one "
                        f"(active: {self.active})", t)
        self.active.pop()
        core.stack.pop()
        self.nvic.complete(exc - 16)
        thread = bool(exc_return & 8)
        if thread and self.active:
            self._fault(f"EXC_RETURN {exc_return:#010x} returns to thread mode while exceptions "
                        f"{self.active} are active", t)
        best = self._best()
        if best is not None and best[0] < self.execution_priority():
            self.enter(best[1], t, tail_return=exc_return)          # tail-chaining
            return
        if thread and self.sleeponexit and not self.wakes():
            # SLEEPONEXIT: sleep with the frame still stacked; the interrupt that wakes the core
            # tail-chains onto it (take_pending), else the frame is popped then
            self.sleep_return = exc_return
            core.state = "sleep"
            return
        self._unstack(exc_return, t)

    def _unstack(self, exc_return: int, t: int) -> None:
        uc, core = self.uc, self.core
        _exc, control, msp, psp, _fm = self._return_in.read()
        thread = bool(exc_return & 8)
        use_psp = bool(exc_return & 4)
        fp = not exc_return & 0x10
        sp = psp if use_psp else msp
        size = 0x68 if fp else 0x20
        if not core._covered(sp, size, ("ram", "flash")):
            self._fault(f"unstacking from SP {sp:#010x} outside memory", t)
        raw = core.read(sp, size)
        words = struct.unpack_from("<8I", raw)
        xpsr = words[7]
        ipsr = xpsr & 0x1FF
        if thread != (ipsr == 0):
            self._fault(f"EXC_RETURN {exc_return:#010x} and the stacked IPSR {ipsr} disagree (INVPC)", t)
        if fp:
            uc.reg_write_batch([*zip(_S, struct.unpack_from("<16I", raw, 0x20)),
                                (A.UC_ARM_REG_FPSCR, struct.unpack_from("<I", raw, 0x60)[0])])
        new_sp = (sp + size + (4 if xpsr & (1 << 9) else 0)) & 0xFFFFFFFF
        control = (control & ~6) | (4 if fp else 0) | (2 if (thread and use_psp) else 0)
        self._return_out[use_psp].write((*words[:6], control & ~3, new_sp, xpsr & ~(1 << 9), xpsr & 0xF8000000,
                                         control, (words[6] & ~1) | (xpsr >> 24 & 1)))  # EPSR.T: the frame's
