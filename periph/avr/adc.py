"""ATmega328P ADC (datasheet §24 "Analog-to-Digital Converter"), event-driven.

Sources: the ATmega328P data sheet (ADC chapter; vector 21). simavr's ADC errors
(its result scaled by 1023, a uint8_t prescale counter that overflows at /128) are not copied.

Registers (data space): ADCL 0x78, ADCH 0x79, ADCSRA 0x7A (ADEN, ADSC, ADATE, ADIF, ADIE,
ADPS2:0), ADCSRB 0x7B (ADTS2:0; ACME belongs to the analog comparator and raises if set),
ADMUX 0x7C (REFS1:0, ADLAR, MUX3:0), DIDR0 0x7E (ADCnD = 1: PINC bit n reads 0, the pin's digital input buffer off).

Modelled
--------
* Prescaler ADPS = 0..7 -> 2, 2, 4, 8, 16, 32, 64, 128. An ADC clock outside 50-200 kHz is allowed
  (only the real chip's accuracy suffers).
* **Prescaler phase (choice):** as the datasheet says, the prescaler is held in reset while ADEN = 0
  and counts from the tick ADEN is set (``t_en``); ADC clock rising edges are at
  ``t_en + k * N * P`` for k >= 1 (N = division factor, P = CPU period in base ticks).
* A conversion starts on the first ADC clock edge strictly after the tick ADSC is written 1 (so 1 to
  N CPU cycles of synchronisation; ADEN and ADSC written together start at ``t_en + N * P``). It
  takes 13 ADC clocks, 25 for the first conversion after ADEN is set. The input is sampled (the
  AnalogNet's ``voltage(t)`` is called with that tick, after the other hardware events of that tick,
  so a PWM edge of the same tick is seen switched) 1.5 ADC clocks after the start (13.5 for the
  first). At the end ADCL/ADCH are written, ADIF is set and, in single-conversion mode, ADSC is
  cleared. Writing ADSC = 0 has no effect; ADSC = 1 while ADEN = 0 is ignored.
* Free-running mode (ADATE = 1, ADTS = 000): the next conversion starts at the completion tick,
  ADSC stays 1. Clearing ADATE lets the running conversion finish and stops. Other ADTS values with
  ADATE = 1 raise UnsupportedConfiguration.
* ADMUX (channel and reference) is read when the conversion starts; an ADMUX write after the start
  tick applies to the next conversion (the datasheet's "locked at start"). ADPS is read at the start.
* Result = floor(Vin * 1024 / Vref) clamped to [0, 1023], computed exactly on the shortest decimal
  form of the float voltages (so 2.5 V at 5.0 V is 512, 1.0 V is 204). ADLAR changes the
  presentation of ADCH/ADCL at once.
* Reading ADCL locks ADCL/ADCH until ADCH is read; a conversion completing meanwhile is lost
  (``results_lost`` counts them) but still sets ADIF.
* ADIF: cleared by writing 1, or on entry to ``vector`` (21); the interrupt line is ADIF AND ADIE.
* ``adc.done`` (a :class:`mcusim.firmware.Signal`) fires at every completion, after the registers
  are updated, so a busy-wait on ADSC/ADIF can block instead of spinning.
* Clearing ADEN aborts a running conversion (no result, no ADIF); ADSC reads 0.
* References: REFS = 01 AVcc (``avcc``), 11 internal 1.1 V, 00 AREF only if an ``aref`` voltage is
  given (else UnsupportedConfiguration); 10 is reserved and raises. Channels: 0-7 from ``inputs``
  (a channel without an AnalogNet raises), 14 = 1.1 V bandgap, 15 = GND; 8 (temperature sensor)
  and the reserved 9-13 raise. The checks run when a conversion is requested or starts, except
  one: with an ``aref`` voltage, writing REFS = 01 or 11 raises at the ADMUX write (the datasheet
  forbids the internal references while an external voltage is on AREF).

Not modelled: auto-trigger sources other than free running, ADC noise reduction sleep mode, PRR.PRADC,
the analog comparator multiplexer (ACME), the bandgap settling time, INL/DNL/offset errors.
"""

from __future__ import annotations

from fractions import Fraction

from mcusim.errors import UnsupportedConfiguration
from mcusim.firmware import Signal
from mcusim.kernel import PRIO_HW
from mcusim.recent import RecentLog
from mcusim.registers import Field, Peripheral, Register
from mcusim.signals import exact_voltage as _exact

ADEN, ADSC, ADATE, ADIF, ADIE = 0x80, 0x40, 0x20, 0x10, 0x08
ADLAR = 0x20
PRESCALE = (2, 2, 4, 8, 16, 32, 64, 128)
BANDGAP = Fraction(11, 10)




class Adc(Peripheral):
    BUS_WIDTH = 1
    ACCESS_SIZES = (1,)
    REGISTERS = (
        Register("ADCL", 0x78, width=8, access="r", on_read="_read_adcl"),
        Register("ADCH", 0x79, width=8, access="r", on_read="_read_adch"),
        Register("ADCSRA", 0x7A, width=8, on_write="_write_adcsra",
                 fields=(Field("ADPS", 0, 3), Field("ADIE", 3), Field("ADIF", 4, access="w1c"),
                         Field("ADATE", 5), Field("ADSC", 6), Field("ADEN", 7))),
        Register("ADCSRB", 0x7B, width=8, on_write="_write_adcsrb",
                 fields=(Field("ADTS", 0, 3), Field("ACME", 6, modelled=False))),
        Register("ADMUX", 0x7C, width=8, on_write="_write_admux",
                 fields=(Field("MUX", 0, 4), Field("ADLAR", 5), Field("REFS", 6, 2))),
        Register("DIDR0", 0x7E, width=8, on_write="_write_didr0",
                 fields=tuple(Field(f"ADC{n}D", n) for n in range(6))),
    )

    def __init__(self, name, mcu, clock, inputs=None, avcc=5.0, vector=21, aref=None):
        super().__init__(name)
        self.mcu, self.kernel, self.irq, self.clock = mcu, mcu.kernel, mcu.irq, clock
        self.inputs = dict(inputs or {})
        self.avcc, self.aref, self.vector = avcc, aref, vector
        self.data = 0                 # the 10-bit result in ADCH:ADCL
        self.locked = False           # ADCL read, ADCH not yet
        self.results_lost = 0
        self.conversions = 0
        self._t_en = 0                # tick ADEN was set (prescaler phase)
        self._first = True            # next conversion is the first after ADEN
        self._busy = False
        self._t_start = None
        self._admux_latched = None    # ADMUX value at the start, if ADMUX was written after it
        self._result = None
        self._ev_sample = self._ev_done = None
        self.history = RecentLog()   # (t_start, t_sample, t_done, result): the recent ones
        self.done = Signal()          # fired at every completion (for busy-waits on ADSC/ADIF)
        mcu.irq.on_entry[vector] = self._entry_clear

    # --- helpers -------------------------------------------------------------------------------
    @property
    def prescaler(self) -> int:
        return PRESCALE[self.value["ADCSRA"] & 7]

    @property
    def adc_clock_ticks(self) -> int:
        return self.prescaler * self.clock.period

    def _next_adc_edge(self, t):
        pt = self.adc_clock_ticks
        return self._t_en + ((t - self._t_en) // pt + 1) * pt

    def _update_irq(self):
        v = self.value["ADCSRA"]
        self.irq.set_line(self.vector, bool(v & ADIF and v & ADIE))

    def _entry_clear(self):
        self.clear_bits("ADCSRA", ADIF)
        self._update_irq()

    def _check_trigger(self, adcsra, adcsrb):
        if adcsra & ADATE and adcsrb & 7:
            raise UnsupportedConfiguration(self.name, "ADCSRB", "ADTS", adcsrb & 7,
                                           "(auto trigger other than free running) is not modelled")

    def _source(self, admux):
        """(vin_fn(t) -> Fraction, vref Fraction) for an ADMUX value; raises if unsupported."""
        refs, mux = admux >> 6, admux & 0x0F
        if refs == 1:
            vref = _exact(self.avcc)
        elif refs == 3:
            vref = BANDGAP
        elif refs == 0:
            if self.aref is None:
                raise UnsupportedConfiguration(self.name, "ADMUX", "REFS", 0,
                                               "(external AREF) needs an aref voltage given to the model")
            vref = _exact(self.aref)
        else:
            raise UnsupportedConfiguration(self.name, "ADMUX", "REFS", refs, "is reserved")
        if mux < 8:
            net = self.inputs.get(mux)
            if net is None:
                raise UnsupportedConfiguration(self.name, "ADMUX", "MUX", mux,
                                               f"selects ADC{mux}, which has no AnalogNet connected")
            return (lambda t: _exact(net.voltage(t))), vref
        if mux == 14:
            return (lambda t: BANDGAP), vref
        if mux == 15:
            return (lambda t: Fraction(0)), vref
        why = "(temperature sensor) is not modelled" if mux == 8 else "is reserved"
        raise UnsupportedConfiguration(self.name, "ADMUX", "MUX", mux, why)

    @staticmethod
    def code(vin: Fraction, vref: Fraction) -> int:
        n = (vin * 1024) // vref
        return max(0, min(1023, int(n)))

    # --- register hooks ------------------------------------------------------------------------
    def _write_adcsra(self, old, new):
        self._check_trigger(new, self.value["ADCSRB"])
        if not new & ADEN:
            if self._busy:
                self._abort()
            self.clear_bits("ADCSRA", ADSC)
            self._update_irq()
            return
        if not old & ADEN:
            self._t_en, self._first = self.kernel.now, True
        if self._busy:
            self.set_bits("ADCSRA", ADSC)  # writing 0 to ADSC has no effect
        elif new & ADSC:
            self._source(self.value["ADMUX"])  # fail loudly at the request
            self._begin(self._next_adc_edge(self.kernel.now))
        self._update_irq()

    def _write_adcsrb(self, old, new):
        self._check_trigger(self.value["ADCSRA"], new)

    def _write_didr0(self, old, new):
        """DIDR0: "the corresponding PIN Register bit will always read as zero when this bit is set"
        (ADC0-ADC5 are PC0-PC5): port C is told which of its inputs are off."""
        for p in self.mcu.periph.values():
            if getattr(p, "port", None) == "C" and hasattr(p, "inputs_off"):
                p.inputs_off = new & 0x3F

    def _write_admux(self, old, new):
        refs = new >> 6
        if self.aref is not None and refs in (1, 3):
            # §24.9.1: the internal reference options may not be used while an external voltage
            # is applied to AREF (the selected reference is switched onto the AREF pin). Refused
            # at the ADMUX write, where the selection is made, not at the next conversion.
            name = "AVcc" if refs == 1 else "internal 1.1 V"
            raise UnsupportedConfiguration(self.name, "ADMUX", "REFS", refs,
                                           f"({name}) would be shorted to the external {self.aref} V "
                                           "on AREF: with an aref voltage only REFS = 00 is allowed")
        if self._busy and self._admux_latched is None and self.kernel.now >= self._t_start:
            self._admux_latched = old

    def _read_adcl(self, stored):
        self.locked = True
        if self.value["ADMUX"] & ADLAR:
            return (self.data & 3) << 6
        return self.data & 0xFF

    def _read_adch(self, stored):
        self.locked = False
        if self.value["ADMUX"] & ADLAR:
            return self.data >> 2
        return self.data >> 8

    # --- conversion ----------------------------------------------------------------------------
    def _begin(self, t_start):
        pt = self.adc_clock_ticks
        first = self._first
        self._first = False
        self._busy, self._t_start, self._admux_latched, self._result = True, t_start, None, None
        self._t_sample = t_start + (pt * (27 if first else 3)) // 2
        # after every hardware event of the sampling tick (a PWM edge of that tick is seen switched,
        # whichever was scheduled first; the fast engine's waveforms give the same)
        self._ev_sample = self.kernel.at(self._t_sample, self._sample, prio=PRIO_HW + 1)
        self._ev_done = self.kernel.at(t_start + pt * (25 if first else 13), self._complete)

    def _abort(self):
        for ev in (self._ev_sample, self._ev_done):
            if ev is not None:
                ev.cancel()
        self._ev_sample = self._ev_done = None
        self._busy = False

    def _sample(self):
        self._ev_sample = None
        admux = self._admux_latched if self._admux_latched is not None else self.value["ADMUX"]
        vin, vref = self._source(admux)
        self._result = self.code(vin(self.kernel.now), vref)

    def _complete(self):
        self._ev_done = None
        now = self.kernel.now
        self.history.append((self._t_start, self._t_sample, now, self._result))
        self.conversions += 1
        if self.locked:
            self.results_lost += 1
        else:
            self.data = self._result
        self._mirror()
        self.set_bits("ADCSRA", ADIF)
        v = self.value["ADCSRA"]
        if v & ADATE:
            self._check_trigger(v, self.value["ADCSRB"])
            self._begin(now)  # free running: the next conversion starts at once, ADSC stays 1
        else:
            self._busy = False
            self.clear_bits("ADCSRA", ADSC)
        self._update_irq()
        self.done.fire()

    def _mirror(self):
        # stored copies for traces and register dumps (reads go through the hooks)
        if self.value["ADMUX"] & ADLAR:
            self.value["ADCL"], self.value["ADCH"] = (self.data & 3) << 6, self.data >> 2
        else:
            self.value["ADCL"], self.value["ADCH"] = self.data & 0xFF, self.data >> 8
