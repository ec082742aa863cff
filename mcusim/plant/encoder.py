"""Quadrature encoder disc on the motor shaft (reference/plants.md §3).

``counts_per_rev`` (C4) is the ×4 count per motor revolution (64 for the Pololu 37D: do not
multiply by 4 again). Threshold k sits at θ = k·2π/C4 on the motor shaft; the encoder position is
``k = floor(θ·C4/2π)`` and the outputs are the quadrature state of k mod 4:
(A, B) = (0,0), (1,0), (1,1), (0,1). θ increasing (positive voltage on OUT1/IN1) therefore gives
A leading B.

The two thresholds around the current position are guards of the motor's segment (the motor owns
the trajectory and the scheduling): crossing up fires at the first tick t with θ(t) ≥ (k+1)·2π/C4,
crossing down at the first tick with θ(t) < k·2π/C4. The edge is set on the nets at that tick,
during the motor's plant event (``PRIO_PLANT``). No per-edge error pattern δ_k, jitter or
hysteresis is modelled (the sheet's [I] options); edges are ideal.
"""

from __future__ import annotations

import math

from ..errors import ConfigError
from ..signals import Net

_QUAD = ((0, 0), (1, 0), (1, 1), (0, 1))


class QuadratureEncoder:
    """``QuadratureEncoder(kernel, motor, a, b, counts_per_rev=64, name="encoder1")``.

    Drives ``a`` and ``b`` (Nets) with driver name ``name``. Attributes: ``position`` (k, absolute
    quarter-steps), ``count`` (quarter-steps since construction, signed), ``edges`` (edges emitted),
    ``counts_per_rev``, ``step`` (rad per count).
    """

    def __init__(self, kernel, motor, a: Net, b: Net, counts_per_rev: int = 64, name: str = "encoder1"):
        if int(counts_per_rev) != counts_per_rev or counts_per_rev <= 0:
            raise ConfigError(f"encoder {name}: counts_per_rev = {counts_per_rev!r} must be a positive integer")
        self.kernel, self.motor, self.name = kernel, motor, name
        self.a, self.b = a, b
        self.counts_per_rev = int(counts_per_rev)
        self.step = 2.0 * math.pi / self.counts_per_rev
        th = motor.angle
        k = math.floor(th / self.step)
        while th < k * self.step:          # make floor() agree with the guard expressions
            k -= 1
        while th >= (k + 1) * self.step:
            k += 1
        self.position = k
        self._k0 = self.position
        self.edges = 0
        self._out()
        motor.add_guard_provider(self)

    @property
    def count(self) -> int:
        return self.position - self._k0

    def _out(self):
        qa, qb = _QUAD[self.position & 3]
        self.a.set(self.name, qa)
        self.b.set(self.name, qb)

    def plant_guards(self):
        k, st = self.position, self.step
        return ((0.0, 0.0, -1.0, (k + 1) * st, False, self, 1),   # θ ≥ (k+1)·step
                (0.0, 0.0, 1.0, -(k * st), True, self, -1))       # θ < k·step

    def on_guard(self, direction):
        th = self.motor.angle
        st = self.step
        k = self.position
        if direction > 0:
            k += 1
            while th >= (k + 1) * st:   # more than one threshold in one tick (only at absurd speeds)
                k += 1
        else:
            k -= 1
            while th < k * st:
                k -= 1
        while self.position != k:       # one quadrature step (one edge) at a time
            self.position += 1 if k > self.position else -1
            self.edges += 1
            self._out()

    def __repr__(self):
        return f"QuadratureEncoder({self.name}: position {self.position}, A={self.a.level} B={self.b.level})"
