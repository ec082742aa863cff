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

    def commit_overflows(self, K: int, k_entry: int) -> None:
        """The overflows up to clock ``K`` were served, the last one's vector entered in clock
        ``k_entry`` (≥ K: an encoder handler may have delayed it, and a fast prescaler puts the
        entry latency past K). As that entry does (``_entry_clear``), the flags are brought up to
        k_entry (the compare flags set by counting, sticky), TOVn is cleared, and the next event is
        planned from there (the next overflow is a whole cycle after K)."""
        k = max(K, k_entry)
        F = self.value[self.TIFR]
        for bit in (OCFA, OCFB):
            if not F & bit:
                Kb = self._flag_clock(self._ks, bit)
                if Kb is not None and Kb <= k:
                    F |= bit
        self.value[self.TIFR] = F
        self._ks = k
        self._plan(k)
