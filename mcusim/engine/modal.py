"""Modal screening of a moving chunk: every guard cleared over N periods by a few numbers.

Over one PWM period the motor's current and speed obey ``y_{k+1} = M·y_k + c`` (the (i, ω) block of
the period map, :mod:`mcusim.engine.periodmap`; θ never feeds back). With M's eigenvalues μ1, μ2 and
fixed point y*, the state at the start of period k is ``y* + Σ_j v_j·α_j·μ_j^k`` (α = V⁻¹(y0 − y*)),
and so is the state at every piece boundary inside the period (an affine map of y_k), and every
guard value there (a guard of the motor or the bridge is affine in (i, ω)). A function
``a + c1·μ1^k + c2·μ2^k`` with real 0 < μ < 1 has at most one stationary point in k, so its range
over 0 ≤ k ≤ N − 1 lies between its values at the two ends and there (:func:`span`); with complex
eigenvalues (``a + 2·Re(c·μ^k)``, |μ| < 1) between ``a ± 2|c|``.

:func:`screen` uses these ranges for the test the full screening (:meth:`PeriodPlan.first_flag`)
makes period by period, taken at its worst over all N periods at once: each guard's least value at
a piece's start and end above the largest rounding margin, and their least sum above the largest
Lipschitz term (from the largest |i|, |ω| at a piece start, through the same bounds
``x̄ = W·|x| + w`` and ``|ẋ| ≤ |A|·x̄ + |u|``). What passes this passes every period of the full
test (the margins grow with |x|, and the bounds are monotone in it), so the chunk is clean for all
N periods; what does not is left to the full screening. The returned bounds of |i| and |ω| are
those worst-case values (an upper bound of the full screening's, a lower one for |ω|'s least).
Moving chunks only (no stuck piece: a held shaft has its own shortcut), and only guards without a θ
term (the encoders' are located, not screened).
"""

from __future__ import annotations

import cmath
import math

#: relative slack for the rounding of the modal form against the power table's states (~1e-15)
SLACK = 1e-12


class Modes:
    """The modal form of one plan: fixed point, eigenvalues and vectors of its period map, and per
    piece boundary the affine map from the period-start (i, ω) to the (i, ω) there."""

    __slots__ = ("V", "Vi", "bounds", "cplx", "lg", "mu", "ystar")

    def __init__(self, Ql, like: Modes | None = None):
        """From the plan's piece-start maps ``Ql`` (delta form, as lists). ``like``: the modes of
        a plan with the same linear part (the (i, ω) block of its period map), whose eigenvalues
        and vectors are taken as they are: only the fixed point and the boundary maps move with
        the inputs. Raises ValueError where the period map has no usable modal form."""
        T = Ql[-1]
        t00, t01, t10, t11 = T[0][0], T[0][1], T[1][0], T[1][1]
        det = t00 * t11 - t01 * t10
        if det == 0.0:
            raise ValueError("singular period map")
        c0, c1 = T[0][3], T[1][3]
        # fixed point: (M − I)·y* = −c, M − I = the delta block
        self.ystar = ((-c0 * t11 + c1 * t01) / det, (-t00 * c1 + t10 * c0) / det)
        # boundary b (piece b's start; b = len(pieces): the next period's): y_b = A_b·y + b_b
        self.bounds = [((1.0 + q[0][0], q[0][1], q[1][0], 1.0 + q[1][1]), (q[0][3], q[1][3])) for q in Ql]
        if like is not None:
            self.V, self.Vi, self.cplx, self.mu, self.lg = like.V, like.Vi, like.cplx, like.mu, like.lg
            return
        tr = t00 + t11
        disc = tr * tr - 4.0 * det
        if disc > 0.0:
            s = math.sqrt(disc)
            d1 = 0.5 * (tr - s) if tr <= 0.0 else 0.5 * (tr + s)
            d2 = det / d1
            self.cplx = False
        else:
            d1 = complex(0.5 * tr, 0.5 * math.sqrt(-disc))
            d2 = d1.conjugate()
            self.cplx = True

        if abs(d1 - d2) <= 1e-6 * (abs(d1) + abs(d2)):
            # nearly repeated eigenvalues: the eigenvectors are set by a difference that keeps few
            # digits, and the modal terms grow huge and opposite
            raise ValueError("nearly defective period map")

        def vec(d):
            v1, v2 = (t01, d - t00), (d - t11, t10)
            return v1 if abs(v1[0]) + abs(v1[1]) >= abs(v2[0]) + abs(v2[1]) else v2
        u1, u2 = vec(d1), vec(d2)
        dv = u1[0] * u2[1] - u2[0] * u1[1]
        if dv == 0:
            raise ValueError("defective period map")
        self.V = ((u1[0], u2[0]), (u1[1], u2[1]))
        self.Vi = ((u2[1] / dv, -u2[0] / dv), (-u1[1] / dv, u1[0] / dv))
        # nearly defective (two close eigenvalues): the modal terms grow huge and opposite, and
        # their rounding spoils the form; leave such maps to the full screening
        cond = (sum(abs(v) for r in self.V for v in r)) * (sum(abs(v) for r in self.Vi for v in r))
        if not cond < 1e6:
            raise ValueError("ill-conditioned period map")
        mu = (1.0 + d1, 1.0 + d2)
        self.mu = mu
        if self.cplx:
            self.lg = (cmath.log(mu[0]), cmath.log(mu[1]))
        else:
            if not (0.0 < mu[0] < 1.0 and 0.0 < mu[1] < 1.0):
                raise ValueError("period map not a real contraction")
            self.lg = (math.log1p(d1), math.log1p(d2))
        if self.cplx and abs(mu[0]) >= 1.0:
            raise ValueError("period map not a contraction")


def span(f, lg, en, last: float, cplx: bool):
    """(least, largest) of ``f = (a, c1, c2)``, i.e. ``a + c1·μ1^k + c2·μ2^k``, over real k in
    [0, last], with ``en = (μ1^last, μ2^last)`` and ``lg = (ln μ1, ln μ2)``, widened by the
    rounding slack. With complex eigenvalues (c2 = conj(c1), the sum real) ``a ± 2|c1|``."""
    a, c1, c2 = f
    s = SLACK * (abs(a) + abs(c1) + abs(c2))
    if cplx:
        r = 2.0 * abs(c1) + s
        return a - r, a + r
    f0 = a + c1 + c2
    fn = a + c1 * en[0] + c2 * en[1]
    lo, hi = (f0, fn) if f0 <= fn else (fn, f0)
    den = c1 * lg[0]
    if den and c2 and lg[0] != lg[1]:
        r = -(c2 * lg[1]) / den
        if r > 0.0:
            k = math.log(r) / (lg[0] - lg[1])
            if 0.0 < k < last:
                fk = a + c1 * math.exp(k * lg[0]) + c2 * math.exp(k * lg[1])
                lo, hi = min(lo, fk), max(hi, fk)
    return lo - s, hi + s


def _least(gi, gw, g0, ri, rw):
    """The least of ``gi·i + gw·ω + g0`` over i in ``ri``, ω in ``rw`` (exact where the guard
    has one of the two terms, as the motor's and the bridges' guards have)."""
    return (gi * (ri[0] if gi >= 0.0 else ri[1]) + gw * (rw[0] if gw >= 0.0 else rw[1])) + g0


def screen(plan, modes: Modes, x0, xn, n: int, guards_of, MARGIN: float):
    """(ib, (wlo, whi)) if no guard can fire in the first n periods from ``x0`` by the modal test
    (module docstring), else None. ``guards_of(p)``: the guards of piece p (none with a θ term);
    ``xn``: the state after n periods from the power table, against which the modal form is
    checked at both ends of the chunk."""
    ys = modes.ystar
    y0, y1 = x0[0] - ys[0], x0[1] - ys[1]
    Vi, V, lg, cplx = modes.Vi, modes.V, modes.lg, modes.cplx
    al1 = Vi[0][0] * y0 + Vi[0][1] * y1
    al2 = Vi[1][0] * y0 + Vi[1][1] * y1
    last = n - 1
    if cplx:
        en = None
    else:
        en = (math.exp(last * lg[0]), math.exp(last * lg[1]))
    # (i, ω) at boundary b as (a, c1, c2) per component, c_j = (A_b·v_j)·α_j
    v00, v01, v10, v11 = V[0][0], V[0][1], V[1][0], V[1][1]
    forms = []
    for (m00, m01, m10, m11), (b0, b1) in modes.bounds:
        forms.append(((m00 * ys[0] + m01 * ys[1] + b0, (m00 * v00 + m01 * v10) * al1, (m00 * v01 + m01 * v11) * al2),
                      (m10 * ys[0] + m11 * ys[1] + b1, (m10 * v00 + m11 * v10) * al1, (m10 * v01 + m11 * v11) * al2)))
    # the modal form at k = 0 must give the start state itself: else the decomposition is too
    # ill-conditioned to bound anything
    fi, fw = forms[0]
    err = abs((fi[0] + fi[1] + fi[2]) - x0[0]) + abs((fw[0] + fw[1] + fw[2]) - x0[1])
    size = abs(fi[0]) + abs(fi[1]) + abs(fi[2]) + abs(fw[0]) + abs(fw[1]) + abs(fw[2])
    if not err <= 1e-13 * size:
        return None
    # and after n periods: a nearly defective map (two close eigenvalues, huge opposite modal
    # terms) passes the first check while its μ^k go wrong further on
    if cplx:
        e1 = cmath.exp(n * lg[0])
        e2 = e1.conjugate()
    else:
        e1, e2 = math.exp(n * lg[0]), math.exp(n * lg[1])
    err = (abs((fi[0] + fi[1] * e1 + fi[2] * e2) - xn[0]) + abs((fw[0] + fw[1] * e1 + fw[2] * e2) - xn[1]))
    if not err <= 1e-13 * size + 1e-12 * (abs(xn[0]) + abs(xn[1])):
        return None
    Wt_, w_, taus_, At_, us_ = plan._bound_rows
    ib = whi = 0.0
    wlo = math.inf
    ranges = [(span(f[0], lg, en, last, cplx), span(f[1], lg, en, last, cplx)) for f in forms]
    for p in range(len(plan.pieces)):
        (ri, rw), (ei, ew) = ranges[p], ranges[p + 1]
        (si, sw), (fi, fw) = forms[p], forms[p + 1]
        # the sum of a guard's values at the piece's two ends, per component
        ti = span((si[0] + fi[0], si[1] + fi[1], si[2] + fi[2]), lg, en, last, cplx)
        tw = span((sw[0] + fw[0], sw[1] + fw[1], sw[2] + fw[2]), lg, en, last, cplx)
        Bi, Bw = max(-ri[0], ri[1]), max(-rw[0], rw[1])     # largest |i|, |ω| at the piece's start
        (W00, W10), (W01, W11) = Wt_[p]
        wi, ww = w_[p][0]
        xi = W00 * Bi + W01 * Bw + wi
        xw = W10 * Bi + W11 * Bw + ww
        (a00, a10), (a01, a11) = At_[p]
        ui, uw = us_[p][0]
        Di = xi * a00 + xw * a01 + ui
        Dw = xi * a10 + xw * a11 + uw
        tau = taus_[p][0][0]
        for g in guards_of(p):
            gi, gw, g0 = g[0], g[1], g[3]
            scale = (Bi * abs(gi) + Bw * abs(gw) + abs(g0)) * MARGIN
            if not (_least(gi, gw, g0, ri, rw) > scale and _least(gi, gw, g0, ei, ew) > scale
                    and _least(gi, gw, 2.0 * g0, ti, tw) > tau * (Di * abs(gi) + Dw * abs(gw)) + 2.0 * scale):
                return None
        ib, whi = max(ib, xi), max(whi, xw)
        least = 0.0 if rw[0] <= 0.0 <= rw[1] else min(abs(rw[0]), abs(rw[1]))
        wlo = min(wlo, least - tau * Dw)
    return ib, (max(wlo, 0.0), whi)
