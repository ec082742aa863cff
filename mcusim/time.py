"""Integer time base, clock domains and unit parsing.

Simulation time is an integer number of *base ticks*. The base frequency is the least common
multiple of every clock in the system, so every clock edge falls on an integer tick. Human
quantities ("2ms", "50kHz") are parsed into exact ``Fraction`` values; converting them to ticks
raises :class:`TimeError` unless the result is an integer or rounding is asked for.
"""

from __future__ import annotations

import math
import re
from fractions import Fraction

from .errors import TimeError

# µs with the micro sign (U+00B5) or the Greek mu (U+03BC), which keyboards give as often
_SECONDS = {"s": Fraction(1), "ms": Fraction(1, 10**3), "us": Fraction(1, 10**6), "µs": Fraction(1, 10**6),
            "\u03bcs": Fraction(1, 10**6),
            "ns": Fraction(1, 10**9), "ps": Fraction(1, 10**12), "min": Fraction(60)}
_HERTZ = {"hz": 1, "khz": 10**3, "mhz": 10**6, "ghz": 10**9}
_NUM = r"\s*([+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?)\s*"


def _number(text: str) -> Fraction:
    try:
        return Fraction(text)  # Fraction parses decimal and exponent notation exactly
    except ValueError:      # Python's limit of 4300 digits for an integer read from text
        shown = text.strip()
        raise TimeError(f"bad number {shown[:12]}...{shown[-4:]}: too many digits ({len(shown)})") from None


def _plain_number(value, what: str) -> Fraction:
    """An int/float/Fraction quantity: finite and not negative, else TimeError."""
    if isinstance(value, float) and not math.isfinite(value):
        raise TimeError(f"bad {what} {value!r}: must be a finite number")
    out = Fraction(value) if not isinstance(value, float) else Fraction(str(value))
    if out < 0:
        raise TimeError(f"bad {what} {value!r}: must not be negative")
    return out


def parse_duration(value: str | float | Fraction) -> Fraction:
    """``"2s"``, ``"500ms"``, ``"10us"``, ``"1.5e-3"`` (seconds) -> exact seconds as a Fraction."""
    if isinstance(value, (int, float, Fraction)):
        return _plain_number(value, "duration")
    m = re.fullmatch(_NUM + r"(min|ms|us|µs|\u03bcs|ns|ps|s)?\s*", str(value))
    if not m:
        raise TimeError(f"bad duration {value!r}: expected a number with a unit such as 2s, 500ms, 10us")
    seconds = _number(m.group(1)) * _SECONDS[m.group(2) or "s"]
    if seconds < 0:
        raise TimeError(f"bad duration {value!r}: must not be negative")
    return seconds


def parse_frequency(value: str | float | Fraction) -> Fraction:
    """``"50kHz"``, ``"216MHz"``, ``"16e6"`` (hertz) -> exact hertz as a Fraction."""
    if isinstance(value, (int, float, Fraction)):
        hz = _plain_number(value, "frequency")
        if hz <= 0:
            raise TimeError(f"bad frequency {value!r}: must be positive")
        return hz
    m = re.fullmatch(_NUM + r"([kKmMgG]?[hH][zZ])?\s*", str(value))
    if not m:
        raise TimeError(f"bad frequency {value!r}: expected a number with a unit such as 50kHz or 216MHz")
    hz = _number(m.group(1)) * _HERTZ[(m.group(2) or "hz").lower()]
    if hz <= 0:
        raise TimeError(f"bad frequency {value!r}: must be positive")
    return hz


class TimeBase:
    """The system's base tick: ``base_hz`` = lcm of every clock frequency (all integers in Hz)."""

    def __init__(self, clock_hz):
        freqs = []
        for f in clock_hz:
            f = Fraction(f)
            if f.denominator != 1 or f <= 0:
                raise TimeError(f"clock frequency {f} Hz is not a positive integer")
            freqs.append(int(f))
        if not freqs:
            raise TimeError("a time base needs at least one clock")
        self.base_hz = math.lcm(*freqs)

    def ticks(self, seconds, *, rounding: bool = False) -> int:
        """Exact conversion of seconds (number or unit string) to base ticks."""
        exact = parse_duration(seconds) * self.base_hz
        if exact.denominator != 1:
            if not rounding:
                raise TimeError(
                    f"{seconds} is not a whole number of base ticks at {self.base_hz} Hz "
                    f"({float(exact):.6g} ticks); ask for rounding to accept that")
            return round(exact)
        return int(exact)

    def seconds(self, ticks: int) -> float:
        return ticks / self.base_hz

    def clock(self, name: str, hz) -> Clock:
        return Clock(name, parse_frequency(hz), self)


class Clock:
    """A clock domain: one cycle is an integer number of base ticks."""

    def __init__(self, name: str, hz, base: TimeBase):
        hz = Fraction(hz)
        self.name, self.hz, self.base = name, hz, base
        period = Fraction(base.base_hz) / hz
        if period.denominator != 1:
            raise TimeError(f"clock {name} at {hz} Hz does not divide the base frequency {base.base_hz} Hz")
        self.period = int(period)  # base ticks per cycle

    def cycles(self, n: int) -> int:
        """Base ticks of ``n`` cycles of this clock."""
        return n * self.period

    def next_edge(self, t: int) -> int:
        """The first clock edge at or after base tick ``t`` (edges at multiples of the period)."""
        return -(-t // self.period) * self.period

    def __repr__(self):
        return f"Clock({self.name}, {self.hz} Hz, {self.period} ticks)"
