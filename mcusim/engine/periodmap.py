"""Period maps: one PWM period of a DC motor as one affine map of its state, and its powers.

Within a piece of constant drive and constant mode the motor obeys ``ẋ = A·x + u`` with
x = (i, ω, θ) (:mod:`mcusim.plant.dcmotor`), so the state after τ seconds is an affine function of
the state at the piece start: ``x(τ) = Φ(τ)·x(0) + g(τ)`` (:func:`full_flow`, from the same
eigen-decomposition the closed-form segments use). The pieces of one period compose into one map
``x_{k+1} = M·x_k + c`` (:func:`compose`); N periods are its N-th power. :class:`LinearPowers`
holds ``M^k`` and ``M^0 + … + M^(k−1)`` for k = 0..N, built by doubling, and :class:`PowerTable`
the powers of the augmented map ``T = [[M, c], [0, 1]]`` from them and c, so the states at all N
period boundaries are one matrix product (:meth:`PowerTable.states`). Only c depends on the
inputs (supply voltage, load torque): maps that differ in them share their linear powers.

**Delta form.** Every map is held as ``D = T − I`` and applied as ``x + D·(x, 1)``. A PWM period
changes the state by a small fraction of itself (the mechanical mode decays by ~1e-4 per period):
written as a plain matrix, its entry ``e^{λτ} ≈ 1 − 1e-4`` keeps only ~12 significant digits of the
change, and that same rounding, repeated every period, drifts the state coherently (about 1e-12
relative over thousands of periods). In delta form the change itself is computed to full precision
(``expm1``), products compose as ``(I + B)(I + A) − I = A + B + B·A``, and what remains is the
rounding of one addition per state, as in the edge-by-edge engine's own closed-form steps. The two
engines then agree to ~1e-15 relative (of each piece's steady state, the scale the closed forms
round at), which matters beyond the 1e-9 plant tolerance: an encoder
threshold crossing that lies that close to a tick boundary can only land on different ticks if the
engines' states differ by more.
"""

from __future__ import annotations

import math

import numpy as np


def _expm1c(z: complex) -> complex:
    """e^z − 1 for complex z without cancellation when |z| is small."""
    re, im = z.real, z.imag
    sh = math.sin(0.5 * im)
    return complex(math.expm1(re) * math.cos(im) - 2.0 * sh * sh, math.exp(re) * math.sin(im))


def full_flow(eig, A, u, tau: float):
    """The delta map ``D = T − I`` (4×4 augmented, last column g) of ``ẏ = A·y + u`` (y = (i, ω))
    plus θ = ∫ω over tau s.

    ``eig`` is :func:`mcusim.plant.pwl.eig2` of ``A = (a11, a12, a21, a22)``; ``u = (u1, u2)``.
    """
    a11, a12, a21, a22 = A
    u1, u2 = u
    det = a11 * a22 - a12 * a21
    s1 = -(a22 * u1 - a12 * u2) / det
    s2 = -(-a21 * u1 + a11 * u2) / det
    l1, l2, V, Vi, cplx = eig
    if cplx:
        e1 = _expm1c(l1 * tau)
        e2 = e1.conjugate()
        f1 = e1 / l1
        f2 = f1.conjugate()
    else:
        e1, e2 = math.expm1(l1 * tau), math.expm1(l2 * tau)
        f1, f2 = e1 / l1, e2 / l2
    # E = V diag(e^{λτ} − 1) Vi = Φ − I, G = V[1,:] diag((e^{λτ} − 1)/λ) Vi
    E00 = V[0][0] * e1 * Vi[0][0] + V[0][1] * e2 * Vi[1][0]
    E01 = V[0][0] * e1 * Vi[0][1] + V[0][1] * e2 * Vi[1][1]
    E10 = V[1][0] * e1 * Vi[0][0] + V[1][1] * e2 * Vi[1][0]
    E11 = V[1][0] * e1 * Vi[0][1] + V[1][1] * e2 * Vi[1][1]
    G0 = V[1][0] * f1 * Vi[0][0] + V[1][1] * f2 * Vi[1][0]
    G1 = V[1][0] * f1 * Vi[0][1] + V[1][1] * f2 * Vi[1][1]
    if cplx:
        E00, E01, E10, E11, G0, G1 = (z.real for z in (E00, E01, E10, E11, G0, G1))
    # y(τ) = s + Φ(y0 − s): the constant part of Φ·y0 + g is −(Φ − I)·s
    g0 = -(E00 * s1 + E01 * s2)
    g1 = -(E10 * s1 + E11 * s2)
    g2 = s2 * tau - (G0 * s1 + G1 * s2)
    return np.array(((E00, E01, 0.0, g0), (E10, E11, 0.0, g1), (G0, G1, 0.0, g2), (0.0, 0.0, 0.0, 0.0)))


def stuck_flow(lam: float, i_ss: float, tau: float):
    """Delta map of: only i moves (``i' = lam·(i − i_ss)``); ω is held (0 when stuck) and
    θ += ω·tau."""
    e = math.expm1(lam * tau)
    return np.array(((e, 0.0, 0.0, -e * i_ss), (0.0, 0.0, 0.0, 0.0), (0.0, tau, 0.0, 0.0),
                     (0.0, 0.0, 0.0, 0.0)))


def then(a, b):
    """Delta map of ``a`` followed by ``b``: (I + b)(I + a) − I."""
    return a + b + b @ a


def compose(flows):
    """The delta map of the flows (delta maps) applied in order (the first one first)."""
    out = flows[0]
    for f in flows[1:]:
        out = then(out, f)
    return out


def apply(D, x):
    """``x`` (i, ω, θ) after the delta map ``D``, as floats."""
    return apply_rows(D.tolist(), x)


def apply_rows(M, x, lo: float = 0.0):
    """:func:`apply` with the map as nested lists (``D.tolist()``, kept by whoever applies it
    often). ``lo``: what the angle holds beyond ``x[2]`` (below its last place), added with the
    angle's change in one rounding."""
    a, b, c = x
    return (a + (M[0][0] * a + M[0][1] * b + M[0][2] * c + M[0][3]),
            b + (M[1][0] * a + M[1][1] * b + M[1][2] * c + M[1][3]),
            c + ((M[2][0] * a + M[2][1] * b + M[2][2] * c + M[2][3]) + lo))


class LinearPowers:
    """The powers of a period map's linear part, shared by every map that has it: with
    ``M = I + L`` (i, ω, θ), the table holds ``L_k = M^k − I`` and ``S_k = M^0 + … + M^(k−1)``
    for k = 0..n, as the top rows ``[L_k | S_k]`` (3×6) of ``Z^k − I`` for the block map
    ``Z = [[M, I], [0, I]]``. A map ``T = [[M, c], [0, 1]]`` then has ``T^k − I = [[L_k, S_k·c],
    [0, 0]]``: the states after k periods from x are ``x + L_k·x + S_k·c``, whatever c is. The
    period's constant part c moves with the inputs (a supply voltage, a load torque) while M
    does not: the rover's battery and body change them every millisecond, and the powers
    outlive them. Built by doubling, grown on demand, and only by whole doublings (so every entry
    is the same whether it was built at once or in steps)."""

    __slots__ = ("_flat", "n", "powers")

    def __init__(self, L):
        self.powers = np.zeros((2, 3, 6))
        self.powers[1, :, :3] = L
        self.powers[1, :, 3:] = np.eye(3)
        self.n = 1
        self._flat = self.powers.reshape(-1, 6)

    def ensure(self, n: int) -> None:
        """Make sure the powers 0 .. n are in the table."""
        m = self.n
        if n <= m:
            return
        size = m
        while size < n:
            size *= 2
        P = np.empty((size + 1, 3, 6))
        P[:m + 1] = self.powers
        while m < size:
            # Z^(m+j) = Z^j · Z^m for j = 1..m; in delta form, with the zero bottom rows left
            # out: D_(m+j) = D_j + D_m + D_j[:, :3] · D_m
            Dm = P[m]
            P[m + 1:2 * m + 1] = (P[1:m + 1, :, :3].reshape(-1, 3) @ Dm).reshape(-1, 3, 6) + P[1:m + 1] + Dm
            m *= 2
        self.n, self.powers = size, P
        self._flat = P.reshape(-1, 6)


class PowerTable:
    """Powers ``T^k`` (k = 0..n) of an augmented affine map ``T`` given in delta form ``D = T − I``:
    its linear part's :class:`LinearPowers` (``linear``, shared between maps that have the same
    one, or its own) and its constant column. A chunk that an input change cuts short never pays
    for powers it does not use."""

    __slots__ = ("c", "limit", "linear")

    def __init__(self, D, n: int, linear: LinearPowers | None = None):
        self.limit = n                 # the most powers anyone may ask for
        D = np.asarray(D)
        self.c = (float(D[0, 3]), float(D[1, 3]), float(D[2, 3]))
        self.linear = LinearPowers(D[:3, :3]) if linear is None else linear

    def states(self, x0, n: int | None = None):
        """The states after k = 0..n periods from ``x0`` (rows (i, ω, θ))."""
        return self.augmented_states(x0, self.limit if n is None else n)[:, :3]

    def augmented_states(self, x0, n: int):
        """Rows (i, ω, θ, 1) after k = 0..n periods."""
        lin = self.linear
        lin.ensure(n)
        c = self.c
        v = np.array((x0[0], x0[1], x0[2], c[0], c[1], c[2]))
        out = np.ones((n + 1, 4))
        out[:, :3] = (lin._flat[:3 * (n + 1)] @ v).reshape(n + 1, 3) + v[:3]
        return out

    def state(self, x0, k: int):
        """The state after k periods from ``x0``, as floats."""
        lin = self.linear
        lin.ensure(k)
        c = self.c
        v = np.array((x0[0], x0[1], x0[2], c[0], c[1], c[2]))
        return tuple(float(a) for a in lin.powers[k] @ v + v[:3])
