"""Bit-level waveforms of byte-level buses, for the VCD (:class:`mcusim.trace.VcdTrace`).

The I2C bus (:mod:`mcusim.i2c`) and the LPC43xx USART (:mod:`mcusim.periph.lpc43xx.uart`) are modelled a
byte at a time: they report a byte when it *ends*. These tracers turn each report into the exact
SCL/SDA or TXD edges of that byte, drawn partly in the past. The trace keeps every value change in
a reorder buffer for ``lag`` base ticks (``trace.request_lag``) before writing it, so the VCD still
has non-decreasing timestamps; sigrok-cli's ``i2c`` and ``uart`` decoders and GTKWave read it.

The interface a tracer needs from the trace (``VcdTrace`` has it; a test may pass a stand-in):
``add_wire(scope, name, init) -> var``, ``change(var, tick, value)`` (a change at any tick not
older than ``now - lag``) and ``request_lag(ticks)`` (the lag only grows).

Horizon (lag)
-------------
Each tracer asks for :data:`HORIZON_S` (2 ms) when it is made, and more when a slower bus shows up:
I2C asks, at every bus event (so from a transfer's START on), for ``9*(H + L) + L`` of the master
that owns the bus (the earliest edge drawn for a byte lies ``9*H + 8*L + L//2`` before its end); the
USART asks, at every frame end, for the frame's length plus one PCLK cycle. 2 ms alone covers an
I2C byte down to ~4.8 kHz SCL and a UART frame of 11 bits down to 5500 Bd. Edges that would fall
before what is already written (only possible for the first USART frame slower than 2 ms, or a
master slowing its SCL below ~4.8 kHz in the middle of a transfer) are moved to the oldest tick
still open and counted in ``trace.late_edges`` (0 for every board shipped).

I2C (:class:`I2cWaveform`)
--------------------------
``bus.log`` is replaced by a tap that forwards each entry to the previous log (a list set before,
if any) and draws it. A log set on the bus *after* the tracer was made replaces the tap (the trace
then stops drawing that bus). ``H``/``L`` are the ``scl_high_ticks``/``scl_low_ticks`` of
``bus.owner`` when the entry is logged (still set for ``stop``). Drawn, for an entry at tick ``t``:

* ``start`` (from an idle bus): SDA falls at ``t``, SCL falls at ``t + H`` (a future edge: the
  buffer holds it).
* ``restart``: SDA rises at ``t - H - L//2`` (SCL low), SCL rises at ``t - H``, SDA falls at ``t``,
  SCL falls at ``t + H``.
* ``addr``/``write``/``read`` ``(byte, ack)`` ending at ``e``: ``r = e - 9H - 8L`` (exact even after
  clock stretching, which only lengthens the low phase before ``r``); clock ``k`` (0..8) has SCL high
  on ``[r + k(H+L), r + k(H+L) + H)``; SDA takes bit ``k`` (MSB first; the 9th is the ACK: low =
  ACK, high = NACK) ``L//2`` ticks before that rise (mid-low). The last SCL fall is ``e``.
* ``stop``: SDA falls at ``t - H - L//2``, SCL rises at ``t - H``, SDA rises (STOP) at ``t``.

Between events SDA keeps its last level (the ACK bit after a byte); SCL is low from a byte's end to
the next rise, however long the master or a slave stretches it. (``L//2`` is at least 1 tick.)

USART (:class:`UartWaveform`)
-----------------------------
``usart.tx_log`` is replaced by a log holding the same entries whose ``append`` also draws
the frame (``uart.py`` has no observer list; a reference to the old list taken before the tracer
was made no longer grows). The frame ending at ``tx_log`` tick ``e`` is drawn from the registers at
its end (LCR word length and parity, ``frame_format()``): start bit (low), data bits LSB first,
parity (PS: odd, even, forced 1, forced 0) if LCR.PE, stop bit(s) (high; the line idles high).
Bit ``k`` begins at the exact PCLK-cycle instant ``s + k*bit``, where ``s`` = exact frame end - frame
length; the exact end is the USART's own (a Fraction of PCLK cycles, so back-to-back frames do not
drift), or ``e`` if that is not available. **Rounding:** each edge is put at the first PCLK edge at
or after its exact instant (``ceil(cycles) * PCLK period`` base ticks) -- the USART model's own rule
for the frame end, so the frame ends exactly at ``e``.
"""

from __future__ import annotations

import math
from fractions import Fraction

from .errors import UnsupportedConfiguration
from .recent import KEEP, RecentLog

HORIZON_S = Fraction(2, 1000)     # lag every bus tracer asks for when it is made (seconds)


def horizon_ticks(base_hz: int) -> int:
    """:data:`HORIZON_S` in base ticks (rounded up)."""
    return math.ceil(HORIZON_S * base_hz)


class _LogTap:
    """Stands in for ``bus.log``: each entry goes to the previous log (if any), then to ``fn``.
    Iterating it iterates the previous log."""

    __slots__ = ("fn", "prev")

    def __init__(self, prev, fn):
        self.prev, self.fn = prev, fn

    def append(self, entry) -> None:
        if self.prev is not None:
            self.prev.append(entry)
        self.fn(entry)

    def __iter__(self):
        return iter(() if self.prev is None else self.prev)

    def __len__(self):
        return 0 if self.prev is None else len(self.prev)


class _NotifyingList(RecentLog):
    """A log (:class:`mcusim.recent.RecentLog`, keeping what the log it stands in for keeps) whose
    ``append`` also calls ``fn(item)`` (after storing it)."""

    def __init__(self, items, fn):
        super().__init__(items, keep=getattr(items, "keep", KEEP))
        self.total = getattr(items, "total", len(self))
        self.fn = fn

    def append(self, item) -> None:
        super().append(item)
        self.fn(item)


class I2cWaveform:
    """SCL and SDA of an :class:`mcusim.i2c.I2cBus`, drawn from ``bus.log`` (see the module doc).
    Wires ``<scope>.<bus>_SCL`` and ``<scope>.<bus>_SDA`` (sigrok names channels by the bare
    variable name, so the bus name is part of it)."""

    def __init__(self, trace, bus, scope: str, base_hz: int):
        self.trace, self.bus = trace, bus
        self.scl = trace.add_wire(scope, f"{bus.name}_SCL", init=1)
        self.sda = trace.add_wire(scope, f"{bus.name}_SDA", init=1)
        self.names = (f"{bus.name}_SCL", f"{bus.name}_SDA")
        trace.request_lag(horizon_ticks(base_hz))
        self._master = None
        bus.log = _LogTap(bus.log, self._event)

    def _event(self, entry) -> None:
        t, kind, value = entry
        master = self.bus.owner if self.bus.owner is not None else self._master
        if master is None:
            return
        self._master = master
        H, L = int(master.scl_high_ticks), int(master.scl_low_ticks)
        self.trace.request_lag(9 * (H + L) + L)
        half = max(1, L // 2)
        ch = self.trace.change
        scl, sda = self.scl, self.sda
        if kind == "start":
            ch(sda, t, 0)
            ch(scl, t + H, 0)
        elif kind == "restart":
            ch(sda, t - H - half, 1)
            ch(scl, t - H, 1)
            ch(sda, t, 0)
            ch(scl, t + H, 0)
        elif kind == "stop":
            ch(sda, t - H - half, 0)
            ch(scl, t - H, 1)
            ch(sda, t, 1)
        elif kind in ("addr", "write", "read"):
            byte, ack = value
            bits = [(byte >> (7 - k)) & 1 for k in range(8)] + [0 if ack else 1]
            r = t - 9 * H - 8 * L
            for k, bit in enumerate(bits):
                rise = r + k * (H + L)
                ch(sda, rise - half, bit)
                ch(scl, rise, 1)
                ch(scl, rise + H, 0)


class UartWaveform:
    """The TXD line of a 16550-style LPC43xx :class:`~periph.lpc43xx.uart.Usart` (idle high), drawn
    from ``tx_log`` (see the module doc). Wire ``<scope>.<USART>_TXD``."""

    def __init__(self, trace, usart, scope: str, base_hz: int):
        self.trace, self.usart = trace, usart
        self.name = f"{usart.name}_TXD"
        self.txd = trace.add_wire(scope, self.name, init=1)
        trace.request_lag(horizon_ticks(base_hz))
        usart.tx_log = _NotifyingList(usart.tx_log, self._frame)

    def frame_levels(self, byte: int) -> list[int]:
        """Line level of each bit of the frame of ``byte`` at the current LCR (stop bits as one)."""
        lcr = self.usart.value["LCR"]
        ndata = 5 + (lcr & 3)
        data = [(byte >> k) & 1 for k in range(ndata)]
        levels = [0] + data
        if lcr & 8:
            ones = sum(data) & 1
            levels.append((ones ^ 1, ones, 1, 0)[lcr >> 4 & 3])   # PS: odd, even, forced 1, forced 0
        return levels + [1]

    def _frame(self, entry) -> None:
        tick, byte = entry
        u = self.usart
        try:
            frame, bit, _stop = u.frame_format()
        except UnsupportedConfiguration:    # baud generator stopped since the frame began: no frame
            return
        period = u.clock.period
        end = getattr(u, "_tx_end", None)     # the exact end (PCLK cycles) while the frame ends
        if not isinstance(end, Fraction) or math.ceil(end) * period != tick:
            end = Fraction(tick, period)
        self.trace.request_lag(math.ceil(frame) * period + period)
        start = end - frame
        level = 1
        for k, lv in enumerate(self.frame_levels(byte)):
            if lv != level:
                self.trace.change(self.txd, math.ceil(start + k * bit) * period, lv)
                level = lv
