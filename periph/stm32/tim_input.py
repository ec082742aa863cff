"""Input stage of the STM32 general-purpose timers: TIx resynchronisation and the ICxF filter.

Reference: /work/shared/reference/stm32_tim.md §4.3-§4.4.

A TIx net edge reaches the timer's decoder (encoder mode) or capture stage through:

* polarity: TIxFPx = TIx XOR CCxP (done by the caller, :class:`periph.stm32.tim.Tim`);
* the ICxF digital filter (§4.4): the filter samples at f_SAMPLING (multiples of its period counted
  from base tick 0); the first sample that can see a level change at base tick ``t`` is the first
  sampling edge *strictly after* ``t``. The filtered output takes the new level after ``N``
  consecutive samples at that level. If the input changes back before the N-th sample, the change is
  dropped (the deadline event is cancelled). ICxF=0000 means one sample per f_DTS period (N=1).
* resynchronisation [UNVERIFIED: the sheet says 2-3 CK_INT cycles]: we choose **2 CK_INT cycles**
  after the sample that completes the filter (:data:`RESYNC_CYCLES`).

So with ICxF=0000 and CKD=00 an edge at base tick ``t`` takes effect at
``first CK_INT edge strictly after t + 2 CK_INT cycles``.
"""

from __future__ import annotations

from collections import deque

#: CK_INT cycles between the sample that completes the filter and the decoder seeing the level.
RESYNC_CYCLES = 2

#: ICxF -> (f_SAMPLING divider, source, N): source "ck" = fCK_INT, "dts" = fDTS (§4.4 table).
FILTER_TABLE = (
    (1, "dts", 1),   # 0000: no filter, sampled at fDTS
    (1, "ck", 2), (1, "ck", 4), (1, "ck", 8),
    (2, "dts", 6), (2, "dts", 8), (4, "dts", 6), (4, "dts", 8),
    (8, "dts", 6), (8, "dts", 8),
    (16, "dts", 5), (16, "dts", 6), (16, "dts", 8),
    (32, "dts", 5), (32, "dts", 6), (32, "dts", 8),
)


def filter_timing(icf: int, ckd: int, ck_period: int) -> tuple[int, int]:
    """(sampling period in base ticks, N) for ICxF=``icf`` and CR1.CKD=``ckd`` (tDTS = 1/2/4 tCK_INT)."""
    div, src, n = FILTER_TABLE[icf]
    base = ck_period if src == "ck" else ck_period * (1 << ckd)
    return base * div, n


class TiInput:
    """One timer input TIx after polarity selection: filter + resynchroniser, as scheduled events.

    ``level`` is TIxFPx as the decoder currently sees it. ``last`` is the level at the filter input
    (the target of the newest change in flight). ``queue`` holds the changes in flight, oldest first,
    as lists ``[t_effect, level, t_last_sample, event]``.
    """

    __slots__ = ("kernel", "apply", "ch", "level", "last", "queue")

    def __init__(self, kernel, ch: int, apply):
        self.kernel, self.ch, self.apply = kernel, ch, apply
        self.level = self.last = 0
        self.queue: deque = deque()

    def reset(self, level: int) -> None:
        """Forget changes in flight; the input is (and is seen as) ``level``."""
        for item in self.queue:
            item[3].cancel()
        self.queue.clear()
        self.level = self.last = level

    def edge(self, v: int, t: int, sample_period: int, n: int, ck_period: int) -> None:
        """The polarity-corrected input became ``v`` at base tick ``t``."""
        if v == self.last:
            return
        q = self.queue
        self.last = v
        if q and t < q[-1][2]:
            # §4.4: the newest change has not been seen for N consecutive samples: it is filtered out
            q.pop()[3].cancel()
            return
        s1 = (t // sample_period + 1) * sample_period
        s_n = s1 + (n - 1) * sample_period
        t_eff = s_n + RESYNC_CYCLES * ck_period
        q.append([t_eff, v, s_n, self.kernel.at(t_eff, self._fire)])

    def pending_at(self, t: int):
        """Pop and return the level of a change taking effect exactly at ``t``, else None."""
        q = self.queue
        if q and q[0][0] == t:
            item = q.popleft()
            item[3].cancel()
            self.level = item[1]
            return item[1]
        return None

    def _fire(self) -> None:
        _, v, _, _ = self.queue.popleft()
        self.level = v
        self.apply(self.ch, v)


def encoder_direction_up(ch: int, v: int, other: int) -> bool:
    """§4.2 direction table, compact form: an edge on TI1 to level v counts up iff v != TI2 level;
    an edge on TI2 to level v counts up iff v == TI1 level (levels are TIxFPx, after CCxP)."""
    return (v != other) if ch == 1 else (v == other)
