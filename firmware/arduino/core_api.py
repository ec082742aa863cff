"""The slice of the Arduino AVR core (wiring.c, wiring_digital.c, WInterrupts.c) that the library ports call.

A simulated ATmega328P provides one object satisfying :class:`ArduinoCore` per MCU; the ports
never touch pins or interrupt vectors except through it. :class:`DataBus` is the MCU's data space
as seen by code that writes registers directly (``TCCR1B = ...``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol, runtime_checkable

# Arduino.h
LOW, HIGH = 0, 1
INPUT, OUTPUT, INPUT_PULLUP = 0x0, 0x1, 0x2
CHANGE, FALLING, RISING = 1, 2, 3
NOT_AN_INTERRUPT = -1


@runtime_checkable
class ArduinoCore(Protocol):
    def digital_read(self, pin: int) -> int:
        """digitalRead(pin): 0 or 1."""

    def pin_mode(self, pin: int, mode: int) -> None:
        """pinMode(pin, INPUT | OUTPUT | INPUT_PULLUP)."""

    def attach_interrupt(self, n: int, fn: Callable[[], None], mode: int) -> None:
        """attachInterrupt(n, fn, mode): n is the external interrupt number (INT0 = 0, INT1 = 1)."""

    def digital_pin_to_interrupt(self, pin: int) -> int:
        """digitalPinToInterrupt(pin): 0 for D2, 1 for D3 on the 328P, else NOT_AN_INTERRUPT."""

    def no_interrupts(self) -> None:
        """noInterrupts(): cli."""

    def interrupts(self) -> None:
        """interrupts(): sei."""

    def delay_microseconds(self, us: int) -> None:
        """delayMicroseconds(us): busy wait."""

    def port_input_register(self, pin: int) -> int:
        """portInputRegister(digitalPinToPort(pin)): the data-space address of the pin's PINx."""

    def digital_pin_to_bit_mask(self, pin: int) -> int:
        """digitalPinToBitMask(pin): the pin's bit in its port registers."""

    def read8(self, addr: int) -> int:
        """One byte load from data space (``*(volatile uint8_t *)addr``)."""

    def attach_closed_form(self, n: int, pins, step: Callable[..., None]) -> None:
        """Simulation, no C counterpart: the function attached to interrupt n does exactly
        ``step(*levels)`` of the levels of ``pins`` when it runs (the fast engine may apply it in
        closed form)."""


@runtime_checkable
class DataBus(Protocol):
    def read8(self, addr: int) -> int:
        """One byte load from data space (LDS)."""

    def write8(self, addr: int, value: int) -> None:
        """One byte store to data space (STS)."""
