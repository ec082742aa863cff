"""Brushed DC motor + gearbox + load, simulated exactly between events (ARCHITECTURE invariant 4).

Physics (docs/plants.md §1.1), all on the motor shaft::

    L·di/dt   = v_m − R·i − K·ω
    J_eq·dω/dt = K·i − b·ω − τc·sgn ω − τ_L,m          J_eq = J + load_inertia/N²
    dθ/dt     = ω

- ``load_torque`` τ_out acts on the output shaft *against positive rotation*. Reflected to the
  motor it is ``τ_out/(N·η)`` when the motor drives the load (τ_out opposes the motion) and
  ``τ_out·η/N`` when the load back-drives the motor. [I] The direction is taken from the sign of
  the motion (or, when stuck, of the candidate breakaway direction), not from the sign of the
  gear-mesh torque, so it is constant within a segment and needs no extra event.
- Stiction: at ω = 0 the shaft sticks while ``−τs ≤ K·i − τ_L,m ≤ τs`` (with the τ_L,m of each
  candidate direction) and breaks away when that is exceeded. τs ≥ τc is required.
- The terminal voltage comes from a *driver* (an H-bridge, see :mod:`mcusim.plant.l6206`) as an
  affine law per current-sign domain: ``v_m = V⁺ − R_br·i`` for i > 0 and ``V⁻ − R_br·i`` for
  i < 0 (the two differ only when a leg conducts through a diode). At i = 0 in a diode state the
  clamp test of docs/plants.md §2.1 decides: grow positive if ``V⁺ − K·ω > 0``, negative if ``V⁻ − K·ω < 0``,
  otherwise discontinuous conduction (i ≡ 0, terminals float at E = K·ω). With no driver the
  terminals are open (i ≡ 0 forever).

Simulation: the motor is lazy. Its state is a segment (t0, x0, closed-form trajectory, mode);
reading ``current``/``speed``/``angle`` evaluates the closed form at ``kernel.now``. An input
change (the bridge calls :meth:`DcMotor.input_changed`) first advances to now, then picks the new
mode. Mode-ending and output events are *guards* (linear functions of (i, ω, θ)) located to the
first base tick at which they have fired (:func:`mcusim.plant.pwl.first_fire`): ω reaching 0,
stick breakaway, i reaching 0 in a diode state, DCM exit, plus the guards of registered
providers (bridge over-current, encoder thresholds). Each segment is screened over a horizon H
(``horizon``, 50 µs); the earliest guard gets one kernel event at its tick (``PRIO_PLANT``), or,
if none fires, a re-check event at now + H. The horizon doubles after each quiet re-check up to
``max_horizon`` and returns to ``horizon`` on any other event, so a steady or coasting motor
costs few events. At a guard event the state is projected where the physics says so (ω := 0 at
a zero-speed event, i := 0 at a current-zero event) and the mode is re-selected with the same
guard expressions, so location and re-test cannot disagree by a rounding error.

Cost per segment (pure Python scalar math, eigen-decomposition cached per loop resistance, the
steady state per (R_total, V, friction+load term)): one closed-form evaluation at the horizon
(two ``expm1``), ~6 flops per guard for the margin test, and ~2·log2(H in ticks) ≈ 30 evaluations
for each guard that is actually about to fire. Measured: ≈20 µs of host time per segment,
kernel included, for 20 kHz drive/brake PWM with an encoder attached (0.5 s simulated in 0.44 s).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, fields, replace

from ..errors import ConfigError
from ..kernel import PRIO_HW, PRIO_PLANT
from . import pwl
from .dcmotor_fast import CHUNK_MIN, FLOWS_MAX, PLANS_MAX, PeriodicDrive, SecondSight
from .presets import motor_preset

INF = math.inf

# driver state when nothing drives the terminals: no current can flow in either direction
OPEN_CIRCUIT = (-INF, INF, 0.0, True)


def _check_overrides(cls, overrides: dict, what: str):
    known = {f.name for f in fields(cls)}
    out = {}
    for key, value in overrides.items():
        if key not in known:
            raise ConfigError(f"{what}: unknown parameter {key!r} (known: {', '.join(sorted(known))})")
        try:
            out[key] = float(value)
        except (TypeError, ValueError):
            raise ConfigError(f"{what}: parameter {key} = {value!r} is not a number") from None
    return out


@dataclass(frozen=True)
class MotorParams:
    """Motor + gearbox + load. Defaults: Pololu 37D 12 V 30:1 with 64 CPR encoder (docs/plants.md §1.3)."""

    R: float = 2.18            # armature resistance, Ω
    L: float = 1.5e-3          # armature inductance, H
    K: float = 0.0110          # Ke = Kt, V·s/rad = N·m/A
    J: float = 5e-6            # rotor inertia, kg·m² (motor shaft)
    tau_c: float = 1.54e-3     # Coulomb friction, N·m (motor shaft)
    b: float = 6.3e-7          # viscous friction, N·m·s/rad (motor shaft)
    tau_s: float = 5.0e-3      # stiction (breakaway) torque, N·m (motor shaft)
    gear_ratio: float = 30.0   # N = ω_motor / ω_output
    efficiency: float = 0.78   # η (η₂ of docs/plants.md §1.3 for 30:1)
    load_inertia: float = 0.0  # kg·m² on the output shaft
    load_torque: float = 0.0   # N·m on the output shaft, against positive rotation

    def __post_init__(self):
        for name in ("R", "L", "K", "J", "gear_ratio"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"motor parameter {name} = {getattr(self, name)} must be positive")
        for name in ("tau_c", "b", "tau_s", "load_inertia"):
            if not getattr(self, name) >= 0:
                raise ConfigError(f"motor parameter {name} = {getattr(self, name)} must not be negative")
        if not 0 < self.efficiency <= 1:
            raise ConfigError(f"motor parameter efficiency = {self.efficiency} must be in (0, 1]")
        if self.tau_s < self.tau_c:
            raise ConfigError(f"motor parameter tau_s = {self.tau_s} must be >= tau_c = {self.tau_c}")
        if not math.isfinite(self.load_torque):
            raise ConfigError(f"motor parameter load_torque = {self.load_torque} must be finite")

    @classmethod
    def from_mapping(cls, mapping: dict, base: MotorParams | None = None) -> MotorParams:
        """Defaults (or ``base``) overridden by name; an unknown name raises :class:`ConfigError`."""
        return replace(base or cls(), **_check_overrides(cls, dict(mapping), "motor"))

    @property
    def J_eq(self) -> float:
        return self.J + self.load_inertia / self.gear_ratio ** 2

    def load_reflected(self, direction: int) -> float:
        """τ_L,m for motion (or breakaway) in ``direction`` (+1/−1)."""
        t = self.load_torque
        if t * direction > 0:       # the load opposes the motion: the motor drives it
            return t / (self.gear_ratio * self.efficiency)
        return t * self.efficiency / self.gear_ratio   # the load back-drives the motor


DEFAULT_MOTOR_PARAMS = MotorParams()


class DcMotor(PeriodicDrive):
    """A brushed DC motor with gearbox and load.

    ``DcMotor(kernel, name="motor1", params=None, current=0.0, speed=0.0, angle=0.0,
    horizon=50e-6, max_horizon=5e-3, preset=None, **overrides)`` where ``overrides`` are
    :class:`MotorParams` names (``R, L, K, J, tau_c, b, tau_s, gear_ratio, efficiency, load_inertia,
    load_torque``). ``preset`` names a set of :mod:`mcusim.plant.presets` (e.g.
    ``"openrover-100w-50"``) used as the base under ``params`` (a dict) and ``overrides``.

    Observers (evaluated at ``kernel.now``): ``current`` (A), ``speed`` (motor shaft rad/s),
    ``angle`` (motor shaft rad), ``output_angle``/``output_speed`` (θ/N, ω/N), ``peak_current``,
    ``stuck``, ``conducting``, ``mode``; ``state_at(tick)`` for a tick in the current or previous
    segment.

    Drivers and guard providers: a driver (one per motor) implements ``drive_state() ->
    (V⁺, V⁻, R_br, has_diode)`` and calls :meth:`input_changed` when that may have changed; it is
    attached with :meth:`attach_driver`. A guard provider implements ``plant_guards()`` returning
    guard tuples ``(ci, cw, cθ, c0, strict, provider, tag)`` — fired when ``ci·i + cw·ω + cθ·θ + c0``
    is < 0 (strict) or <= 0 — and ``on_guard(tag)``, called at the located tick with the motor
    already advanced to it; it is registered with :meth:`add_guard_provider` and must call
    :meth:`input_changed` whenever its guards change outside ``on_guard``.
    """

    def __init__(self, kernel, name: str = "motor1", params: MotorParams | dict | None = None, *,
                 current: float = 0.0, speed: float = 0.0, angle: float = 0.0,
                 horizon: float = 50e-6, max_horizon: float = 5e-3, preset: str | None = None,
                 **overrides):
        self.kernel = kernel
        self.name = name
        base = None
        if preset is not None:      # named set (mcusim.plant.presets) under params and overrides
            if isinstance(params, MotorParams):
                raise ConfigError(f"{name}: give either preset={preset!r} or a MotorParams, not both")
            base = MotorParams.from_mapping(motor_preset(preset))
        if isinstance(params, dict):
            params = MotorParams.from_mapping(params, base=base)
        elif params is None:
            params = base
        self.params = MotorParams.from_mapping(overrides, base=params)
        self._fs = kernel.timebase.base_hz
        self._inv_hz = 1.0 / self._fs
        self._h0 = max(1, round(float(horizon) * self._fs))
        self._hmax = max(self._h0, round(float(max_horizon) * self._fs))
        self._h = self._h0
        self._grow = False
        self._driver = None
        self._providers = []
        self._busy = False
        self._ev = None
        self._pending = None
        self._pending_time = None
        self._t0 = kernel.now
        self._x0 = (float(current), float(speed), float(angle))
        # the accumulated angle is x0[2] + _th_lo: _th_lo, below x0[2]'s last places, is the
        # rounding error of the angle added segment after segment (_advance), which would otherwise
        # grow as a random walk with the run and part the two engines' angles (and the ticks of
        # the encoder edges) on long runs; every segment built from x0 includes it in the angles
        # it gives after its start (``lo``), so the next re-base takes exactly what it gave
        self._th_lo = 0.0
        self._traj = None
        self._memo = (None, 0, None)   # (segment, tick offset, state) of the last observation
        self._prev = None          # (t0, traj) of the previous segment, for state_at()
        self._hist = deque()       # older (t0, traj), kept while within history_ticks (need_history)
        self.history_ticks = 0
        self._es = 0               # electrical sign domain: None (no diode), +1, −1, 0 (DCM)
        self._s = 0                # mechanical: +1, −1, 0 (stuck)
        self._peak = abs(self._x0[0])
        self.segments = 0          # segments built (a cost counter)
        self.chunk_ticks = 0       # fast engine: simulated ticks covered by whole-period chunks
        self._fast = bool(getattr(kernel, "fast", False))
        self._eig_cache = {}       # per (R_total, L, K, J_eq, b): kept when only an input changes
        self._full_cache = {}
        # fast engine: PeriodPlan per (schedule, first piece, modes, params), a piece's delta map
        # per (drive, mode, ticks, params)
        self._plans = SecondSight(PLANS_MAX)
        self._flows = SecondSight(FLOWS_MAX)
        self._guard_arrays = {}      # fast engine: the plans' stacked guard arrays (PeriodPlan.guard_cache)
        self._linear_parts = {}      # fast engine: powers and modes by period-map linear part (PeriodPlan.linear_cache)
        self._chunk_n = CHUNK_MIN
        self._chunk_retry = -1
        self._stale = False        # fast engine: inputs changed at this tick, rebuild due
        # fast engine: the tick whose drive edge the next rebuild stands for (a piece's end, or a
        # change made before that tick's hardware events, which edge by edge the edge then sees);
        # a bridge checks its switches' limits there only (Bts7960Bridge)
        self.edge_tick = None
        self._due = []             # fast engine: encoders with a crossing due now (fire_due at an advance)
        self._rebuild_ev = None
        self._ev_passive = None    # fast engine: next passive guard (encoder threshold) in a segment
        self._passive = ()
        self._passive_hint = None    # fast engine: a tick the next encoder crossing may be at
        self._seg_end = 0
        self._set_params(self.params)
        self._sync()

    # ---- configuration ---------------------------------------------------------------------------
    def _set_params(self, p: MotorParams):
        self.params = p
        self._J = p.J_eq
        self._tlp = p.load_reflected(+1)
        self._tln = p.load_reflected(-1)
        # every parameter a segment, a piece flow or a guard depends on besides R (keys of the caches)
        self._pkey = (p.L, p.K, self._J, p.b, p.tau_c, p.tau_s, self._tlp, self._tln)

    #: the part that sets this motor's load (a rover body, every step), or None; nobody else may
    load_owner = None
    _OWNED = ("load_torque", "load_inertia")

    def set_params(self, **overrides) -> None:
        """Change parameters at run time (advances to now first). Unknown names raise ConfigError,
        and so does the load of a motor whose load a part owns (``load_owner``: a rover body
        would overwrite it at its next step)."""
        owned = [k for k in self._OWNED if k in overrides]
        if owned and self.load_owner is not None:
            raise ConfigError(f"{self.name}.{owned[0]}: {self.owned_load_reason()}")
        self._apply_params(overrides)

    def owned_load_reason(self) -> str:
        """Why this motor's load may not be set (its ``load_owner`` sets it), for a message."""
        who = getattr(self.load_owner, "name", self.load_owner)
        return (f"this wheel's load comes from {who} (the rover body sets it from the vehicle's motion at "
                "every step); change the body's parameters (mass, crr, mu_turn ...) instead")

    def _apply_params(self, overrides) -> None:
        new = MotorParams.from_mapping(overrides, base=self.params)
        self._change(lambda: self._set_params(new))

    def set_load_by(self, owner, **loads) -> None:
        """The load (``load_torque``, ``load_inertia``) set by the part that owns it, which
        claims the motor first (``load_owner``)."""
        if owner is not self.load_owner or set(loads) - set(self._OWNED):
            raise ConfigError(f"{self.name}: set_load_by from {getattr(owner, 'name', owner)}, which does not "
                              f"own its load, or with other keys than {', '.join(self._OWNED)}")
        self._apply_params(loads)

    def apply_load_torque(self, tau_out: float) -> None:
        """Set the output-shaft load torque (N·m, against positive rotation) from now on."""
        self.set_params(load_torque=tau_out)

    def set_state(self, current: float | None = None, speed: float | None = None,
                  angle: float | None = None) -> None:
        """Overwrite the state at now (test and scenario set-up)."""
        def do():
            i, w, th = self._x0
            self._x0 = (i if current is None else float(current), w if speed is None else float(speed),
                        th if angle is None else float(angle))
            if angle is not None:
                self._th_lo = 0.0
            self._peak = max(self._peak, abs(self._x0[0]))
        for prov in self._providers:    # a jump of the state: whoever reads it lazily settles first
            before = getattr(prov, "before_jump", None)
            if before is not None:
                before()
        self._change(do)

    def attach_driver(self, driver) -> None:
        if self._driver is not None and self._driver is not driver:
            raise ConfigError(f"{self.name}: already driven by {getattr(self._driver, 'name', self._driver)}")
        self._change(lambda: setattr(self, "_driver", driver))

    def add_guard_provider(self, provider) -> None:
        self._change(lambda: self._providers.append(provider))

    def _change(self, fn):
        if self._busy:
            fn()
            return
        self._busy = True
        try:
            self._advance()
            fn()
            self._grow = False
            if self._fast:
                if self.kernel.early_in_tick(PRIO_HW):
                    self.edge_tick = self.kernel.now
                self._defer_rebuild()
            else:
                self._rebuild()
        finally:
            self._busy = False

    def _defer_rebuild(self) -> None:
        """Fast engine: inputs often change several times in one tick (the rover's battery and body
        steps both land on each millisecond), so the segment is rebuilt once, after the plant's
        events of this tick, from the same state and inputs the edge-by-edge engine's last rebuild
        uses. Until then the state at this tick is the x0 the old segment gives at it."""
        self._stale = True
        if self._rebuild_ev is None:
            self._rebuild_ev = self.kernel.at(self.kernel.now, self._rebuild_due, prio=PRIO_PLANT + 1)

    def _rebuild_due(self) -> None:
        self._rebuild_ev = None
        if self._stale:
            self._sync()

    # ---- observers -------------------------------------------------------------------------------
    def _now_state(self):
        n = self.kernel.now - self._t0
        tr = self._traj
        if n == 0 or tr is None:
            return self._x0
        memo = self._memo     # several observers read one tick (angle and current for a trace)
        if memo[0] is tr and memo[1] == n:
            return memo[2]
        x = self._at(tr, n)
        self._memo = (tr, n, x)
        return x

    def state_at(self, tick: int):
        """(i, ω, θ) at ``tick``, which must lie in the current or the previous segment (≤ now)."""
        if tick > self.kernel.now:
            raise ValueError(f"state_at({tick}) is in the future (now {self.kernel.now})")
        if tick >= self._t0:
            n = tick - self._t0
            return self._x0 if (n == 0 or self._traj is None) else self._at(self._traj, n)
        if self._prev is not None and tick >= self._prev[0]:
            t0, tr = self._prev
            return self._at(tr, tick - t0)
        for t0, tr in reversed(self._hist):
            if tick >= t0:
                return self._at(tr, tick - t0)
        raise ValueError(f"state_at({tick}) is before the segments kept (history_ticks {self.history_ticks})")

    def need_history(self, ticks: int) -> None:
        """Keep the segments of at least the last ``ticks`` ticks for :meth:`state_at` (a lazy
        reader of the encoder, :mod:`mcusim.plant.encoder`, looks back through the input filter)."""
        self.history_ticks = max(self.history_ticks, int(ticks))

    def passive_changed(self) -> None:
        """Fast engine: a passive provider's guards changed outside ``on_guard`` (an encoder going
        from lazy to edge-by-edge counting): locate them again on the current trajectory."""
        if self._busy or self._traj is None:
            return          # the running rebuild asks for them
        if self._ev_passive is not None:
            self._ev_passive.cancel()
            self._ev_passive = None
        if self._pending is not None:
            self._pending = [g for g in self._pending if not getattr(g[5], "passive_guards", False)] or None
        self._find_passive()

    @property
    def current(self) -> float:
        return self._now_state()[0]

    @property
    def speed(self) -> float:
        return self._now_state()[1]

    @property
    def angle(self) -> float:
        return self._now_state()[2]

    @property
    def output_angle(self) -> float:
        return self._now_state()[2] / self.params.gear_ratio

    @property
    def output_speed(self) -> float:
        return self._now_state()[1] / self.params.gear_ratio

    @property
    def peak_current(self) -> float:
        """Largest |i| so far: at every segment boundary and at the current extremum located
        inside each segment (real-eigenvalue case; complex case: boundaries only)."""
        n = self.kernel.now - self._t0
        if n and self._traj is not None:
            return max(self._peak, self._segment_peak(self._traj, n))
        return self._peak

    @property
    def fast_ticks(self) -> int:
        """Fast engine: simulated ticks this motor spent in whole-period chunks so far."""
        tr = self._traj
        return self.chunk_ticks + (self.kernel.now - self._t0 if tr is not None and tr.kind == "chunk" else 0)

    @property
    def stuck(self) -> bool:
        return self._s == 0

    @property
    def conducting(self) -> bool:
        return self._es != 0

    @property
    def mode(self) -> str:
        e = {None: "on", 1: "i>0", -1: "i<0", 0: "dcm"}[self._es]
        m = {1: "w>0", -1: "w<0", 0: "stuck"}[self._s]
        return f"{e},{m}"

    def _at(self, tr, n: int):
        """State n ticks into segment ``tr`` (a closed form, or a chunk of PWM periods)."""
        return tr.at(n) if tr.kind == "chunk" else tr.eval(n * self._inv_hz)

    def _segment_peak(self, tr, n: int):
        if tr.kind == "chunk":
            # the screening's bound of |i| over the chunk: nothing in it can raise the peak so far
            return 0.0 if self._peak >= tr.ibound else tr.peak(n)
        t = n * self._inv_hz
        x = tr.eval(t)
        p = abs(x[0])
        for te in tr.x1_extrema(t):
            p = max(p, abs(tr.eval(te)[0]))
        return p

    # ---- the segment engine ----------------------------------------------------------------------
    def input_changed(self) -> None:
        """A driver's output or a provider's guards changed at ``kernel.now``."""
        if self._busy:
            return  # the running advance/rebuild will pick the change up
        self._grow = False
        self._sync()

    def _on_event(self):
        self._ev = None
        self._grow = self._pending is None
        self._sync()

    def _sync(self):
        if self._busy:
            return
        self._busy = True
        try:
            self._advance()
            self._rebuild()
        finally:
            self._busy = False

    def _advance(self):
        """Re-base the segment at now; run the guard handlers that are due at now."""
        now = self.kernel.now
        n = now - self._t0
        if n and self._traj is not None:
            tr = self._traj
            if tr.kind == "chunk":
                self.chunk_ticks += n
                self._chunk_lived(tr, n)
            self._peak = max(self._peak, self._segment_peak(tr, n))
            th0 = self._x0[2]
            self._x0 = x = self._at(tr, n)
            # θ: the state takes the angle the segment gives (what every reader saw at this tick);
            # _th_lo keeps what the accumulated angle (the angle so far plus the angle turned in
            # the segment, summed from small terms) holds beyond it
            d = tr.dtheta(n) if tr.kind == "chunk" else tr.dtheta(n * self._inv_hz)
            self._th_lo = (th0 - x[2]) + (d + self._th_lo)
            if self.history_ticks and self._prev is not None:
                hist = self._hist
                hist.append(self._prev)
                # an old segment is needed while it ends after now − history_ticks
                while len(hist) > 1 and hist[1][0] <= now - self.history_ticks:
                    hist.popleft()
                if self._t0 <= now - self.history_ticks:
                    hist.clear()
            self._prev = (self._t0, tr)
        self._t0 = now
        if self._pending is not None and self._pending_time == now:
            guards, self._pending = self._pending, None
            if self._ev is not None:
                self._ev.cancel()
                self._ev = None
            for g in guards:
                g[5].on_guard(g[6])
        if self._due:                           # a crossing a lazy encoder left due at this tick
            due, self._due = self._due, []
            for prov in due:
                prov.fire_due()
        ev = self._ev_passive
        if ev is not None and ev.time == now:   # an encoder threshold due at this very tick: an
            ev.cancel()                         # input change got here first; it still fires now
            self._ev_passive = None
            self._peak = max(self._peak, abs(self._x0[0]))
            for g in self._passive:
                g[5].on_guard(g[6])

    def on_guard(self, tag):
        i, w, th = self._x0
        if tag == "w0":
            self._x0 = (i, 0.0, th)
        elif tag == "i0":
            self._x0 = (0.0, w, th)
        # 'brk+', 'brk-', 'dcm+', 'dcm-': the mode re-selection sees it

    def _stick_guards(self):
        p = self.params
        return ((-p.K, 0.0, 0.0, p.tau_s + self._tlp, True, self, "brk+"),
                (p.K, 0.0, 0.0, p.tau_s - self._tln, True, self, "brk-"))

    def _dcm_guards(self, vp, vn):
        K = self.params.K
        out = []
        if math.isfinite(vp):
            out.append((0.0, K, 0.0, -vp, True, self, "dcm+"))
        if math.isfinite(vn):
            out.append((0.0, -K, 0.0, vn, True, self, "dcm-"))
        return out

    def _select(self, x, drive):
        vp, vn, _, diode = drive
        hval, fired = pwl.hval, pwl.fired
        i, w, _ = x
        if not diode:
            es = None
        elif i > 0.0:
            es = 1
        elif i < 0.0:
            es = -1
        else:
            es = 0
            for g in self._dcm_guards(vp, vn):
                if fired(g, hval(g, x)):
                    es = 1 if g[6] == "dcm+" else -1
                    break
        if w > 0.0:
            s = 1
        elif w < 0.0:
            s = -1
        else:
            s = 0
            for g in self._stick_guards():
                if fired(g, hval(g, x)):
                    s = 1 if g[6] == "brk+" else -1
                    break
        return es, s

    def _build(self, x0, drive, es, s):
        """The closed form from ``x0`` under ``drive`` in mode (es, s)."""
        if es == 0:
            p, J = self.params, self._J
            if s == 0:
                return pwl.static(x0)
            T = p.tau_c * s + (self._tlp if s > 0 else self._tln)
            return pwl.first_order_x2(-p.b / J, -T / J, x0)
        return self._piece_former(drive, es, s)(x0)

    def _drive_terms(self, drive, es, s):
        """(loop resistance, voltage, torque term) of mode (es, s) under ``drive``, not DCM (es != 0);
        the torque term is None when stuck (s = 0: only the current moves)."""
        p = self.params
        vp, vn, rbr, _ = drive
        T = None if s == 0 else p.tau_c * s + (self._tlp if s > 0 else self._tln)
        return p.R + rbr, vn if es == -1 else vp, T

    def _piece_former(self, drive, es, s):
        """``x0 -> closed form`` under ``drive`` in mode (es, s), not DCM, with the parameters of now
        resolved once. A fast-engine plan holds these for its pieces: a chunk builds its pieces when
        they are read, and a read of a tick in the previous segment (``state_at``) may come after a
        ``set_params``; it must see the parameters that segment ran with, as the reference engine's
        closed form does."""
        rt, v0, T = self._drive_terms(drive, es, s)
        if T is None:
            lam, i_ss = -rt / self.params.L, v0 / rt
            return lambda x0: pwl.first_order_x1(lam, i_ss, x0)
        system = self._full_system(rt, v0, T)[3]
        return lambda x0: pwl.affine2_from(system, x0)

    def _full_system(self, rt, v0, T):
        """(eig, A, u, affine2_system) of the full (i, ω) system for loop resistance rt, voltage v0,
        torque term T."""
        p, J = self.params, self._J
        key = (rt, v0, T, self._pkey)
        ent = self._full_cache.get(key)
        if ent is None:
            ekey = (rt, p.L, p.K, J, p.b)
            A = (-rt / p.L, -p.K / p.L, p.K / J, -p.b / J)
            eig = self._eig_cache.get(ekey)
            if eig is None:
                eig = self._eig_cache[ekey] = pwl.eig2(*A)
            if len(self._full_cache) > 256:
                self._full_cache.clear()
            u = (v0 / p.L, -T / J)
            ent = self._full_cache[key] = (eig, A, u, pwl.affine2_system(eig, A, u))
        return ent

    def _mode_guards(self, es, s, drive):
        """The motor's own guards in mode (es, s): i reaching 0, ω reaching 0, DCM exit, breakaway."""
        guards = []
        if es is not None and es != 0:
            guards.append((float(es), 0.0, 0.0, 0.0, False, self, "i0"))
        if s != 0:
            guards.append((0.0, float(s), 0.0, 0.0, False, self, "w0"))
            if es == 0:
                guards.extend(self._dcm_guards(drive[0], drive[1]))
        elif es != 0:
            guards.extend(self._stick_guards())
        return guards

    def _rebuild(self):
        self._stale = False
        if self._ev is not None:
            self._ev.cancel()
            self._ev = None
        # the tick of the next encoder crossing located on the old trajectory: where the new one's
        # is, nearly always (a guess that _find_passive checks, whatever its origin)
        self._passive_hint = None
        if self._ev_passive is not None:
            self._passive_hint = self._ev_passive.time
            self._ev_passive.cancel()
            self._ev_passive = None
        self._pending = None
        x0 = self._x0
        if self._fast and self._driver is not None and hasattr(self._driver, "drive_schedule"):
            sched = self._driver.drive_schedule()
            if sched is not None:
                self._rebuild_periodic(sched, x0)
                return
        if self._driver is None:
            drive = OPEN_CIRCUIT
            if x0[0] != 0.0:
                # open terminals carry no current (module docstring): a current given to the
                # state (the constructor's, set_state's) lasts this tick only, where a bridge that
                # attaches now still finds it; the segment runs from i = 0 (the open circuit's
                # infinite voltages would make a conducting one NaN)
                x0 = (0.0, x0[1], x0[2])
        else:
            drive = self._driver.drive_state()
        tr, es, s = self._new_segment(x0, drive)
        guards = [] if tr.kind == "static" else self._mode_guards(es, s, drive)
        for prov in self._providers:
            guards.extend(prov.plant_guards())
        if tr.kind == "static":
            # nothing moves: a provider guard can only be fired now or never
            return
        if not guards:
            return
        self._screen(tr, x0, guards)

    def _new_segment(self, x0, drive):
        """Select the mode at ``x0`` under ``drive`` and start its closed-form segment (the horizon
        doubles while segments end at it, else starts over)."""
        es, s = self._select(x0, drive)
        self._es, self._s = es, s
        tr = self._traj = self._build(x0, drive, es, s)
        if tr.b[2] or tr.c[2] or tr.d1[2] or tr.d2[2]:     # (a shaft at rest reports the angle it holds)
            tr.lo = self._th_lo
        self.segments += 1
        self._h = min(self._h * 2, self._hmax) if self._grow else self._h0
        self._grow = False
        return tr, es, s

    def _screen(self, tr, x0, guards, limit=None):
        """Locate the first guard to fire within the horizon (or ``limit`` ticks, the end of a
        periodic drive's piece, if sooner) and schedule its event, or the re-check/piece-end event."""
        inv = self._inv_hz
        H = self._h if limit is None else min(self._h, limit)
        cache = {0: x0}
        ev = tr.eval

        def state(n):
            x = cache.get(n)
            if x is None:
                x = cache[n] = ev(n * inv)
            return x

        passive = ()
        if self._fast:  # encoder thresholds: located after the others, without ending the segment
            passive = [g for g in guards if getattr(g[5], "passive_guards", False)]
            if passive:
                guards = [g for g in guards if not getattr(g[5], "passive_guards", False)]
        xH = state(H)
        m2 = tr.m2
        best = None
        firing = []
        hval = pwl.hval
        for g in guards:
            nb = H if best is None else best
            ha = hval(g, x0)
            hb = hval(g, xH if nb == H else state(nb))
            gm2 = abs(g[0]) * m2[0] + abs(g[1]) * m2[1] + abs(g[2]) * m2[2]
            n = pwl.first_fire(lambda k, g=g: hval(g, state(k)), gm2, 0, nb, ha, hb, g[4], inv)
            if n is None:
                continue
            if best is None or n < best:
                best, firing = n, [g]
            else:  # n == best
                firing.append(g)
        at_end = limit is not None and (H if best is None else best) == limit
        if best is None:
            if at_end:
                self._ev = self.kernel.at(self._t0 + H, self._on_piece_end, prio=PRIO_HW)
            else:
                self._ev = self.kernel.at(self._t0 + H, self._on_event, prio=PRIO_PLANT)
        else:
            self._pending, self._pending_time = firing, self._t0 + best
            # a guard firing on the piece's last tick: that event is the drive's edge too (a bridge
            # checks the switches turning on there, as after a piece end without a guard)
            self._ev = (self.kernel.at(self._t0 + best, self._on_piece_end, prio=PRIO_HW) if at_end else
                        self.kernel.at(self._t0 + best, self._on_event, prio=PRIO_PLANT))
        if passive:
            self._seg_end = H if best is None else best
            self._find_passive()

    def __repr__(self):
        i, w, th = self._now_state()
        return f"DcMotor({self.name}: i={i:.4g} A, ω={w:.4g} rad/s, θ={th:.4g} rad, {self.mode})"
