"""Skid-steer (or differential-drive) rover body coupled to its wheel motors (docs/plants.md
§1.4 "Vehicle", §1.5; kinematics after Mandow et al. 2007, turning resistance after Wong).

Frame (REP 103, as the controller firmware's kinematics, ``firmware/openrover_rcm/kinematics.py``): x forward, y to the left, yaw
counter-clockwise positive. Wheel i belongs to side ``sides[i]`` ("L"/"R"); ``directions[i]``
(+1 default, −1 for a mirrored motor) maps the motor's output rotation to forward wheel rotation.

Model (a documented approximation; values without a source are [I]):

1. **Inertia, per wheel.** Each wheel motor carries its share of the vehicle as output-shaft
   inertia: ``load_inertia = (mass/n)·r² + ½·wheel_mass·r²`` (mass: whole vehicle, translating;
   wheel_mass: a solid-disc wheel spinning), set on every motor at construction, *overriding* the
   motor's preset value (which is the same number for the default 50 kg / 4 wheels / 2 kg /
   0.195 m: docs/plants.md §1.4). The body has no state of its own: its motion follows the wheels.
2. **Kinematics** (ICR model of Mandow et al. 2007, "Experimental kinematics for skid-steer mobile
   robots", IROS, symmetric case): with ω̄_L, ω̄_R the mean forward output speeds of a side's wheels,
   ``v = r·(ω̄_L + ω̄_R)/2`` and ``ω_z = r·(ω̄_R − ω̄_L)/(χ·track)``. χ ≥ 1 is the ICR expansion
   factor (χ = 1: ideal differential drive). χ = 1.5 [S/I: the order Mandow et al. report for a
   four-wheel skid-steer robot on hard ground; not re-read here; it depends on the surface and the
   load distribution, and the firmware's own kinematics takes it as a parameter too].
3. **Turning resistance** (Wong, "Theory of Ground Vehicles", skid-steering: lateral resistance
   moment of a uniformly loaded track of contact length l, ``M_r = μ_t·W·l/4``), with l = wheelbase:
   ``M_r = mu_turn·m·g·wheelbase/4`` opposing the yaw rate, through a smooth sign
   ``tanh(ω_z/ω_ε)`` with ω_ε = ``yaw_rate_eps`` = 0.05 rad/s (≈ 3 °/s: below it the resistance
   fades out linearly, so it does not chatter at zero yaw rate). For four point contacts at
   ±wheelbase/2 all sliding sideways the moment would be μ·m·g·wheelbase/2: mu_turn is an effective
   coefficient, 0.5 [I] (i.e. a lateral tyre friction of ≈ 0.25 in the point-contact picture;
   rubber on concrete is higher, but during a skid turn the tyres also slip longitudinally, which
   takes part of the friction budget). The moment is balanced by the longitudinal wheel forces at
   ±track/2 (moment balance about the centre, Wong): every wheel carries ``f = 2·M_r/(n·track)``,
   applied as an output-shaft load torque ``r·f``, *against* forward rotation on the right wheels
   and *with* it on the left wheels for ω_z > 0 (a left turn has to push the right side forward
   and hold the left side back). The wheels thus supply χ·M_r·ω_z of power in a turn: M_r·ω_z for
   the lateral sliding and (χ−1)·M_r·ω_z for the longitudinal slip the ICR expansion implies.
4. **Rolling resistance** ``crr·m·g/n`` per wheel (Crr 0.03, docs/plants.md §1.4 [I]), against the
   wheel's rotation through ``tanh(r·ω_i/v_ε)`` with v_ε = ``speed_eps`` = 0.01 m/s.
5. **Coupling in time.** The load torques are recomputed every ``step`` (1 ms, a ``PRIO_PLANT``
   kernel event) from the wheel speeds at that instant and held constant in between (applied with
   :meth:`DcMotor.set_load_by`: the body owns the load, and anyone else's ``set_params`` of it is
   refused), so each motor stays exact between events with a constant load). The smooth signs
   make the held loads behave like a damper near zero speed; with the vehicle share (m/n)·r² as the wheel inertia (the rotor and the wheel disc only add to it) the
   damper's time constant is η·v_ε/(crr·g) = 27 ms (rolling) and η·χ·track²·ω_ε/(mu_turn·g·wheelbase)
   = 8.2 ms (turning) with the defaults (η: the motors drive these loads through the gearbox, so they
   reach the motor divided by η, a stiffer damper; the wheel disc only lengthens them), against
   the 1 ms hold: the explicit hold is stable and accurate (checked at construction: the step must
   stay below half of either time constant).
6. **Pose.** Integrated at every step from the exact change of the wheel output angles over the
   step: ``Δs = r·(Δφ̄_L + Δφ̄_R)/2``, ``Δψ = r·(Δφ̄_R − Δφ̄_L)/(χ·track)``, with the exact arc for
   constant curvature within the step (chord ``Δs·sinc(Δψ/2)`` along ψ + Δψ/2). The pose is exact
   when v and ω_z keep their ratio within a step (a straight run, a spot turn, any steady arc);
   otherwise the arc assumption errs by O(Δs·ΔΔψ) per step (µm at rover speeds).
   :meth:`pose_at_now` adds the partial step since the last step event.

Limitations:

- **Yaw inertia.** Splitting the mass over the wheels gives the body a yaw inertia of
  ``m·(χ·track/2)²`` (the kinetic energy of the wheel shares in a spot turn): 8.5 kg·m² with the
  defaults, against ``yaw_inertia`` (default: the m(L² + B²)/12 of a uniform rectangle of
  wheelbase × track, 2.1 kg·m²). Yaw accelerations are therefore ≈ 4× slower than the rigid body's
  (``yaw_inertia_ratio``); steady turning rates are unaffected (they are kinematic). Fixing it needs
  an inertia coupling between the wheel motors (one state vector for all of them), which the
  per-motor exact segments do not have.
- The wheels of one side are not tied to each other: each follows its own motor and load. The
  kinematics uses the side mean; ``slip`` reports the spread within each side. With a velocity loop
  per wheel (the OpenRover motor modules) the spread stays small.
- Flat ground, no load transfer, no traction limit (a wheel never spins out), no lateral slip of
  the body (its velocity is along x), and the smooth signs let the body creep under a yaw or
  rolling torque below the static friction (the motors' own stiction still holds them).
"""

from __future__ import annotations

import math

from ..errors import ConfigError, McusimError
from ..kernel import PRIO_PLANT

__all__ = ["G", "RoverBody", "wrap_angle"]

G = 9.80665            # standard gravity, m/s²


def wrap_angle(a: float) -> float:
    """``a`` wrapped to (−π, π]."""
    w = math.remainder(a, 2.0 * math.pi)
    return math.pi if w == -math.pi else w


def _sinc(u: float) -> float:
    if abs(u) < 1e-4:
        return 1.0 - u * u / 6.0
    return math.sin(u) / u


def _arc(x, y, psi, ds, dpsi):
    """Pose after a constant-curvature move of arc length ds and heading change dpsi."""
    half = 0.5 * dpsi
    c = ds * _sinc(half)
    a = psi + half
    return x + c * math.cos(a), y + c * math.sin(a), psi + dpsi


class RoverBody:
    """``RoverBody(kernel, name="body", *, motors, sides, wheel_diameter=0.39, track=0.55,
    wheelbase=0.45, mass=50.0, wheel_mass=2.0, yaw_inertia=None, chi=1.5, mu_turn=0.5, crr=0.03,
    step="1ms", directions=None, yaw_rate_eps=0.05, speed_eps=0.01, x=0.0, y=0.0, yaw=0.0)``.

    ``motors``: the wheel :class:`~mcusim.plant.dcmotor.DcMotor` s (4 for the skid-steer rover, 2
    for a differential robot); ``sides``: "L"/"R" per motor (a list, or a string such as "LRLR").
    The body owns the motors' ``load_inertia`` and ``load_torque`` (see the module).

    Observers: ``pose`` (x, y, yaw ∈ (−π, π]) at the last step, :meth:`pose_at_now` (exact now),
    ``yaw_unwrapped``, ``velocity`` ((v, ω_z) now), ``distance`` (path length at the last step, m),
    ``slip`` (dict), ``wheel_loads`` (output-shaft load torques last applied, N·m),
    ``yaw_inertia``, ``yaw_inertia_implied``, ``yaw_inertia_ratio``, ``turn_moment`` (M_r, N·m),
    ``steps``.
    """

    def __init__(self, kernel, name: str = "body", *, motors, sides, wheel_diameter=0.39, track=0.55,
                 wheelbase=0.45, mass=50.0, wheel_mass=2.0, yaw_inertia=None, chi=1.5, mu_turn=0.5,
                 crr=0.03, step="1ms", directions=None, yaw_rate_eps=0.05, speed_eps=0.01,
                 x=0.0, y=0.0, yaw=0.0):
        self.kernel, self.name = kernel, name
        who = f"rover body {name}"

        def num(key, value, positive=True):
            try:
                v = float(value)
            except (TypeError, ValueError):
                raise ConfigError(f"{who}: {key} = {value!r} is not a number") from None
            if not math.isfinite(v) or (v <= 0 if positive else v < 0):
                raise ConfigError(f"{who}: {key} = {value!r} must be {'positive' if positive else '>= 0'}")
            return v

        motors = list(motors) if isinstance(motors, (list, tuple)) else [motors]
        sides = [str(s).upper() for s in (list(sides) if not isinstance(sides, str) else sides)]
        if len(motors) < 2 or len(sides) != len(motors):
            raise ConfigError(f"{who}: needs at least 2 motors and one side per motor "
                              f"(got {len(motors)} motors, {len(sides)} sides)")
        for mot in motors:
            if not all(hasattr(mot, a) for a in ("output_angle", "output_speed", "set_params",
                                                  "apply_load_torque")):
                raise ConfigError(f"{who}: {getattr(mot, 'name', mot)!r} is not a wheel motor")
        twice = next((m for i, m in enumerate(motors) if any(m is n for n in motors[:i])), None)
        if twice is not None:
            raise ConfigError(f"{who}: motor {getattr(twice, 'name', twice)!r} is listed twice (each wheel "
                              f"has its own motor: the body sets each one's load)")
        if any(s not in ("L", "R") for s in sides) or "L" not in sides or "R" not in sides:
            raise ConfigError(f"{who}: sides = {sides!r}: each must be 'L' or 'R', with both sides present")
        if directions is None:
            directions = [1] * len(motors)
        directions = list(directions)
        if len(directions) != len(motors) or any(d not in (1, -1) for d in directions):
            raise ConfigError(f"{who}: directions = {directions!r}: one +1 or -1 per motor")
        self.motors, self.sides, self.directions = motors, sides, [float(d) for d in directions]
        self.n = n = len(motors)
        self.r = 0.5 * num("wheel_diameter", wheel_diameter)
        self.track = num("track", track)
        self.wheelbase = num("wheelbase", wheelbase)
        self.mass = num("mass", mass)
        self.wheel_mass = num("wheel_mass", wheel_mass, positive=False)
        self.chi = num("chi", chi)
        if self.chi < 1.0:
            raise ConfigError(f"{who}: chi = {chi!r} must be >= 1 (1: ideal differential drive)")
        self.mu_turn = num("mu_turn", mu_turn, positive=False)
        self.crr = num("crr", crr, positive=False)
        self.yaw_rate_eps = num("yaw_rate_eps", yaw_rate_eps)
        self.speed_eps = num("speed_eps", speed_eps)
        try:
            self.step_ticks = kernel.timebase.ticks(step)
        except McusimError as exc:
            raise ConfigError(f"{who}: step = {step!r}: {exc}") from None
        if self.step_ticks <= 0:
            raise ConfigError(f"{who}: step = {step!r} must be positive")
        self.step_s = self.step_ticks / kernel.timebase.base_hz

        r, m = self.r, self.mass
        self.yaw_inertia = (num("yaw_inertia", yaw_inertia) if yaw_inertia is not None
                            else m * (self.wheelbase ** 2 + self.track ** 2) / 12.0)
        self.yaw_inertia_implied = m * (0.5 * self.chi * self.track) ** 2
        self.yaw_inertia_ratio = self.yaw_inertia_implied / self.yaw_inertia
        self.turn_moment = self.mu_turn * m * G * self.wheelbase / 4.0        # M_r, N·m
        self._f_turn = 2.0 * self.turn_moment / (n * self.track)             # per wheel, N
        self._f_roll = self.crr * m * G / n                                   # per wheel, N
        # explicit-hold check (module note 5), with the vehicle share as the least wheel inertia and
        # the least gearbox efficiency: the motors drive these loads, which reach them divided by η
        eta = min((mot.params.efficiency for mot in motors), default=1.0)
        tau_roll = eta * self.speed_eps / (self.crr * G) if self.crr > 0 else math.inf
        tau_yaw = (eta * self.chi * self.track ** 2 * self.yaw_rate_eps / (self.mu_turn * G * self.wheelbase)
                   if self.mu_turn > 0 else math.inf)
        self.hold_time_constants = (tau_roll, tau_yaw)
        if self.step_s > 0.5 * min(tau_roll, tau_yaw):
            raise ConfigError(f"{who}: step {self.step_s * 1e3:g} ms is too long for the smooth-sign "
                              f"time constants {tau_roll * 1e3:.3g} ms (rolling) / {tau_yaw * 1e3:.3g} ms "
                              f"(turning): shorten step or raise speed_eps / yaw_rate_eps")
        for mot in motors:      # the body sets their loads: a second setter would be overwritten
            owner = getattr(mot, "load_owner", None)
            if owner is not None and owner is not self:
                raise ConfigError(f"{who}: motor {getattr(mot, 'name', mot)!r} is a wheel of "
                                  f"{getattr(owner, 'name', owner)} already")
        for mot in motors:
            if hasattr(mot, "set_load_by"):
                mot.load_owner = self
        self._setters = [self._setter(mot) for mot in motors]
        self.wheel_inertia = (m / n) * r * r + 0.5 * self.wheel_mass * r * r
        self._iL = [k for k, s in enumerate(sides) if s == "L"]
        self._iR = [k for k, s in enumerate(sides) if s == "R"]
        self._sgn = [1.0 if s == "R" else -1.0 for s in sides]
        for set_load in self._setters:
            set_load(load_inertia=self.wheel_inertia)

        self._x, self._y, self._psi = float(x), float(y), float(yaw)
        self.distance = 0.0
        self.steps = 0
        self._phi = self._angles()
        self.wheel_loads = [0.0] * n
        self._apply_loads(self._speeds())
        self._ev = kernel.after(self.step_ticks, self._step, prio=PRIO_PLANT)

    def _setter(self, mot):
        """How the body sets a wheel's load: as its owner (a DcMotor), else through set_params."""
        by = getattr(mot, "set_load_by", None)
        if by is not None:
            return lambda **loads: by(self, **loads)
        return lambda **loads: (mot.apply_load_torque(loads["load_torque"]) if "load_torque" in loads
                                else mot.set_params(**loads))

    # ---- wheel readings ----------------------------------------------------------------------------
    def _angles(self):
        return [d * mot.output_angle for d, mot in zip(self.directions, self.motors, strict=True)]

    def _speeds(self):
        return [d * mot.output_speed for d, mot in zip(self.directions, self.motors, strict=True)]

    def _sides(self, vals):
        sl = sum(vals[k] for k in self._iL) / len(self._iL)
        sr = sum(vals[k] for k in self._iR) / len(self._iR)
        return sl, sr

    def _move(self, dphi):
        """(Δs, Δψ) of the body for wheel angle changes ``dphi``."""
        dl, dr = self._sides(dphi)
        return self.r * 0.5 * (dl + dr), self.r * (dr - dl) / (self.chi * self.track)

    # ---- the step ----------------------------------------------------------------------------------
    def _step(self):
        phi = self._angles()
        ds, dpsi = self._move([a - b for a, b in zip(phi, self._phi, strict=True)])
        self._x, self._y, self._psi = _arc(self._x, self._y, self._psi, ds, dpsi)
        self.distance += abs(ds)
        self._phi = phi
        self.steps += 1
        self._apply_loads(self._speeds())
        self._ev = self.kernel.after(self.step_ticks, self._step, prio=PRIO_PLANT)

    def _apply_loads(self, w):
        r = self.r
        wl, wr = self._sides(w)
        wz = r * (wr - wl) / (self.chi * self.track)
        turn = self._f_turn * math.tanh(wz / self.yaw_rate_eps)
        k_roll = r / self.speed_eps
        for k, mot in enumerate(self.motors):
            tau = r * (self._f_roll * math.tanh(k_roll * w[k]) + self._sgn[k] * turn)   # wheel frame
            tau_m = self.directions[k] * tau
            if tau_m == 0.0:
                tau_m = 0.0                    # no −0.0
            self.wheel_loads[k] = tau_m
            if tau_m != mot.params.load_torque:
                self._setters[k](load_torque=tau_m)

    # ---- observers ---------------------------------------------------------------------------------
    @property
    def pose(self):
        """(x, y, yaw) at the last step event, yaw wrapped to (−π, π]."""
        return self._x, self._y, wrap_angle(self._psi)

    @property
    def yaw_unwrapped(self) -> float:
        return self._psi

    def pose_at_now(self):
        """(x, y, yaw) now: the last step's pose plus the exact wheel motion since (one arc)."""
        phi = self._angles()
        ds, dpsi = self._move([a - b for a, b in zip(phi, self._phi, strict=True)])
        x, y, psi = _arc(self._x, self._y, self._psi, ds, dpsi)
        return x, y, wrap_angle(psi)

    @property
    def velocity(self):
        """(v, ω_z) now: m/s along the body x axis, rad/s counter-clockwise."""
        wl, wr = self._sides(self._speeds())
        return self.r * 0.5 * (wl + wr), self.r * (wr - wl) / (self.chi * self.track)

    @property
    def slip(self) -> dict:
        """Slip now: ``v_slip_L``/``v_slip_R`` (m/s): tread speed r·ω̄ minus the ground speed of the
        side's wheel line (v ∓ ω_z·track/2), the longitudinal slip the ICR expansion implies;
        ``spread_L``/``spread_R`` (m/s): max − min wheel surface speed within each side (the model
        does not tie a side's wheels together); ``chi``."""
        w = self._speeds()
        wl, wr = self._sides(w)
        r = self.r
        v = r * 0.5 * (wl + wr)
        wz = r * (wr - wl) / (self.chi * self.track)
        half = 0.5 * self.track * wz
        sp_l = [r * w[k] for k in self._iL]
        sp_r = [r * w[k] for k in self._iR]
        return {"chi": self.chi, "v_slip_L": r * wl - (v - half), "v_slip_R": r * wr - (v + half),
                "spread_L": max(sp_l) - min(sp_l), "spread_R": max(sp_r) - min(sp_r)}

    def summary_entries(self) -> dict:
        x, y, yaw = self.pose_at_now()
        return {"pose": {"x": round(x, 6), "y": round(y, 6), "yaw": round(yaw, 6)},
                "distance": round(self.distance, 6)}

    def __repr__(self):
        x, y, yaw = self.pose
        return f"RoverBody({self.name}: x={x:.4f} m, y={y:.4f} m, yaw={math.degrees(yaw):.2f}°)"
