"""One microcontroller: its clocks, bus, interrupt controller, CPU, pins and peripherals."""

from __future__ import annotations

import numbers

from .errors import ConfigError, McusimError
from .params import a_or_an
from .signals import Net


class Mcu:
    def __init__(self, name, kernel, bus, core_clock):
        self.name, self.kernel, self.bus, self.core_clock = name, kernel, bus, core_clock
        self.nvic = None
        self.cpu = None
        self.rtos = None
        self.pins: dict[str, Net] = {}
        self.analog: dict[str, object] = {}  # analog input nets by name (A0 ...)
        self.periph: dict[str, object] = {}
        self.clocks: dict[str, object] = {}       # name -> Clock (e.g. "APB1_TIM")
        self.clock_users: dict[str, list] = {}    # clock name -> peripherals with set_kernel_clock

    def pin(self, name: str) -> Net:
        try:
            return self.pins[name]
        except KeyError:
            raise ConfigError(f"{self.name} has no pin {name!r}") from None

    def add_pin(self, name: str) -> Net:
        if name not in self.pins:
            self.pins[name] = Net(name)
        return self.pins[name]

    # bus access as firmware (or a test) does it; the arguments checked here (the ported firmware
    # calls the bus itself, with its own ints)
    def read8(self, a): return self.bus.read(_address(a), 1)
    def read32(self, a): return self.bus.read(_address(a), 4)
    def write8(self, a, v): self.bus.write(_address(a), _value(v, 1), 1)
    def write32(self, a, v): self.bus.write(_address(a), _value(v, 4), 4)

    def read16(self, a):
        """On an 8-bit data bus (AVR) two byte reads, low byte first as avr-gcc emits them (the
        high byte of a 16-bit timer register comes through TEMP)."""
        a = _address(a)
        if self._byte_bus(a):
            lo = self.bus.read(a, 1)
            return lo | self.bus.read(a + 1, 1) << 8
        return self.bus.read(a, 2)

    def write16(self, a, v):
        """On an 8-bit data bus (AVR) two byte writes, high byte first (into TEMP), as avr-gcc."""
        a, v = _address(a), _value(v, 2)
        if self._byte_bus(a):
            self.bus.write(a + 1, v >> 8, 1)
            self.bus.write(a, v & 0xFF, 1)
        else:
            self.bus.write(a, v, 2)

    def _byte_bus(self, a) -> bool:
        hit = self.bus.peripheral_at(a)
        return hit is not None and hit[0].BUS_WIDTH == 1


def _address(a) -> int:
    if isinstance(a, bool) or not isinstance(a, numbers.Integral) or a < 0:
        raise McusimError(f"bus address {a!r:.40}: expected an int >= 0 (such as 0x40010034)")
    return int(a)


def _value(v, size: int) -> int:
    if isinstance(v, bool) or not isinstance(v, numbers.Integral) or not 0 <= v < 1 << (8 * size):
        raise McusimError(f"bus value {v!r:.40}: expected an int in 0 .. {(1 << (8 * size)) - 1:#x} "
                          f"for {a_or_an(f'{8 * size}-bit')} write")
    return int(v)
