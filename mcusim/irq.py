"""Interrupt controllers. The Cortex-M NVIC: enable, pending, active, priority, as registers.

Peripherals drive interrupt *lines*: ``nvic.set_line(n, level)``. A rising line sets the pending
bit (it stays latched until the handler is entered, as on the chip); when a handler returns and its
line is still asserted, the interrupt becomes pending again. Dispatch decisions (preemption by
priority, 12-cycle entry latency) belong to the CPU model in :mod:`mcusim.firmware`.

System exceptions use negative numbers as in CMSIS: SysTick = -1, PendSV = -2.

:class:`AvrInterrupts` is the AVR model: fixed priority by vector number, a global I flag (SREG
bit 7) cleared on entry and set again by RETI, and one flag per source kept by its peripheral.
"""

from __future__ import annotations

from .registers import Field, Peripheral, Register

SYSTICK = -1
PENDSV = -2
_THREAD_PRIO = 1 << 16  # mcusim.firmware.THREAD_PRIO (thread mode, below every exception)


def _words(name, offset, count):
    # set/clear/read views of the NVIC state; bus_read/write_register below implement them
    return tuple(Register(f"{name}{k}", offset + 4 * k) for k in range(count))


class Nvic(Peripheral):
    """NVIC at 0xE000E100 (ISER, ICER, ISPR, ICPR, IABR, IPR). ``prio_bits`` implemented bits."""

    SIZE = 0x400
    REGISTERS = (
        _words("ISER", 0x000, 8)
        + _words("ICER", 0x080, 8)
        + _words("ISPR", 0x100, 8)
        + _words("ICPR", 0x180, 8)
        + _words("IABR", 0x200, 8)
        + tuple(Register(f"IPR{k}", 0x300 + 4 * k) for k in range(60))
    )

    def __init__(self, name="NVIC", num_irqs=98, prio_bits=4):
        super().__init__(name)
        self.num_irqs, self.prio_bits = num_irqs, prio_bits
        self.enabled: set[int] = set()
        self.pending: set[int] = set()
        self.active: set[int] = set()
        self.lines: dict[int, bool] = {}
        self.priority: dict[int, int] = {}
        self.cpu = None  # the CPU model; told when something may need dispatching
        self.line_listeners = []  # fn(irqn, level) for traces

    # --- peripheral side -------------------------------------------------------------
    def set_line(self, irqn: int, level: bool) -> None:
        level = bool(level)
        if self.lines.get(irqn, False) == level:
            return
        self.lines[irqn] = level
        for fn in self.line_listeners:
            fn(irqn, level)
        if level:
            self.set_pending(irqn)

    def set_pending(self, irqn: int) -> None:
        """Pend ``irqn`` (the CPU decides at the end of the tick's hardware events, and may take
        the entry in place then: ``Cpu.request_dispatch``)."""
        self.pending.add(irqn)
        if self.cpu is not None:
            self.cpu.request_dispatch()

    def prio(self, irqn: int) -> int:
        return self.priority.get(irqn, 0)

    def context_priority(self, irqn: int) -> int:
        """Execution priority while the handler of ``irqn`` runs (its own priority on Cortex-M)."""
        return self.prio(irqn)

    def best_pending(self):
        """(priority, irqn) of the most urgent pending, enabled interrupt, or None."""
        best = None
        enabled, priority = self.enabled, self.priority
        for n in self.pending:
            if n < 0 or n in enabled:
                key = (priority.get(n, 0), n)
                if best is None or key < best:
                    best = key
        return best

    def acknowledge(self, irqn: int) -> None:
        self.pending.discard(irqn)
        self.active.add(irqn)

    def entered(self, irqn: int) -> None:
        """The handler's first instruction runs (entry done): nothing more changes on the NVIC."""

    def complete(self, irqn: int) -> None:
        self.active.discard(irqn)
        if self.lines.get(irqn, False):
            self.pending.add(irqn)

    # --- register side -----------------------------------------------------------------
    @staticmethod
    def _bits(word, s):
        return sum(1 << (n - 32 * word) for n in s if 32 * word <= n < 32 * word + 32)

    @staticmethod
    def _word(reg_name):
        return int("".join(c for c in reg_name if c.isdigit()))

    def _changed(self):
        if self.cpu is not None:
            self.cpu.request_dispatch()

    def bus_read(self, offset, size, address):
        reg = self._reg_at(offset, size, address)
        w = self._word(reg.name)
        if reg.name.startswith(("ISER", "ICER")):
            v = self._bits(w, self.enabled)
        elif reg.name.startswith(("ISPR", "ICPR")):
            v = self._bits(w, self.pending)
        elif reg.name.startswith("IABR"):
            v = self._bits(w, self.active)
        else:
            return super().bus_read(offset, size, address)
        shift = (offset % 4) * 8
        return (v >> shift) & ((1 << (8 * size)) - 1)

    def _set_from(self, word, new, target, add):
        """Set or clear in ``target`` the IRQs 32·word + bit for every 1 bit of the written ``new``."""
        for bit in range(32):
            if new >> bit & 1:
                n = 32 * word + bit
                if n < self.num_irqs:
                    (target.add if add else target.discard)(n)
        self._changed()

    def write_register(self, reg, data, lanes=-1):
        if reg.name.startswith("IPR"):
            return super().write_register(reg, data, lanes)
        word = self._word(reg.name)
        data &= lanes
        if reg.name.startswith("ISER"):
            self._set_from(word, data, self.enabled, True)
        elif reg.name.startswith("ICER"):
            self._set_from(word, data, self.enabled, False)
        elif reg.name.startswith("ISPR"):
            self._set_from(word, data, self.pending, True)
        elif reg.name.startswith("ICPR"):
            self._set_from(word, data, self.pending, False)
            # ARM Generic User Guide: clearing the pending state of a level interrupt whose line is
            # still asserted has no effect
            self.pending |= {n for n, lv in self.lines.items() if lv and n >= 0}

    def bus_write(self, offset, data, size, address):
        reg = self._reg_at(offset, size, address)
        super().bus_write(offset, data, size, address)
        if reg.name.startswith("IPR"):
            keep = (0xFF << (8 - self.prio_bits)) & 0xFF
            word = self._word(reg.name)
            v = self.value[reg.name]
            v &= keep * 0x01010101
            for b in range(4):      # Armv7-M B3.4: the fields of interrupts not implemented are RAZ/WI
                if 4 * word + b >= self.num_irqs:
                    v &= ~(0xFF << (8 * b))
            self.value[reg.name] = v
            for b in range(4):
                self.priority[4 * word + b] = ((v >> (8 * b)) & 0xFF) >> (8 - self.prio_bits)
            self._changed()

    def set_priority(self, irqn: int, prio: int) -> None:
        """Priority in implemented bits (0 = most urgent), as HAL_NVIC_SetPriority(n, prio, 0)."""
        self.priority[irqn] = prio
        if irqn >= 0:
            word, b = divmod(irqn, 4)
            reg = f"IPR{word}"
            v = self.value[reg] & ~(0xFF << (8 * b))
            self.value[reg] = v | ((prio << (8 - self.prio_bits)) & 0xFF) << (8 * b)
        self._changed()


class Scb(Peripheral):
    """The part of the System Control Block that firmware here touches: SHPR2/SHPR3 priorities."""

    SIZE = 0x90
    REGISTERS = (
        Register("SHPR2", 0x1C, on_write="_write_shpr", fields=(Field("PRI_11", 24, 8),)),
        Register("SHPR3", 0x20, on_write="_write_shpr", fields=(Field("PRI_14", 16, 8), Field("PRI_15", 24, 8))),
    )

    def __init__(self, nvic: Nvic, name="SCB"):
        super().__init__(name)
        self.nvic = nvic

    def _write_shpr(self, old, new):
        v = self.value["SHPR3"]
        shift = 8 - self.nvic.prio_bits
        self.nvic.priority[PENDSV] = ((v >> 16) & 0xFF) >> shift
        self.nvic.priority[SYSTICK] = ((v >> 24) & 0xFF) >> shift
        self.nvic._changed()


class AvrInterrupts:
    """ATmega interrupt logic (datasheet "Reset and Interrupt Handling").

    A peripheral reports each source's condition (its flag AND its enable bit) with
    ``set_line(vector, level)``; the flag is a single bit, so an event that arrives while the flag is
    already set is lost, as on the chip. The lowest vector number wins. Entering a handler clears
    the global I flag at once and, when the vector executes after the four-cycle response, calls
    the source's ``on_entry`` hook (which clears the flags the hardware clears on vector entry,
    e.g. TOV1, OCF1A, INTF0, ADIF; TWINT is not cleared). RETI sets I.
    Nesting happens only if a handler sets I itself (``sei()``).
    """

    def __init__(self, num_vectors: int = 26):
        self.num_vectors = num_vectors
        self.lines: dict[int, bool] = {}
        self._raised = 0     # how many lines are high (quiet() asks at every served edge)
        self.on_entry: dict[int, object] = {}
        self.i_flag = False  # SREG.I; the Arduino core's init() starts with sei()
        self.cpu = None
        self.line_listeners = []
        self.active: set[int] = set()

    def set_line(self, vector: int, level: bool) -> None:
        level = bool(level)
        if self.lines.get(vector, False) == level:
            return
        self.lines[vector] = level
        self._raised += 1 if level else -1
        for fn in self.line_listeners:
            fn(vector, level)
        if level and self.cpu is not None:
            self.cpu.request_dispatch()

    def set_i(self, enabled: bool) -> None:
        self.i_flag = bool(enabled)
        if self.i_flag and self.cpu is not None:
            self.cpu.request_dispatch()

    def best_pending(self):
        if not self.i_flag:
            return None
        best = None
        for v, lv in self.lines.items():
            if lv and (best is None or v < best):
                best = v
        return None if best is None else (best, best)

    def quiet(self) -> bool:
        """Global interrupts on, no request pending or in service, the lines untraced: a request
        raised now is taken at once and is all that happens (``Cpu.served``)."""
        return self.i_flag and not self.active and not self.line_listeners and not self._raised

    @staticmethod
    def context_priority(vector: int) -> int:
        return _THREAD_PRIO  # priority never blocks nesting on AVR: only the I flag does

    def acknowledge(self, vector: int) -> None:
        """The request is accepted: I is cleared at once (the response's four cycles push PC)."""
        self.i_flag = False
        self.active.add(vector)

    def entered(self, vector: int) -> None:
        """The vector executes, after the response: the flags the hardware clears "when executing
        the corresponding interrupt handling vector" (TOV0, INTF0, ...) clear now, so one set again
        during the response is the same request (an edge then is lost, as on the chip)."""
        hook = self.on_entry.get(vector)
        if hook is not None:
            hook()

    def complete(self, vector: int) -> None:  # RETI
        self.active.discard(vector)
        self.i_flag = True
