"""The fast engine's part of :class:`mcusim.plant.dcmotor.DcMotor`: a driver's steady periodic drive.

A driver whose inputs are steady waveforms hands the motor a drive schedule (``drive_schedule()``:
anchor, period, pieces). From the start of a piece the motor tries a *chunk*: the pieces of one period
composed into a period map (:mod:`mcusim.engine.periodmap`), every guard screened over N periods at
once (:mod:`mcusim.engine.screening`), and, if the first k periods are clean, one segment covering
them (:class:`~mcusim.engine.chunk.ChunkTraj`). Otherwise it runs the piece as the reference
engine runs a segment, screened up to the piece's end. Encoder thresholds (*passive* guards: they
change nothing the motor sees) are located inside a chunk or a segment without ending it.
"""

from __future__ import annotations

from collections import OrderedDict, deque

from ..engine import periodmap, served
from ..engine.chunk import ChunkTraj
from ..engine.screening import PeriodPlan
from ..kernel import PRIO_HW, PRIO_PLANT
from . import pwl

# whole-period chunks are screened CHUNK_MIN periods ahead at first, doubling up to CHUNK_MAX while
# nothing fires; chunks that input changes keep cutting short bring it down, not below CHUNK_LO
# (_chunk_lived)
CHUNK_LO, CHUNK_MIN, CHUNK_MAX = 4, 16, 512
# cached period plans and piece flows per motor, least recently used dropped first (a plan's power
# table is up to CHUNK_MAX + 1 4×4 maps, 66 kB: the bound keeps memory flat in run length). A PID
# winding its integral up against a stuck motor makes a new plan at every step and meets none again:
# 16 plans keep the ones a limit cycle revisits (pro-mini: 28 builds/s against 24 with 64)
PLANS_MAX, FLOWS_MAX = 16, 512


class SecondSight:
    """An LRU cache (order = use order, the least recently used dropped first) that keeps a value
    only for a key seen before: the first time a key comes, what was built for it is not kept.

    Most plans and flows are never met again: the rover's battery and body move the supply
    voltage and the load torques every millisecond (every key is new: 0 of 2,196 plans in half a
    second met twice), and a PID holding a position writes a new duty at most steps (17-28 % of
    the nucleo-f746's plans met again). Kept, each such value waits for 16 others to push it out
    and is freed from memory long gone cold (the rover ran 7 % faster without the caches; the
    pro-mini, whose limit cycle meets 61 % of its plans again, 5 % slower). Admitted on its second
    sight, a value that repeats is kept from then on, and one that does not dies with the segment
    that used it. ``seen`` remembers the hashes of the last ``4 · limit`` keys (a collision only
    admits a value early)."""

    __slots__ = ("_d", "_order", "_seen", "limit")

    def __init__(self, limit: int):
        self.limit = limit
        self._d = OrderedDict()
        self._seen = set()
        self._order = deque()

    def __len__(self) -> int:
        return len(self._d)

    def get(self, key):
        """The value kept for ``key`` (now the most recently used), or None."""
        d = self._d
        v = d.get(key)
        if v is not None:
            d.move_to_end(key)
        return v

    def put(self, key, value) -> None:
        """``value`` was built for ``key``: keep it if ``key`` came before (dropping the least
        recently used value when full), else only remember that it came."""
        h = hash(key)
        seen = self._seen
        if h in seen:
            d = self._d
            if len(d) >= self.limit:
                d.popitem(last=False)
            d[key] = value
            return
        order = self._order
        if len(order) >= 4 * self.limit:
            seen.discard(order.popleft())
        seen.add(h)
        order.append(h)


class PeriodicDrive:
    """Mixin of DcMotor (uses its state: _x0, _t0, _traj, _providers, _driver, params ...)."""

    def _piece_flow(self, drive, es, s, ticks):
        """(flow, |A|, |u|, (a11, a12, u1), flow rows) of one piece of ``ticks`` in mode (es, s)
        (|A| as the tuple (|a11|, |a12|, |a21|, |a22|), |u| as (|u1|, |u2|)),
        cached per (drive, mode, ticks, parameters): a PID loop that moves the duty by a count or
        two keeps meeting the same pieces."""
        key = (drive, es, s, ticks, self._pkey, self.params.R)
        flows = self._flows
        ent = flows.get(key)
        if ent is None:
            ent = self._piece_flow_new(drive, es, s, ticks)
            ent += (ent[0].tolist(),)
            flows.put(key, ent)
        return ent

    def _piece_flow_new(self, drive, es, s, ticks):
        rt, v0, T = self._drive_terms(drive, es, s)
        tau = ticks * self._inv_hz
        if T is None:
            lam = -rt / self.params.L
            i_ss = v0 / rt
            return (periodmap.stuck_flow(lam, i_ss, tau), (abs(lam), 0.0, 0.0, 0.0),
                    (abs(lam * i_ss), 0.0), (lam, 0.0, -lam * i_ss))
        eig, A, u, _ = self._full_system(rt, v0, T)
        return (periodmap.full_flow(eig, A, u, tau), tuple(abs(a) for a in A),
                (abs(u[0]), abs(u[1])), (A[0], A[1], u[0]))

    def _try_chunk(self, sched, j, x0, into: int = 0) -> bool:
        """From ``into`` ticks into piece ``j`` (0: its start): advance whole periods if no guard can
        fire in them. A period that starts inside piece ``j`` ends with that piece's first ``into``
        ticks (an input change inside a piece: the rover's 1 ms battery and body steps, a duty
        written at the bottom of a phase-correct period, start the chunk at once)."""
        _, P, pieces = sched
        npc = len(pieces)
        order = []      # (piece index, ticks) of one period from here
        for q in range(npc):
            idx = (j + q) % npc
            order.append((idx, (pieces[idx + 1][0] if idx + 1 < npc else P) - pieces[idx][0]))
        if into:
            order[0] = (j, order[0][1] - into)
            order.append((j, into))
        plan_pieces, modes = [], []
        x = x0
        for idx, ticks in order:
            drive = pieces[idx][1]
            es, s = self._select(x, drive)
            if es == 0:
                return False        # discontinuous conduction: a guard event every period
            flow, absA, absu, lin, rows = self._piece_flow(drive, es, s, ticks)
            plan_pieces.append((ticks, flow, absA, absu, drive, (es, s), lin))
            modes.append((es, s))
            x = periodmap.apply_rows(rows, x)
        key = (P, pieces, j, into, tuple(modes), self._pkey, self.params.R)
        plans = self._plans
        plan = plans.get(key)
        if plan is None:
            for q, pc in enumerate(plan_pieces):     # the guards only when the plan is new
                ticks, flow, absA, absu, drive, mode, lin = pc
                bguards = pieces[order[q][0]][2]
                plan_pieces[q] = (ticks, flow, absA, absu,
                                  tuple(self._mode_guards(*mode, drive)) + tuple(bguards), drive, mode, lin)
            plan = PeriodPlan(plan_pieces, P, self._inv_hz, CHUNK_MAX,
                              [self._piece_former(pc[5], *pc[6]) for pc in plan_pieces], self._guard_arrays,
                              self._linear_parts)
            plans.put(key, plan)
        extra = []
        for prov in self._providers:
            if prov is not self._driver and not getattr(prov, "passive_guards", False):
                extra.extend(prov.plant_guards())
        n = self._chunk_n
        k, X, ib, wspan = plan.first_flag(x0, n, tuple(extra))
        now = self.kernel.now
        if k == 0:
            self._chunk_n = CHUNK_MIN
            self._chunk_retry = now + P
            return False
        self._chunk_n = min(2 * n, CHUNK_MAX) if k == n else CHUNK_MIN
        self._es, self._s = modes[0]
        self._traj = ChunkTraj(plan, x0, X, ib, wspan, self._th_lo)
        self.segments += 1
        self._ev = self.kernel.at(now + k * P, self._on_piece_end, prio=PRIO_HW)
        self._find_passive()
        return True

    def _chunk_lived(self, tr, n: int) -> None:
        """The chunk ``tr`` ends after ``n`` ticks. One that an input change cut short after m
        periods moves the next horizon down towards m + 2, but not below half the horizon already
        set for the next chunk: after a chunk screened clean over h periods that is 2·h, so the
        floor is h itself (one early cut is no pattern, and the slack spares chunks that start
        late in an input's interval an end at their horizon: a floor of h/2 measured more
        screenings, not fewer). Screening periods that inputs changing at a steady rate (the rover's
        1 ms battery and body steps, the nucleo's PID writing a new duty every 250 PWM periods)
        never let run is wasted work, and the screening's cost grows with the horizon."""
        P = tr.plan.P
        if n < tr.periods * P:
            self._chunk_n = max(min(n // P + 2, CHUNK_MAX), self._chunk_n // 2, CHUNK_LO)

    def _passive_search(self, after: int):
        """(search, end): ``search(g)`` is the first tick offset in (``after``, ``end``] at which the
        θ-only guard ``g`` fires on the current trajectory, or None; ``end`` is its own last tick."""
        tr = self._traj
        if tr.kind == "chunk":
            return (lambda g: tr.first_fire(g, after)), tr.periods * tr.plan.P
        # a closed-form segment, up to its own next event
        end = self._seg_end
        if end <= after:
            return (lambda g: None), end
        inv = self._inv_hz
        xa, xe = self._at(tr, after), tr.eval(end * inv)
        hval = pwl.hval
        # θ is monotone up to the segment's own next event (a speed reversal is one of its guards):
        # an encoder threshold fires once, found by a bracketing search
        return (lambda g: pwl.first_fire_monotone(
            lambda k: hval(g, tr.eval(k * inv)), after, end, hval(g, xa), hval(g, xe), g[4])), end

    def _first_passive(self, guards, after: int):
        """(tick offset, the guards firing there) of the first of ``guards`` (passive, θ-only) to
        fire after offset ``after``, or (None, [])."""
        search = None
        best, firing = None, []
        s = self._s
        x1 = None
        for g in guards:
            if after == 0 and pwl.fired(g, pwl.hval(g, self._x0)):
                # already fired where the trajectory starts (a state jump put θ past it): the
                # edge-by-edge screening takes a guard as not fired at the segment start and finds
                # it at the first tick after that, whichever way θ moves
                if search is None:
                    search, end = self._passive_search(after)
                if end < 1:
                    continue
                if x1 is None:
                    x1 = self._at(self._traj, 1)
                if not pwl.fired(g, pwl.hval(g, x1)):
                    continue
                n = 1
            elif g[2] * s > 0.0 or s == 0:    # θ moves away from it (or stands still)
                continue
            else:
                if search is None:
                    search, end = self._passive_search(after)
                n = search(g)
            if n is None or (best is not None and n > best):
                continue
            if best is None or n < best:
                best, firing = n, [g]
            else:
                firing.append(g)
        return best, firing

    def _find_passive(self):
        """Schedule the next firing of a passive provider's guards (an encoder threshold: its
        handler changes no input of the motor) inside the current chunk, which stays as it is."""
        tr = self._traj
        after = self.kernel.now - self._t0
        end = tr.periods * tr.plan.P if tr.kind == "chunk" else self._seg_end
        if tr.kind != "chunk" and end <= after:
            return
        guards = [g for prov in self._providers if getattr(prov, "passive_guards", False)
                  for g in prov.plant_guards()]
        hint, self._passive_hint = self._passive_hint, None
        got = None if hint is None else self._passive_at(guards, after, end, hint - self._t0)
        best, firing = got or self._first_passive(guards, after)
        if best is not None:
            self._schedule_passive(best, end, firing)

    def _passive_at(self, guards, after: int, end: int, n: int):
        """(n, the guards firing there) where the first of ``guards`` to fire after offset
        ``after`` fires at offset ``n``, as :meth:`_first_passive` would find it; else None (not
        settled here). A rebuild at an input change (the rover's battery and body steps, every
        millisecond) moves the trajectory so little that the next encoder crossing nearly always
        stays on its tick: the rebuild passes that tick, and two evaluations settle it. The guards
        are θ-only and θ is monotone on the trajectory up to ``end`` (as for the search), so a
        guard fired at n and not at n − 1 first fires at n; one fired at n − 1 fires earlier."""
        if not after < n - 1 < end or self._s == 0:
            return None
        tr = self._traj
        x1, x0 = self._at(tr, n), self._at(tr, n - 1)
        s = self._s
        hval, fired = pwl.hval, pwl.fired
        firing = []
        for g in guards:
            if g[2] * s > 0.0:
                continue            # θ moves away from it (the search skips it too)
            if fired(g, hval(g, x0)):
                return None
            if fired(g, hval(g, x1)):
                firing.append(g)
        return (n, firing) if firing else None

    def _schedule_passive(self, best: int, end: int, firing) -> None:
        """The passive ``firing`` guards fire at offset ``best`` of the trajectory ending at ``end``."""
        if best == end:      # at the segment's own event: that event runs it first
            if self._pending is not None and self._pending_time == self._t0 + best:
                self._pending = self._pending + firing
            else:
                self._pending, self._pending_time = firing, self._t0 + best
        else:
            self._passive = firing
            self._ev_passive = self.kernel.at(self._t0 + best, self._on_passive, prio=PRIO_PLANT)

    def _locate_passive(self, guards, after_tick: int):
        """For an encoder serving its crossings (:mod:`mcusim.engine.served`): the absolute tick at
        which the first of its ``guards`` fires after ``after_tick`` on the current trajectory,
        and those guards; (None, []) if none does before its end."""
        best, firing = self._first_passive(guards, after_tick - self._t0)
        return (None, []) if best is None else (self._t0 + best, firing)

    def _passive_span(self):
        """For a counted run of crossings (:mod:`mcusim.engine.served`): (end tick, wlo, whi) of the
        current trajectory, a chunk in which wlo ≤ |ω| ≤ whi, or None for any other trajectory."""
        tr = self._traj
        if tr is None or tr.kind != "chunk":
            return None
        return (self._t0 + tr.periods * tr.plan.P,) + tr.wspan

    def _state_ahead(self, tick: int):
        """(i, ω, θ) at ``tick`` ≥ now on the current trajectory, as the observers read it there
        (now: the observers' memo, which the encoder's own read at its crossing has filled)."""
        if tick == self.kernel.now:
            return self._now_state()
        n = tick - self._t0
        return self._x0 if (n == 0 or self._traj is None) else self._at(self._traj, n)

    def _serving_provider(self):
        """The motor's only passive provider if it can serve its crossings (else None)."""
        firing = self._passive
        if len(firing) != 1:
            return None
        prov = firing[0][5]
        if not hasattr(prov, "crossing_stream") or sum(
                1 for p in self._providers if getattr(p, "passive_guards", False)) != 1:
            return None
        return prov

    def served_stream(self, ev):
        """The stream of this motor's encoder crossings whose next one is the queued event ``ev``,
        for another encoder's served run to absorb (:func:`mcusim.engine.served.serve_run`)."""
        prov = self._serving_provider() if ev is self._ev_passive else None
        if prov is None:
            return None

        def finish(nxt):    # the run served some: its event is done
            ev.cancel()
            self._ev_passive = None
            self._served_next(nxt)
        return prov.crossing_stream(self._passive[0][6], ev.time, self._locate_passive, self._state_ahead,
                                    finish, span=self._passive_span)

    def _served_next(self, nxt) -> None:
        """Schedule the crossing a served run located after its last one ((tick, direction, guards)
        or None): the one ``_find_passive`` would find now, since none lies in between."""
        if nxt is not None:
            tr = self._traj
            end = tr.periods * tr.plan.P if tr.kind == "chunk" else self._seg_end
            self._schedule_passive(nxt[0] - self._t0, end, nxt[2])

    def _on_passive(self):
        self._ev_passive = None
        tr = self._traj
        # the edge-by-edge engine starts a segment here and samples |i| at its start: an interior
        # point of this segment, never above the maximum the segment's own tracking finds (its
        # boundaries and the current's stationary points), so nothing is sampled here
        prov = self._serving_provider()
        stream = None if prov is None else prov.crossing_stream(
            self._passive[0][6], self.kernel.now, self._locate_passive, self._state_ahead, self._served_next,
            first=True, span=self._passive_span)
        if stream is not None and served.serve_run(self.kernel, stream):
            return          # the run scheduled what comes next (_served_next)
        for g in self._passive:
            g[5].on_guard(g[6])
        if self._traj is tr and self._ev_passive is None:
            self._find_passive()

    def _on_piece_end(self):
        self._ev = None
        self._grow = False
        self.edge_tick = self.kernel.now     # the drive's switching tick: its edge, edge by edge
        self._sync()

    def _rebuild_periodic(self, sched, x0):
        anchor, P, pieces = sched
        now = self.kernel.now
        ph = (now - anchor) % P
        j = len(pieces) - 1
        while pieces[j][0] > ph:
            j -= 1
        if now >= self._chunk_retry and self._try_chunk(sched, j, x0, ph - pieces[j][0]):
            return
        # one piece, edge by edge: the reference engine's segment, screened up to the piece end
        n_end = (pieces[j + 1][0] if j + 1 < len(pieces) else P) - ph
        drive = pieces[j][1]
        tr, es, s = self._new_segment(x0, drive)
        if tr.kind == "static":
            self._ev = self.kernel.at(now + n_end, self._on_piece_end, prio=PRIO_HW)
            return
        guards = self._mode_guards(es, s, drive)
        for prov in self._providers:
            guards.extend(prov.plant_guards())
        self._screen(tr, x0, guards, limit=n_end)

