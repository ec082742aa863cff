"""Quadrature encoder disc on the motor shaft (docs/plants.md §3).

``counts_per_rev`` (C4) is the ×4 count per motor revolution (64 for the Pololu 37D: do not
multiply by 4 again). Threshold k sits at θ = k·2π/C4 on the motor shaft; the encoder position is
``k = floor(θ·C4/2π)`` and the outputs are the quadrature state of k mod 4:
(A, B) = (0,0), (1,0), (1,1), (0,1). θ increasing (positive voltage on OUT1/IN1) therefore gives
A leading B.

The two thresholds around the current position are guards of the motor's segment (the motor owns
the trajectory and the scheduling): crossing up fires at the first tick t with θ(t) ≥ (k+1)·2π/C4,
crossing down at the first tick with θ(t) < k·2π/C4. The edge is set on the nets at that tick,
during the motor's plant event (``PRIO_PLANT``). No per-edge error pattern δ_k, jitter or
hysteresis is modelled (the [I] options of docs/plants.md §3.1); edges are ideal.

Lazy counting (fast engine): where the decoder reading the outputs can compute its count from the
shaft angle (an STM32 timer in encoder mode, ``lazy_enter`` in :mod:`mcusim.periph.stm32.tim_lazy`)
and nobody else needs the edges, the outputs become :class:`ShaftCode` descriptors: their level at
any tick is the quadrature state of ``k(θ(t))``, and no threshold crossing is located or scheduled.
The stretch holds while θ is monotone and no two crossings come closer than the decoder's input
delay (two guards of the motor end it: ω reaching zero, |ω| reaching that speed limit) and ends at
a threshold the decoder names (the crossing before its counter wraps), at a state jump, a fault
injection, a listener that needs edges, or a register write the decoder cannot follow.
:meth:`QuadratureEncoder.materialize` turns the outputs back into levels.

Fault injection (used by scenarios, :mod:`mcusim.scenario`): :meth:`QuadratureEncoder.glitch`
puts a noise spike on one output; :meth:`QuadratureEncoder.drop_edges` makes the next crossings
emit no edge (the decoder then lags the shaft by that many counts for good).
"""

from __future__ import annotations

import math

from ..engine import served
from ..engine.ticks import tick_run
from ..errors import ConfigError
from ..kernel import PRIO_PLANT
from ..signals import Net
from .encoder_served import Crossings

_QUAD = ((0, 0), (1, 0), (1, 1), (0, 1))


class ShaftCode:
    """One encoder output as a level descriptor (lazy counting, module docstring): the level at any
    tick from the shaft angle there. Carried by nets like a waveform, but never expanded into edges
    (``release`` turns the outputs back into levels when a reader needs them)."""

    __slots__ = ("ch", "enc", "end", "kernel")

    def __init__(self, enc, ch: int):
        self.enc, self.ch, self.kernel, self.end = enc, ch, enc.kernel, None

    def level_at(self, t: int) -> int:
        enc = self.enc
        return enc.levels(enc.k_now() if t == self.kernel.now else enc.k_at(t))[self.ch]

    settled_level = level_at

    @property
    def level(self) -> int:
        return self.level_at(self.kernel.now)

    def release(self) -> None:
        self.enc.materialize()

    def same_shape(self, other) -> bool:
        return False

    def __repr__(self):
        return f"ShaftCode({self.enc.name}.{'AB'[self.ch]})"


class _Lazy:
    """A lazy-counting stretch: the direction θ moves in, the position and edge count at its start,
    the threshold crossing that ends it and the speed limit."""

    __slots__ = ("d", "edges0", "exit_guard", "k0", "w_lim")

    def __init__(self, d, k0, edges0, exit_guard, w_lim):
        self.d, self.k0, self.edges0, self.exit_guard, self.w_lim = d, k0, edges0, exit_guard, w_lim


class _Window:
    """The motor guards that bound a lazy stretch: ω reaching zero (θ would stop being monotone) and
    |ω| reaching the decoder's speed limit (crossings closer than its input delay). Registered
    before the encoder, so the motor asks it first at each rebuild: that is where a stretch starts."""

    __slots__ = ("enc",)

    def __init__(self, enc):
        self.enc = enc

    def plant_guards(self):
        enc = self.enc
        if enc._lazy is None:
            enc._try_lazy()
        lz = enc._lazy
        if lz is None:
            return ()
        d = float(lz.d)
        return ((0.0, d, 0.0, 0.0, False, self, "turn"), (0.0, -d, 0.0, lz.w_lim, False, self, "fast"))

    def on_guard(self, tag):
        self.enc.materialize()

    def before_jump(self):
        self.enc.materialize()


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
        if counts_per_rev % 4:
            # the ×4 count of a disc of n lines is 4·n (four edges per cycle of A and B); any other
            # count is no quadrature disc: the A/B state would not repeat after one revolution
            raise ConfigError(f"encoder {name}: counts_per_rev = {counts_per_rev!r} is not a multiple of 4 "
                              f"(the ×4 count: 4 per cycle of A and B, e.g. {4 * max(1, round(counts_per_rev / 4))})")
        self.kernel, self.motor, self.name = kernel, motor, name
        self.a, self.b = a, b
        self.counts_per_rev = int(counts_per_rev)
        self.step = 2.0 * math.pi / self.counts_per_rev
        k = self._k_of(motor.angle)
        self._pos = k
        self._k0 = k
        self._edges = 0
        self.dropped = 0
        self._drop = 0                     # crossings still to suppress (drop_edges)
        self._slip = 0                     # outputs show the state of position - _slip
        self._serve_hint = None            # fast engine: (cpu, vectors) of the last routes
        self._lazy = None                  # fast engine: the lazy-counting stretch (_Lazy) or None
        self._due_ev = None                # fast engine: a crossing due now left by a stretch ended early
        self.lazy_stretches = 0            # fast engine: stretches counted lazily so far
        self.counted_edges = 0             # fast engine: served edges a counted run served (served._count)
        self._retry = None                 # after a stretch: the gap of its decoder (retry after an edge)
        self._retry_ev = None
        self._glitch_ev = None
        self._glitched = None              # the channel ("A"/"B") a glitch shows wrong, while it lasts
        self._out()
        if getattr(kernel, "fast", False):
            motor.add_guard_provider(_Window(self))
        motor.add_guard_provider(self)

    @property
    def position(self) -> int:
        """k, the absolute quarter-step position (computed from the shaft angle while lazy)."""
        return self._pos if self._lazy is None else self.k_now()

    @position.setter
    def position(self, k: int) -> None:
        self._pos = k

    @property
    def edges(self) -> int:
        """Edges emitted so far (a lazy stretch emits one per threshold: θ is monotone there)."""
        lz = self._lazy
        return self._edges if lz is None else lz.edges0 + abs(self.k_now() - lz.k0)

    @edges.setter
    def edges(self, n: int) -> None:
        self._edges = n

    def levels(self, k: int):
        """(A, B) at position ``k``."""
        return _QUAD[(k - self._slip) & 3]

    def k_at(self, t: int) -> int:
        """The position at tick ``t`` (≤ now) from the shaft angle."""
        return self._k_of(self.motor.state_at(t)[2])

    def k_now(self) -> int:
        """The position the edge-by-edge encoder shows now (lazy counting). A crossing due at this
        very tick is its plant event (PRIO_PLANT there): an event earlier in the tick (hardware, a
        scenario's fault or input) still sees the position before it."""
        now = self.kernel.now
        if now and self.kernel.early_in_tick(PRIO_PLANT) and self.motor._t0 != now:
            return self.k_at(now - 1)       # (a motor advanced to now has fired it, as edge by edge)
        return self.k_at(now)

    def _k_of(self, th: float) -> int:
        """The position at angle ``th`` by the guards' own comparisons (θ ≥ (k+1)·step crosses up,
        θ < k·step crosses down), which floor() alone may round differently."""
        st = self.step
        k = math.floor(th / st)
        while th < k * st:
            k -= 1
        while th >= (k + 1) * st:
            k += 1
        return k

    # ---- lazy counting (fast engine) -------------------------------------------------------------
    def _try_lazy(self) -> None:
        """Start a lazy stretch now if the outputs' only reader is one decoder that takes it."""
        if self._drop or self._glitch_ev is not None:
            return
        w = self.motor.speed            # a shaft at rest (holding a position) first: no stretch
        if w == 0.0 or self.k_at(self.kernel.now) != self._pos:
            return
        da, db = ShaftCode(self, 0), ShaftCode(self, 1)
        sa = self.a.wave_sinks(da)      # an interrupt pin (an AVR's INTn) says no at once
        if not sa or len(sa) != 1:
            return
        sb = self.b.wave_sinks(db)
        if not sb or len(sb) != 1 or sa[0][0] is not sb[0][0]:
            return
        sink = sa[0][0]
        d = 1 if w > 0 else -1
        got = sink.lazy_enter(self, {sa[0][1]: 0, sb[0][1]: 1}, d, self._pos)
        if got is None:
            return
        k_exit, gap = got
        # crossings at least `gap` ticks apart: |ω|·(gap + 1) ticks < one step, with a factor 2
        w_lim = 0.5 * self.step * self.kernel.timebase.base_hz / (gap + 1)
        if abs(w) >= 0.5 * w_lim:
            sink.lazy_cancel()
            return
        self.motor.need_history(gap)
        self._retry = (gap, sink, w_lim)
        self._lazy = _Lazy(d, self._pos, self._edges, self._exit_guard(k_exit, d), w_lim)
        self.lazy_stretches += 1
        self.a.set_wave(self.name, da)
        self.b.set_wave(self.name, db)

    def _retry_lazy(self) -> None:
        self._retry_ev = None
        w = abs(self.motor.speed)
        if self._lazy is not None or w == 0.0 or w >= 0.5 * self._retry[2]:
            return      # (too fast for a stretch: the next edge asks again, without a rebuild)
        if not self._retry[1].lazy_possible():
            self._retry = None      # the decoder's configuration says no: the next rebuild asks again
            return
        self.motor.input_changed()  # a rebuild asks the window (_Window.plant_guards) first

    def _exit_guard(self, k_exit: int, d: int):
        """The passive guard of the crossing into ``k_exit`` moving in direction ``d``."""
        st = self.step
        if d > 0:
            return (0.0, 0.0, -1.0, k_exit * st, False, self, "exit")       # θ ≥ k_exit·step
        return (0.0, 0.0, 1.0, -((k_exit + 1) * st), True, self, "exit")   # θ < (k_exit+1)·step

    def set_exit(self, k_exit: int) -> None:
        """The decoder's stretch now ends at the crossing into ``k_exit`` (a counter write)."""
        lz = self._lazy
        if lz is not None:
            lz.exit_guard = self._exit_guard(k_exit, lz.d)
            self.motor.passive_changed()

    def materialize(self) -> None:
        """End a lazy stretch at now: the outputs are levels again and every crossing is an edge."""
        lz = self._lazy
        if lz is None:
            return
        now = self.kernel.now
        k = self.k_now()
        self._edges = lz.edges0 + abs(k - lz.k0)
        self._pos = k
        self._lazy = None
        self._out()         # the decoder, told its descriptors end, rebuilds what is in flight
        self.motor.passive_changed()
        if k != self.k_at(now):
            # a crossing due at this tick that an earlier event of the tick ended the stretch
            # before: it comes at the plant's priority, as the edge-by-edge encoder's event does,
            # or when the motor is advanced to now before that (fire_due)
            self._due_ev = self.kernel.at(now, self._due_crossing, prio=PRIO_PLANT)
            self.motor._due.append(self)

    def fire_due(self) -> None:
        """The motor is advanced to now: a crossing due now that a lazy stretch left behind fires
        here, as the edge-by-edge motor's advance fires a guard due at its tick."""
        ev = self._due_ev
        if ev is not None and not ev.cancelled and ev.time == self.kernel.now:
            ev.cancel()
            self._due_crossing()

    def _due_crossing(self) -> None:
        self._due_ev = None
        k = self.k_at(self.kernel.now)
        if k != self._pos and self._lazy is None:
            self.on_guard(1 if k > self._pos else -1)
            self.motor.passive_changed()

    @property
    def count(self) -> int:
        return self.position - self._k0

    def _out(self):
        qa, qb = _QUAD[(self.position - self._slip) & 3]
        g = self._glitched
        if g is not None:                   # a glitch: its channel shows the wrong level until it ends
            if g == "A":
                qa = 1 - qa
            else:
                qb = 1 - qb
        self.a.set(self.name, qa)
        self.b.set(self.name, qb)

    def plant_guards(self):
        lz = self._lazy
        if lz is not None:
            return (lz.exit_guard,)
        return self._guards_at(self._pos)

    def _guards_at(self, k):
        st = self.step
        return ((0.0, 0.0, -1.0, (k + 1) * st, False, self, 1),   # θ ≥ (k+1)·step
                (0.0, 0.0, 1.0, -(k * st), True, self, -1))       # θ < k·step

    def on_guard(self, direction):
        if direction == "exit":
            self.materialize()      # the crossing before the decoder's wrap: edge by edge from here
            return
        if (self._retry is not None and self._retry_ev is None
                and abs(self.motor.speed) < 0.5 * self._retry[2]):
            # counting edge by edge after a stretch: try another once this edge has reached the
            # decoder (a stretch starts at a rebuild of the motor, with nothing in flight)
            self._retry_ev = self.kernel.after(self._retry[0] + 1, self._retry_lazy, prio=PRIO_PLANT)
        th = self.motor.angle
        st = self.step
        k = self._pos
        if direction > 0:
            k += 1
            while th >= (k + 1) * st:   # more than one threshold in one tick (only at absurd speeds)
                k += 1
        else:
            k -= 1
            while th < k * st:
                k -= 1
        while self._pos != k:       # one quadrature step (one edge) at a time
            d = 1 if k > self._pos else -1
            self._pos += d
            if self._drop:              # injected fault: this crossing emits no edge
                self._drop -= 1
                self._slip += d
                self.dropped += 1
                continue
            self._edges += 1
            self._out()

    def crossing_stream(self, direction, tick, locate, state_at, on_finish, first=False, span=None):
        """Fast engine: the crossing due at ``tick`` and the ones after it as a stream of served
        edges (:func:`mcusim.engine.served.serve_run`), or None if its edges cannot be served now.

        ``locate(guards, after)`` is the motor's search: (tick, guards firing there) of the first
        of ``guards`` to fire after tick ``after`` on its trajectory, or (None, []);
        ``state_at(tick)`` its state there. ``on_finish(nxt)`` runs after the stream has committed
        crossings, with the next one located ((tick, direction, guards) or None), for the motor to
        schedule. ``first``: the crossing is the event running now. ``span()``: (end tick, wlo,
        whi) of the motor's trajectory if it is a chunk with wlo ≤ |ω| ≤ whi, else None (a counted
        run needs it)."""
        if self._drop or self._glitched is not None:
            return None             # (a glitch: the outputs are not the position's; edge by edge)
        kernel = self.kernel
        hint = self._serve_hint
        if first and hint is not None:
            # the crossing due now: its handler takes at least entry latency + the cheaper of the
            # two handlers as bound now; if an event of no motor comes before that return (a
            # motor's may be a crossing to absorb, a busy task's end is moved by the handler),
            # the route lookups would be in vain (a timer overflow a run may serve is passed over:
            # this handler may delay it, and so is an inert event: served.inert_until)
            cpu, va, vb = hint
            ha, hb = cpu.vectors.get(va), cpu.vectors.get(vb)
            if ha is not None and hb is not None:
                head = kernel.first_queued()
                ticks = (cpu.entry_latency + min(ha[1], hb[1])) * cpu.clock.period
                if (head is not None and head[0] < tick + ticks
                        and not hasattr(getattr(head[3].fn, "__self__", None), "served_stream")):
                    task = cpu.busy_task()
                    if ((task is None or head[3] is not task.end_ev) and tick_run(head[3]) is None
                            and served.inert_until(head[3]) is None):
                        return None
        ra, rb = served.route(self.a), served.route(self.b)
        if ra is None or rb is None:
            return None
        self._serve_hint = (ra.cpu, ra.vector, rb.vector)
        return Crossings(self, direction, tick, locate, state_at, ra, rb, on_finish, span)

    # ---- fault injection ---------------------------------------------------------------------------
    def glitch(self, channel: str = "A", width: int = 1) -> None:
        """Injected noise spike: output ``channel`` ("A" or "B") shows the wrong level from now for
        ``width`` base ticks, then the true level again (an edge pair the decoder may or may not
        see, depending on its filter and on how fast it samples)."""
        if channel not in ("A", "B") or int(width) != width or width < 1:
            raise ConfigError(f"encoder {self.name}: glitch channel must be 'A' or 'B' and width "
                              f"a positive number of ticks, not {channel!r}, {width!r}")
        self.materialize()
        if self._glitch_ev is not None:
            self._glitch_ev.cancel()
        # (a crossing of either channel meanwhile leaves the glitched one wrong: _out)
        self._glitched = channel
        self._out()
        self._glitch_ev = self.kernel.after(int(width), self._glitch_end, prio=PRIO_PLANT)

    def _glitch_end(self) -> None:
        self._glitch_ev = None
        self._glitched = None
        self._out()

    def drop_edges(self, n: int) -> None:
        """Injected fault: the next ``n`` threshold crossings in time emit no edge (missed edges,
        wherever the shaft is then: not a spot on the disc, which would miss the same angles both
        ways). The outputs stay a valid quadrature sequence, so a decoder ends up ``n`` counts
        behind (in the direction of those crossings) for good. ``n = 0`` cancels what is left."""
        if int(n) != n or n < 0:
            raise ConfigError(f"encoder {self.name}: drop_edges({n!r}) needs a whole number >= 0")
        if n:
            self.materialize()
        self._drop = int(n)

    def __repr__(self):
        return f"QuadratureEncoder({self.name}: position {self.position}, A={self.a.level} B={self.b.level})"
