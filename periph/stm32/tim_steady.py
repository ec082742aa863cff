"""Fast engine part of :class:`mcusim.periph.stm32.tim.Tim`: steady waveforms instead of edge events.

While the counter runs edge-aligned (CMS=00) and no compare interrupt is enabled on an output
channel, a PWM output is fully described by the counter's period and the channel's compare value:
the timer publishes a :class:`mcusim.engine.waveform.Waveform` on the channel's port
(:meth:`Port.set_wave`) and schedules no compare-match events. The flags those matches set (CCxIF,
and UIF at wraps) are set lazily, at their exact ticks, when SR (or CNT with UIFREMAP) is read or
written. The wrap event itself is still scheduled when something happens at the wrap (a preload
waiting for the update event, UIE, the repetition counter, one-pulse mode); otherwise the counter
wraps arithmetically and costs nothing. Any register write re-plans at its exact tick, so a
waveform ends exactly where the edge-by-edge engine's edges would change.

Outputs per §3.2 (edge-aligned): PWM1 counting up is high from the wrap (CNT = 0) for CCR ticks
(always high when CCR > ARR, never when CCR = 0); counting down it is high from CNT = CCR down to
the underflow, CCR + 1 ticks. PWM2 and CCxP = 1 take the complement.
"""

from __future__ import annotations

from mcusim.engine.waveform import Waveform

_CEN, _UDIS, _OPM, _ARPE = 1, 1 << 1, 1 << 3, 1 << 7
_UIF = 1
_CCIF = (0, 1 << 1, 1 << 2, 1 << 3, 1 << 4)
_CCR = (None, "CCR1", "CCR2", "CCR3", "CCR4")
_PWM1, _PWM2 = 0b0110, 0b0111


class SteadyStage:
    """Mixin for Tim; state: ``_steady`` (outputs published as waveforms, no compare events) and
    ``_uif_lazy`` (tick of the next UIF a wrap without an event sets, or None)."""

    # --- deciding -------------------------------------------------------------------------------
    def _steady_possible(self) -> bool:
        """Outputs can be waveforms until the next wrap: edge-aligned, no compare interrupts."""
        if not (self.kernel.fast and self._run and self._cms == 0):
            return False
        if self._cnt > self._arr:   # (ARR lowered below CNT: the counter runs on to 0 or its maximum)
            return False
        for ch in (1, 2, 3, 4):
            if self._mode[ch] >= 0 and self._ccie[ch]:
                return False
        return True

    def _wrap_needed(self) -> bool:
        """Something happens at the next wrap besides counting: it needs its event."""
        v = self.value
        cr1 = v["CR1"]
        if cr1 & _OPM or v["DIER"] & _UIF or self._rep or (self.advanced and v["RCR"]):
            return True
        if v["PSC"] != self._psc or (cr1 & _ARPE and v["ARR"] != self._arr):
            return True
        for ch in (1, 2, 3, 4):
            if self._ocpe[ch] and self._mode[ch] >= 0 and v[_CCR[ch]] != self._ccr[ch]:
                return True
        return False

    # --- the waveforms ------------------------------------------------------------------------
    def _channel_wave(self, ch: int, t_wrap: int):
        """The output of channel ``ch`` as a Waveform, or None when it is a constant level."""
        if not self._wave_coming(ch):
            return None
        m = self._mode[ch]
        arr, c, tick = self._arr, self._ccr[ch], self._tick
        P = (arr + 1) * tick
        if self._up:
            rise, width = t_wrap, c * tick
        else:
            rise, width = t_wrap + (arr - c) * tick, (c + 1) * tick
        if (m == _PWM2) ^ bool(self._pol[ch]):
            rise, width = rise + width, P - width
        # a wrap with an event (a preload, UIE...) may change the waveform: it ends there
        return Waveform(self.kernel, rise, P, width, t_wrap if self._ev_wrap is not None else None)

    def _wave_coming(self, ch: int) -> bool:
        """Channel ``ch`` is a PWM output whose level changes within a period: edge-aligned up,
        0 < CCRx ≤ ARR (0 is always inactive, above ARR always active); down, CCRx < ARR."""
        if not self._en[ch] or self._mode[ch] not in (_PWM1, _PWM2):
            return False
        c = self._ccr[ch]
        return 0 < c <= self._arr if self._up else c < self._arr

    def _publish_waves(self) -> None:
        for ch in (1, 2, 3, 4):
            w = self._channel_wave(ch, self._t_wrap)
            port = self.oc[ch]
            if w is None:
                if port.wave is not None:   # now a constant level (computed by _refresh_outputs)
                    port.set(int(self._ref[ch]) ^ self._pol[ch] if self._en[ch] else None)
                continue
            old = port.wave
            if old is None or not old.same_shape(w):
                port.set_wave(w)

    def _await_update(self) -> None:
        """Synced to now: a write went into a preload register (CCRx with OCxPE, ARR with ARPE,
        PSC), so nothing changes before the next wrap, which now needs its event. What _plan
        would do, without re-deriving what the write did not change: the wrap event, the
        waveforms ending there, and the lazy flags up to it (the wrap sets UIF)."""
        t_wrap = self._t_wrap
        self._ev_wrap = self.kernel.at(t_wrap, self._on_wrap)
        self._uif_lazy = None
        lazy = self._lazy
        for ch in (1, 2, 3, 4):
            if lazy[ch] is not None and lazy[ch] >= t_wrap:
                lazy[ch] = None
        self._publish_waves()
        self._steady_lazy(self.kernel.now)

    # --- lazy counter and flags ----------------------------------------------------------------
    def _steady_cnt_at(self, t: int) -> int:
        k = (t - self._tb) // self._tick
        if k <= 0:
            return self._cnt
        m = self._arr + 1
        return (self._cnt + k) % m if self._up else (self._cnt - k) % m

    def _steady_sync(self) -> None:
        """Bring the counter to now across any number of plain wraps (their flags stay lazy)."""
        now = self.kernel.now
        k = (now - self._tb) // self._tick
        if k <= 0:
            return
        self._steady_flush(now)
        m = self._arr + 1
        self._cnt = (self._cnt + k) % m if self._up else (self._cnt - k) % m
        self._tb += k * self._tick
        self._t_wrap = self._tb + ((self._arr - self._cnt + 1) if self._up else (self._cnt + 1)) * self._tick

    def _next_match(self, ch: int, after: int):
        """First tick > ``after`` on which CNT becomes CCRx, counting from (_cnt at _tb)."""
        c, arr, tick = self._ccr[ch], self._arr, self._tick
        if c > arr:
            return None
        m = arr + 1
        j = (c - self._cnt) % m if self._up else (self._cnt - c) % m
        t = self._tb + (j if j else m) * tick
        if t > after:
            return t
        P = m * tick
        return t + ((after - t) // P + 1) * P

    def _next_wrap(self, after: int) -> int:
        t = self._t_wrap
        if t > after:
            return t
        P = (self._arr + 1) * self._tick
        return t + ((after - t) // P + 1) * P

    def _steady_lazy(self, after: int) -> None:
        """Re-arm the lazy flags: the next match of each output channel, the next UIF."""
        flag = self._flag_up if self._up else self._flag_down
        # with a wrap event ahead (a preload...), matches from the wrap on are re-derived there
        limit = self._t_wrap if self._ev_wrap is not None else None
        for ch in (1, 2, 3, 4):
            if flag and self._mode[ch] >= 0 and self._lazy[ch] is None:
                t = self._next_match(ch, after)
                self._lazy[ch] = t if limit is None or (t is not None and t < limit) else None
        if self._ev_wrap is None and not self.value["CR1"] & _UDIS and self._uif_lazy is None:
            self._uif_lazy = self._next_wrap(after)

    def _steady_flush(self, now: int) -> None:
        """Set the flags of matches and wraps due by ``now`` (SR is about to be seen or changed)."""
        sr = self.value["SR"]
        t = self._uif_lazy
        if t is not None and t <= now:
            sr |= _UIF
            self._uif_lazy = None
        for ch in (1, 2, 3, 4):
            t = self._lazy[ch]
            if t is not None and t <= now:
                sr |= _CCIF[ch]
                self._lazy[ch] = None
        self.value["SR"] = sr
