"""Input stage of the STM32 general-purpose timers: TIx resynchronisation and the ICxF filter.

Sources: ST RM0385 (STM32F75xxx/74xxx reference manual), TIM input stage and filter.

A TIx net edge reaches the timer's decoder (encoder mode) or capture stage through:

* polarity: TIxFPx = TIx XOR CCxP (done by the caller, :class:`mcusim.periph.stm32.tim.Tim`);
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

    __slots__ = ("apply", "ch", "kernel", "last", "level", "queue")

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


_CEN = 1
_CCIF = (0, 1 << 1, 1 << 2, 1 << 3, 1 << 4)
_CCOF = (0, 1 << 9, 1 << 10, 1 << 11, 1 << 12)


class EncoderStage:
    """Encoder-mode part of :class:`mcusim.periph.stm32.tim.Tim` (§4): decoding, DIR, up-only prescaler
    counter, wrap with UEV, and the capture of CNT on the active edge of TI1FP1/TI2FP2."""

    def _filter(self, ch: int):
        return filter_timing(self._icf[ch], (self.value["CR1"] >> 8) & 3, self._P)

    def _ti_net(self, net) -> None:
        if self._enc_lazy is not None:      # counting lazily (tim_lazy)
            if net.wave is not None:
                return                      # a descriptor taken by lazy_enter
            enc = self._enc_lazy.enc
            self._lazy_end()                # it ends: the crossings in flight, edge by edge
            enc.materialize()               # (if the pin left the encoder: a drive, a GPIO mode)
        if not self._sms:
            return
        ch = 1 if net is self.ti[1] else 2 if net is self.ti[2] else 0
        if ch:
            self._inp[ch].edge(net.level ^ self._pol[ch], self.kernel.now, *self._filter(ch), self._P)

    def _ti_apply(self, ch: int, v: int) -> None:
        """A filtered TIxFPx transition reaches the decoder (§4.2, §4.3)."""
        other = self._inp[3 - ch]
        if other.pending_at(self.kernel.now) is not None:
            return  # TI1 and TI2 changed in the same sample: undefined in the RM, count nothing
        if not self._sms or not self.value["CR1"] & _CEN:
            return
        up = encoder_direction_up(ch, v, other.level)
        self._up = up  # DIR follows every transition, counting or not
        if self._sms == 3 or self._sms == ch:
            self._encoder_pulse(up)
        if self._cap[ch] and v:  # IC1 = TI1FP1 rising (CCxP already applied): capture CNT
            self._capn[ch] += 1
            if self._capn[ch] >= (1 << self._icpsc[ch]):
                self._capn[ch] = 0
                sr = self.value["SR"]
                if sr & _CCIF[ch]:
                    sr |= _CCOF[ch]
                self.value["SR"] = sr | _CCIF[ch]
                self.value[f"CCR{ch}"] = self._cnt
                self._irq()

    def _encoder_pulse(self, up: bool) -> None:
        """§4.3: the prescaler counter counts every pulse upwards; CNT moves when it wraps."""
        if self._pscc < self._psc:
            self._pscc += 1
            return
        self._pscc = 0
        if self._arr == 0:  # ARR=0 blocks the counter
            return
        cnt = self._cnt
        if up:
            if cnt >= self._arr:  # overflow ARR -> 0
                self._count_wrap()
                self._cnt = 0
            else:
                self._cnt = cnt + 1
        elif cnt == 0:  # underflow 0 -> ARR (ARR loads first)
            self._count_wrap()
            self._cnt = self._arr
        else:
            self._cnt = cnt - 1
        self._plan(tick_up=up)
