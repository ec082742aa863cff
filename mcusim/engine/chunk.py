"""The chunk segment of a DC motor: whole PWM periods of a period plan (:mod:`.screening`) that
screened clean, read at any tick from the period-start states and the pieces' closed forms, with
the first tick an encoder threshold fires located as the edge-by-edge engine locates it."""

from __future__ import annotations

import bisect
import math

import numpy as np

from ..plant import pwl
from . import periodmap
from .held import HeldRows
from .screening import MARGIN, PeriodPlan


class ChunkTraj:
    """A motor segment of whole periods: state at any tick from the power table and the pieces."""

    kind = "chunk"

    def __init__(self, plan: PeriodPlan, x0, X, ibound=math.inf, wspan=(0.0, math.inf), lo: float = 0.0):
        self.plan, self.x0 = plan, tuple(x0)
        # what the motor's accumulated angle holds beyond x0[2] (``DcMotor._th_lo``): every angle
        # the chunk reports after its start includes it, as a closed-form segment's do; a shaft
        # held by static friction in every piece reports the angle it holds
        self.lo = 0.0 if all(plan._stuck_t) else lo
        self.ibound = ibound * (1.0 + MARGIN)   # no |i| in the chunk exceeds it (peak() skips)
        # wlo ≤ |ω| ≤ whi everywhere in the chunk (the screening's bounds, with the margin)
        self.wspan = (wspan[0] * (1.0 - MARGIN), wspan[1] * (1.0 + MARGIN))
        self._form = plan.formers            # per piece: start state -> closed-form pwl.Traj
        self.X = X                           # states at the period starts of the chunk
        self.periods = len(X) - 1
        self._piece_memo = (None, None, None)   # (tick offset of a piece start, its state, closed form)
        self._evals = {}                     # tick in that piece -> its state (see _eval)
        self._theta = None                   # θ at the period starts, as floats (first_fire)
        self._rows = {}                      # period q -> X[q] as floats

    def _row(self, q: int):
        """X[q] as floats, its angle with ``lo`` added (q > 0)."""
        r = self._rows.get(q)
        if r is None:
            X = self.X
            r = self._rows[q] = X.row(q) if type(X) is HeldRows else X[q].tolist()
            if q and self.lo:
                r[2] += self.lo
        return r

    def _start(self, q: int, p: int):
        """State at the start of piece ``p`` of period ``q``: the one expression that the readers of
        a state (``at``), the threshold search and the piece closed forms all use, so they agree to
        the bit. (``peak`` screens whole arrays of piece starts with numpy, which may differ in the
        last bit; it only bounds the peak current.)"""
        if not p:
            return self.x0 if q == 0 else tuple(self._row(q)[:3])
        if q == 0:
            return periodmap.apply_rows(self.plan.Ql[p], self.x0, self.lo)
        return periodmap.apply_rows(self.plan.Ql[p], self._row(q)[:3])

    def first_fire(self, g, after: int):
        """First tick offset > ``after`` (≤ the chunk's end) at which the θ-only guard ``g`` fires,
        or None. θ is monotone in a chunk (ω keeps its sign: its guard is screened), so the period
        is found from the period-start values, and the tick inside it exactly as the edge-by-edge
        engine finds it: from the closed form of the piece (from ``after`` if that lies inside)."""
        ct, c0, strict = g[2], g[3], g[4]
        th = self._theta
        if th is None:
            X = self.X
            # as _row reads them: lo added after the first (numpy adds as Python does, to the bit)
            th = self._theta = [float(X[0][2])] + (X[1:, 2] + self.lo).tolist() if self.lo else X[:, 2].tolist()

        def fired(v):
            h = v * ct + c0
            return h < 0.0 if strict else h <= 0.0
        # θ is monotone over the period starts, so "fired" is too: the first fired one by bisection
        hi = len(th) - 1
        if not fired(th[hi]):
            return None
        kb = bisect.bisect_left(th, True, 0, hi, key=fired)
        plan = self.plan
        P = plan.P
        # θ is monotone: the crossing lies in the period ending at the first fired boundary kb
        # (period q0 then; q0 + 1 is searched only if rounding made the rows non-monotone)
        q0 = max(kb - 1, after // P, 0)
        npc = len(plan.pieces)
        Ql = plan.Ql
        ev, hval = self._eval, pwl.hval
        h_at = lambda j: hval(g, ev(j))     # the guard j ticks into the current piece
        for q in range(q0, min(q0 + 2, self.periods)):
            for p, pc in enumerate(plan.pieces):
                ts = q * P + plan.starts[p]
                te = ts + pc[0]
                if te <= after:
                    continue
                # θ at the piece end (monotone in the chunk): no crossing in this piece if not fired
                if p + 1 < npc:
                    # the next piece's start angle, as _start gives it (lo: in the row, or added here)
                    x = self.x0 if q == 0 else self._row(q)
                    r = Ql[p + 1][2]
                    d = r[0] * x[0] + r[1] * x[1] + r[2] * x[2] + r[3]
                    the = x[2] + (d + self.lo) if q == 0 else x[2] + d
                else:
                    the = th[q + 1]
                he = the * ct + c0
                if not (he < 0.0 if strict else he <= 0.0):
                    continue
                self._piece(q, p)
                lo, n = max(after - ts, 0), te - ts
                # the guard at the piece end is ``he``: the state there is the next piece's start,
                # from the period rows, as ``at`` reads it
                k = pwl.first_fire_monotone(h_at, lo, n, h_at(lo), he, strict)
                if k is not None:
                    return ts + k
        return None

    def _piece(self, q: int, p: int):
        """(start state, closed form) of piece ``p`` of period ``q``; the last one is kept, since
        reads and threshold searches come in runs inside one piece."""
        plan = self.plan
        ts = q * plan.P + plan.starts[p]
        memo = self._piece_memo
        if memo[0] == ts:
            return memo[1], memo[2]
        xk = self._start(q, p)
        tr = self._form[p](xk)
        self._piece_memo = (ts, xk, tr)
        self._evals = {}
        return xk, tr

    def _eval(self, j: int):
        """State ``j`` ticks into the piece last made current by :meth:`_piece`. Kept per tick: an
        encoder edge's search ends on the tick its event comes back to read (the encoder reads θ
        there), and the next edge's search starts from it, against the same piece end."""
        x = self._evals.get(j)
        if x is None:
            x = self._evals[j] = self._piece_memo[2].eval(j * self.plan.inv) if j else self._piece_memo[1]
        return x

    def _where(self, n: int):
        """(period, piece, ticks into the piece) of tick offset ``n``."""
        k, r = divmod(n, self.plan.P)
        starts = self.plan.starts
        p = 0
        while p + 1 < len(starts) and starts[p + 1] <= r:
            p += 1
        return k, p, r - starts[p]

    def at(self, n: int):
        """State n ticks after the chunk start."""
        if n == 0:
            return self.x0
        k, p, rest = self._where(n)
        if rest == 0:
            memo = self._piece_memo
            if memo[0] == n:
                return memo[1]
            return self._start(k, p)
        self._piece(k, p)
        return self._eval(rest)

    def dtheta(self, n: int) -> float:
        """θ n ticks after the chunk start less θ at its start (the angle turned), summed from
        small terms: the period map's powers up to the period (held: none), the piece start's
        offset in the period, the piece's closed form, without ``lo``. ``DcMotor._advance`` adds it
        to the angle accumulated over many segments; ``at`` gives the angle itself, ``lo``
        included, rounded at the angle's scale."""
        if n == 0:
            return 0.0
        plan = self.plan
        k, p, rest = self._where(n)
        d = 0.0
        table = plan._table
        if k and table is not None and type(self.X) is not HeldRows:
            # (rows not from the powers are a held chunk's, whose θ does not move)
            x0, c = self.x0, table.c
            lin = table.linear
            lin.ensure(k)
            row = lin.powers[k][2].tolist()         # θ's row of [L_k | S_k]
            d = (row[0] * x0[0] + row[1] * x0[1] + row[2] * x0[2] + row[3] * c[0] + row[4] * c[1]
                 + row[5] * c[2])
        if p:
            x = self.x0 if k == 0 else self._row(k)
            m = plan.Ql[p][2]
            d += m[0] * x[0] + m[1] * x[1] + m[2] * x[2] + m[3]
        if rest:
            self._piece(k, p)
            d += self._piece_memo[2].dtheta(rest * plan.inv)
        return d

    def peak(self, n: int) -> float:
        """Largest |i| over the first n ticks: at every piece boundary and at the current's
        stationary point inside a piece (as the edge-by-edge engine tracks it per segment)."""
        plan = self.plan
        k = n // plan.P
        best = abs(self.x0[0])
        npc = len(plan.pieces)
        if k:
            S = plan.states_at_piece_starts(self.x0, k)            # (k, pieces, 3)
            best = max(best, float(np.abs(S[:, :, 0]).max()), abs(float(self.X[k][0])))
            for p, pc in enumerate(plan.pieces):
                a11, a12, u1 = pc[7]
                xs = S[:, p]
                xe = S[:, p + 1] if p + 1 < npc else self.X[1:k + 1, :3]
                ds = a11 * xs[:, 0] + a12 * xs[:, 1] + u1
                de = a11 * xe[:, 0] + a12 * xe[:, 1] + u1
                # a stationary point of i inside the piece: di/dt changes sign between its ends, or
                # (complex eigenvalues) the piece is long enough to hold two of them
                tr0 = self._form[p](tuple(float(v) for v in xs[0]))
                span = pc[0] * plan.inv
                two = tr0.cplx and abs(tr0.lam1.imag) * span >= math.pi
                for kk in (range(k) if two else np.nonzero(ds * de < 0.0)[0]):
                    tr = self._form[p](tuple(float(v) for v in xs[kk]))
                    for te in tr.x1_extrema(span):
                        best = max(best, abs(tr.eval(te)[0]))
        r = n - k * plan.P
        if r:   # the partial last period
            t = k * plan.P
            for p, pc in enumerate(plan.pieces):
                s = plan.starts[p]
                if s >= r:
                    break
                xs = self.at(t + s)
                tr = self._form[p](xs)
                span = min(pc[0], r - s) * plan.inv
                best = max(best, abs(xs[0]), abs(tr.eval(span)[0]))
                for te in tr.x1_extrema(span):
                    best = max(best, abs(tr.eval(te)[0]))
        return best


__all__ = ["ChunkTraj"]
