"""Fast engine part of :class:`mcusim.plant.bts7960.Bts7960Bridge`: a periodic drive schedule.

When the IN/INH inputs carry steady waveforms of one period (a timer's PWM, see
:mod:`mcusim.engine.waveform`) and no half bridge is in current limitation or thermal shutdown,
the bridge hands the motor a drive schedule ``(anchor, period, pieces)`` as the L6206 does
(:meth:`mcusim.plant.l6206.L6206Bridge.drive_schedule`): each piece ``(offset, drive_state,
guards)`` carries the current-limit guards of the switches that are on in it (high side: j >
I_CLH, low side: −j > I_CLL), so the motor screens them per piece over whole chunks of periods and
locates a trip to the tick inside the period where it happens. A switching tick at which the
current is already over the new switch's limit trips at once, as the edge-by-edge bridge does at
the edge (:meth:`_check_now` when the schedule is asked for at a piece boundary).

Supply charge over a chunk. Within each piece the leg states and the conduction sign are
constant, so the charge drawn from B+ is ``c/(R+R_br)·(V·τ − L·Δi − K·Δθ)`` exactly as per
segment (see :mod:`mcusim.plant.bts7960`). Over k whole periods the Δi and Δθ of piece p summed
over the periods are ``(Q[p+1] − Q[p])·Σ_q X_q`` (Q: the maps from the period start to the piece
starts, X_q: the state at the start of period q), one 4×4 product per piece; a partial period is
summed piece by piece from the closed form. So the account stays exact (to float rounding) over
chunks of any length, and ``supply_charge()`` may be read at any tick inside one.

IS outputs: while the schedule runs, the state history holds the waveforms themselves, so
``is_current(side, t)`` evaluates the leg states at any tick t from them, and the current from
``motor.state_at(t)`` (inside a chunk: the period maps and the piece's closed form).

Falls back to edge by edge (an event per input edge, as the reference engine) while a half
bridge is in current limitation or thermal shutdown, or when the inputs' periods differ.
"""

from __future__ import annotations

from ..errors import McusimError
from .hbridge import input_shape, leg_pieces


class SteadyDrive:
    """Mixin for Bts7960Bridge (fast engine)."""

    def _nets(self):
        return (self.rpwm, self.lpwm, self.r_en, self.l_en)

    def _waves(self):
        return [n.wave for n in self._nets() if n is not None and n.wave is not None]

    def _legs_from(self, vals, t):
        """Leg states at tick t from stored input values (a level or a Waveform per net)."""
        lv = [1 if v is None else (v if type(v) is int else v.level_at(t)) for v in vals]
        return tuple("Z" if not lv[2 + k] else ("H" if lv[k] else "L") for k in (0, 1))

    def _piece_guards(self, legs):
        p = self.params
        out = []
        for side, leg, sgn in (("R", legs[0], 1.0), ("L", legs[1], -1.0)):
            if leg == "H":
                out.append((-sgn, 0.0, 0.0, p.I_CLH, True, self, (side, "H")))
            elif leg == "L":
                out.append((sgn, 0.0, 0.0, p.I_CLL, True, self, (side, "L")))
        return tuple(out)

    def drive_schedule(self):
        """``(anchor, period, pieces)`` when the inputs are steady waveforms of one period and no
        fault overrides them, else None (the motor asks drive_state(); edges come one by one)."""
        self._close_account_now()
        now = self.kernel.now
        m = self.motor
        if m.edge_tick == now:
            m.edge_tick = None
            if self._switches_now():
                self._check_now()
        waves = self._waves()
        halves = self._half.values()
        if not waves or any(h.fault or h.overtemp for h in halves):
            return self._not_periodic(waves)
        vals = self._input_values()
        shape = input_shape(self._nets())
        # the pieces depend on the inputs' shapes only: a rebuild for another reason (a supply
        # or load change, a chunk's end) finds them again
        cache = self._pieces_cache
        if shape in cache:
            found = cache[shape]
        else:
            found = leg_pieces(waves, lambda t: self._legs_from(vals, t))
            if found is not None:
                anchor, P, pieces = found
                found = (anchor % P, P, tuple(pieces))
            if len(cache) >= 32:
                cache.clear()
            cache[shape] = found
        if found is None:
            return self._not_periodic(waves)
        anchor, P, pieces = found
        if self._edge_ev is not None:
            self._edge_ev.cancel()
            self._edge_ev = None
        self._periodic = True
        self._legs_seen = None
        self._record(("w", vals))
        self._shape = shape
        self._sched = found
        mp = self.motor.params
        self._cacc = (now, self._sched, mp.R, mp.L, mp.K)
        return (anchor, P, tuple((o, self.drive_for(lg), self._piece_guards(lg)) for o, lg in pieces))

    def _switches_now(self) -> bool:
        """The legs change at this tick (an input edge, an enable, a fault's end): the edge-by-edge
        bridge checks the limits of the switches that are on from here at that edge, with the
        state the edge sees. A rebuild standing for no edge (``motor.edge_tick``: a supply, load or
        parameter change after the tick's hardware events, a chunk's end inside a piece) does not
        check: the screening of the new segment finds a limit already passed, at the next tick, in
        both engines."""
        now = self.kernel.now
        for t_c, s in reversed(self._hist):
            if t_c < now:
                before = self._legs_from(s[1], now - 1) if s[0] == "w" else (s[0], s[1])
                return before != self.legs
        return True

    def _input_values(self):
        """Per input net (RPWM, LPWM, R_EN, L_EN): its waveform, else its level (None: no net)."""
        return tuple(None if n is None else (n.wave if n.wave is not None else (1 if n.level else 0))
                     for n in self._nets())

    def _schedule_stands(self) -> bool:
        """The inputs keep the shape the running schedule was made from (``input_shape``: a
        timer republished a waveform that now ends at its next update, where a new duty waits):
        the schedule, and the motor's chunk, stand until the timer publishes again."""
        return self._periodic and self._shape == input_shape(self._nets())

    def _not_periodic(self, waves):
        self._periodic = False
        self._record()
        if waves and self._edge_ev is None:
            self._next_edge()

    # ---- edge by edge while waveforms are present but no schedule covers them ------------------
    def _next_edge(self):
        now = self.kernel.now
        ts = [w.next_edge(now)[0] for w in self._waves()]
        if ts:
            self._edge_ev = self.kernel.at(min(ts), self._on_edge)

    def _on_edge(self):
        self._edge_ev = None
        if self._periodic:
            return
        now = self.kernel.now
        for h in self._half.values():
            # an INH low pulse resets the thermal latch (_on_pin, edge by edge): a falling edge of
            # an INH waveform at this tick is one
            w = None if h.en is None else h.en.wave
            if (h.overtemp and w is not None and (w.end is None or now < w.end) and not h.en.level
                    and w.next_edge(now - 1) == (now, 0)):
                self._reset_overtemp(h)
        if self.legs != self._legs_seen:
            self._check_now()
            self._record()
            self.motor.input_changed()
        if not self._periodic and self._edge_ev is None:
            self._next_edge()

    # ---- supply charge over chunks ---------------------------------------------------------------
    def _close_account_now(self):
        """Close whatever supply account is open at now (a segment's or a chunk's)."""
        self._close_segment()

    def _close_chunk(self, now):
        t_from, sched, R, L, K = self._cacc
        if now <= t_from:
            return
        m = self.motor
        if m._t0 < now:
            t_c, tr = m._t0, m._traj
        else:
            t_c, tr = m._prev if m._prev is not None else (None, None)
        if tr is None or t_c is None or t_c > t_from:
            raise McusimError(f"{self.name}: supply accounting lost a motor segment")
        if tr.kind == "static":
            return          # stuck in discontinuous conduction: i ≡ 0, no charge
        if tr.kind != "chunk":
            raise McusimError(f"{self.name}: supply accounting expected a chunk of periods")
        q = self._chunk_charge(tr, t_c, now - t_c, sched, R, L, K) - \
            self._chunk_charge(tr, t_c, t_from - t_c, sched, R, L, K)
        self._q += q
        self.charge_total += q

    def _chunk_coeffs(self, tr, t_c, sched, R):
        anchor, P, pieces = sched
        ph = (t_c - anchor) % P
        # the piece the chunk starts in (at its start, or inside it: then the plan's last piece is
        # that piece's beginning, index j again)
        j = max(k for k, (o, _) in enumerate(pieces) if o <= ph)
        out = []
        for p, pc in enumerate(tr.plan.pieces):
            legs = pieces[(j + p) % len(pieces)][1]
            c, v, rbr = self._supply_coeffs_for(legs, pc[6][0], pc[5])
            out.append((c, v, R + rbr))
        return out

    def _supply_coeffs_for(self, legs, es, drive):
        """:meth:`_supply_coeffs` with the voltage and R_br of the drive the plan was built with."""
        c = self._supply_coeffs(legs, es)[0]
        return c, (drive[1] if es is not None and es < 0 else drive[0]), drive[2]

    def _chunk_charge(self, tr, t_c, n, sched, R, L, K):
        """Charge from the chunk's start to ``n`` ticks into it."""
        if n <= 0:
            return 0.0
        plan = tr.plan
        P, inv, Q = plan.P, self._inv_hz, plan.Q
        coef = self._chunk_coeffs(tr, t_c, sched, R)
        k, r = divmod(n, P)
        total = 0.0
        if k:
            s = tr.X[:k].sum(axis=0)
            for p, (c, v, rt) in enumerate(coef):
                if c:
                    d = (Q[p + 1] - Q[p]) @ s
                    total += c * (v * plan.pieces[p][0] * k * inv - L * d[0] - K * d[2]) / rt
        if r:
            Xk = tr.X[k]
            for p, (c, v, rt) in enumerate(coef):
                st = plan.starts[p]
                if st >= r:
                    break
                if not c:
                    continue
                xs = Xk + Q[p] @ Xk          # Q: delta maps (periodmap)
                end = st + plan.pieces[p][0]
                if end <= r:
                    i1 = (Xk + Q[p + 1] @ Xk)[0]
                else:
                    end = r
                    i1 = tr.at(k * P + r)[0]
                # the angle turned from the angles turned since the chunk start (an absolute
                # angle's difference loses its rounding at the angle's scale: Bts7960Bridge._turned)
                dth = self._turned(tr, 0, k * P + st, k * P + end)
                total += c * (v * (end - st) * inv - L * (i1 - xs[0]) - K * dth) / rt
        return float(total)
