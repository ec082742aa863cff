"""A quadrature encoder's crossings served in closed form (fast engine, :mod:`mcusim.engine.served`).

:class:`Crossings` is the plant side of a served run: the crossings of one
:class:`~mcusim.plant.encoder.QuadratureEncoder` planned one after the other (``plan``,
``commit``), or counted up to a tick from the shaft angle (``count_bound``, ``count_window``,
``cut``, ``commit_count``). The encoder hands one out (``QuadratureEncoder.crossing_stream``)
when its edges could be served now.
"""

from __future__ import annotations

from ..engine import served


class Crossings:
    """An encoder's crossings as a stream of served edges (:func:`mcusim.engine.served.serve_run`):
    ``plan`` one after the other from the planned position and output levels, ``commit`` the ones
    served; or count them up to a tick (``count_bound`` … ``commit_count``)."""

    __slots__ = ("K", "after_last", "committed", "cpus", "enc", "la", "lb", "locate", "nxt", "on_finish",
                 "pending", "pos", "ra", "rb", "span", "state_at", "t_max", "wlo")

    def __init__(self, enc, direction, tick, locate, state_at, ra, rb, on_finish, span=None):
        self.enc, self.locate, self.state_at, self.on_finish = enc, locate, state_at, on_finish
        self.span = span
        self.t_max = None           # a counted run's window (count_bound)
        self.ra, self.rb = ra, rb
        self.cpus = frozenset((ra.cpu, rb.cpu))
        self.pending = (tick, direction)
        self.pos, self.la, self.lb = enc._pos, enc.a.level, enc.b.level
        # whether a crossing was committed, and the next one after the last committed (not the
        # committed item itself: it refers to this stream, and the cycle would leave both to the
        # garbage collector, thousands of them per simulated second on the rover)
        self.committed, self.after_last = False, None

    def first_return(self) -> int:
        """The earliest tick at which the handler of the stream's first crossing could return
        (whichever output it changes)."""
        t = self.pending[0]
        return min(self.ra.returns(t), self.rb.returns(t))

    def plan(self, t, d):
        """The crossing at tick ``t`` in direction ``d`` as a served edge, or None if it is not one
        edge of one output (more than one threshold in the tick, or both outputs change)."""
        enc = self.enc
        st = enc.step
        th = self.state_at(t)[2]
        k = self.pos + d
        if (th >= (k + 1) * st) if d > 0 else (th < k * st):
            return None         # more than one threshold in this tick: on_guard's loop
        qa, qb = enc.levels(k)
        if (qa != self.la) == (qb != self.lb):
            return None         # not exactly one output changes (after a glitch)
        route = self.ra if qa != self.la else self.rb
        nt, firing = self.locate(enc._guards_at(k), t)
        self.pos, self.la, self.lb = k, qa, qb
        return served.Item(self, t, route.returns(t), None if nt is None else (nt, firing[0][6], firing),
                           (k, qa, qb), route)

    def commit(self, item):
        k, qa, qb = item.data
        route = item.route
        enc = self.enc
        enc._pos = k
        enc._edges += 1
        route.serve({enc.a: qa, enc.b: qb})
        self.committed, self.after_last = True, item.nxt

    # ---- counted runs (served._count): the crossings up to a tick, without locating each ----
    def count_bound(self, R: int, base_hz: int) -> int:
        """At most how many crossings a counted run whose handlers return by tick ``R`` could hold
        (0 if this stream cannot be counted): from the motor's speed bound, without evaluating θ.
        It cannot be counted when its motor is not in a chunk of PWM periods, when crossings may
        come closer together than a handler takes (with a factor 2 margin), or when the outputs do
        not show the position's quadrature state."""
        self.t_max = None
        sp = None if self.span is None else self.span()
        if sp is None:
            return 0
        end, wlo, whi = sp
        ra, rb = self.ra, self.rb
        clock = ra.clock
        enc = self.enc
        if (rb.clock is not clock or enc._glitch_ev is not None
                or (self.la, self.lb) != enc.levels(self.pos)):
            return 0
        ticks = max(ra.ticks, rb.ticks)
        # crossings come ≥ floor(step/whi·hz) ticks apart; a handler returns < P + ticks after its edge
        if not 0.0 < whi * 2.0 * (clock.period + ticks + 1) < enc.step * base_hz:
            return 0
        t_max = min(served.last_tick_returning_by(clock, ticks, R), end - 1)
        self.t_max, self.K, self.wlo = t_max, self.pos, wlo
        t0 = self.pending[0]
        return 0 if t_max < t0 else 1 + int(whi * (t_max - t0) / (enc.step * base_hz))

    def count_window(self, R: int, base_hz: int):
        """After :meth:`count_bound`: how many crossings come by the window's last tick (t_max),
        or None if they cannot be counted (as there, or θ moves too slowly for its float values to
        grow tick by tick)."""
        t_max = self.t_max
        if t_max is None:
            return None
        t0, d = self.pending
        if t_max < t0:
            return 0
        # the crossing due at t0 is one threshold, as ``plan`` requires: a jump of the angle can
        # leave the encoder several behind, and edge by edge on_guard's loop emits them all at
        # t0 (the handlers then lose most); counted, they would be spread out and all served
        k, st = self.pos + d, self.enc.step
        th0 = self.state_at(t0)[2]
        if (th0 >= (k + 1) * st) if d > 0 else (th0 < k * st):
            return None
        th = self.state_at(t_max)[2]
        if self.wlo <= 1e-12 * (abs(th) + 1.0) * base_hz:
            return None         # θ may gain less per tick than its float rounding
        K = self.enc._k_of(th)
        if (K - self.pos) * d < 1:
            return None         # the crossing due at t0 is not seen at t_max: do not guess
        self.K = K
        return abs(K - self.pos)

    def tick_end(self, T: int, isr: int, pas: int, base_hz: int):
        """For a run serving another handler on this stream's CPU (:mod:`mcusim.engine.ticks`),
        requested at tick ``T`` (on a CPU clock edge), ``isr`` ticks from request to return, then
        a task's pass of ``pas`` ticks: (the tick the handler is taken at, the tick by which the
        pass is over) with this stream's edges around them as edge by edge, or None where they
        interact in a way not worked out here.

        From the shaft angle, as a count (θ monotone in a chunk, fast enough for its float values
        to grow tick by tick; the counted run's spacing keeps two edges more than a handler and
        this one apart). An edge whose handler returns before T, or that comes after the handler
        (its request preempts the pass, which then ends later by its handler's ticks), does not
        interact. One edge in between is worked out as the CPU queues it: one whose handler still
        runs at T delays the other handler to its return; one whose request comes while the other
        runs waits for its return (a request at T itself is left out: the lower vector would go
        first). A handler delayed so may return after another stream's first crossing left out
        of the run: that crossing is on another CPU, which the delay does not reach. Otherwise
        None."""
        sp = None if self.span is None else self.span()
        ra, rb = self.ra, self.rb
        if sp is None or rb.clock is not ra.clock:
            return None
        clock, h = ra.clock, max(ra.ticks, rb.ticks)
        if T + isr + h + pas + h >= sp[0]:
            return None         # past the chunk: θ may not be monotone there
        enc, state_at = self.enc, self.state_at
        t0, pos = self.pending[0], self.pos
        R = T + isr
        th = state_at(R + pas)[2]
        if sp[1] <= 1e-12 * (abs(th) + 1.0) * base_hz:
            return None         # θ may gain less per tick than its float rounding

        def at(t):              # the position after the crossings up to tick t
            return pos if t < t0 else enc._k_of(state_at(t)[2])

        a = served.last_tick_returning_by(clock, h, T - 1)
        pa = at(a)
        if pa == enc._k_of(th):
            return T, R + pas   # no edge from before T to the pass's end
        pr = at(R)
        if pa != pr:
            if abs(pr - pa) != 1:
                return None
            d = pr - pa
            c, _ = self.locate(enc._guards_at(pa), max(a, t0 - 1))
            if c is None or c > R:
                return None
            e, hc = clock.next_edge(c), self._route_into(pa + d, d).ticks
            if e == T:
                return None
            # the handler that waits starts at the other's return; nothing else comes meanwhile
            if e < T:
                T = max(e + hc, T)
                R = T + isr
            else:
                R += hc
            if at(R) != pr:
                return None
        # the pass: an edge in it preempts it and moves its end by its handler (the costlier one:
        # the end comes no earlier), so the stretch that adds may hold another edge
        n = 0
        while True:
            m = abs(at(R + pas + n * h) - pr)
            if m == n:
                return T, R + pas + n * h
            if m > 8:
                return None
            n = m

    def locate_next(self):
        """The first crossing after the window (tick, direction, guards) or None, as ``nxt``."""
        nt, firing = self.locate(self.enc._guards_at(self.K), self.t_max)
        self.nxt = None if nt is None else (nt, firing[0][6], firing)
        return self.nxt

    def _route_into(self, k: int, d: int):
        qa = self.enc.levels(k)[0]
        return self.ra if qa != self.enc.levels(k - d)[0] else self.rb

    def cut(self, c):
        """The crossings before tick ``c`` (all of the window's if ``c`` is None or after it):
        (how many, the last one's tick, its handler's return), (0, None, None) if none, or None if
        the last one is not where the count says (a float surprise: the run is not counted)."""
        t0, d = self.pending
        if c is None or c > self.t_max:
            K = self.K
        elif c - 1 < t0:
            K = self.pos
        else:
            K = self.enc._k_of(self.state_at(c - 1)[2])
        m = (K - self.pos) * d
        if m <= 0:
            return (0, None, None) if m == 0 else None
        if K == self.K and (c is None or self._returns_by(self.t_max) < c):
            # the whole window, and every handler in it returns before c wherever its last
            # crossing lies: the run needs neither that crossing's tick nor its return
            return m, None, None
        g = self.enc._guards_at(K - d)[0 if d > 0 else 1]      # the crossing into K
        L, _ = self.locate((g,), t0 - 1)
        if L is None or L > self.t_max or (c is not None and L >= c):
            return None
        return m, L, self._route_into(K, d).returns(L)

    def _returns_by(self, t: int) -> int:
        """The latest return of a handler of a crossing at or before tick ``t``."""
        ra, rb = self.ra, self.rb
        return max(ra.returns(t), rb.returns(t))

    def commit_count(self, m: int, L) -> None:
        """Serve the first ``m`` crossings of the window (the last one at tick ``L``; None when
        the whole window is served, see :meth:`cut`)."""
        enc = self.enc
        d = self.pending[1]
        k = self.pos
        ra, rb = self.ra, self.rb
        fa, fb = ra.form, rb.form
        if fa.walk is not None and fa.walk is fb.walk and fa.nets == fb.nets and fa.nets in (
                (enc.a, enc.b), (enc.b, enc.a)):
            # one state stepped by both handlers: the walk at once. A and B change by turns on a
            # quadrature walk, A first where the first step changes it
            fa.walk(Walk(enc, k, d, m, fa.nets[0] is not enc.a))
            na = (m + 1) // 2 if enc.levels(k + d)[0] != self.la else m // 2
            k += d * m
        else:
            step_a, step_b = ra.stepper(enc.a, enc.b), rb.stepper(enc.a, enc.b)
            la, na = self.la, 0
            for _ in range(m):
                k += d
                qa, qb = enc.levels(k)
                if qa != la:            # A changed: INT on A's pin
                    step_a(qa, qb)
                    na += 1
                    la = qa
                else:
                    step_b(qa, qb)
        ra.charge(na)
        rb.charge(m - na)
        self.la, self.lb = enc.levels(k)
        enc._pos = self.pos = k
        enc._edges += m
        enc.counted_edges += m
        if k != self.K:     # cut short: the next crossing is the first after the last one served
            nt, firing = self.locate(enc._guards_at(k), L)
            self.nxt = None if nt is None else (nt, firing[0][6], firing)
        self.committed, self.after_last = True, self.nxt

    def finish(self):
        """After the run: the outputs show the last served edge, and ``on_finish(nxt)`` gets the
        next crossing located from the last one served ((tick, direction, firing guards) or None)."""
        if self.committed:
            enc = self.enc
            qa, qb = enc.levels(enc._pos)
            enc.a.settle(enc.name, qa)
            enc.b.settle(enc.name, qb)
            self.on_finish(self.after_last)


class Walk:
    """The output levels (A, B) after each of ``m`` steps of a quadrature walk from position ``k``
    in direction ``d`` ((B, A) where ``swap``): a sequence whose items are computed when read.
    They repeat every 4 steps (``cycle``), which a handler's ``walk`` may use
    (:class:`mcusim.firmware.ClosedForm`)."""

    __slots__ = ("d", "enc", "k", "m", "swap")
    cycle = 4

    def __init__(self, enc, k: int, d: int, m: int, swap: bool):
        self.enc, self.k, self.d, self.m, self.swap = enc, k, d, m, swap

    def __len__(self) -> int:
        return self.m

    def __getitem__(self, j):
        if isinstance(j, slice):
            return [self[i] for i in range(*j.indices(self.m))]
        if j < 0:
            j += self.m
        if not 0 <= j < self.m:
            raise IndexError(j)
        a, b = self.enc.levels(self.k + self.d * (j + 1))
        return (b, a) if self.swap else (a, b)
