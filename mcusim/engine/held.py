"""Held chunks: a motor whose pieces are all stuck (static friction holds the shaft, only the
current moves), as while a position loop holds its set-point and moves the duty at every step.

* :func:`held_states`: the period-start states in closed form, ``i_k = i0 + (a^k − 1)(i0 − i*)``
  with ``a^k − 1 = expm1(k·log1p(a − 1))``, as rows computed when read (:class:`HeldRows`);
* :func:`stuck_ends`: the chunk's guards screened at its first and last period only.

:class:`~mcusim.engine.screening.PeriodPlan` uses both for its plans of stuck pieces.
"""

from __future__ import annotations

import math

import numpy as np

from . import periodmap


def held_states(plan, x0, n: int):
    """Rows (i, ω, θ, 1) after k = 0..n periods of a plan whose pieces are all stuck, from a shaft
    at rest: ω stays 0, θ stays, and the current closes in on its periodic value i* as
    ``i_k = i0 + (a^k − 1)·(i0 − i*)``, with ``a^k − 1 = expm1(k·log1p(a − 1))`` (the period map's
    delta entry, to full precision as the power table's delta form keeps it). Holding a position,
    every PID step builds such a plan: the power table's n products are not needed, and the rows
    are computed when read (:class:`HeldRows`)."""
    la, r = plan._held             # log1p(a − 1), b / (a − 1) = −i*
    return HeldRows(x0[0], x0[2], la, x0[0] + r, n)


def stuck_ends(plan, X, n: int, extra_guards, MARGIN: float):
    """A chunk whose pieces are all stuck, each guard either without a θ term or on θ alone:
    screened at its first and last period only, or None if a guard may fire there.

    Stuck (ω held at 0, θ held), the current is the only state that moves: in each piece one
    exponential towards the piece's steady value, so over a period ``i ← a·i + b`` with
    0 < a < 1. The current at the period starts is then monotone in k (it closes in on the
    fixed point geometrically), and so is the current at each piece start and end (affine in it
    with a positive factor), and every guard (affine in i, θ and ω constant) with it; inside a
    piece it is monotone in t. So a guard positive, beyond the largest rounding margin of the
    two periods, at both ends of every piece in the first and the last period is positive
    everywhere in between. The full screening tests such guards at the piece ends alone too
    (no Lipschitz term: monotone, or on θ alone, which ω = 0 holds), so it would find the same
    (k = n), and its bounds of |i| and |ω| are the two periods' too, to the last bit (|·| of a
    monotone sequence peaks at an end; the computed currents are monotone to rounding, and the
    bound gets a margin). Holding a position (static friction, the PID moving the duty every
    step) is all such chunks."""
    r = [X.row(q) for q in (0, 1, n - 1, n)] if type(X) is HeldRows else X[[0, 1, n - 1, n]].tolist()
    Ql = plan.Ql
    npc = len(plan.pieces)
    # per period (the first, the last): the states at the piece boundaries, from its start row
    # as x + Q[p]·(x, 1) (what ``ChunkTraj`` reads there), and the next period's start
    bounds = []
    for a, b in ((r[0], r[1]), (r[2], r[3])):
        x = (a[0], a[1], a[2])
        bounds.append([x] + [periodmap.apply_rows(Ql[p], x) for p in range(1, npc)] + [(b[0], b[1], b[2])])
    (P0, P1), ib, wb = bounds, 0.0, 0.0
    for p, pc in enumerate(plan.pieces):
        xs = (P0[p], P0[p + 1], P1[p], P1[p + 1])
        bi = max(abs(x[0]) for x in xs)
        bw = max(abs(x[1]) for x in xs)
        bt = max(abs(x[2]) for x in xs)
        ib, wb = max(ib, bi), max(wb, bw)
        for g in pc[4] + extra_guards:
            ci, cw, ct, c0 = g[0], g[1], g[2], g[3]
            scale = (bi * abs(ci) + bw * abs(cw) + bt * abs(ct) + abs(c0)) * MARGIN
            for x in xs:
                if not ci * x[0] + cw * x[1] + ct * x[2] + c0 > scale:
                    return None
    return n, head(X, n + 1), ib, (0.0, wb)


class HeldRows:
    """The period-start rows (i, ω, θ, 1), k = 0..n, of a chunk of stuck pieces from a shaft at
    rest (``PeriodPlan._held_states``): ``i_k = i0 + expm1(k·la)·d``, ω = 0, θ held. A row is
    computed when read (``row``, an integer index); any other index reads the whole array, built
    once from the same expression, so every reader sees the same values."""

    __slots__ = ("_a", "d", "i0", "la", "n", "th")

    def __init__(self, i0: float, th: float, la: float, d: float, n: int):
        self.i0, self.th, self.la, self.d, self.n = i0, th, la, d, n
        self._a = None

    def row(self, k: int):
        return [self.i0 + math.expm1(k * self.la) * self.d, 0.0, self.th, 1.0]

    def __len__(self) -> int:
        return self.n + 1

    def __array__(self, dtype=None, copy=None):
        a = self._a
        if a is None:
            a = self._a = np.array([self.row(k) for k in range(self.n + 1)])
        return a if dtype is None else a.astype(dtype)

    def __getitem__(self, key):
        if type(key) is int:
            if not -self.n - 1 <= key <= self.n:
                raise IndexError(key)
            return np.array(self.row(key % (self.n + 1)))
        return np.asarray(self)[key]

    def head(self, m: int):
        """The first m rows, as rows computed when read."""
        return self if m == self.n + 1 else HeldRows(self.i0, self.th, self.la, self.d, m - 1)


def head(X, m: int):
    """The first m rows of period-start states ``X`` (an array or :class:`HeldRows`)."""
    return X.head(m) if type(X) is HeldRows else X[:m]
