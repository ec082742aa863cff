"""Exact piecewise-linear plant segments and rigorous guard location on integer ticks.

Between two events a plant's inputs are constant, so its linear part is an affine ODE
``ẋ = A·x + u`` with constant ``A`` and ``u``. This module gives the closed-form solution of the
2-state case used by the DC motor (x = (i, ω), plus θ = ∫ω) and of its reduced forms:

- :func:`affine2`: full 2×2 system, eigen-decomposed (complex arithmetic when the eigenvalues
  are a conjugate pair);
- :func:`first_order_x1`: only x1 moves (motor stuck: ω ≡ 0, θ constant);
- :func:`first_order_x2`: only x2 and θ move (discontinuous conduction: i ≡ 0), including the
  singular case λ = 0 (no viscous friction: ω linear, θ quadratic);
- :func:`static`: nothing moves.

Every component of every trajectory has the form ``f(t) = a + b·t + c·t² + Σ d_k·e^{λ_k t}``
(evaluated as ``x0 + b·t + c·t² + Σ d_k·expm1(λ_k t)``)
with ``Re λ_k ≤ 0`` (t in seconds from the segment start), so on ``[0, ∞)`` its second
derivative is bounded by ``M2 = 2|c| + Σ |d_k λ_k²|`` (:attr:`Traj.m2`). A *guard* is a linear
function of the state, ``h(x) = ci·i + cw·ω + cθ·θ + c0`` (see :func:`hval`); its ``M2`` is
bounded by ``|ci|·M2_i + |cw|·M2_ω + |cθ|·M2_θ``. :func:`first_fire` uses that bound: if ``h``
is positive at both ends of an interval of length ``Δ`` and exceeds ``M2·Δ²/8`` there (the
linear-interpolation error bound), ``h`` has no root inside; otherwise the interval is halved,
down to single ticks. The answer is the *first* integer tick at which the guard has fired, with
no tolerance other than the float evaluation of the closed form itself.

Cost (pure Python, no numpy): building a segment is a few dozen float operations (the eigen
decomposition is cached by the caller per mode key); one evaluation is two ``math.expm1`` (or one
complex expm1 built from exp/sin/cos) plus ~15 multiply-adds; screening a segment whose guards are far from firing
costs one evaluation at the horizon and ~6 flops per guard. A guard that is close to firing
costs ~2·log2(horizon ticks) extra evaluations.
"""

from __future__ import annotations

import cmath
import math

__all__ = ["Traj", "affine2", "affine2_from", "affine2_system", "eig2", "first_fire", "first_order_x1", "first_order_x2", "hval", "static"]


class Traj:
    """Closed-form trajectory of (x1, x2, x3 = x3(0) + ∫x2) from a segment start.

    Component j is ``x0[j] + b[j]·t + c[j]·t² + Σ_k d[j][k]·(e^{lam[k]·t} − 1)`` (the same function
    as ``a + b·t + c·t² + Σ d·e^{λt}`` with ``a = x0 − Σ d``, written with ``expm1`` so that a far
    steady state or a slow eigenvalue costs no cancellation). In the complex case only one
    eigenvalue of the conjugate pair is stored and the sum is ``2·Re(d[j][0]·(e^{lam[0]·t} − 1))``.
    """

    __slots__ = ("_m2", "b", "c", "cplx", "d1", "d2", "kind", "lam1", "lam2", "lo", "x0")

    @property
    def m2(self):
        """Bounds of |x1''|, |x2''|, |x3''| over t ≥ 0 (per s²), for guard location; computed when
        first asked (a chunk's piece closed forms are only evaluated)."""
        m2 = self._m2
        if m2 is None:
            c0, c1, c2 = self.c
            if self.cplx:
                l2 = abs(self.lam1) ** 2
                e0, e1, e2 = self.d1
                m2 = (2.0 * abs(c0) + 2.0 * abs(e0) * l2, 2.0 * abs(c1) + 2.0 * abs(e1) * l2,
                      2.0 * abs(c2) + 2.0 * abs(e2) * l2)
            else:
                s1, s2 = self.lam1 * self.lam1, self.lam2 * self.lam2
                (e0, e1, e2), (f0, f1, f2) = self.d1, self.d2
                m2 = (2.0 * abs(c0) + abs(e0) * s1 + abs(f0) * s2, 2.0 * abs(c1) + abs(e1) * s1 + abs(f1) * s2,
                      2.0 * abs(c2) + abs(e2) * s1 + abs(f2) * s2)
            self._m2 = m2
        return m2

    def eval(self, t: float):
        """State (x1, x2, x3) at ``t`` seconds after the segment start (``t == 0`` gives x0 exactly)."""
        if t == 0:
            return self.x0
        x0, b, c = self.x0, self.b, self.c
        if self.cplx:
            lam = self.lam1
            re, im = lam.real * t, lam.imag * t
            sh = math.sin(0.5 * im)
            e = complex(math.expm1(re) * math.cos(im) - 2.0 * sh * sh, math.exp(re) * math.sin(im))
            d = self.d1
            return (x0[0] + (b[0] + c[0] * t) * t + 2.0 * (d[0] * e).real,
                    x0[1] + (b[1] + c[1] * t) * t + 2.0 * (d[1] * e).real,
                    x0[2] + ((b[2] + c[2] * t) * t + 2.0 * (d[2] * e).real + self.lo))
        e1 = math.expm1(self.lam1 * t)
        e2 = math.expm1(self.lam2 * t)
        d1, d2 = self.d1, self.d2
        return (x0[0] + (b[0] + c[0] * t) * t + d1[0] * e1 + d2[0] * e2,
                x0[1] + (b[1] + c[1] * t) * t + d1[1] * e1 + d2[1] * e2,
                x0[2] + ((b[2] + c[2] * t) * t + d1[2] * e1 + d2[2] * e2 + self.lo))

    def dtheta(self, t: float) -> float:
        """The angle turned since the segment start, before it is added to x3(0): the segment's
        contribution to an angle accumulated over many segments (``DcMotor._advance``). ``eval``
        gives x3(t) = x3(0) + (dtheta(t) + lo) in one rounding, ``lo`` (0 unless set) being what
        the accumulated angle holds beyond x3(0)."""
        if t == 0:
            return 0.0
        b, c = self.b, self.c
        if self.cplx:
            lam = self.lam1
            re, im = lam.real * t, lam.imag * t
            sh = math.sin(0.5 * im)
            e = complex(math.expm1(re) * math.cos(im) - 2.0 * sh * sh, math.exp(re) * math.sin(im))
            return (b[2] + c[2] * t) * t + 2.0 * (self.d1[2] * e).real
        return ((b[2] + c[2] * t) * t + self.d1[2] * math.expm1(self.lam1 * t)
                + self.d2[2] * math.expm1(self.lam2 * t))

    def x1_extrema(self, t_end: float):
        """Times in (0, t_end) of the stationary points of x1 that can hold its largest |x1| there.

        Real case: the one stationary point (:meth:`x1_extremum`). Complex case (``full`` kind, where
        x1 = x1(0) + 2·Re(d·(e^{λt} − 1))): the stationary points are t_k = (π/2 − arg(d·λ) + kπ)/Im λ;
        their swings about the steady value shrink as e^{Re λ·t}, alternating in sign, so the first
        two hold the largest |x1|."""
        if not self.cplx:
            t = self.x1_extremum(t_end)
            return () if t is None else (t,)
        if self.kind != "full":
            return ()
        lam = self.lam1
        z = self.d1[0] * lam
        beta = lam.imag
        if z == 0 or beta == 0.0:
            return ()
        phi = cmath.phase(z)
        k = math.floor((phi - 0.5 * math.pi) / math.pi) + 1
        out = []
        for kk in (k, k + 1):
            t = (0.5 * math.pi - phi + kk * math.pi) / beta
            if 0.0 < t < t_end:
                out.append(t)
        return tuple(out)

    def x1_extremum(self, t_end: float):
        """Time in (0, t_end) where x1 has a stationary point, for the real two-exponential case
        (x1 has at most one there); ``None`` otherwise. Used to catch current peaks inside a segment."""
        if self.cplx or self.kind != "full":
            return None
        p = self.d1[0] * self.lam1
        q = self.d2[0] * self.lam2
        if p == 0.0 or q == 0.0 or self.lam1 == self.lam2:
            return None
        r = -q / p  # p e^{l1 t} + q e^{l2 t} = 0  ->  e^{(l1-l2) t} = -q/p
        if r <= 0.0:
            return None
        t = math.log(r) / (self.lam1 - self.lam2)
        return t if 0.0 < t < t_end else None


def _make(kind, x0, b, c, lam1, lam2, d1, d2, cplx):
    tr = Traj()
    tr.kind, tr.x0, tr.b, tr.c = kind, tuple(x0), b, c
    tr.lam1, tr.lam2, tr.d1, tr.d2, tr.cplx = lam1, lam2, d1, d2, cplx
    tr._m2 = None
    tr.lo = 0.0
    return tr


_Z3 = (0.0, 0.0, 0.0)


def eig2(a11: float, a12: float, a21: float, a22: float):
    """Eigen-decomposition of a real 2×2 matrix with eigenvalues of negative real part.

    Returns ``(lam1, lam2, V, Vinv, cplx)``: eigenvalues, eigenvector matrix (rows) and its inverse
    as nested tuples. Cache the result per matrix: this is the expensive part of a mode change.
    A (numerically) repeated eigenvalue is split by a relative 1e-7 so the diagonal form stays
    usable (the trajectory error this causes is of that relative order, only at exact critical
    damping).
    """
    tr = a11 + a22
    det = a11 * a22 - a12 * a21
    disc = tr * tr - 4.0 * det
    scale = tr * tr if tr != 0.0 else abs(det) + 1.0
    if abs(disc) <= 1e-14 * scale:
        disc = 1e-14 * scale
    if disc > 0.0:
        s = math.sqrt(disc)
        l1 = 0.5 * (tr - s) if tr <= 0.0 else 0.5 * (tr + s)
        l2 = det / l1 if l1 != 0.0 else 0.5 * (tr + s)
        cplx = False
    else:
        s = math.sqrt(-disc)
        l1 = complex(0.5 * tr, 0.5 * s)
        l2 = l1.conjugate()
        cplx = True

    def vec(lam):
        # (A - lam I) v = 0: v = (a12, lam - a11) or (lam - a22, a21); take the better conditioned
        v1 = (a12, lam - a11)
        v2 = (lam - a22, a21)
        return v1 if abs(v1[0]) + abs(v1[1]) >= abs(v2[0]) + abs(v2[1]) else v2

    u1, u2 = vec(l1), vec(l2)
    V = ((u1[0], u2[0]), (u1[1], u2[1]))  # columns are eigenvectors
    dv = V[0][0] * V[1][1] - V[0][1] * V[1][0]
    Vinv = ((V[1][1] / dv, -V[0][1] / dv), (-V[1][0] / dv, V[0][0] / dv))
    return l1, l2, V, Vinv, cplx


def affine2(eig, A, u, x0):
    """Segment of ``ẋ = A x + u`` (x = (x1, x2)) plus ``x3 = x3(0) + ∫x2``, from ``x0``.

    ``eig`` is :func:`eig2` of ``A``; ``A = (a11, a12, a21, a22)``; ``u = (u1, u2)``.
    """
    return affine2_from(affine2_system(eig, A, u), x0)


def affine2_system(eig, A, u):
    """What :func:`affine2` computes from the system alone (the steady state ``-A⁻¹u`` and the
    eigen-decomposition): cached by a caller that starts many segments of one system."""
    a11, a12, a21, a22 = A
    u1, u2 = u
    det = a11 * a22 - a12 * a21
    # steady state x_ss = -A^{-1} u
    s1 = -(a22 * u1 - a12 * u2) / det
    s2 = -(-a21 * u1 + a11 * u2) / det
    return (s1, s2, (0.0, 0.0, s2)) + tuple(eig)


def affine2_from(system, x0):
    """:func:`affine2` from :func:`affine2_system`'s result."""
    s1, s2, b, l1, l2, V, Vi, cplx = system
    y1, y2 = x0[0] - s1, x0[1] - s2
    al1 = Vi[0][0] * y1 + Vi[0][1] * y2
    if cplx:
        d1 = (V[0][0] * al1, V[1][0] * al1, V[1][0] * al1 / l1)
        return _make("full", x0, b, _Z3, l1, l2, d1, _Z3, True)
    al2 = Vi[1][0] * y1 + Vi[1][1] * y2
    d1 = (V[0][0] * al1, V[1][0] * al1, V[1][0] * al1 / l1)
    d2 = (V[0][1] * al2, V[1][1] * al2, V[1][1] * al2 / l2)
    return _make("full", x0, b, _Z3, l1, l2, d1, d2, False)


def first_order_x1(lam: float, x1_ss: float, x0):
    """Only x1 moves: ``x1 = x1_ss + (x1(0) - x1_ss)·e^{lam t}`` (lam < 0); x2 is held and
    x3 = x3(0) + x2(0)·t (constant when x2 = 0)."""
    return _make("x1", x0, (0.0, 0.0, x0[1]), _Z3, lam, 0.0, (x0[0] - x1_ss, 0.0, 0.0), _Z3, False)


def first_order_x2(lam: float, k: float, x0):
    """Only x2 (and x3 = ∫x2) move, x1 held: ``ẋ2 = lam·x2 + k``.

    lam < 0: x2 = s + (x2(0) - s)·e^{lam t} with s = -k/lam; lam == 0: x2 = x2(0) + k·t.
    """
    if lam == 0.0:
        return _make("x2", x0, (0.0, k, x0[1]), (0.0, 0.0, 0.5 * k), 0.0, 0.0, _Z3, _Z3, False)
    s = -k / lam
    d = x0[1] - s
    return _make("x2", x0, (0.0, 0.0, s), _Z3, lam, 0.0, (0.0, d, d / lam), _Z3, False)


def static(x0):
    return _make("static", x0, _Z3, _Z3, 0.0, 0.0, _Z3, _Z3, False)


def hval(g, x) -> float:
    """Guard value ``ci·x1 + cw·x2 + cθ·x3 + c0`` for guard tuple ``g = (ci, cw, cθ, c0, strict, ...)``.

    Every decision made on a guard (locating it and re-testing it at a mode switch) goes through
    this one expression, so the two never disagree by a rounding error.
    """
    return g[0] * x[0] + g[1] * x[1] + g[2] * x[2] + g[3]


def fired(g, h: float) -> bool:
    """A guard fires when its value is < 0 (``strict``) or <= 0."""
    return h < 0.0 if g[4] else h <= 0.0


def guard_m2(g, m2) -> float:
    return abs(g[0]) * m2[0] + abs(g[1]) * m2[1] + abs(g[2]) * m2[2]


def first_fire_monotone(h_at, na: int, nb: int, ha: float, hb: float, strict: bool):
    """:func:`first_fire` for a guard known to be monotone on [na, nb] (its fired ticks are a
    suffix): the first fired tick in (na, nb], or None. Exact for the same reason as first_fire:
    the answer n is fired and n − 1 is not.

    Each step evaluates the secant point m and its neighbour towards the other side: a guard that
    is nearly linear over the interval (an encoder threshold within one PWM piece) is settled by
    two such steps at most, usually one. Every second unsettled step also halves the bracket, so
    a strongly bent guard costs at most ~6·log2(nb − na) evaluations."""
    if not (hb < 0.0 if strict else hb <= 0.0):
        return None
    lo, hi, hlo, hhi = na, nb, ha, hb
    second = True
    while hi - lo > 1:
        d = hlo - hhi
        m = lo + int((hi - lo) * (hlo / d)) if d > 0.0 else (lo + hi) >> 1
        if m <= lo or m >= hi:
            m = lo + 1 if m <= lo else hi - 1
        hm = h_at(m)
        if hm < 0.0 if strict else hm <= 0.0:
            hi, hhi = m, hm
            if m - 1 > lo:                       # fired at m: is m − 1 not?
                m -= 1
                hm = h_at(m)
                if hm < 0.0 if strict else hm <= 0.0:
                    hi, hhi = m, hm
                else:
                    return hi
        else:
            lo, hlo = m, hm
            if m + 1 < hi:                       # not fired at m: is m + 1?
                m += 1
                hm = h_at(m)
                if hm < 0.0 if strict else hm <= 0.0:
                    return m
                lo, hlo = m, hm
        second = not second
        if second and hi - lo > 4:               # the second unsettled step: halve the bracket too
            mb = (lo + hi) >> 1
            hmb = h_at(mb)
            if hmb < 0.0 if strict else hmb <= 0.0:
                hi, hhi = mb, hmb
            else:
                lo, hlo = mb, hmb
    return hi


def first_fire(h_at, m2: float, na: int, nb: int, ha: float, hb: float, strict: bool, inv_hz: float):
    """First integer tick n in (na, nb] where the guard has fired, or ``None``.

    ``h_at(n)`` evaluates the guard at tick offset n; ``ha``/``hb`` are its values at na/nb; the
    guard is taken as not fired at na. ``m2`` bounds |h''| (per s²); ``inv_hz`` is seconds per tick.
    """
    if nb - na == 1:
        return nb if (hb < 0.0 if strict else hb <= 0.0) else None
    dt = (nb - na) * inv_hz
    e = 0.125 * m2 * dt * dt
    # min of h on [na, nb] >= min(ha, hb) - e. A strict guard fires only below 0, so a guard
    # resting exactly on 0 (a shaft stuck on an encoder threshold, e = 0) is proven quiet at once.
    if (ha >= e and hb >= e) if strict else (ha > e and hb > e):
        return None
    nm = (na + nb) >> 1
    hm = h_at(nm)
    r = first_fire(h_at, m2, na, nm, ha, hm, strict, inv_hz)
    if r is not None:
        return r
    return first_fire(h_at, m2, nm, nb, hm, hb, strict, inv_hz)
