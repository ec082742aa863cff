"""One microcontroller: its clocks, bus, interrupt controller, CPU, pins and peripherals."""

from __future__ import annotations

from .errors import ConfigError
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

    # bus access as firmware (or a test) does it
    def read8(self, a): return self.bus.read(a, 1)
    def read16(self, a): return self.bus.read(a, 2)
    def read32(self, a): return self.bus.read(a, 4)
    def write8(self, a, v): self.bus.write(a, v, 1)
    def write16(self, a, v): self.bus.write(a, v, 2)
    def write32(self, a, v): self.bus.write(a, v, 4)
