"""Steady periodic waveforms: a digital level described instead of toggled.

A :class:`Waveform` is high on ``[rise + k·period, rise + k·period + width)`` for every integer k,
low elsewhere (0 < width < period, all in base ticks). A timer whose registers do not change
publishes one on its output port for each PWM channel; nets and ports carry it
(:mod:`mcusim.signals`), and whoever needs an edge derives it exactly from the descriptor:
:meth:`Waveform.level_at` for a level read at any tick, :meth:`Waveform.next_edge` for the next
transition (a VCD writer, or an expander feeding a listener that needs every edge).

A waveform object is immutable; a change of the waveform (a register write, a preload reaching
the shadow register) is a new object, or a constant level, published at its exact tick.
"""

from __future__ import annotations


class Waveform:
    """``end``: the tick at which the owner already knows it will publish again (a preload reaching
    the shadow register at the next update event), or None. No edge at or after ``end`` is
    expanded from this descriptor: the owner's state at ``end`` decides."""

    __slots__ = ("end", "kernel", "period", "rise", "width")

    def __init__(self, kernel, rise: int, period: int, width: int, end: int | None = None):
        if not 0 < width < period:
            raise ValueError(f"waveform width {width} must lie strictly between 0 and the period {period}")
        self.kernel, self.rise, self.period, self.width = kernel, int(rise), int(period), int(width)
        self.end = end

    def level_at(self, t: int) -> int:
        return 1 if (t - self.rise) % self.period < self.width else 0

    def settled_level(self, t: int) -> int:
        """The level at ``t`` as far as this descriptor is valid: before ``end``, or its last
        level before ``end`` (what an edge listener has been told)."""
        if self.end is not None and t >= self.end:
            t = self.end - 1
        return 1 if (t - self.rise) % self.period < self.width else 0

    @property
    def level(self) -> int:
        """The level now."""
        return 1 if (self.kernel.now - self.rise) % self.period < self.width else 0

    def next_edge(self, t: int) -> tuple[int, int]:
        """(tick, new level) of the first transition strictly after tick ``t``."""
        p = (t - self.rise) % self.period
        if p < self.width:
            return t + self.width - p, 0
        return t + self.period - p, 1

    def edges(self, a: int, b: int):
        """Transitions (tick, new level) with a < tick <= b, in order."""
        t, lv = self.next_edge(a)
        w, P = self.width, self.period
        if self.end is not None:
            b = min(b, self.end - 1)
        while t <= b:
            yield t, lv
            t += w if lv else P - w   # high for the width after a rise, low for the rest
            lv ^= 1

    def same_shape(self, other) -> bool:
        return (isinstance(other, Waveform) and other.period == self.period and other.width == self.width
                and (other.rise - self.rise) % self.period == 0 and self.end is None and other.end is None)

    def __repr__(self):
        return f"Waveform(rise={self.rise}, period={self.period}, width={self.width})"
