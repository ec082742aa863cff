"""ATmega328P Timer/Counter1 (16-bit): all waveform modes, OC1A/OC1B, input capture, TEMP.

Sources: the ATmega328P data sheet ("the sheet" below; § marks are the project's AVR notes).  The counting engine
(:class:`AvrTimer`) is shared with Timer0 (:mod:`mcusim.periph.avr.timer0`); the per-clock reference model
used as the test oracle is ``tests/avr_timer_oracle.py``.

Modelled
--------
* WGM modes 0-12, 14, 15 with TOP per mode (§1.3); 13 is reserved and raises.  Single-slope (normal,
  CTC, fast PWM) and dual-slope (phase-correct, phase-and-frequency-correct) counting.
* OCR1A/B double buffering: loaded at TOP in phase-correct modes (1-3, 10, 11), at BOTTOM in PFC
  (8, 9) and fast PWM (5-7, 14, 15; "BOTTOM" = the clock that takes TCNT1 from TOP to 0); written
  through at once in normal/CTC.  ICR1 is never buffered.  Fixed-TOP modes mask the OCR high bits on
  write.  Reads of OCR1x return the buffer (what the CPU wrote).
* Flags TOV1/OCF1A/OCF1B/ICF1 in TIFR1 (write 1 to clear; cleared on vector entry through
  ``irq.on_entry``), TIMSK1, interrupt lines = flag AND enable.
* COM1x output behaviour of §1.4 in every mode, including the extreme OCR values.
* CS12:0 = 1..5; 6/7 (external T1) raise.  FOC1A/FOC1B strobes in non-PWM modes (ignored in PWM
  modes, as the datasheet says they must be written 0 there).
* The 16-bit TEMP latch shared by TCNT1/ICR1/OCR1A/OCR1B (§1.5).
* Input capture of TCNT1 into ICR1 on an ``icp`` edge selected by ICES1, in modes where ICR1 is not
  TOP; ICNC1 (noise canceller) raises.

Choices on [DS-recall]/[INF] items
----------------------------------
* Prescaler phase: the prescaler is shared and free-running from reset (t = 0), so with divider N the
  timer clocks fall on CPU cycles that are multiples of N (base ticks k·N·P, P = CPU period).  A
  register write at base tick t acts on the timer clocks strictly after t (hardware events of tick t
  are processed before the CPU, kernel priorities).  PSRSYNC is not modelled (Timer0's GTCCR raises).
* Flag and pin timing: compare logic looks at the counter value being *left*: the timer clock that
  moves TCNT1 off OCR1x sets OCF1x and applies the COM action (the datasheet figure "Setting of
  OCF1x": the flag is set one clock after TCNT1 == OCR1x); the pin changes in that same clock.
  Likewise TOV1/ICF1/OCF1A-at-TOP are set on the clock that leaves TOP (single slope: TOP->0) or
  leaves BOTTOM (dual slope: 0->1), and buffers load on that clock.  On a clock that loads the
  buffers, the compare of that clock already uses the new value.
* Direction of a match in dual-slope modes = direction of the step leaving the value: a match at
  BOTTOM is an up-count match (COM=10 clears), a match at TOP a down-count match (COM=10 sets).
* PC/PFC OC transition at TOP without a match (sheet §1.4, 8-bit-timer text applied to TC1): on the
  clock that leaves TOP, a connected COM=10/11 output takes the level of an up-count match when
  OCR1x < TOP and of a down-count match when OCR1x >= TOP (evaluated after the PC buffer load).  This
  keeps the waveform symmetric when OCR changes from TOP, or when the counter started above OCR.
* Fast PWM: the set/clear "at BOTTOM" is applied after the compare action of the same clock, so
  OCR1x = TOP gives a constant output (the datasheet's "match ignored"); OCF1x is still set.
* Writing TCNT1 blocks the compare matches (flags and pin actions) of the next timer clock only; the
  counter still counts on that clock, and TOP/BOTTOM events still happen.  The counting direction is
  kept across a TCNT1 write.  TCNT1 written equal to BOTTOM while counting down (which the datasheet
  says not to do, as for TOP, without saying what follows) is BOTTOM reached: the counter turns up
  and TOV1 is set [choice; for TOP the datasheet does say the match is missed, see _derive].
* Counter above TOP (TOP lowered below TCNT1, or TCNT1 written above TOP): single slope counts up to
  0xFFFF and wraps to 0, setting TOV1 at that wrap (in fast PWM too); no buffer load or pin action at
  that wrap.  Dual slope counting up does the same but TOV1 comes at the BOTTOM that follows; counting
  down it passes TOP without a TOP event and joins the slope.
* Input capture: the ICP1 edge is synchronised to the CPU clock and captures TCNT1 on the first CPU
  clock edge strictly after it (the real synchroniser/edge detector delay is a few cycles more and is
  not modelled).
* Dual-slope TOP = 0 with the clock running raises (the datasheet minimum TOP is 3).
* ICR1 is writable in every mode [choice]. The datasheet says it "can only be written when using a
  Waveform Generation mode that utilizes the ICR1 Register for defining the counter's TOP value",
  with WGM set first; a Uno read back after init() (Arduino forum thread 509204) shows silicon
  accepting the write in mode 1. Sketches that set ICR1 before WGM13 (a common order) run.

Performance: TCNT1 is computed from the anchor (clock index, value, direction) when read.  Only these
clocks are scheduled: compare matches that change a connected output or set a flag whose interrupt is
enabled and pending-able, TOP/BOTTOM clocks that load a pending buffer, change a pin or set such a flag (a dual-slope TOP
whose level forcing cannot change the pin is not scheduled).
A flag whose interrupt is disabled is set lazily when TIFR1 is read or before any register write.  A
steady output (e.g. OCR = 0 or TOP in PC/PFC) schedules nothing.  Work per event is O(1).
"""

from __future__ import annotations

from functools import partial

from mcusim.errors import UnsupportedConfiguration
from mcusim.registers import Field, Peripheral, Register
from mcusim.signals import Net, Port

from .timer1_steady import SteadyOutputs
from .timer_served import ServedOverflows

# flag / enable bits, the same positions in TIFRn and TIMSKn
TOV, OCFA, OCFB, ICF = 1 << 0, 1 << 1, 1 << 2, 1 << 5
OCF = {"A": OCFA, "B": OCFB}
CS_DIV = {1: 1, 2: 8, 3: 64, 4: 256, 5: 1024}

# mode -> (kind, top): top is an int (fixed), "A" (OCRnA) or "I" (ICRn)
MODES16 = {
    0: ("normal", 0xFFFF), 1: ("pc", 0xFF), 2: ("pc", 0x1FF), 3: ("pc", 0x3FF), 4: ("ctc", "A"),
    5: ("fast", 0xFF), 6: ("fast", 0x1FF), 7: ("fast", 0x3FF), 8: ("pfc", "I"), 9: ("pfc", "A"),
    10: ("pc", "I"), 11: ("pc", "A"), 12: ("ctc", "I"), 14: ("fast", "I"), 15: ("fast", "A"),
}
KIND_NAMES = {"normal": "normal", "ctc": "CTC", "fast": "fast PWM", "pc": "phase-correct PWM",
              "pfc": "phase and frequency correct PWM"}


def com_behaviour(kind: str, top, ch: str, com: int):
    """Decode COMnx for a mode: (action, level).  action None = disconnected; "toggle"; "set"/"clear"
    (non-PWM, level = value driven); "pwm" (level = value at an up-count / fast-PWM match)."""
    if com == 0:
        return None, 0
    if kind in ("normal", "ctc"):
        return ("toggle", 0) if com == 1 else (("clear", 0) if com == 2 else ("set", 1))
    if com == 1:
        if ch != "A" or isinstance(top, int) or (kind != "fast" and top != "A"):
            return None, 0          # disconnected (§1.4 table)
        return "toggle", 0
    return "pwm", (0 if com == 2 else 1)


class AvrTimer(SteadyOutputs, ServedOverflows, Peripheral):
    """Event-driven engine shared by Timer0 and Timer1.  Subclasses give registers and names."""

    BUS_WIDTH = 1
    ACCESS_SIZES = (1,)          # the AVR data bus is 8 bits wide
    MAX = 0xFFFF
    MODES = MODES16
    TIFR = TIMSK = ""
    CHANNELS = ("A", "B")

    def __init__(self, name, mcu, clock, vectors):
        super().__init__(name)
        self.mcu, self.kernel, self.irq = mcu, mcu.kernel, mcu.irq
        self._P = clock.period
        self.vectors = dict(vectors)
        self.oc: dict[str, Port] = {ch: Port(f"{name}_OC{ch}") for ch in self.CHANNELS}
        self._flagvec = [(TOV, self.vectors["ovf"]), (OCFA, self.vectors["compa"]),
                         (OCFB, self.vectors["compb"])]
        if "capt" in self.vectors:
            self._flagvec.append((ICF, self.vectors["capt"]))
        for bit, vec in self._flagvec:
            self.irq.on_entry[vec] = partial(self._entry_clear, bit)
        # configuration
        self._mode, self._cs, self._N = 0, 0, 1
        self._kind, self._topsrc = self.MODES[0]
        self._dual, self._upd = False, None
        self._com = {ch: 0 for ch in self.CHANNELS}
        self._act = {ch: (None, 0) for ch in self.CHANNELS}
        self._ocr = {ch: 0 for ch in self.CHANNELS}   # active compare values
        self._buf = {ch: 0 for ch in self.CHANNELS}   # what the CPU wrote
        self._icr = 0
        self._latch = {ch: 0 for ch in self.CHANNELS}  # OCnx register (waveform generator output)
        self._top = self.MAX
        self._top_flags = TOV
        # counter anchor: value _c0 and last-step direction _d0 after timer clock _k0
        self._run, self._k0, self._c0, self._d0 = False, 0, 0, 1
        self._kj, self._qj, self._L, self._exu = 0, 0, self.MAX + 1, True
        self._ks = 0            # flags are known for every clock <= _ks
        self._kblock = -1       # clock whose compare matches are blocked by a TCNT write
        self._block_start = False   # a TCNT write while stopped: the first clock after the start
        self._ev = None
        self._in_clock = False      # inside _on_clock: an ISR entry clearing a flag need not plan

    # ------------------------------------------------------------------ public helpers
    @property
    def counter(self) -> int:
        """TCNTn now, without side effects."""
        return self._state(self._clock_now())[0]

    @property
    def prescaler(self) -> int:
        return self._N if self._run else 0

    # ------------------------------------------------------------------ time and counter
    def _clock_now(self) -> int:
        return self.kernel.now // (self._N * self._P) if self._run else 0

    def _state(self, k):
        """(value, direction of the last step) after timer clock k (k >= _k0 when running)."""
        if not self._run or k <= self._k0:
            return self._c0, self._d0
        if k < self._kj:
            if self._exu:
                return self._c0 + (k - self._k0), 1
            return self._c0 - (k - self._k0), -1
        q = (self._qj + k - self._kj) % self._L
        if self._dual:
            T = self._top
            if q <= T:
                return q, (1 if q else -1)
            return 2 * T - q, -1
        return q, 1

    def _derive(self):
        """Place the anchor on the cycle: the join clock _kj and its phase _qj (excursion before).

        A counter written equal to a TOP held in OCRnA or ICR1 starts an excursion: the write
        blocks the compare matches of the next timer clock, TOP's among them, so "the Compare
        Match for the TOP will be ignored and the counter will continue to 0xFFFF" (ATmega328P
        datasheet, TC1 "Using the Output Compare Unit", for the PWM modes with variable TOP; in
        CTC, whose TOP is the same compare, we take the same mechanism to hold)."""
        c, d, T, M = self._c0, self._d0, self._top, self.MAX
        self._kj, self._qj, self._exu = self._k0, 0, True
        blocked = c == T and self._kblock == self._k0 + 1 and self._topsrc in ("A", "I") and c < M
        if self._dual:
            if self._run and T == 0:
                held = self._buf["A"] if self._topsrc == "A" else 0
                raise UnsupportedConfiguration(
                    self.name, self._topname(), None, 0, "as TOP of a dual-slope mode is not modelled"
                    + (f" (the {held} written to it waits in the double buffer for an update point; "
                       "write it before selecting the mode, as the buffer then passes it through)" if held else ""))
            self._L = 2 * T
            if c <= T and not (c == T and d < 0 and c > 0) and not (blocked and d > 0):
                self._qj = c if (d > 0 or c == 0) else 2 * T - c
            elif d > 0:
                self._kj = self._k0 + M + 1 - c
            else:
                self._exu = False
                self._kj, self._qj = self._k0 + c - T + 1, (T + 1) % self._L
        else:
            self._L = T + 1
            if c <= T and not blocked:
                self._qj = c
            else:
                self._kj = self._k0 + M + 1 - c

    def _phase_next(self, k, phases):
        """First clock K > k whose old state (after K-1) is on the cycle at one of ``phases``."""
        if not phases:
            return None
        k = max(k, self._k0, self._kj)
        L = self._L
        q = (self._qj + k - self._kj) % L
        return k + 1 + min((p - q) % L for p in phases)

    def _next_match(self, k, v):
        """First clock K > k leaving counter value v (a compare match), or None."""
        k = max(k, self._k0)
        T = self._top
        if k < self._kj:
            if self._exu:
                j = self._k0 + v - self._c0 if v >= self._c0 else -1
            else:
                j = self._k0 + self._c0 - v if T <= v <= self._c0 else -1
            if k <= j < self._kj:
                return j + 1
        if v > T:
            return None
        if self._dual:
            ph = (v,) if v in (0, T) else (v, 2 * T - v)
        else:
            ph = (v,)
        return self._phase_next(k, ph)

    def _next_match_ch(self, k, ch):
        K = self._next_match(k, self._ocr[ch])
        if K is not None and K == self._kblock:
            K = self._next_match(K, self._ocr[ch])
        return K

    def _next_top(self, k):
        return self._phase_next(k, (self._top,))

    def _next_bottom(self, k):
        return self._phase_next(k, (0,))

    def _next_max(self, k):
        """Single slope: the wrap at MAX of an up excursion above TOP."""
        if self._dual or not self._exu or max(k, self._k0) >= self._kj:
            return None
        return self._kj

    # ------------------------------------------------------------------ flags and lines
    def _lines(self):
        m = self.value[self.TIFR] & self.value[self.TIMSK]
        for bit, vec in self._flagvec:
            self.irq.set_line(vec, m & bit)

    def _entry_clear(self, bit):
        self._sync_now()
        self.value[self.TIFR] &= ~bit
        self._lines()
        if self._in_clock:
            return      # taken from inside _on_clock (the flag it set): that clock plans at its end
        self._plan(self._clock_now())

    def _flag_clock(self, k, bit):
        """Next clock > k that sets flag ``bit`` by counting (not ICF by capture)."""
        if bit in (OCFA, OCFB):
            ch = "A" if bit == OCFA else "B"
            K = self._next_match_ch(k, ch)
            if bit & self._top_flags:
                t = self._next_top(k)
                K = t if K is None else (K if t is None else min(K, t))
            return K
        cands = []
        if bit & self._top_flags:
            cands.append(self._next_top(k))
        if bit == TOV:
            cands.append(self._next_bottom(k) if self._dual else self._next_max(k))
        cands = [c for c in cands if c is not None]
        return min(cands) if cands else None

    def _sync_flags(self, k):
        """Set the flags of every unprocessed clock in (_ks, k] (config constant over that span)."""
        ks = self._ks
        if self._run and k > ks:
            F = self.value[self.TIFR]
            missing = (OCFA | OCFB | TOV | self._top_flags) & ~F
            new = 0
            b = 1
            while missing:
                if missing & b:
                    missing &= ~b
                    K = self._flag_clock(ks, b)
                    if K is not None and K <= k:
                        new |= b
                b <<= 1
            if new:
                self.value[self.TIFR] = F | new
                self._lines()
        if k > ks:
            self._ks = k

    def _sync_now(self):
        self._sync_flags(self._clock_now())

    # ------------------------------------------------------------------ events
    def _pending(self):
        return any(self._buf[ch] != self._ocr[ch] for ch in self.CHANNELS)

    def _steady(self, ch):
        """The constant level of a 'pwm' channel when its output cannot change, else None."""
        v, T = self._ocr[ch], self._top
        lev = self._act[ch][1]
        if self._kind == "fast":
            return 1 - lev if v >= T else None
        if v == 0:
            return lev
        return 1 - lev if v >= T else None

    def _need_pin(self, ch, k, pend):
        act, lev = self._act[ch]
        if act is None:
            return False
        if act == "toggle":
            return True
        if act != "pwm":
            return self._latch[ch] != lev
        if pend or k < self._kj:
            return True
        s = self._steady(ch)
        return s is None or s != self._latch[ch]

    def _top_acts(self, ch, k, pend):
        """Whether the next TOP clock can change a 'pwm' output (fast: set/clear at BOTTOM; dual: the
        level forcing, which matters only when no up-count match lies between now and that TOP)."""
        if self._kind == "fast" or pend or k < self._kj:
            return True
        v, T, lev = self._ocr[ch], self._top, self._act[ch][1]
        if v >= T:
            return self._latch[ch] != 1 - lev
        k = max(k, self._k0)
        q = (self._qj + k - self._kj) % self._L
        # the up-count match is behind us, or it is the very next clock and a TCNT write blocks it
        return (v < q <= T or (v == q and k + 1 == self._kblock)) and self._latch[ch] != lev

    def _plan(self, k):
        if self._ev is not None:
            self._ev.cancel()
            self._ev = None
        if not self._run:
            if self.kernel.fast:
                self._publish_waves(k, False)
            return
        want = self.value[self.TIMSK] & ~self.value[self.TIFR]
        pend = self._upd is not None and self._pending()
        waved = self._publish_waves(k, pend) if self.kernel.fast else ()
        cands = []
        pins = False
        for ch in self.CHANNELS:
            pin = ch not in waved and self._need_pin(ch, k, pend)
            if pin and self._act[ch][0] == "pwm" and not pins:
                pins = self._top_acts(ch, k, pend)
            if pin or want & OCF[ch]:
                cands.append(self._next_match_ch(k, ch))
        if pins or (pend and self._upd == "top") or (want & self._top_flags):
            cands.append(self._next_top(k))
        if self._dual:
            if (pend and self._upd == "bottom") or (want & TOV):
                cands.append(self._next_bottom(k))
        elif want & TOV:
            cands.append(self._next_max(k))
        cands = [c for c in cands if c is not None]
        if cands:
            K = min(cands)
            self._ev = self.kernel.at(K * self._N * self._P, self._on_clock, K)

    def _on_clock(self, K):
        self._in_clock = True
        try:
            self._clock(K)
        finally:
            self._in_clock = False

    def _clock(self, K):
        self._ev = None
        if self.kernel.fast:
            self._wave_latch(K * self._N * self._P - 1)   # the level before this clock
        self._sync_flags(K - 1)
        c, d = self._state(K - 1)
        T = self._top
        in_cycle = K - 1 >= self._kj
        at_top = in_cycle and c == T and (d > 0 or not self._dual)
        at_bottom = self._dual and c == 0
        at_max = not self._dual and not in_cycle and c == self.MAX
        flags = 0
        newtop = None
        if ((at_top and self._upd == "top") or (at_bottom and self._upd == "bottom")) and self._pending():
            for ch in self.CHANNELS:
                self._ocr[ch] = self._buf[ch]
            if self._topsrc == "A" and self._ocr["A"] != T:
                newtop = self._ocr["A"]
        latch = self._latch
        if K != self._kblock:
            up = (c == 0) or (d > 0 and not at_top) or not self._dual
            for ch in self.CHANNELS:
                if c == self._ocr[ch]:
                    flags |= OCF[ch]
                    act, lev = self._act[ch]
                    if act == "pwm":
                        latch[ch] = lev if (up or self._kind == "fast") else 1 - lev
                    elif act == "toggle":
                        latch[ch] ^= 1
                    elif act is not None:
                        latch[ch] = lev
        if at_top:
            flags |= self._top_flags
            Tn = T if newtop is None else newtop
            for ch in self.CHANNELS:
                act, lev = self._act[ch]
                if act == "pwm":
                    if self._kind == "fast":
                        latch[ch] = 1 - lev
                    else:
                        latch[ch] = 1 - lev if self._ocr[ch] >= Tn else lev
        if at_bottom or at_max:
            flags |= TOV
        if flags & ~self.value[self.TIFR]:
            self.value[self.TIFR] |= flags
            self._lines()
        self._ks = K
        if newtop is not None:
            self._c0, self._d0 = self._state(K)
            self._k0 = K
            self._top = newtop
            self._derive()
        for ch in self.CHANNELS:
            self._drive(ch)
        self._plan(K)

    def _drive(self, ch):
        if self.oc[ch].wave is not None:
            return      # fast engine: _plan, which always follows, republishes or withdraws it
        self.oc[ch].set(None if self._act[ch][0] is None else self._latch[ch])

    # ------------------------------------------------------------------ configuration
    def _topname(self):
        return {"A": "OCR1A", "I": "ICR1"}.get(self._topsrc, "TOP")

    def _reanchor(self):
        """Freeze the current counter state as the anchor (call before changing the trajectory)."""
        k = self._clock_now()
        self._sync_flags(k)
        if self.kernel.fast:
            self._wave_latch(self.kernel.now)
        self._c0, self._d0 = self._state(k)
        self._k0 = k

    def _top_value(self):
        src = self._topsrc
        if src == "A":
            return self._ocr["A"]
        if src == "I":
            return self._icr
        return src

    # what _configure changes: restored when the new configuration is refused (a register write
    # that raises leaves the register, and the timer, as they were)
    _CONFIG_STATE = ("_mode", "_kind", "_topsrc", "_dual", "_upd", "_ocr", "_top_flags", "_com", "_act",
                     "_top", "_N", "_run", "_k0", "_ks", "_kblock", "_block_start", "_cs", "_kj", "_qj",
                     "_L", "_exu", "_c0", "_d0")

    def _configure(self, mode, cs, coms):
        """Apply a new mode/clock/COM configuration (validated by the caller); one refused
        (UnsupportedConfiguration) leaves the timer as it was."""
        self._reanchor()
        saved = {k: (dict(v) if isinstance(v, dict) else v)
                 for k, v in ((k, getattr(self, k)) for k in self._CONFIG_STATE)}
        try:
            self._configure_to(mode, cs, coms)
        except UnsupportedConfiguration:
            for k, v in saved.items():
                setattr(self, k, v)
            raise
        for ch in self.CHANNELS:
            self._drive(ch)
        self._plan(self._clock_now())

    def _configure_to(self, mode, cs, coms):
        self._mode = mode
        self._kind, self._topsrc = self.MODES[mode]
        self._dual = self._kind in ("pc", "pfc")
        self._upd = {"pc": "top", "pfc": "bottom", "fast": "top"}.get(self._kind)
        if self._upd is None:
            for ch in self.CHANNELS:
                self._ocr[ch] = self._buf[ch]
        if self._dual:
            self._top_flags = ICF if self._topsrc == "I" else (OCFA if self._topsrc == "A" else 0)
        elif self._kind == "fast":
            self._top_flags = TOV | (ICF if self._topsrc == "I" else (OCFA if self._topsrc == "A" else 0))
        else:  # normal / CTC: TOV only when TOP is MAX
            self._top_flags = (ICF if self._topsrc == "I" else (OCFA if self._topsrc == "A" else 0))
            if self._top_value() == self.MAX:
                self._top_flags |= TOV
        if "capt" not in self.vectors:
            self._top_flags &= ~ICF
        for ch in self.CHANNELS:
            self._com[ch] = coms[ch]
            self._act[ch] = com_behaviour(self._kind, self._topsrc, ch, coms[ch])
        self._top = self._top_value()
        was_run = self._run
        # a TCNT write blocks the compare matches of the next timer clock, "even when the timer is
        # stopped" (datasheet, "Compare Match Blocking by TCNTn Write"): still due, it moves to the
        # first clock of a new prescaler or of a restart
        pending = self._block_start or (was_run and self._kblock == self._k0 + 1)
        if cs:
            N = CS_DIV[cs]
            if not was_run or N != self._N:
                self._N, self._run = N, True
                self._k0 = self._ks = self._clock_now()
                self._kblock = self._k0 + 1 if pending else -1
                self._block_start = False
        else:
            self._run = False
            self._block_start, self._kblock = pending, -1
        self._cs = cs
        if self._dual and self._topsrc == "A" and self._buf["A"] == 0 and self._ocr["A"] != 0:
            # the buffered 0 would become TOP at the next update point, refused mid-run there
            raise UnsupportedConfiguration(self.name, self._topname(), None, 0,
                                           "(in its double buffer) as TOP of a dual-slope mode is not modelled")
        self._derive()

    def _retop(self):
        """TOP or an active compare value changed at once (ICRn write, OCR write in normal/CTC)."""
        if self._kind in ("normal", "ctc"):
            self._top_flags &= ~TOV
            if self._top_value() == self.MAX:
                self._top_flags |= TOV
        self._top = self._top_value()
        self._derive()
        self._plan(self._clock_now())

    # ------------------------------------------------------------------ register-side operations
    def write_register(self, reg, data, lanes=-1):
        self._sync_now()  # flags of past clocks, under the old configuration
        super().write_register(reg, data, lanes)

    def _read_tifr(self, stored):
        self._sync_now()
        return self.value[self.TIFR] & self.regs[self.TIFR].readable

    def _write_flags(self, old, new):
        self._lines()
        self._plan(self._clock_now())

    def _set_tcnt(self, v):
        self._reanchor()
        self._c0 = v & self.MAX
        if not self._dual:
            self._d0 = 1
        if self._run:
            self._kblock = self._k0 + 1
        else:           # blocks the first clock after the start (_configure)
            self._block_start = True
        self._derive()
        self._plan(self._clock_now())

    def _set_ocr(self, ch, v):
        v &= self.MAX
        if isinstance(self._topsrc, int) and self._kind != "normal":
            v &= self._topsrc        # fixed-TOP PWM modes mask the high bits
        if v == 0 and ch == "A" and self._topsrc == "A" and self._dual:
            # it would become TOP at the next update point and be refused there, mid-run
            raise UnsupportedConfiguration(self.name, "OCR1A" if self.MAX > 0xFF else "OCR0A", None, 0,
                                           "as TOP of a dual-slope mode is not modelled")
        self._reanchor()
        self._buf[ch] = v
        if self._upd is None:
            self._ocr[ch] = v
            self._retop()
        else:
            self._plan(self._clock_now())

    def _set_icr(self, v):
        self._reanchor()
        old, self._icr = self._icr, v & self.MAX
        if self._topsrc == "I":
            try:
                self._retop()
            except UnsupportedConfiguration:    # refused: the timer goes on as before the write
                self._icr = old
                self._retop()
                raise

    def _force(self, chans):
        """FOCnx: a forced compare match in non-PWM modes (no flag, no counter clear)."""
        if self._kind not in ("normal", "ctc"):
            return
        for ch in chans:
            act, lev = self._act[ch]
            if act == "toggle":
                self._latch[ch] ^= 1
            elif act is not None:
                self._latch[ch] = lev
            self._drive(ch)
        self._plan(self._clock_now())


def _r16(name, lo, doc=""):
    return (Register(f"{name}L", lo, width=8, on_read=f"_rd_{name}L", on_write=f"_wr_{name}L", doc=doc),
            Register(f"{name}H", lo + 1, width=8, on_read=f"_rd_{name}H", on_write=f"_wr_{name}H"))


class Timer1(AvrTimer):
    """Timer/Counter1 of the ATmega328P.  Register offsets are data-space addresses (attach at 0)."""

    TIFR, TIMSK = "TIFR1", "TIMSK1"
    REGISTERS = (
        Register("TIFR1", 0x36, width=8, on_read="_read_tifr", on_write="_write_flags", fields=(
            Field("TOV1", 0, access="rc_w1"), Field("OCF1A", 1, access="rc_w1"),
            Field("OCF1B", 2, access="rc_w1"), Field("ICF1", 5, access="rc_w1"))),
        Register("TIMSK1", 0x6F, width=8, on_write="_write_flags", fields=(
            Field("TOIE1", 0), Field("OCIE1A", 1), Field("OCIE1B", 2), Field("ICIE1", 5))),
        Register("TCCR1A", 0x80, width=8, on_write="_write_tccr", fields=(
            Field("WGM10", 0), Field("WGM11", 1), Field("COM1B0", 4), Field("COM1B1", 5),
            Field("COM1A0", 6), Field("COM1A1", 7))),
        Register("TCCR1B", 0x81, width=8, on_write="_write_tccr", fields=(
            Field("CS10", 0), Field("CS11", 1), Field("CS12", 2), Field("WGM12", 3), Field("WGM13", 4),
            Field("ICES1", 6), Field("ICNC1", 7, modelled=False, doc="input noise canceller"))),
        Register("TCCR1C", 0x82, width=8, on_write="_write_foc", fields=(
            Field("FOC1B", 6, access="w"), Field("FOC1A", 7, access="w"))),
        *_r16("TCNT1", 0x84),
        *_r16("ICR1", 0x86),
        *_r16("OCR1A", 0x88),
        *_r16("OCR1B", 0x8A),
    )

    def __init__(self, name, mcu, clock, vectors=None, icp="PB0"):
        super().__init__(name, mcu, clock, vectors or {"capt": 10, "compa": 11, "compb": 12, "ovf": 13})
        self._temp = 0
        self._ices = 0
        self._icp: Net | None = None
        self._icp_level = None
        if icp:
            self.icp = mcu.add_pin(icp)     # ICP1 is PB0 on the ATmega328P (datasheet pin list)
        for reg in ("TCNT1", "ICR1", "OCR1A", "OCR1B"):
            setattr(self, f"_wr_{reg}H", partial(self._wr_hi))
            setattr(self, f"_wr_{reg}L", partial(self._wr_lo, reg))
            setattr(self, f"_rd_{reg}L", partial(self._rd_lo, reg))
            setattr(self, f"_rd_{reg}H", partial(self._rd_hi, reg))

    def _topname(self):
        return {"A": "OCR1A", "I": "ICR1"}.get(self._topsrc, "TOP")

    # --- 16-bit access through TEMP (§1.5)
    def _get16(self, reg):
        if reg == "TCNT1":
            return self.counter
        if reg == "ICR1":
            return self._icr
        return self._buf[reg[-1]]

    def _wr_hi(self, old, new):
        self._temp = new & 0xFF

    def _wr_lo(self, reg, old, new):
        v = (self._temp << 8) | (new & 0xFF)
        if reg == "TCNT1":
            self._set_tcnt(v)
        elif reg == "ICR1":
            self._set_icr(v)
        else:
            self._set_ocr(reg[-1], v)

    def _rd_lo(self, reg, stored):
        v = self._get16(reg)
        if reg in ("TCNT1", "ICR1"):
            self._temp = v >> 8
        return v & 0xFF

    def _rd_hi(self, reg, stored):
        if reg in ("TCNT1", "ICR1"):
            return self._temp
        return self._get16(reg) >> 8

    # --- control
    def _write_tccr(self, old, new):
        a, b = self.value["TCCR1A"], self.value["TCCR1B"]
        mode = (a & 3) | ((b >> 1) & 0xC)
        if mode not in self.MODES:
            raise UnsupportedConfiguration(self.name, "TCCR1A/TCCR1B", "WGM1", mode,
                                           "(reserved waveform mode 13) is not supported")
        cs = b & 7
        if cs in (6, 7):
            raise UnsupportedConfiguration(self.name, "TCCR1B", "CS1", cs,
                                           "(external clock on pin T1) is not modelled")
        self._ices = (b >> 6) & 1
        self._configure(mode, cs, {"A": (a >> 6) & 3, "B": (a >> 4) & 3})

    def _write_foc(self, old, new):
        self._force([ch for ch, bit in (("A", 0x80), ("B", 0x40)) if new & bit])

    # --- input capture
    @property
    def icp(self) -> Net | None:
        """The ICP1 input net (PB0 unless the profile's ``icp`` says otherwise; assigning a net
        connects the capture listener there instead)."""
        return self._icp

    @icp.setter
    def icp(self, net: Net | None) -> None:
        self._icp = net
        if net is not None:
            self._icp_level = net.level
            net.listen(self._icp_edge)

    def _icp_edge(self, net):
        if net is not self._icp:
            return
        level, prev = net.level, self._icp_level
        self._icp_level = level
        if level == prev or level != self._ices:
            return
        t = self.kernel.now
        self.kernel.at((t // self._P + 1) * self._P, self._capture)

    def _capture(self):
        if self._topsrc == "I":
            return   # ICR1 defines TOP: the capture function is disabled
        self._sync_now()
        self._icr = self.counter
        self.value["TIFR1"] |= ICF
        self._lines()
