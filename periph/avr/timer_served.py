"""Fast engine part of :class:`mcusim.periph.avr.timer1.AvrTimer`: overflows served in closed form.

The Arduino core's Timer0 does one thing a millisecond: its overflow interrupt advances
``millis()``. Where the handler declares a closed form and the ``loop()`` pass it wakes is idle
(:class:`mcusim.firmware.TickForm`, :class:`mcusim.firmware.IdlePass`), the fast engine serves
those overflows inside a counted run of encoder edges (:mod:`mcusim.engine.ticks`) instead of
running each one as events. The timer's part: telling that its queued event is such an overflow
and where the next ones fall (:meth:`served_overflow`), and afterwards leaving its flags and its
next event as the overflows' vector entries leave them (:meth:`commit_overflows`).
"""

from __future__ import annotations

TOV, OCFA, OCFB = 1 << 0, 1 << 1, 1 << 2


class ServedOverflows:
    """Mixin of AvrTimer (uses its counting engine: _ev, _run, _dual, _topsrc, _kj, ...)."""

    def served_overflow(self, ev):
        """(cpu, vector, K, L, ticks per clock) where the queued event ``ev`` is this timer's next
        clock and all that clock does is an overflow for the overflow interrupt: a single-slope
        mode with a fixed TOP, the clock running on its cycle, TOIEn the only interrupt enable,
        TOVn clear, no output pin action and no compare value waiting in its buffer. The overflows
        then come at clocks K, K + L, K + 2L, ...; else None."""
        if (ev is not self._ev or not self._run or self._dual or self._in_clock
                or not isinstance(self._topsrc, int) or not self._top_flags & TOV
                or self.value[self.TIMSK] != TOV or self.value[self.TIFR] & TOV
                or any(self._act[ch][0] is not None for ch in self.CHANNELS)
                or (self._upd is not None and self._pending())):
            return None
        K = ev.args[0]
        if K - 1 < self._kj or self._kblock >= K or self._next_top(K - 1) != K:
            return None
        return self.irq.cpu, self.vectors["ovf"], K, self._L, self._N * self._P

    def commit_overflows(self, K: int) -> None:
        """The overflows up to clock ``K`` were served: each one's vector entry cleared TOVn at its
        clock (entry latency < the prescaler: the entry falls in that clock). The compare flags
        are set by counting as ever (sticky: set once, they stay), the flags are known up to K,
        and the next event is planned from K."""
        F = self.value[self.TIFR]
        for bit in (OCFA, OCFB):
            if not F & bit:
                Kb = self._flag_clock(self._ks, bit)
                if Kb is not None and Kb <= K:
                    F |= bit
        self.value[self.TIFR] = F
        self._ks = K
        self._plan(K)
