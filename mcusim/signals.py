"""Digital nets (pins) with edge listeners, and analog nets.

A :class:`Net` is driven by at most one level at a time. Drivers are named (``"GPIOE"``,
``"encoder1"``); an external stimulus (``drive()``) overrides every driver until ``release()``.
Listeners are called synchronously, at the current kernel time, when the resolved level changes.
"""

from __future__ import annotations

import math
from fractions import Fraction

from .errors import McusimError


class Net:
    __slots__ = ("_drivers", "_forced", "_listeners", "level", "name", "pull")

    def __init__(self, name: str, level: int = 0, pull: int | None = None):
        self.name = name
        self.pull = pull  # level when nothing drives the net (None: keeps its last level)
        self.level = level if pull is None else pull
        self._drivers: dict[str, int] = {}
        self._forced: int | None = None
        self._listeners = []

    def listen(self, fn) -> None:
        """``fn(net)`` is called after every level change."""
        self._listeners.append(fn)

    def set(self, driver: str, level: int | None) -> None:
        """Driver ``driver`` drives ``level`` (0/1), or releases the net with ``None``."""
        if level is None:
            self._drivers.pop(driver, None)
        else:
            self._drivers[driver] = 1 if level else 0
        self._resolve()

    def set_pull(self, level: int | None) -> None:
        """Change the level the net takes when nothing drives it (a board pull-up or pull-down)."""
        self.pull = level
        self._resolve()

    def drive(self, level: int) -> None:
        """External stimulus: force the level, taking the net away from every driver."""
        self._forced = 1 if level else 0
        self._resolve()

    def release(self) -> None:
        self._forced = None
        self._resolve()

    @property
    def forced(self) -> bool:
        return self._forced is not None

    def _resolve(self) -> None:
        if self._forced is not None:
            new = self._forced
        elif self._drivers:
            levels = set(self._drivers.values())
            if len(levels) > 1:
                raise McusimError(f"contention on net {self.name}: drivers {sorted(self._drivers)} disagree")
            new = levels.pop()
        elif self.pull is not None:
            new = self.pull
        else:
            new = self.level
        if new != self.level:
            self.level = new
            for fn in self._listeners:
                fn(self)

    def __repr__(self):
        return f"Net({self.name}={self.level})"


def exact_voltage(v) -> Fraction:
    """A voltage as an exact Fraction (a float through its shortest decimal form), so that an ADC's
    ``floor(V * 1024 / Vref)`` decides code boundaries exactly (2.5 V at 5 V is 512)."""
    if isinstance(v, (int, Fraction)):
        return Fraction(v)
    v = float(v)
    if not math.isfinite(v):
        raise McusimError(f"ADC input voltage {v} is not a finite number")
    return Fraction(repr(v))


class AnalogNet:
    """A voltage. Either set directly, or computed on demand by a source callable ``source(t)``."""

    def __init__(self, name: str, volts: float = 0.0):
        self.name, self._volts, self.source = name, volts, None

    def set(self, volts: float) -> None:
        self._volts, self.source = float(volts), None

    def voltage(self, t: int | None = None) -> float:
        return self.source(t) if self.source is not None else self._volts


class Port:
    """A peripheral's output towards the pin mux: 0, 1, or ``None`` (not driving).

    Listeners ``fn(port)`` are called whenever the value changes, including to or from ``None``.
    """

    __slots__ = ("_listeners", "name", "value")

    def __init__(self, name: str):
        self.name, self.value, self._listeners = name, None, []

    def listen(self, fn) -> None:
        self._listeners.append(fn)

    def set(self, value: int | None) -> None:
        if value is not None:
            value = 1 if value else 0
        if value != self.value:
            self.value = value
            for fn in self._listeners:
                fn(self)

    def __repr__(self):
        return f"Port({self.name}={self.value})"
