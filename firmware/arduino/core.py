"""The Arduino AVR core (ArduinoCore-avr 1.8.x: wiring.c, wiring_digital.c, wiring_analog.c,
WInterrupts.c) for the ATmega328P at 16 MHz, over the simulated registers.

Function names are the core's in snake_case. Deviations, as the simulation needs them:

* ``analog_read`` busy-waits on ADSC like the C; it is a coroutine (``await core.analog_read(A0)``)
  because simulated time passes while it spins. The wait blocks on the ADC's completion signal
  instead of simulating each pass of the loop.
* ``delay_microseconds`` (synchronous in the libraries that call it) adds its cycles to a debt the
  running sketch pays at its next ``await core.pay_debt()`` (the module's loop does this each pass).
* ``millis_changed`` (a :class:`~mcusim.firmware.Signal`) fires when Timer0's overflow ISR has
  advanced ``timer0_millis``: a ``loop()`` whose idle pass polls only ``millis()`` waits on it
  instead of running pass after pass that cannot see anything new.
* ``attach_interrupt`` takes an optional declared cost of the user function in cycles (the
  trampoline in WInterrupts.c is part of the figure; the PJRC Encoder's measured 148 cycles is
  the whole ISR).
* ``attach_closed_form`` (no C counterpart) declares that the function attached to an external
  interrupt is a pure function of some pin levels, so the fast engine may apply it in closed form
  to edges nothing else interacts with (:mod:`mcusim.engine.served`). It stands while that
  function is the one attached and the vector runs the core's handler.
* Timer2 is not modelled, so ``init`` leaves it alone (the core would start it in phase-correct
  PWM mode for pins 3 and 11), and ``analog_write`` refuses pins 3/11 and Timer0's pins 5/6.
"""

from __future__ import annotations

from mcusim.fw.arduino.core_api import (  # noqa: F401
    CHANGE,
    FALLING,
    HIGH,
    INPUT,
    INPUT_PULLUP,
    LOW,
    NOT_AN_INTERRUPT,
    OUTPUT,
    RISING,
)

from mcusim.errors import ConfigError
from mcusim.firmware import ClosedForm, IdlePass, Signal, TickForm

# data-space addresses (iom328p.h)
PINB, DDRB, PORTB = 0x23, 0x24, 0x25
PINC, DDRC, PORTC = 0x26, 0x27, 0x28
PIND, DDRD, PORTD = 0x29, 0x2A, 0x2B
TIFR0, EIFR, EIMSK, SREG = 0x35, 0x3C, 0x3D, 0x5F
TCCR0A, TCCR0B, TCNT0, TIMSK0 = 0x44, 0x45, 0x46, 0x6E
EICRA = 0x69
TCCR1A, TCCR1B = 0x80, 0x81
OCR1AL, OCR1AH, OCR1BL, OCR1BH = 0x88, 0x89, 0x8A, 0x8B
ADCL, ADCH, ADCSRA, ADMUX = 0x78, 0x79, 0x7A, 0x7C
TIMER0_OVF_vect, INT0_vect, INT1_vect = 16, 1, 2

A0, A1, A2, A3, A4, A5, A6, A7 = range(14, 22)
# pins_arduino.h (standard / eightanaloginputs): digital pin -> (port, bit)
_PORTS = {"B": (PINB, DDRB, PORTB), "C": (PINC, DDRC, PORTC), "D": (PIND, DDRD, PORTD)}
_PIN = {**{d: ("D", d) for d in range(8)}, **{d: ("B", d - 8) for d in range(8, 14)},
        **{d: ("C", d - 14) for d in range(14, 20)}}
_PWM_TIMER1 = {9: 1 << 7, 10: 1 << 5}  # COM1A1, COM1B1

MILLIS_INC, FRACT_INC, FRACT_MAX = 1, 3, 125  # 16 MHz: 1024 µs per Timer0 overflow
TIMER0_OVF_CYCLES = 80   # declared cost of ISR(TIMER0_OVF_vect), ≈ 5 µs (reference sheet §3)
INT_TRAMPOLINE_CYCLES = 60  # WInterrupts.c ISR + call of the user function, when none is declared


class ArduinoCore:
    def __init__(self, mcu, adc=None):
        self.mcu, self.bus, self.cpu, self.rtos, self.irq = mcu, mcu.bus, mcu.cpu, mcu.rtos, mcu.irq
        self._read, self._write = mcu.bus.read, mcu.bus.write
        self.adc = adc
        self.timer0_overflow_count = 0
        self.timer0_millis = 0
        self.timer0_fract = 0
        self.millis_changed = Signal()
        self.int_func = [None, None]
        # WInterrupts.c's ISR(INT0_vect)/ISR(INT1_vect): call the attached function (one object
        # each, so a closed form can tell that the vector still runs it)
        self._int_isr = (lambda: self.int_func[0](), lambda: self.int_func[1]())
        self.analog_reference = 1  # DEFAULT: AVcc
        self.debt_cycles = 0
        self.isr_cycles = {0: INT_TRAMPOLINE_CYCLES, 1: INT_TRAMPOLINE_CYCLES}
        isr = self.timer0_ovf_isr       # one bound object: the tick form stands while it is the vector's
        self.cpu.vector(TIMER0_OVF_vect, isr, cost=TIMER0_OVF_CYCLES)
        self.cpu.tick_form(TIMER0_OVF_vect, TickForm(isr, self.millis_changed, self._millis_after,
                                                     self._overflows))

    # --- registers --------------------------------------------------------------------------
    def _r(self, a):
        return self._read(a, 1)

    def _w(self, a, v):
        self._write(a, v & 0xFF, 1)

    def cli(self):
        self.irq.set_i(False)

    def sei(self):
        self.irq.set_i(True)

    no_interrupts, interrupts = cli, sei

    # --- wiring.c ---------------------------------------------------------------------------
    def init(self) -> None:
        self.sei()
        self._w(TCCR0A, self._r(TCCR0A) | 0b11)          # WGM01 | WGM00: fast PWM
        self._w(TCCR0B, self._r(TCCR0B) | 0b011)         # CS01 | CS00: clk/64
        self._w(TIMSK0, self._r(TIMSK0) | 1)             # TOIE0
        self._w(TCCR1B, 0)
        self._w(TCCR1B, self._r(TCCR1B) | 0b011)         # CS11 | CS10: clk/64
        self._w(TCCR1A, self._r(TCCR1A) | 1)             # WGM10: 8-bit phase-correct PWM
        if self.adc is not None:
            self._w(ADCSRA, self._r(ADCSRA) | 0b111)     # ADPS2:0 = clk/128
            self._w(ADCSRA, self._r(ADCSRA) | 0x80)      # ADEN

    def timer0_ovf_isr(self) -> None:
        self._timer0_ovf()
        self.millis_changed.fire()      # simulation: wakes a loop() waiting for millis() to move

    def _timer0_ovf(self) -> None:
        # the body of ISR(TIMER0_OVF_vect) in wiring.c
        m = self.timer0_millis + MILLIS_INC
        f = self.timer0_fract + FRACT_INC
        if f >= FRACT_MAX:
            f -= FRACT_MAX
            m += 1
        self.timer0_fract = f
        self.timer0_millis = m & 0xFFFFFFFF
        self.timer0_overflow_count = (self.timer0_overflow_count + 1) & 0xFFFFFFFF

    # simulation: the ISR as a TickForm (the fast engine serves overflows whose loop() pass is idle)
    def _millis_after(self, n: int) -> int:
        """``timer0_millis`` after ``n`` more overflows (nothing changes)."""
        m, f = self.timer0_millis, self.timer0_fract
        for _ in range(n):
            m, f = m + MILLIS_INC, f + FRACT_INC
            if f >= FRACT_MAX:
                f -= FRACT_MAX
                m += 1
        return m & 0xFFFFFFFF

    def _overflows(self, n: int) -> None:
        """What ``n`` runs of the ISR do; the signal is counted, its waiter serves an idle pass."""
        for _ in range(n):
            self._timer0_ovf()
        self.millis_changed.count += n

    def idle_pass(self, cycles: int, idle) -> IdlePass:
        """Simulation: the :class:`IdlePass` of a ``loop()`` whose pass reads ``millis()`` only and,
        while ``idle(millis)`` holds, does nothing else for ``cycles`` (the sketch's own rule). It
        stands while no delay is owed and no register log watches SREG (``millis()`` reads and
        writes it)."""
        sreg = self.bus.peripheral_at(SREG)[0]
        return IdlePass(cycles, idle, lambda: not self.debt_cycles and sreg.access_log is None)

    def millis(self) -> int:
        old = self._r(SREG)
        self.cli()
        m = self.timer0_millis
        self._w(SREG, old)
        return m

    def micros(self) -> int:
        old = self._r(SREG)
        self.cli()
        m = self.timer0_overflow_count
        t = self._r(TCNT0)
        if self._r(TIFR0) & 1 and t < 255:
            m += 1
        self._w(SREG, old)
        return (((m << 8) + t) * 4) & 0xFFFFFFFF

    def delay_microseconds(self, us: int) -> None:
        """wiring.c at 16 MHz: ``us`` is an unsigned int (16 bits); 1 or less returns at once (the
        call's ~16 cycles are the microsecond); else ``us <<= 2; us -= 5`` (in 16 bits) loop
        iterations of 4 cycles after ~20 cycles of call and set-up: 16·us cycles up to 16383 µs,
        and a count that wraps beyond."""
        us &= 0xFFFF
        if us <= 1:
            self.debt_cycles += 16
            return
        self.debt_cycles += 4 * (((us << 2) - 5) & 0xFFFF) + 20

    async def pay_debt(self) -> None:
        if self.debt_cycles:
            n, self.debt_cycles = self.debt_cycles, 0
            await self.cpu.cycles(n)

    # --- wiring_digital.c -------------------------------------------------------------------
    def _port(self, pin):
        try:
            port, bit = _PIN[pin]
        except KeyError:
            raise ConfigError(f"pin {pin} has no digital function on the ATmega328P Pro Mini") from None
        return _PORTS[port], 1 << bit

    def pin_mode(self, pin: int, mode: int) -> None:
        (_, ddr, port), bit = self._port(pin)
        old = self._r(SREG)
        self.cli()
        if mode == INPUT:
            self._w(ddr, self._r(ddr) & ~bit)
            self._w(port, self._r(port) & ~bit)
        elif mode == INPUT_PULLUP:
            self._w(ddr, self._r(ddr) & ~bit)
            self._w(port, self._r(port) | bit)
        else:
            self._w(ddr, self._r(ddr) | bit)
        self._w(SREG, old)

    def _turn_off_pwm(self, pin: int) -> None:
        com = _PWM_TIMER1.get(pin)
        if com is not None:
            self._w(TCCR1A, self._r(TCCR1A) & ~com)

    def digital_write(self, pin: int, val: int) -> None:
        (_, _, port), bit = self._port(pin)
        self._turn_off_pwm(pin)  # as the core does: digitalWrite on a PWM pin disconnects the timer
        old = self._r(SREG)
        self.cli()
        self._w(port, (self._r(port) | bit) if val else (self._r(port) & ~bit))
        self._w(SREG, old)

    def digital_read(self, pin: int) -> int:
        (pin_reg, _, _), bit = self._port(pin)
        self._turn_off_pwm(pin)
        return HIGH if self._r(pin_reg) & bit else LOW

    # --- Arduino.h pin macros, for libraries that read registers directly -----------------------
    def port_input_register(self, pin: int) -> int:
        return self._port(pin)[0][0]

    def digital_pin_to_bit_mask(self, pin: int) -> int:
        return self._port(pin)[1]

    read8 = _r

    # --- wiring_analog.c --------------------------------------------------------------------
    def analog_write(self, pin: int, val: int) -> None:
        self.pin_mode(pin, OUTPUT)
        if val == 0:
            self.digital_write(pin, LOW)
        elif val == 255:
            self.digital_write(pin, HIGH)
        elif pin in _PWM_TIMER1:
            self._w(TCCR1A, self._r(TCCR1A) | _PWM_TIMER1[pin])
            lo, hi = (OCR1AL, OCR1AH) if pin == 9 else (OCR1BL, OCR1BH)
            v = val & 0xFFFF                   # OCR1A = val: the int's 16 bits, high byte first
            self._w(hi, v >> 8)
            self._w(lo, v & 0xFF)
        else:
            raise ConfigError(f"analogWrite({pin}): only pins 9 and 10 (Timer1) are modelled")

    async def analog_read(self, pin: int) -> int:
        if pin >= 14:
            pin -= 14
        self._w(ADMUX, (self.analog_reference << 6) | (pin & 0x07))
        self._w(ADCSRA, self._r(ADCSRA) | (1 << 6))      # ADSC
        while self._r(ADCSRA) & (1 << 6):                 # while (bit_is_set(ADCSRA, ADSC));
            await self.rtos.wait_signal(self.adc.done)
        low = self._r(ADCL)
        high = self._r(ADCH)
        return (high << 8) | low

    # --- WInterrupts.c ----------------------------------------------------------------------
    def digital_pin_to_interrupt(self, pin: int) -> int:
        return {2: 0, 3: 1}.get(pin, NOT_AN_INTERRUPT)

    def attach_interrupt(self, n: int, fn, mode: int, cycles: int | None = None) -> None:
        if n not in (0, 1):
            return
        self.int_func[n] = fn
        if cycles is not None:
            self.isr_cycles[n] = cycles
        self.cpu.vector((INT0_vect, INT1_vect)[n], self._int_isr[n], cost=self.isr_cycles[n])
        self._w(EICRA, (self._r(EICRA) & ~(3 << 2 * n)) | (mode << 2 * n))
        self._w(EIMSK, self._r(EIMSK) | (1 << n))

    def set_isr_cycles(self, n: int, cycles: int) -> None:
        """Declare the cost of external interrupt n's whole ISR (e.g. the Encoder's measured 148)."""
        self.isr_cycles[n] = cycles
        if self.int_func[n] is not None:
            self.attach_interrupt(n, self.int_func[n], (self._r(EICRA) >> 2 * n) & 3)

    def attach_closed_form(self, n: int, pins, step, walk=None) -> None:
        """Simulation: the function attached to external interrupt ``n`` does exactly
        ``step(*levels)``, ``levels`` being the levels (0/1) its pins ``pins`` have when it runs,
        and reads no other register. The fast engine then serves edges that nothing else
        interacts with in closed form; while a register log watches the pins' PINx reads, or once
        another function is attached (or none), it runs the function itself. ``walk(levels)``,
        if given, does ``step`` for each tuple of ``levels`` in order (:class:`ClosedForm`)."""
        fn = self.int_func[n] if n in (0, 1) else None
        if fn is None:
            raise ConfigError(f"attach_closed_form({n}): nothing is attached to interrupt {n}")
        ports = []
        for pin in pins:
            address = self._port(pin)[0][0]
            ports.append(self.bus.peripheral_at(address)[0])
        nets = [self.pin_net(pin) for pin in pins]
        valid = lambda: self.int_func[n] is fn and all(p.access_log is None for p in ports)
        self.cpu.closed_form((INT0_vect, INT1_vect)[n], ClosedForm(self._int_isr[n], nets, step, valid, walk))

    def pin_net(self, pin: int):
        """The net of digital pin ``pin`` (simulation)."""
        port, bit = _PIN.get(pin, (None, None))
        if port is None:
            self._port(pin)        # the error
        return self.mcu.pin(f"P{port}{bit}")

    def detach_interrupt(self, n: int) -> None:
        if n not in (0, 1):         # WInterrupts.c: interruptNum < EXTERNAL_NUM_INTERRUPTS, else nothing
            return
        self._w(EIMSK, self._r(EIMSK) & ~(1 << n))
        self.int_func[n] = None
