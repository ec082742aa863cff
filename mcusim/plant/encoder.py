"""Quadrature encoder disc on the motor shaft (the plant notes §3).

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

Fault injection (used by scenarios, :mod:`mcusim.scenario`): :meth:`QuadratureEncoder.glitch`
puts a noise spike on one output; :meth:`QuadratureEncoder.drop_edges` makes the next crossings
emit no edge (the decoder then lags the shaft by that many counts for good).
"""

from __future__ import annotations

import math

from ..engine import served
from ..errors import ConfigError
from ..kernel import PRIO_CPU, PRIO_PLANT
from ..signals import Net

_QUAD = ((0, 0), (1, 0), (1, 1), (0, 1))


class QuadratureEncoder:
    """``QuadratureEncoder(kernel, motor, a, b, counts_per_rev=64, name="encoder1")``.

    Drives ``a`` and ``b`` (Nets) with driver name ``name``. Attributes: ``position`` (k, absolute
    quarter-steps), ``count`` (quarter-steps since construction, signed), ``edges`` (edges emitted),
    ``counts_per_rev``, ``step`` (rad per count), ``dropped`` (edges suppressed by
    :meth:`drop_edges`).
    """

    # the guards depend on θ only and their handler changes no input of the motor: the fast engine
    # locates them inside a chunk of PWM periods without ending it
    passive_guards = True

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
        self.dropped = 0
        self._drop = 0                     # crossings still to suppress (drop_edges)
        self._slip = 0                     # outputs show the state of position - _slip
        self._serve_ticks = None           # fast engine: handler ticks of the last served route
        self._out()
        motor.add_guard_provider(self)

    @property
    def count(self) -> int:
        return self.position - self._k0

    def _out(self):
        qa, qb = _QUAD[(self.position - self._slip) & 3]
        self.a.set(self.name, qa)
        self.b.set(self.name, qb)

    def plant_guards(self):
        return self._guards_at(self.position)

    def _guards_at(self, k):
        st = self.step
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
            d = 1 if k > self.position else -1
            self.position += d
            if self._drop:              # injected fault: this crossing emits no edge
                self._drop -= 1
                self._slip += d
                self.dropped += 1
                continue
            self.edges += 1
            self._out()

    def serve_crossings(self, direction, locate) -> None:
        """Fast engine: :meth:`on_guard` for the crossing due now and the ones after it, as long as
        each one's edge is *served* (:mod:`mcusim.engine.served`): its interrupt handler applied
        in closed form and its CPU time charged at its ticks, with no event of its own.

        ``locate(guards, after)`` is the motor's search: (tick, guards firing there) of the first
        of ``guards`` to fire after tick ``after`` on its trajectory, or (None, []). A crossing
        whose edge cannot be served runs as :meth:`on_guard` runs it: here, at its own tick, if
        that is the next thing to happen; else the motor schedules it as usual."""
        kernel, a, b = self.kernel, self.a, self.b
        ra = rb = None
        # a handler takes at least the ticks it took last time: if even that return would not be
        # the next thing to happen (the rover's wheels alike: a twin's edge at the same tick), the
        # routes need not be looked up
        if not self._drop and (self._serve_ticks is None
                               or kernel.would_be_next(kernel.now + self._serve_ticks, PRIO_CPU)):
            ra, rb = served.route(a, kernel), served.route(b, kernel)
        if ra is None or rb is None:
            self.on_guard(direction)
            return
        self._serve_ticks = min(ra.ticks, rb.ticks)
        st, motor = self.step, self.motor
        la, lb = a.level, b.level
        d = direction
        n_served = 0
        run_here = True         # the crossing due now runs as on_guard runs it
        while True:
            th = motor.angle
            k = self.position + d
            if (th >= (k + 1) * st) if d > 0 else (th < k * st):
                break           # more than one threshold in this tick: on_guard's loop
            qa, qb = _QUAD[(k - self._slip) & 3]
            if (qa != la) == (qb != lb):
                break           # not exactly one output changes (after a glitch)
            route = ra if qa != la else rb
            ret = route.returns(kernel.now)
            if ret is None:
                break
            nxt, firing = locate(self._guards_at(k), kernel.now)
            if nxt is not None and nxt <= ret:
                break           # the next edge comes before this handler returns: timing interacts
            self.position = k
            self.edges += 1
            la, lb = qa, qb
            route.serve({a: qa, b: qb})
            kernel.now = ret
            n_served += 1
            if nxt is None or not kernel.would_be_next(nxt, PRIO_PLANT):
                run_here = False    # the motor schedules the next crossing (if any) as usual
                break
            kernel.now = nxt        # the next crossing's event would be the next one: it is here
            d = firing[0][6]
        if n_served:
            a.settle(self.name, la)
            b.settle(self.name, lb)
        if run_here:
            self.on_guard(d)

    # ---- fault injection ---------------------------------------------------------------------------
    def glitch(self, channel: str = "A", width: int = 1) -> None:
        """Injected noise spike: output ``channel`` ("A" or "B") shows the wrong level from now for
        ``width`` base ticks, then the true level again (an edge pair the decoder may or may not
        see, depending on its filter and on how fast it samples)."""
        if channel not in ("A", "B") or int(width) != width or width < 1:
            raise ConfigError(f"encoder {self.name}: glitch channel must be 'A' or 'B' and width "
                              f"a positive number of ticks, not {channel!r}, {width!r}")
        net = self.a if channel == "A" else self.b
        net.set(self.name, 1 - _QUAD[(self.position - self._slip) & 3][channel == "B"])
        self.kernel.after(int(width), self._out, prio=PRIO_PLANT)

    def drop_edges(self, n: int) -> None:
        """Injected fault: the next ``n`` threshold crossings emit no edge (a dirty or damaged
        disc). The outputs stay a valid quadrature sequence, so a decoder ends up ``n`` counts
        behind (in the direction of those crossings) for good. ``n = 0`` cancels what is left."""
        if int(n) != n or n < 0:
            raise ConfigError(f"encoder {self.name}: drop_edges({n!r}) needs a whole number >= 0")
        self._drop = int(n)

    def __repr__(self):
        return f"QuadratureEncoder({self.name}: position {self.position}, A={self.a.level} B={self.b.level})"
