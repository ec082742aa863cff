"""Guard screening over whole chunks of PWM periods (the chunk segment itself: :mod:`.chunk`).

A motor fed a steady waveform (:mod:`mcusim.engine.waveform`) sees a periodic sequence of
*pieces* (constant drive, constant mode). :class:`PeriodPlan` composes the pieces of one period,
starting at a piece boundary, into a period map (:mod:`mcusim.engine.periodmap`) and screens every
guard the edge-by-edge engine would screen in each piece (current reaching zero, speed reaching
zero, breakaway, the bridge's over-current or current limit, encoder thresholds) over N periods at
once:

* the states at the start and end of every piece of every period come from the power table (one
  matrix product per piece), or, for a plan whose pieces are all stuck, from the current's
  closed form (:mod:`mcusim.engine.held`);
* inside a piece of τ seconds starting at x, ``|x(t)|`` is bounded component-wise by
  ``x̄ = (I − τ|A|)⁻¹(|x| + τ|u|)`` and so ``|ẋ| ≤ D = |A|·x̄ + |u|``; a guard h = c·x + c0 that is
  positive at both ends with ``h_start + h_end > τ·|c|·D`` cannot reach zero inside (a Lipschitz
  bound), with a safety margin for float rounding;
* in a stuck piece (ω held) the current is a single exponential, so a guard without a θ term is
  monotone there and positive ends suffice; |i| and |ω| there are bounded by their values at the
  piece's ends, whatever its length.

A chunk whose pieces are all stuck is screened at its first and last period only
(:mod:`mcusim.engine.held`: every guard is monotone there).

The first period in which any guard *may* fire ends the chunk: the motor advances to its start
with the period map's power and runs that period piece by piece, exactly as the edge-by-edge engine
does (closed-form segments, guards located to the tick). The bound is conservative, never
optimistic: a flagged period that does not fire costs only speed.
"""

from __future__ import annotations

import math

import numpy as np

from . import held, modal, periodmap
from .held import head
from .periodmap import LinearPowers, PowerTable

#: screen chunks of stuck pieces at their ends only (PeriodPlan._stuck_ends); off: every period
STUCK_ENDS = True

#: clear moving chunks by the modal test first (mcusim.engine.modal); off: every period
MODAL = True

#: relative safety margin of a screened guard value (far above the maps' float rounding, ~1e-15 in
#: delta form, and the screening's own numpy rounding)
MARGIN = 1e-9


class PeriodPlan:
    """One period of pieces starting at a piece boundary, with its maps, guards and power table.

    ``pieces``: list of ``(ticks, flow, absA, absu, guards, drive, mode)`` in time order, where
    ``flow`` is the augmented 4×4 delta map of the piece (``T − I``, :mod:`.periodmap`),
    ``absA``/``absu`` the absolute values of the piece's (i, ω) dynamics, and guards ``(ci, cw, cθ, c0, strict, provider, tag)``.
    """

    def __init__(self, pieces, period_ticks: int, inv_hz: float, n: int, formers=None, guard_cache=None,
                 linear_cache=None):
        self.pieces = pieces
        # guard arrays by (each piece's guards, the extra guards, which pieces are stuck), shared by
        # the plans of one motor: a PID moving the duty builds a plan at every step, same guards
        self.guard_cache = {} if guard_cache is None else guard_cache
        # what depends on the period map's linear part alone (its powers, its modes), by that part,
        # shared by the plans of one motor: a supply voltage or a load torque that changes every
        # millisecond (the rover's battery and body) makes a new plan each time, with the same
        # linear part
        self.linear_cache = {} if linear_cache is None else linear_cache
        # per piece, the closed form of the piece from a start state (a pwl.Traj): the motor's
        # segment builder bound to the piece's drive, mode and the plan's parameters
        self.formers = formers
        self.P = period_ticks
        self.inv = inv_hz
        # Q[p]: delta map from the period start to the start of piece p; Q[len]: the period's
        Q = [np.zeros((4, 4))]
        for pc in pieces:
            Q.append(periodmap.then(Q[-1], pc[1]))
        self.Q = Q
        self.Ql = Ql = [q.tolist() for q in Q]      # the same, as lists (one state at a time)
        self.T = Q[-1]
        self._n = n
        self._table = None
        self.starts = []   # tick offset of each piece from the period start
        off = 0
        for pc in pieces:
            self.starts.append(off)
            off += pc[0]
        self._stuck_t = tuple(pc[6][1] == 0 for pc in pieces)
        # x̄ = W·|x| + w per piece (_bound_rows), W = (I − τ|A|)⁻¹: none when τ|A| is not a
        # contraction (no bound, never chunk). A stuck piece needs none: its |i| is largest at an
        # end and ω is held (first_flag), so a plan of stuck pieces (holding) is always bounded and
        # builds the rows only if a screening of every period asks for them.
        self._brows = None
        self._bounded = True if all(self._stuck_t) else self._bound_rows is not None
        self._arrays = None                  # the same, stacked (_stacked)
        # every piece stuck: over a period only the current moves, i ← a·i + b (``_held_states``)
        T = Ql[-1]
        t00, t03 = T[0][0], T[0][3]
        self._held = ((math.log1p(t00), t03 / t00) if all(self._stuck_t) and -1.0 < t00 < 0.0
                      and not (T[0][1] or T[0][2]) and not any(T[1]) else None)
        self._screens = {}   # extra guards -> the stacked guard arrays (_guard_arrays)
        self._modes = None   # the period map's modal form (modal.Modes), False where it has none
        self._theta_guards = any(g[2] for pc in pieces for g in pc[4])

    @property
    def _bound_rows(self):
        """Per piece (Wt, w, τ, |A|ᵀ, |u|) of the bound ``x̄ = W·|x| + w`` as nested tuples, or
        None where a moving piece has no bound (τ|A| not a contraction)."""
        rows = self._brows
        if rows is None:
            Wt, w, taus, At, us = [], [], [], [], []
            for ticks, _, absA, absu, _, _, mode, _ in self.pieces:
                tau = ticks * self.inv
                a00, a01, a10, a11 = absA
                m00, m01, m10, m11 = 1.0 - tau * a00, -tau * a01, -tau * a10, 1.0 - tau * a11
                det = m00 * m11 - m01 * m10
                if det <= 0 or tau * (a00 + a11) >= 1.0:
                    if mode[1] != 0:
                        rows = self._brows = False
                        return None
                    W00 = W01 = W10 = W11 = 0.0
                else:
                    # (I − τ|A|)⁻¹ of the 2×2 in closed form; its off-diagonal entries are τ|a|/det ≥ 0
                    W00, W01, W10, W11 = m11 / det, -m01 / det, -m10 / det, m00 / det
                tu0, tu1 = tau * absu[0], tau * absu[1]
                Wt.append(((W00, W10), (W01, W11)))
                w.append(((W00 * tu0 + W01 * tu1, W10 * tu0 + W11 * tu1),))
                taus.append(((tau,),))
                At.append(((a00, a10), (a01, a11)))
                us.append((absu,))
            rows = self._brows = (Wt, w, taus, At, us)
        return rows or None

    @property
    def table(self) -> PowerTable:
        """The powers of the period map (built when first asked for: a held plan needs none)."""
        if self._table is None:
            key = ("powers", self.T[:3, :3].tobytes())
            lin = self._shared(key, lambda: LinearPowers(self.T[:3, :3]))
            self._table = PowerTable(self.T, self._n, lin)
        return self._table

    def _shared(self, key, make):
        """The entry ``key`` of the linear cache, made by ``make()`` if missing (the cache is
        emptied when it holds 64 entries: memory stays flat)."""
        cache = self.linear_cache
        got = cache.get(key)
        if got is None:
            if len(cache) >= 64:
                cache.clear()
            got = cache[key] = make()
        return got

    def _stacked(self):
        """(Wt, w, τ, |A|ᵀ, |u|, stuck, Q[1..npc-1]ᵀ side by side) as arrays, for the screening of
        every period: built once per plan, when first needed."""
        a = self._arrays
        if a is None:
            Wt, w, taus, At, us = self._bound_rows
            npc = len(self.pieces)
            # Q[1..npc-1] side by side: one product gives every inner piece start
            qcat = np.concatenate([q.T for q in self.Q[1:npc]], axis=1) if npc > 1 else None
            a = self._arrays = (np.array(Wt), np.array(w), np.array(taus), np.array(At), np.array(us),
                                np.array(self._stuck_t)[:, None, None], qcat)
        return a

    def first_flag(self, x0, n: int, extra_guards):
        """(k, X, ib, (wlo, whi)): the first period k (0..n) in which a guard may fire (n if none
        fires in n periods), the states X[0..k] at the period starts (rows (i, ω, θ, 1)), a bound of
        |i| over those k periods (at least as large as the largest |i| in them), and bounds of |ω|
        there (wlo ≤ |ω| ≤ whi)."""
        X = self._held_states(x0, n) if self._held is not None and x0[1] == 0.0 else None
        if X is None:
            X = self.table.augmented_states(x0, n)   # (n+1, 4)
        if not self._bounded or n == 0:
            return 0, head(X, 1), 0.0, (0.0, 0.0)
        arrays = self._screens.get(extra_guards)
        if arrays is None:
            if len(self._screens) > 16:
                self._screens.clear()
            # the same guards in the same modes make the same arrays, whatever the pieces' lengths:
            # a PID moving the duty builds a new plan at every step, with the guards of the last
            shared = self.guard_cache
            key = (tuple(pc[4] for pc in self.pieces), extra_guards, self._stuck_t)
            arrays = shared.get(key)
            if arrays is None:
                if len(shared) >= 64:
                    shared.clear()
                arrays = shared[key] = self._guard_arrays(extra_guards)
            self._screens[extra_guards] = arrays
        G, aGd, aGth, aGx, aG0, mono, ends = arrays
        if STUCK_ENDS and ends and n > 2:
            clean = self._stuck_ends(X, n, extra_guards)
            if clean is not None:
                return clean
        if MODAL and n > 2 and not any(self._stuck_t):
            clean = self._modal(x0, X, n, extra_guards)
            if clean is not None:
                return clean
        Wt, w, tau, At, u, stuck, qcat = self._stacked()
        X = np.asarray(X)
        npc = len(self.pieces)
        # St[p]: the state at the start of piece p in each period (rows), St[npc] the next period's
        Xn = X[:n]
        St = np.empty((npc + 1, n, 4))
        St[0] = Xn
        if npc > 1:
            St[1:npc] = (Xn @ qcat).reshape(n, npc - 1, 4).swapaxes(0, 1) + Xn
        St[npc] = X[1:]
        S, E = St[:-1], St[1:]                  # (pieces, periods, 4) at each piece's start and end
        xb = np.abs(S[:, :, :2]) @ Wt + w               # bound of |i|, |ω| inside the piece
        if any(self._stuck_t):
            # a stuck piece: i is one exponential (monotone), ω is held: |i|, |ω| peak at an end
            xb = np.where(stuck, np.maximum(np.abs(S[:, :, :2]), np.abs(E[:, :, :2])), xb)
        D = xb @ At + u                                  # bound of |di/dt|, |dω/dt|
        hs = S @ G                                       # (pieces, periods, guards)
        he = E @ G
        lip = tau * (D @ aGd + xb[:, :, 1:2] * aGth)
        if mono is not None:
            lip *= mono
        scale = (np.abs(S[:, :, :3]) @ aGx + aG0) * MARGIN
        bad = ((hs <= scale) | (he <= scale) | (hs + he <= lip + 2.0 * scale)).any(axis=(0, 2))
        k = int(np.argmax(bad)) if bad.any() else n
        if k == 0:
            return 0, head(X, 1), 0.0, (0.0, 0.0)
        # |ω| over the k periods: at most the inside bound, at least |ω| at a piece start less the
        # most dω/dt can move it over the piece (a counted run of encoder crossings needs both)
        wk = xb[:, :k, 1]
        wlo = float((np.abs(S[:, :k, 1]) - tau[:, :, 0] * D[:, :k, 1]).min())
        return k, X[:k + 1], float(xb[:, :k, 0].max()), (max(wlo, 0.0), float(wk.max()))

    def _modal(self, x0, X, n: int, extra_guards):
        """The modal test of a moving chunk (:mod:`mcusim.engine.modal`): (n, X, ib, (wlo, whi)) if
        it clears every guard over all n periods, else None (the full screening decides)."""
        modes = self._modes
        if modes is None:
            T = self.Ql[-1]
            like = self._shared(("modes", T[0][0], T[0][1], T[1][0], T[1][1]), lambda: self._modes_of(None))
            modes = self._modes = like and self._modes_of(like)
        if modes is False or any(g[2] for g in extra_guards) or self._theta_guards:
            return None
        pieces = self.pieces
        got = modal.screen(self, modes, x0, X[n], n, lambda p: pieces[p][4] + extra_guards, MARGIN)
        if got is None:
            return None
        return n, head(X, n + 1), got[0], got[1]

    def _modes_of(self, like):
        """The plan's :class:`modal.Modes` (eigenvectors as ``like``'s, if given), False if none."""
        try:
            return modal.Modes(self.Ql, like)
        except (ValueError, ZeroDivisionError, OverflowError):
            return False

    def _held_states(self, x0, n: int):
        """Period-start rows of a held chunk from a shaft at rest (:func:`held.held_states`)."""
        return held.held_states(self, x0, n)

    def _stuck_ends(self, X, n: int, extra_guards):
        """Screen a chunk of stuck pieces at its two end periods (:func:`held.stuck_ends`)."""
        return held.stuck_ends(self, X, n, extra_guards, MARGIN)

    def _guard_arrays(self, extra_guards):
        """Each piece's guards and ``extra_guards`` as the stacked arrays :meth:`first_flag`
        multiplies by: G as (pieces, 4, guards), one column (ci, cw, cθ, c0) per guard, and the
        parts of |G| the bounds use. Pieces with fewer guards are padded with h ≡ 1, which never flags."""
        rows = [[g[:4] for g in pc[4] + extra_guards] for pc in self.pieces]
        m = max(1, max(len(r) for r in rows))
        G = np.array([r + [(0.0, 0.0, 0.0, 1.0)] * (m - len(r)) for r in rows], dtype=float)
        aG = np.abs(G)                                   # (pieces, guards, 4)
        Gt = G.transpose(0, 2, 1)
        aGt = aG.transpose(0, 2, 1)
        # In a stuck piece (s = 0) the current is one exponential, i(t) = i_ss + (i0 − i_ss)·e^{λt}, and
        # ω is held: a guard without a θ term is monotone in t there, so its ends decide it and the
        # Lipschitz term is dropped (mono 0). A shaft held at the breakaway threshold by a position
        # loop sits 1-3 % of the threshold below it, well inside the bound's slack of one piece.
        mono = None
        stuck = np.array(self._stuck_t)[:, None]
        if stuck.any():
            mono = np.where(stuck & (G[:, :, 2] == 0.0), 0.0, 1.0)[:, None, :]
        # every piece stuck and every guard either without a θ term or on θ alone: the chunk's two
        # end periods decide it (_stuck_ends)
        ends = bool(stuck.all() and not (mono * aGt[:, :2].any(axis=1, keepdims=True)).any())
        return Gt, aGt[:, :2], aGt[:, 2:3], aGt[:, :3], aGt[:, 3:4], mono, ends

    def states_at_piece_starts(self, x0, k: int):
        """Rows: the state at the start of each piece, for periods 0..k-1 (shape (k, pieces, 3))."""
        X = self.table.augmented_states(x0, k - 1)
        return np.stack([X + X @ q.T for q in self.Q[:-1]], axis=1)[:, :, :3]


__all__ = ["MARGIN", "PeriodPlan"]
