"""TimerOne.h / TimerOne.cpp (PaulStoffregen, v1.1.1+), the ``__AVR__`` branch, on the ATmega328P.

Register assignments become ``bus.write8``/``bus.read8`` on data-space addresses, in the byte order
avr-gcc emits: a 16-bit store writes the high byte (into TEMP) then the low byte; a 16-bit load
reads the low byte then the high byte. ``TCCR1A |= x`` is a load and a store. The C types are kept
with masks: ``unsigned long`` 32-bit, ``unsigned int`` 16-bit, ``unsigned short pwmPeriod``,
``unsigned char clockSelectBits``.
"""

from __future__ import annotations

from collections.abc import Callable

from mcusim.fw.arduino.core_api import OUTPUT, ArduinoCore, DataBus

F_CPU = 16_000_000

# iom328p.h
TIMSK1 = 0x6F
TCCR1A = 0x80
TCCR1B = 0x81
TCNT1L, TCNT1H = 0x84, 0x85
ICR1L, ICR1H = 0x86, 0x87
OCR1AL, OCR1AH = 0x88, 0x89
OCR1BL, OCR1BH = 0x8A, 0x8B
TCNT1, ICR1, OCR1A, OCR1B = TCNT1L, ICR1L, OCR1AL, OCR1BL   # 16-bit names: the low-byte address
# TCCR1A bits
COM1A1, COM1A0, COM1B1, COM1B0, WGM11, WGM10 = 7, 6, 5, 4, 1, 0
# TCCR1B bits
ICNC1, ICES1, WGM13, WGM12, CS12, CS11, CS10 = 7, 6, 4, 3, 2, 1, 0
# TIMSK1 bits
ICIE1, OCIE1B, OCIE1A, TOIE1 = 5, 2, 1, 0
TIMER1_OVF_VECTOR = 13

# config/known_16bit_timers.h, __AVR_ATmega328P__
TIMER1_A_PIN = 9
TIMER1_B_PIN = 10
TIMER1_ICP_PIN = 8
TIMER1_CLK_PIN = 5

TIMER1_RESOLUTION = 65536    # 65536UL, Timer1 is 16 bit

_U32 = 0xFFFFFFFF


def _bv(bit: int) -> int:
    return 1 << bit


class TimerOne:
    """The global ``Timer1`` object of one firmware image (its statics are instance attributes)."""

    def __init__(self, bus: DataBus, core: ArduinoCore, f_cpu: int = F_CPU):
        self.bus = bus
        self.core = core
        self.f_cpu = f_cpu
        self.pwm_period = 0           # static unsigned short
        self.clock_select_bits = 0    # static unsigned char
        self.isr_callback: Callable[[], None] = self.isr_default_unused

    # 16-bit register access as avr-gcc emits it
    def _write16(self, addr_low: int, value: int) -> None:
        value &= 0xFFFF
        self.bus.write8(addr_low + 1, value >> 8)
        self.bus.write8(addr_low, value & 0xFF)

    def _read16(self, addr_low: int) -> int:
        lo = self.bus.read8(addr_low)
        return (self.bus.read8(addr_low + 1) << 8) | lo

    # Configuration
    def initialize(self, microseconds: int = 1000000) -> None:
        self.bus.write8(TCCR1B, _bv(WGM13))   # set mode as phase and frequency correct pwm, stop the timer
        self.bus.write8(TCCR1A, 0)            # clear control register A
        self.set_period(microseconds)

    def set_period(self, microseconds: int) -> None:
        microseconds &= _U32
        cycles = (((self.f_cpu // 100000) * microseconds) & _U32) // 20
        if cycles < TIMER1_RESOLUTION:
            self.clock_select_bits = _bv(CS10)
            self.pwm_period = cycles
        elif cycles < TIMER1_RESOLUTION * 8:
            self.clock_select_bits = _bv(CS11)
            self.pwm_period = cycles // 8
        elif cycles < TIMER1_RESOLUTION * 64:
            self.clock_select_bits = _bv(CS11) | _bv(CS10)
            self.pwm_period = cycles // 64
        elif cycles < TIMER1_RESOLUTION * 256:
            self.clock_select_bits = _bv(CS12)
            self.pwm_period = cycles // 256
        elif cycles < TIMER1_RESOLUTION * 1024:
            self.clock_select_bits = _bv(CS12) | _bv(CS10)
            self.pwm_period = cycles // 1024
        else:
            self.clock_select_bits = _bv(CS12) | _bv(CS10)
            self.pwm_period = TIMER1_RESOLUTION - 1
        self._write16(ICR1, self.pwm_period)
        self.bus.write8(TCCR1B, _bv(WGM13) | self.clock_select_bits)

    # Run Control
    def start(self) -> None:
        self.bus.write8(TCCR1B, 0)
        self._write16(TCNT1, 0)   # TODO: does this cause an undesired interrupt?
        self.resume()

    def stop(self) -> None:
        self.bus.write8(TCCR1B, _bv(WGM13))

    def restart(self) -> None:
        self.start()

    def resume(self) -> None:
        self.bus.write8(TCCR1B, _bv(WGM13) | self.clock_select_bits)

    # PWM outputs
    def set_pwm_duty(self, pin: int, duty: int) -> None:
        duty_cycle = self.pwm_period
        duty_cycle = (duty_cycle * (duty & 0xFFFF)) & _U32
        duty_cycle >>= 10
        if pin == TIMER1_A_PIN:
            self._write16(OCR1A, duty_cycle)
        elif pin == TIMER1_B_PIN:
            self._write16(OCR1B, duty_cycle)

    def pwm(self, pin: int, duty: int, microseconds: int | None = None) -> None:
        if microseconds is not None and microseconds & _U32:   # pwm(pin, duty, us), us > 0 unsigned
            self.set_period(microseconds)
        if pin == TIMER1_A_PIN:
            self.core.pin_mode(TIMER1_A_PIN, OUTPUT)
            self.bus.write8(TCCR1A, self.bus.read8(TCCR1A) | _bv(COM1A1))
        elif pin == TIMER1_B_PIN:
            self.core.pin_mode(TIMER1_B_PIN, OUTPUT)
            self.bus.write8(TCCR1A, self.bus.read8(TCCR1A) | _bv(COM1B1))
        self.set_pwm_duty(pin, duty)
        self.bus.write8(TCCR1B, _bv(WGM13) | self.clock_select_bits)

    def disable_pwm(self, pin: int) -> None:
        if pin == TIMER1_A_PIN:
            self.bus.write8(TCCR1A, self.bus.read8(TCCR1A) & ~_bv(COM1A1) & 0xFF)
        elif pin == TIMER1_B_PIN:
            self.bus.write8(TCCR1A, self.bus.read8(TCCR1A) & ~_bv(COM1B1) & 0xFF)

    # Interrupt Function
    def attach_interrupt(self, isr: Callable[[], None], microseconds: int | None = None) -> None:
        if microseconds is not None and microseconds & _U32:   # attachInterrupt(isr, us), us > 0
            self.set_period(microseconds)
        self.isr_callback = isr
        self.bus.write8(TIMSK1, _bv(TOIE1))

    def detach_interrupt(self) -> None:
        self.bus.write8(TIMSK1, 0)

    def isr_default_unused(self) -> None:
        pass

    def timer1_ovf_vect(self) -> None:
        """ISR(TIMER1_OVF_vect) { Timer1.isrCallback(); } — bind to vector TIMER1_OVF_VECTOR."""
        self.isr_callback()
