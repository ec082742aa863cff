"""ATmega328P Timer/Counter0 (8-bit), as the Arduino core uses it (millis/micros) and beyond.

Sources: the ATmega328P data sheet and ArduinoCore-avr's init() (mode 3, clk/64, TOIE0; vector 16).
The counting engine is :class:`mcusim.periph.avr.timer1.AvrTimer`, shared with Timer1 and checked against
the per-clock oracle; every choice listed in :mod:`mcusim.periph.avr.timer1` applies here too (free-running
shared prescaler: with divider N the timer clocks fall on CPU cycles that are multiples of N; flags
and pin actions on the clock that leaves the compared value; TCNT0 write blocks the next clock's
compare match).

Modelled: WGM0 modes 0 (normal), 1 (phase-correct, TOP 0xFF), 2 (CTC, TOP OCR0A), 3 (fast PWM, TOP
0xFF), 5 (phase-correct, TOP OCR0A), 7 (fast PWM, TOP OCR0A) with OCR0A/B double buffering, TOV0,
OCF0A, OCF0B (TIFR0, write 1 to clear, cleared on vector entry), TIMSK0, the OC0A/OC0B outputs (D6/D5)
in ``oc`` with the COM0x table of Timer1 (the 8-bit rows), FOC0A/FOC0B in non-PWM modes.
Raises UnsupportedConfiguration: reserved modes 4 and 6, CS0 = 6/7 (external T0 clock), and GTCCR
(TSM, PSRSYNC prescaler reset, PSRASY) set to 1.
"""

from __future__ import annotations

from mcusim.errors import UnsupportedConfiguration
from mcusim.registers import Field, Register

from .timer1 import AvrTimer

MODES8 = {0: ("normal", 0xFF), 1: ("pc", 0xFF), 2: ("ctc", "A"), 3: ("fast", 0xFF), 5: ("pc", "A"),
          7: ("fast", "A")}


class Timer0(AvrTimer):
    """Timer/Counter0.  Register offsets are data-space addresses (attach with base 0)."""

    MAX = 0xFF
    MODES = MODES8
    TIFR, TIMSK = "TIFR0", "TIMSK0"
    REGISTERS = (
        Register("TIFR0", 0x35, width=8, on_read="_read_tifr", on_write="_write_flags", fields=(
            Field("TOV0", 0, access="rc_w1"), Field("OCF0A", 1, access="rc_w1"),
            Field("OCF0B", 2, access="rc_w1"))),
        Register("GTCCR", 0x43, width=8, fields=(
            Field("PSRSYNC", 0, modelled=False, doc="prescaler reset of Timer0/Timer1"),
            Field("PSRASY", 1, modelled=False), Field("TSM", 7, modelled=False))),
        Register("TCCR0A", 0x44, width=8, on_write="_write_tccr", fields=(
            Field("WGM00", 0), Field("WGM01", 1), Field("COM0B0", 4), Field("COM0B1", 5),
            Field("COM0A0", 6), Field("COM0A1", 7))),
        Register("TCCR0B", 0x45, width=8, on_write="_write_tccr", fields=(
            Field("CS00", 0), Field("CS01", 1), Field("CS02", 2), Field("WGM02", 3),
            Field("FOC0B", 6, access="w"), Field("FOC0A", 7, access="w"))),
        Register("TCNT0", 0x46, width=8, on_read="_rd_tcnt", on_write="_wr_tcnt"),
        Register("OCR0A", 0x47, width=8, on_read="_rd_ocra", on_write="_wr_ocra"),
        Register("OCR0B", 0x48, width=8, on_read="_rd_ocrb", on_write="_wr_ocrb"),
        Register("TIMSK0", 0x6E, width=8, on_write="_write_flags", fields=(
            Field("TOIE0", 0), Field("OCIE0A", 1), Field("OCIE0B", 2))),
    )

    def __init__(self, name, mcu, clock, vectors=None):
        super().__init__(name, mcu, clock, vectors or {"compa": 14, "compb": 15, "ovf": 16})

    def _topname(self):
        return "OCR0A" if self._topsrc == "A" else "TOP"

    def _write_tccr(self, old, new):
        a, b = self.value["TCCR0A"], self.value["TCCR0B"]
        mode = (a & 3) | ((b >> 1) & 4)
        if mode not in self.MODES:
            raise UnsupportedConfiguration(self.name, "TCCR0A/TCCR0B", "WGM0", mode,
                                           "(reserved waveform mode) is not supported")
        cs = b & 7
        if cs in (6, 7):
            raise UnsupportedConfiguration(self.name, "TCCR0B", "CS0", cs,
                                           "(external clock on pin T0) is not modelled")
        if (a >> 4) & 3 == 1 and self.MODES[mode][0] in ("fast", "pc"):
            # COM0B = 01 in the PWM modes is "Reserved" (datasheet, TC0 compare output mode tables
            # for fast PWM and phase correct PWM), unlike COM0A = 01 (toggle with WGM02 = 1)
            raise UnsupportedConfiguration(self.name, "TCCR0A", "COM0B", 1,
                                           "(reserved in the PWM modes) is not supported")
        self._configure(mode, cs, {"A": (a >> 6) & 3, "B": (a >> 4) & 3})
        foc = [ch for ch, bit in (("A", 0x80), ("B", 0x40)) if self.value["TCCR0B"] & bit]
        if foc:
            self._force(foc)

    def _rd_tcnt(self, stored):
        return self.counter

    def _wr_tcnt(self, old, new):
        self._set_tcnt(new)

    def _rd_ocra(self, stored):
        return self._buf["A"]

    def _rd_ocrb(self, stored):
        return self._buf["B"]

    def _wr_ocra(self, old, new):
        self._set_ocr("A", new)

    def _wr_ocrb(self, old, new):
        self._set_ocr("B", new)
