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
        Register("LOAD", 0x4, fields=(Field("RELOAD", 0, 24),)),
        Register("VAL", 0x8, on_read="_read_val", on_write="_write_val", fields=(Field("CURRENT", 0, 24),)),
        Register("CALIB", 0xC, fields=(Field("TENMS", 0, 24, access="r"), Field("SKEW", 30, access="r"),
                                       Field("NOREF", 31, access="r"))),
    )

    def __init__(self, name, mcu, core_clock, ref_clock):
        super().__init__(name)
        self.kernel, self.nvic = mcu.kernel, mcu.nvic
        self.core_clock, self.ref_clock = core_clock, ref_clock
        self._t0 = None      # tick at which counting started (counter held VAL0 then)
        self._val0 = 0
        self._ev = None

    def _clock(self):
        return self.core_clock if self.field("CTRL", "CLKSOURCE") else self.ref_clock

    def _cycles(self):
        return (self.kernel.now - self._t0) // self._clock().period

    def _read_val(self, stored):
        if self._t0 is None:
            return self._val0
        c = self._cycles()
        load = self.value["LOAD"] & 0xFFFFFF
        if c == 0:
            return self._val0
        # the first clock loads LOAD if VAL was 0, otherwise decrements
        if self._val0 == 0:
            return load - ((c - 1) % (load + 1))
        if c <= self._val0:
            return self._val0 - c
        return load - ((c - self._val0 - 1) % (load + 1))

    def _read_ctrl(self, stored):
        return stored

    def _write_val(self, old, new):
        self._val0 = 0
        self.clear_bits("CTRL", 1 << 16)
        self._restart()

    def _write_ctrl(self, old, new):
        if (old ^ new) & 0b101:
            if self._t0 is not None:
                self._val0 = self._read_val(0)
            self._restart()

    def _restart(self):
        if self._ev is not None:
            self._ev.cancel()
            self._ev = None
        if not self.field("CTRL", "ENABLE"):
            self._t0 = None
            return
        self._t0 = self.kernel.now
        load = self.value["LOAD"] & 0xFFFFFF
        first = self._val0 if self._val0 else load + 1
        self._schedule(self._t0 + first * self._clock().period)

    def _schedule(self, t):
        self._ev = self.kernel.at(t, self._zero)

    def _zero(self):
        self.set_bits("CTRL", 1 << 16)
        if self.field("CTRL", "TICKINT"):
            self.nvic.set_pending(SYSTICK)
        load = self.value["LOAD"] & 0xFFFFFF
        if load:
            self._schedule(self.kernel.now + (load + 1) * self._clock().period)
