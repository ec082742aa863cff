"""SysTick (Armv7-M ARM, B3.3): a 24-bit down-counter raising exception 15 each time it reaches 0.

Counting: once enabled, the counter loads LOAD on the next clock and then decrements once per
clock; the clock on which it goes 1 -> 0 sets COUNTFLAG and (TICKINT=1) pends the exception; the
next clock reloads LOAD. So the period is LOAD+1 clocks. CLKSOURCE=1 counts the processor clock,
0 the external reference (HCLK/8 on STM32). VAL is computed when read; writing VAL clears it and
COUNTFLAG. COUNTFLAG clears when CTRL is read.
"""

from __future__ import annotations

from mcusim.irq import SYSTICK
from mcusim.registers import Field, Peripheral, Register


class SysTick(Peripheral):
    SIZE = 0x10
    REGISTERS = (
        Register("CTRL", 0x0, on_write="_write_ctrl", on_read="_read_ctrl", fields=(
            Field("ENABLE", 0), Field("TICKINT", 1), Field("CLKSOURCE", 2), Field("COUNTFLAG", 16, access="rc_r"))),
        Register("LOAD", 0x4, on_write="_write_load", fields=(Field("RELOAD", 0, 24),)),
        Register("VAL", 0x8, on_read="_read_val", on_write="_write_val", fields=(Field("CURRENT", 0, 24),)),
        Register("CALIB", 0xC, fields=(Field("TENMS", 0, 24, access="r"), Field("SKEW", 30, access="r"),
                                       Field("NOREF", 31, access="r"))),
    )

    def __init__(self, name, mcu, core_clock, ref_clock):
        super().__init__(name)
        self.kernel, self.nvic = mcu.kernel, mcu.nvic
        self.core_clock, self.ref_clock = core_clock, ref_clock
        # the counter held _val0 at the clock edge _t0 (None: stopped), counting with _clk and _load
        self._t0 = None
        self._val0 = 0
        self._clk = ref_clock
        self._load = 0
        self._ev = None

    def _selected_clock(self):
        return self.core_clock if self.field("CTRL", "CLKSOURCE") else self.ref_clock

    def _state_now(self):
        """(last clock edge <= now, VAL at that edge) under the configuration in force."""
        if self._t0 is None:
            return None, self._val0
        per = self._clk.period
        c = (self.kernel.now - self._t0) // per
        edge = self._t0 + c * per
        if c <= self._val0:
            return edge, self._val0 - c
        # after reaching 0 the next clock reloads LOAD, then it counts down again
        return edge, self._load - ((c - self._val0 - 1) % (self._load + 1))

    def _read_val(self, stored):
        return self._state_now()[1]

    def _read_ctrl(self, stored):
        return stored

    def _rebase(self, running: bool) -> None:
        """Freeze the count under the old configuration, then restart it under the new one."""
        edge, val = self._state_now()
        if self._ev is not None:
            self._ev.cancel()
            self._ev = None
        self._val0 = val
        old_clk, self._clk = self._clk, self._selected_clock()
        self._load = self.value["LOAD"] & 0xFFFFFF
        if not running:
            self._t0 = None
            return
        per = self._clk.period
        # count on the selected clock's own edges: after a CLKSOURCE change (or from stopped) that
        # is the new clock's last edge <= now, not the old clock's (which would count the new
        # clock's cycles from an instant before the switch, or off its edges)
        same = edge is not None and self._clk is old_clk
        self._t0 = edge if same else (self.kernel.now // per) * per
        first = self._val0 if self._val0 else self._load + 1  # cycles until VAL next reaches 0
        if self._load or self._val0:
            self._schedule(self._t0 + first * per)

    def _write_val(self, old, new):
        self._val0 = 0  # any write clears VAL and COUNTFLAG; the next clock loads LOAD
        self.clear_bits("CTRL", 1 << 16)
        if self._ev is not None:
            self._ev.cancel()
            self._ev = None
        if self._t0 is not None:
            self._t0 = None
            self._rebase(True)

    def _write_ctrl(self, old, new):
        self._rebase(bool(new & 1))

    def _write_load(self, old, new):
        self._rebase(self._t0 is not None)

    def _schedule(self, t):
        self._ev = self.kernel.at(t, self._zero)

    def _zero(self):
        ctrl = self.value["CTRL"] | (1 << 16)
        self.value["CTRL"] = ctrl
        if self._load:
            self._ev = None
            self._t0, self._val0 = self.kernel.now, 0  # rebase at each wrap: exact and cheap
            self._schedule(self.kernel.now + (self._load + 1) * self._clk.period)
        if ctrl & 2:  # TICKINT. Pended after the next wrap is scheduled (a CPU-priority entry
            # cannot tie with that hardware-priority wrap), so the CPU may take the entry in place
            self.nvic.set_pending(SYSTICK)
