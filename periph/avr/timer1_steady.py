"""Fast engine part of :class:`mcusim.periph.avr.timer1.AvrTimer`: steady waveforms on OC outputs.

While the counter runs on its cycle (no excursion above TOP pending, no TCNT write blocking a coming
compare match) a connected PWM output (COMnx = 10/11 in fast PWM, phase-correct or PFC mode) whose
compare value is strictly inside the cycle is periodic: the timer publishes it as a
:class:`mcusim.engine.waveform.Waveform` on its ``oc`` port (:meth:`Port.set_wave`) and schedules no
compare-match or TOP events for it. Whoever needs an edge derives it from the descriptor (the pin
mux passes the waveform to the pin, :mod:`mcusim.periph.avr.port`).

Flags need nothing new: the engine already sets a flag whose interrupt is disabled lazily, at its
exact clock, when TIFRn is read or a register is written (``_sync_flags``). Events stay where they
are needed: a flag whose interrupt is enabled, and a double-buffered OCRnx waiting for its update
clock (TOP or BOTTOM); the waveform then ends at that update clock (``Waveform.end``) and the
event republishes it.

The waveform in timer clocks (the clock that *leaves* counter phase p happens at clock
``kj − qj + 1 + p`` modulo the cycle length L, see ``AvrTimer._phase_next``), with v = OCRnx and
lev the level a match drives (0 for COM = 10):

* fast PWM (L = TOP + 1, 0 <= v < TOP): 1 − lev from the clock leaving TOP (the BOTTOM action) for
  v + 1 clocks, then lev from the clock leaving v;
* phase-correct / PFC (L = 2·TOP, 0 < v < TOP): lev from the up-count match (leaving v) to the
  down-count match (leaving 2·TOP − v, i.e. the value v on the way down): 2·TOP − 2v clocks.

Other actions (toggle, set/clear in normal/CTC mode) keep their events: they are not periodic in a
way a PWM bridge would profit from. The channel's latch (its OCnx level) is brought up to date
from the waveform before the engine reads it (:meth:`_wave_latch`), so leaving the fast path at
any register write continues exactly where the edge-by-edge model would be. A waveform is
published only if the latch agrees with it now: an output that still has to reach its periodic
level (after a mode change, a COM change, a buffer update from a constant level) runs edge by edge
until it does.
"""

from __future__ import annotations

from mcusim.engine.waveform import Waveform


class SteadyOutputs:
    """Mixin for AvrTimer (fast engine only: ``kernel.fast``)."""

    def _wave_latch(self, t: int) -> None:
        """Set the latch of every channel published as a waveform to its level at tick ``t``."""
        for ch in self.CHANNELS:
            w = self.oc[ch].wave
            if w is not None and (w.end is None or t < w.end):
                self._latch[ch] = w.level_at(t)

    def _channel_wave(self, ch, k: int, end):
        """The output of ``ch`` from timer clock ``k`` on as a Waveform, or None (edge by edge)."""
        act, lev = self._act[ch]
        if act != "pwm" or self._steady(ch) is not None:
            return None
        v, T, L = self._ocr[ch], self._top, self._L
        base = self._kj - self._qj + 1
        if self._kind == "fast":
            start, width = (base + T, v + 1) if lev == 0 else (base + v, T - v)
        else:
            start, width = (base + v, 2 * T - 2 * v) if lev == 1 else (base + 2 * T - v, 2 * v)
        U = self._N * self._P
        w = Waveform(self.kernel, start * U, L * U, width * U, end)
        if w.level_at(k * U) != self._latch[ch]:
            return None                 # not yet on its periodic level
        return w

    def _publish_waves(self, k: int, pend: bool):
        """Publish or withdraw the waveforms for the state at clock ``k``; returns the channels that
        carry one (their pin actions need no events)."""
        oc = self.oc
        now = self.kernel.now
        for ch in self.CHANNELS:
            w = oc[ch].wave
            if w is not None and (w.end is None or now < w.end):
                self._latch[ch] = w.level_at(now)
        steady = self._run and k >= self._kj and self._kblock <= k
        end = None
        if steady and pend:
            K = self._next_top(k) if self._upd == "top" else self._next_bottom(k)
            end = K * self._N * self._P
        waved = ()
        for ch in self.CHANNELS:
            w = self._channel_wave(ch, k, end) if steady else None
            port = oc[ch]
            if w is None:
                if port.wave is not None:
                    port.set(None if self._act[ch][0] is None else self._latch[ch])
                continue
            waved += (ch,)
            old = port.wave
            if old is None or not old.same_shape(w):
                port.set_wave(w)
        return waved
