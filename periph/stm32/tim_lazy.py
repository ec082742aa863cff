"""Lazy encoder counting for :class:`mcusim.periph.stm32.tim.Tim` (fast engine).

Edge by edge, every threshold crossing of a quadrature encoder is located in the motor's
trajectory, set on two nets, passed through the TIx input stage (:mod:`.tim_input`: the filter's
samples, two CK_INT cycles of resynchronisation) and decoded (§4.2) into a CNT step. Lazily, the
encoder's outputs are level descriptors computed from the shaft angle
(:class:`mcusim.plant.encoder.ShaftCode`) and the timer computes what those edges would have done
when a register is read or written.

The rule. A change at pin tick ``t`` takes effect at ``t_eff = (t // sp + N)·sp + 2·P`` (sampling
period ``sp``, ``N`` samples, CK_INT period ``P``), so a read at tick ``now`` has seen exactly the
crossings at ticks before ``t_cut = ((now − 2P) // sp − N + 1)·sp``: the decoder's position is the
encoder position ``k`` at tick ``t_cut − 1``. That holds while every crossing is one transition the
filter passes and the decoder counts: θ monotone (no pulse shorter than N samples, no reversal)
and crossings more than ``gap = N·sp + sp + 2P`` ticks apart (never TI1 and TI2 in one sample,
at most one crossing in flight). The encoder ends the stretch before either fails (its guards:
ω reaching zero, |ω| reaching the speed at which crossings come ``gap`` ticks apart).

In a stretch of ``m`` transitions in one direction, starting at CNT = c:

* CNT moves by one per transition (x4 decoding, ``SMS=011``), in the direction the §4.2 table
  gives for that shaft direction; DIR takes it;
* the counter does not wrap: the stretch ends at the crossing before the one that would wrap it
  (then the wrap, UEV and UIF run edge by edge);
* CCxIF of an output-mode channel is set if CNT steps onto CCRx (as ``Tim._plan`` flags a tick);
* a capture channel (CCxS = 01, CCxE = 1) captures on TIxFPx rising, which for one direction
  happens at positions of one residue mod 4: the number of captures through ICxPSC, CCRx = CNT
  after the last one, CCxIF, and CCxOF when a capture finds CCxIF set.

Taken lazily only where this is all there is: SMS = 011, CEN = 1, encoder prescaler 0, ARR ≠ 0, no
CCxIE, no PWM output enabled on the timer, the same filter on TI1 and TI2, nothing in flight in
the input stage. A write of CR1, SMCR, CCMRx, CCER or BDTR ends the stretch before it takes
effect (the input stage as configured so far gets the crossings in flight); any other write is
followed by the same check. Reads and writes first bring the counter to their tick.
"""

from __future__ import annotations

from mcusim.errors import McusimError

from .tim_input import encoder_direction_up

_CEN = 1
_CCIF = (0, 1 << 1, 1 << 2, 1 << 3, 1 << 4)
_CCOF = (0, 1 << 9, 1 << 10, 1 << 11, 1 << 12)
_PWM1 = 0b0110
#: writes that end a lazy stretch before they take effect (they change the input stage or decoding)
EXIT_FIRST = frozenset(("CR1", "SMCR", "CCMR1", "CCMR2", "CCER", "BDTR"))


class Stretch:
    """A lazy stretch: the encoder, which of its outputs each input carries, the shaft direction,
    the position already decoded and from which tick, and the constants of the rule."""

    __slots__ = ("chmap", "d", "enc", "inv", "kb", "kx", "n", "rise", "sp", "t0", "tq", "u", "up")

    def __init__(self, enc, chmap, d, k, t0, sp, n):
        self.enc, self.chmap, self.d, self.kb, self.t0, self.sp, self.n = enc, chmap, d, k, t0, sp, n
        self.inv = {e: c for c, e in chmap.items()}
        self.tq = t0            # the tick up to which crossings are decoded (their effect taken)
        self.kx = None          # the exit position (the crossing into it ends the stretch)
        self.up = None
        self.u = 0
        self.rise = {}


class LazyEncoderStage:
    """The lazy-counting part of :class:`mcusim.periph.stm32.tim.Tim` (module docstring)."""

    def lazy_possible(self) -> bool:
        """Whether the configuration lets a stretch start (what is in flight aside)."""
        return self._enc_lazy is None and self._lazy_ok()

    def _lazy_ok(self) -> bool:
        v = self.value
        return bool(self.kernel.fast and self._sms == 3 and v["CR1"] & _CEN and self._psc == 0
                    and self._arr != 0 and not v["DIER"] & 0x1E and self._icf[1] == self._icf[2]
                    and not any(self._en[ch] and self._mode[ch] >= _PWM1 for ch in (1, 2, 3, 4)))

    def lazy_enter(self, enc, chmap, d: int, k: int):
        """The encoder ``enc`` (position ``k`` now, shaft moving in direction ``d``) offers its
        outputs as descriptors, output ``chmap[c]`` (0 = A, 1 = B) on TIc. Returns (exit position,
        gap) and counts lazily from now, or None (then nothing changed)."""
        if set(chmap) != {1, 2} or self._enc_lazy is not None or not self._lazy_ok():
            return None
        inp, pol = self._inp, self._pol
        if inp[1].queue or inp[2].queue:
            return None
        lv = enc.levels(k)
        for c in (1, 2):
            if inp[c].level != lv[chmap[c]] ^ pol[c] or inp[c].last != inp[c].level:
                return None
        sp, n = self._filter(1)
        L = Stretch(enc, chmap, d, k, self.kernel.now, sp, n)
        ups = set()
        for r in range(4):      # one transition of each position residue in direction d
            a, b = enc.levels(k + r), enc.levels(k + r + d)
            e = 0 if a[0] != b[0] else 1
            c = L.inv[e]
            v = b[e] ^ pol[c]
            ups.add(encoder_direction_up(c, v, b[1 - e] ^ pol[3 - c]))
            if v and self._cap[c]:
                L.rise[c] = (k + r + d) % 4         # TIcFPc rises on entering positions of this residue
        if len(ups) != 1:
            return None         # (cannot happen: CCxP flips both channels' transitions alike)
        L.up = ups.pop()
        L.u = 1 if L.up else -1
        L.kx = self._lazy_exit_k(L)
        if L.kx is None:
            return None
        self._enc_lazy = L
        return L.kx, n * sp + sp + 2 * self._P

    def lazy_cancel(self) -> None:
        """The encoder did not start the stretch after all (nothing was counted lazily)."""
        self._enc_lazy = None

    def _lazy_exit_k(self, L):
        """The position whose crossing ends the stretch: the one before the transition that wraps
        CNT (§4.3: up from CNT ≥ ARR, down from 0), or None if that is the next one."""
        c, arr = self._cnt, self._arr
        m = (1 if c >= arr else arr - c + 1) if L.u > 0 else c + 1
        return None if m < 2 else L.kb + L.d * (m - 1)

    def _lazy_tq(self, L, now: int) -> int:
        t_cut = ((now - 2 * self._P) // L.sp - L.n + 1) * L.sp
        return max(t_cut - 1, L.t0)

    def _lazy_sync(self) -> None:
        """Bring CNT, DIR, flags and captures to now: the crossings whose effect has been taken."""
        L = self._enc_lazy
        tq = self._lazy_tq(L, self.kernel.now)
        if tq <= L.tq:
            return
        L.tq = tq
        k2 = L.enc.k_at(tq)
        if k2 != L.kb:
            self._lazy_moves(L, k2)

    def _lazy_moves(self, L, k2: int) -> None:
        k1, d, u = L.kb, L.d, L.u
        m = (k2 - k1) * d
        c1 = self._cnt
        c2 = c1 + u * m
        if m < 0 or not 0 <= c2 <= max(self._arr, c1):
            raise McusimError(f"{self.name}: lazy encoder count left its stretch ({k1} -> {k2}, CNT {c1} -> {c2})")
        self._cnt, self._up = c2, L.up
        L.kb = k2
        v = self.value
        sr = sr0 = v["SR"]
        lo, hi = (k1 + 1, k2) if d > 0 else (k2, k1 - 1)
        if self._flag_up if L.up else self._flag_down:
            a, b = (c1 + 1, c2) if u > 0 else (c2, c1 - 1)
            for ch in (1, 2, 3, 4):     # CNT stepped onto CCRx (output-mode channels)
                if self._mode[ch] >= 0 and a <= self._ccr[ch] <= b:
                    sr |= _CCIF[ch]
        for c, r in L.rise.items():
            if not self._cap[c]:
                continue
            rises = (hi - r) // 4 - (lo - 1 - r) // 4     # positions j in [lo, hi], j ≡ r (mod 4)
            if not rises:
                continue
            div = 1 << self._icpsc[c]
            capn = min(self._capn[c], div - 1)   # ICxPSC lowered: the next rise captures
            caps, self._capn[c] = divmod(capn + rises, div)
            if not caps:
                continue
            nth = caps * div - capn                       # the last capture is the nth rise
            first = lo + (r - lo) % 4 if d > 0 else hi - (hi - r) % 4
            j = first + d * 4 * (nth - 1)
            v[f"CCR{c}"] = c1 + u * (j - k1) * d
            if sr & _CCIF[c] or caps > 1:
                sr |= _CCOF[c]
            sr |= _CCIF[c]
        if sr != sr0:
            v["SR"] = sr
            self._irq()
        self._refresh_outputs()

    def _lazy_end(self) -> None:
        """The encoder's descriptors end at now: decode what has taken effect, and put the
        crossings still in flight (at most one, and one at now itself) into the input stage."""
        L = self._enc_lazy
        self._lazy_sync()
        now = self.kernel.now
        enc, pol, inp = L.enc, self._pol, self._inp
        tq = L.tq
        kq = L.kb
        lv = enc.levels(kq)
        for c in (1, 2):
            inp[c].reset(lv[L.chmap[c]] ^ pol[c])
        crossings = []
        if now > tq:
            k1 = enc.k_at(now - 1) if now - 1 > tq else kq
            if k1 != kq:
                if abs(k1 - kq) != 1:
                    raise McusimError(f"{self.name}: lazy encoder: two crossings in flight")
                lo, hi = tq, now - 1
                while hi - lo > 1:
                    mid = (lo + hi) // 2
                    if enc.k_at(mid) == kq:
                        lo = mid
                    else:
                        hi = mid
                crossings.append((hi, k1))
            kn = enc.k_now()      # a crossing due now, unless an earlier event of the tick asks
            if kn != k1:
                if abs(kn - k1) != 1:
                    raise McusimError(f"{self.name}: lazy encoder: two crossings in one tick")
                crossings.append((now, kn))
        self._enc_lazy = None
        prev = kq
        for tc, k in crossings:
            a, b = enc.levels(prev), enc.levels(k)
            e = 0 if a[0] != b[0] else 1
            c = L.inv[e]
            inp[c].edge(b[e] ^ pol[c], tc, L.sp, L.n, self._P)
            prev = k

    def _lazy_after_write(self) -> None:
        L = self._enc_lazy
        if not self._lazy_ok():
            L.enc.materialize()
            return
        kx = self._lazy_exit_k(L)
        if kx is None:
            L.enc.materialize()
        elif kx != L.kx:
            L.kx = kx
            L.enc.set_exit(kx)
