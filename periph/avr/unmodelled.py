"""The ATmega328P's I/O registers that no peripheral model covers, declared so that firmware
touching them gets an error naming the register instead of a bus fault at a bare address.

Each is declared at its data-space address (datasheet, "Register Summary") with its reset
value; reading gives that value, and writing anything else raises
:class:`~mcusim.errors.UnsupportedConfiguration` naming the register (the unit behind it is not
modelled). GPIOR0-2 are general-purpose storage and are modelled as such; MCUSR holds the reset
flags (PORF after power-on, each cleared by writing 0); WDTCSR takes the writes of
``wdt_disable()`` (WDCE|WDE, then WDE = 0 within 4 cycles), which leave the watchdog off; a
watchdog left on (WDE set without WDCE, or not cleared within the 4 cycles) or its interrupt is
refused. The board builder maps
only the addresses no declared peripheral took, so a profile that adds a model of one of these
units (a USART0, Timer2) takes its registers over.
"""

from __future__ import annotations

from mcusim.errors import UnsupportedConfiguration
from mcusim.registers import Field, Peripheral, Register

# (name, data-space address, reset value, unit); reset values that depend on fuses or on the
# reset source are given as the datasheet's value after a power-on reset with the Arduino fuses
UNITS = (
    ("TIFR2", 0x37, 0x00, "Timer/Counter2"), ("TIMSK2", 0x70, 0x00, "Timer/Counter2"),
    ("TCCR2A", 0xB0, 0x00, "Timer/Counter2"), ("TCCR2B", 0xB1, 0x00, "Timer/Counter2"),
    ("TCNT2", 0xB2, 0x00, "Timer/Counter2"), ("OCR2A", 0xB3, 0x00, "Timer/Counter2"),
    ("OCR2B", 0xB4, 0x00, "Timer/Counter2"), ("ASSR", 0xB6, 0x00, "Timer/Counter2"),
    ("PCIFR", 0x3B, 0x00, "pin change interrupts"), ("PCICR", 0x68, 0x00, "pin change interrupts"),
    ("PCMSK0", 0x6B, 0x00, "pin change interrupts"), ("PCMSK1", 0x6C, 0x00, "pin change interrupts"),
    ("PCMSK2", 0x6D, 0x00, "pin change interrupts"),
    ("EECR", 0x3F, 0x00, "EEPROM"), ("EEDR", 0x40, 0x00, "EEPROM"), ("EEARL", 0x41, 0x00, "EEPROM"),
    ("EEARH", 0x42, 0x00, "EEPROM"),
    ("SPCR", 0x4C, 0x00, "SPI"), ("SPSR", 0x4D, 0x00, "SPI"), ("SPDR", 0x4E, 0x00, "SPI"),
    ("ACSR", 0x50, 0x00, "analog comparator"), ("DIDR1", 0x7F, 0x00, "analog comparator"),
    ("SMCR", 0x53, 0x00, "sleep modes"),
    ("MCUCR", 0x55, 0x00, "MCU control"), ("SPMCSR", 0x57, 0x00, "self-programming"),
    ("SPL", 0x5D, 0xFF, "stack pointer"), ("SPH", 0x5E, 0x08, "stack pointer"),
    ("WDTCSR", 0x60, 0x00, "watchdog"), ("CLKPR", 0x61, 0x00, "clock prescaler"),
    ("PRR", 0x64, 0x00, "power reduction"), ("OSCCAL", 0x66, 0x00, "oscillator calibration"),
    ("UCSR0A", 0xC0, 0x20, "USART0"), ("UCSR0B", 0xC1, 0x00, "USART0"), ("UCSR0C", 0xC2, 0x06, "USART0"),
    ("UBRR0L", 0xC4, 0x00, "USART0"), ("UBRR0H", 0xC5, 0x00, "USART0"), ("UDR0", 0xC6, 0x00, "USART0"),
)
STORAGE = (("GPIOR0", 0x3E), ("GPIOR1", 0x4A), ("GPIOR2", 0x4B), ("MCUSR", 0x54))
# MCUSR: the reset flags, PORF after a power-on reset; firmware clears them by writing 0
MCUSR_FIELDS = tuple(Field(f, i, access="rc_w0") for i, f in enumerate(("PORF", "EXTRF", "BORF", "WDRF")))
WDE, WDCE, WDIE = 0x08, 0x10, 0x40


class AvrUnmodelled(Peripheral):
    """``AvrUnmodelled(name, free)``: the registers above whose address is in ``free``."""

    BUS_WIDTH = 1
    ACCESS_SIZES = (1,)          # the AVR data bus is 8 bits wide

    def __init__(self, name: str, free, mcu) -> None:
        regs = [Register(reg, addr, reset=reset, width=8,
                         fields=(Field(reg, 0, 8, modelled=False, doc=unit),))
                for reg, addr, reset, unit in UNITS if addr in free]
        regs += [Register(reg, addr, width=8, reset=0x01 if reg == "MCUSR" else 0,
                          fields=MCUSR_FIELDS if reg == "MCUSR" else ())
                 for reg, addr in STORAGE if addr in free]
        self.REGISTERS = tuple(regs)
        self.units = {reg: unit for reg, _, _, unit in UNITS}
        super().__init__(name)
        self.mcu = mcu
        self._wd_timed = None   # WDCE|WDE written: the 4-cycle window for wdt_disable()'s next write

    def write_register(self, reg, data, lanes=-1):
        unit = self.units.get(reg.name)
        if reg.name == "WDTCSR" and not data & WDIE:
            # WDE = 1 enables the watchdog at once (safety level 1, WDTON unprogrammed as on the
            # Arduino fuses); with WDCE it also opens the 4-cycle window in which wdt_disable()
            # writes WDE = 0. Off is all that is modelled: WDE = 1 still set after the window is
            # refused then, as is WDE = 1 written without WDCE at once
            if self._wd_timed is not None:
                self._wd_timed.cancel()
                self._wd_timed = None
            if not data & WDE:
                return
            if data & WDCE:
                k = self.mcu.kernel
                self._wd_timed = k.at(k.now + 4 * self.mcu.core_clock.period, self._wd_left_on, data & 0xFF)
                return
        if unit is not None and data & 0xFF != reg.reset:
            raise UnsupportedConfiguration(self.name, reg.name, None, data & 0xFF,
                                           f"is not supported ({unit}: not modelled)")
        super().write_register(reg, data, lanes)

    def _wd_left_on(self, data):
        self._wd_timed = None
        raise UnsupportedConfiguration(self.name, "WDTCSR", "WDE", 1,
                                       f"(written {data:#04x} with WDCE, and not cleared within the 4 cycles "
                                       "of the timed sequence: the watchdog is on) is not supported "
                                       "(watchdog: not modelled)")


__all__ = ["STORAGE", "UNITS", "AvrUnmodelled"]
