"""Observer logs that keep the recent past only, so that memory stays flat in run length.

Peripherals keep logs of what happened for tests and scripts to read: a USART's bytes sent and
received with their ticks (``tx_log``, ``rx_log``), an I2C controller's status codes
(``status_log``). A rover transmitting telemetry appends thousands of entries per simulated second,
so a run of an hour would hold millions. A :class:`RecentLog` is a ``list`` (it compares, slices
and iterates like one) that drops its oldest entries once it holds twice ``keep``: at any time it
holds at least the last ``keep`` entries (all of them while there are fewer), and ``total`` counts
every entry ever appended. :class:`RecentBytes` is the same for a byte stream (an in-memory serial
end's ``sent``). Whoever needs a complete record of a long run streams it instead (a serial link, a
MAVLink link, the VCD's bus wires).
"""

from __future__ import annotations

#: entries a log keeps at least (it trims back to this when it reaches twice as many)
KEEP = 10_000


class _Recent:
    """What :class:`RecentLog` and :class:`RecentBytes` share: a sequence (the class's other base,
    whose ``append`` is ``_add``) holding at least the last ``keep`` of the ``total`` items
    appended, trimmed back to ``keep`` once it holds twice as many."""

    _what = "entry"

    def __init__(self, items=(), keep: int | None = None):
        super().__init__(items)
        keep = KEEP if keep is None else keep
        if keep < 1:
            raise ValueError(f"{type(self).__name__} keeps at least one {self._what}, not {keep!r}")
        self.keep = keep
        self.total = len(self)
        self._trim()

    def append(self, item) -> None:
        self._add(item)
        self.total += 1
        if len(self) > 2 * self.keep:
            self._trim()

    def _trim(self) -> None:
        # once per ``keep`` appends, so appending stays O(1) amortised
        if len(self) > self.keep:
            del self[:len(self) - self.keep]

    @property
    def dropped(self) -> int:
        """How many of the oldest items are no longer held."""
        return self.total - len(self)


class RecentLog(_Recent, list):
    """A list of the most recent entries: at least the last ``keep`` of the ``total`` appended."""

    _add = list.append


class RecentBytes(_Recent, bytearray):
    """A bytearray of the most recent bytes: at least the last ``keep`` of the ``total`` appended
    (it drops its oldest bytes once it holds twice ``keep``, like :class:`RecentLog`)."""

    _add = bytearray.append
    _what = "byte"
