"""Wheel kinematics of the rover layouts that ``rover_control`` drives.

Conventions (all layouts):

* Body frame: x forward, y to the left, z up; yaw and ``wz`` are counter-clockwise positive (REP 103).
* Body velocity ``(vx, vy, wz)`` in m/s, m/s, rad/s. Wheel speeds in rad/s at the wheel (after the
  gearbox), as a tuple in the layout's wheel order.
* ``inverse(vx, vy, wz)`` maps a body velocity to wheel speeds, ``forward(wheel_speeds)`` maps wheel
  motion back to body motion. Both are linear, so ``forward`` applied to wheel angle changes (rad)
  gives the body displacement for a constant twist (used by the odometry).

Layouts and wheel order:

* ``differential``: (L, R). Positive wheel speed rolls the robot forward on both sides; the sign flip
  of the mirrored right motor belongs to the motor driver, not here.
* ``skid_steer``: (FL, FR, RL, RR), same sign convention. Symmetric ICR model of Mandow et al. 2007
  ("Experimental kinematics for skid-steer mobile robots", IROS) and Martinez et al. 2005: the
  effective track is ``chi * track_width`` with the ICR expansion factor ``chi >= 1``.
* ``omni``: one wheel per mounting angle ``theta_i`` (counter-clockwise from +x), at ``wheel_distance``
  from the centre, rolling direction tangential, positive speed drives the contact point towards
  ``(-sin theta_i, cos theta_i)`` (counter-clockwise about the centre).
* ``mecanum``: (FL, FR, RL, RR), 45 degree rollers, ``lx`` half wheelbase (along x), ``ly`` half
  track (along y). Lynch & Park, "Modern Robotics" (2017) section 13.2, eq. 13.10, whose wheel order
  is FL, FR, RR, RL; reordered here. Roller angle (MR's gamma) -45 deg on FL and RR, +45 deg on FR
  and RL, the common mounting: a pure +vy (strafe left) spins FL and RR backwards, FR and RL forwards.
"""

from __future__ import annotations

import math

KINDS = ("differential", "skid_steer", "omni", "mecanum")

# ElementAll rover (the OpenRover reference vehicle): 0.39 m diameter wheels, 1:50 gearmotors with
# 2048 encoder counts per motor turn read by the motor-control modules.
ELEMENTALL_WHEEL_RADIUS = 0.195
ELEMENTALL_COUNTS_PER_WHEEL_REV = 2048 * 50


def _positive(name, value):
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    return value


def _check_count(speeds, n):
    speeds = tuple(speeds)
    if len(speeds) != n:
        raise ValueError(f"expected {n} wheel speeds, got {len(speeds)}")
    return speeds


class Differential:
    kind = "differential"
    wheels = 2
    holonomic = False

    def __init__(self, wheel_radius, track_width):
        self.r = _positive("wheel_radius", wheel_radius)
        self.track_width = _positive("track_width", track_width)
        self.b_eff = self.track_width

    def inverse(self, vx, vy=0.0, wz=0.0):
        if vy != 0.0:
            raise ValueError(f"{self.kind} layout cannot move sideways (vy={vy!r} requested)")
        half = 0.5 * wz * self.b_eff
        return ((vx - half) / self.r, (vx + half) / self.r)

    def _sides(self, speeds):
        return _check_count(speeds, 2)

    def forward(self, wheel_speeds):
        w_l, w_r = self._sides(wheel_speeds)
        return (0.5 * self.r * (w_l + w_r), 0.0, self.r * (w_r - w_l) / self.b_eff)


class SkidSteer(Differential):
    kind = "skid_steer"
    wheels = 4

    def __init__(self, wheel_radius, track_width, chi=1.0):
        super().__init__(wheel_radius, track_width)
        try:
            chi = float(chi)
        except (TypeError, ValueError):
            raise ValueError(f"chi must be a number, got {chi!r}") from None
        if not (math.isfinite(chi) and chi >= 1.0):
            raise ValueError(f"chi (ICR expansion factor) must be finite and >= 1, got {chi!r}")
        self.chi = chi
        self.b_eff = chi * self.track_width

    def inverse(self, vx, vy=0.0, wz=0.0):
        w_l, w_r = super().inverse(vx, vy, wz)
        return (w_l, w_r, w_l, w_r)

    def _sides(self, speeds):
        fl, fr, rl, rr = _check_count(speeds, 4)
        return (0.5 * (fl + rl), 0.5 * (fr + rr))


def _gram(rows):
    n = len(rows)
    return [[sum(rows[k][i] * rows[k][j] for k in range(n)) for j in range(3)] for i in range(3)]


def _det3(a):
    return (a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
            - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]))


def _pinv(rows):
    """Least-squares pseudo-inverse (J^T J)^-1 J^T of an n x 3 matrix of full column rank.

    For a square J it is J^-1. Computed once per layout, as firmware would at configuration time.
    """
    a = _gram(rows)
    cof = [[a[(i + 1) % 3][(j + 1) % 3] * a[(i + 2) % 3][(j + 2) % 3]
            - a[(i + 1) % 3][(j + 2) % 3] * a[(i + 2) % 3][(j + 1) % 3] for j in range(3)] for i in range(3)]
    det = _det3(a)
    inv = [[cof[j][i] / det for j in range(3)] for i in range(3)]      # adjugate / det
    return [[sum(inv[i][j] * row[j] for j in range(3)) for row in rows] for i in range(3)]


class _MatrixLayout:
    holonomic = True

    def _set_matrix(self, rows):
        self.rows = [tuple(row) for row in rows]           # wheel speed = row . (vx, vy, wz)
        self.wheels = len(self.rows)
        self.pinv = [tuple(row) for row in _pinv(self.rows)]

    def inverse(self, vx, vy=0.0, wz=0.0):
        return tuple(a * vx + b * vy + c * wz for a, b, c in self.rows)

    def forward(self, wheel_speeds):
        w = _check_count(wheel_speeds, self.wheels)
        return tuple(sum(p * s for p, s in zip(row, w)) for row in self.pinv)


class Omni(_MatrixLayout):
    kind = "omni"

    def __init__(self, wheel_radius, wheel_distance, angles_deg=(90.0, 210.0, 330.0)):
        self.r = _positive("wheel_radius", wheel_radius)
        self.wheel_distance = _positive("wheel_distance", wheel_distance)
        try:
            angles = tuple(float(a) for a in angles_deg)
        except (TypeError, ValueError):
            raise ValueError(f"angles_deg must be a list of numbers, got {angles_deg!r}") from None
        if len(angles) < 3 or not all(math.isfinite(a) for a in angles):
            raise ValueError(f"angles_deg needs at least 3 finite mounting angles, got {angles_deg!r}")
        th = [math.radians(a) for a in angles]
        # Rank check on the unit-free matrix rows (-sin, cos, 1): for 3 wheels its determinant is
        # twice the area of the triangle of the wheel positions, zero only when two angles coincide.
        unit = [(-math.sin(t), math.cos(t), 1.0) for t in th]
        if _det3(_gram(unit)) <= 1e-9 * len(unit) ** 3:
            raise ValueError(f"angles_deg {angles_deg!r}: mounting angles coincide, the wheels cannot "
                             "produce every body velocity")
        self.angles_deg = angles
        lr = self.wheel_distance / self.r
        self._set_matrix([(-math.sin(t) / self.r, math.cos(t) / self.r, lr) for t in th])


class Mecanum(_MatrixLayout):
    kind = "mecanum"

    def __init__(self, wheel_radius, lx, ly):
        self.r = _positive("wheel_radius", wheel_radius)
        self.lx = _positive("lx", lx)
        self.ly = _positive("ly", ly)
        k = self.lx + self.ly
        r = self.r
        self._set_matrix([(1 / r, -1 / r, -k / r),     # FL
                          (1 / r, 1 / r, k / r),       # FR
                          (1 / r, 1 / r, -k / r),      # RL
                          (1 / r, -1 / r, k / r)])     # RR


_CLASSES = {"differential": Differential, "skid_steer": SkidSteer, "omni": Omni, "mecanum": Mecanum}
_PARAMS = {"differential": ("wheel_radius", "track_width"),
           "skid_steer": ("wheel_radius", "track_width", "chi"),
           "omni": ("wheel_radius", "wheel_distance", "angles_deg"),
           "mecanum": ("wheel_radius", "lx", "ly")}
_OPTIONAL = {"chi", "angles_deg"}


def make_layout(kind, **geometry):
    """Build a layout: ``make_layout("skid_steer", wheel_radius=0.195, track_width=0.6, chi=1.4)``."""
    key = str(kind).replace("-", "_").lower()
    if key not in _CLASSES:
        raise ValueError(f"unknown layout kind {kind!r}; expected one of {', '.join(KINDS)}")
    params = _PARAMS[key]
    for name in geometry:
        if name not in params:
            raise ValueError(f"{key} layout has no parameter {name!r}; expected {', '.join(params)}")
    for name in params:
        if name not in geometry and name not in _OPTIONAL:
            raise ValueError(f"{key} layout needs parameter {name!r}")
    return _CLASSES[key](**geometry)


def saturate(wheel_speeds, w_max):
    """Wheel speed limit: scale all wheels by one factor so that max |w| <= w_max.

    A common factor keeps the ratios between wheels, so the path curvature (and for holonomic
    layouts the direction of travel) is kept and only the pace drops.
    """
    w_max = _positive("w_max", w_max)
    speeds = tuple(float(w) for w in wheel_speeds)
    peak = max((abs(w) for w in speeds), default=0.0)
    if peak <= w_max:
        return speeds
    k = w_max / peak
    # The clamp only absorbs the last-bit rounding of w * k on the fastest wheel.
    return tuple(min(w_max, max(-w_max, w * k)) for w in speeds)
