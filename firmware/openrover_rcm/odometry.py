"""Wheel odometry of ``rover_control``: 16-bit encoder unwrapping and pose integration.

The motor-control modules report their encoder count in the 16-bit POSITION register, wrapping
modulo 65536 (counts at the motor shaft, before the gearbox). ``Unwrap16`` extends it to an
unbounded count; ``Odometry`` turns the per-wheel counts into a pose (x, y, yaw) in the odometry
frame (x forward and yaw counter-clockwise at the start, REP 103).
"""

from __future__ import annotations

import math

RANGE16 = 1 << 16
HALF16 = 1 << 15


def wrap_angle(a):
    """Wrap an angle to (-pi, pi]."""
    a = math.remainder(a, 2.0 * math.pi)      # [-pi, pi]
    return math.pi if a == -math.pi else a


class Unwrap16:
    """Extend successive uint16 POSITION reads to an unbounded (int64 in C) count.

    Each read is taken as the previous count plus the change since the previous read, that change
    being the 16-bit difference interpreted as signed (two's complement). This is exact only if the
    true change between two reads lies in -32768..+32767 counts; a faster wheel or a slower poll
    aliases by 65536 counts and cannot be detected. The module's counter is 0 at its reset, so the
    unwrapper starts at ``count`` (default 0) and the first read is taken relative to it.

    Poll interval needed: 32767 / (counts per second), see ``max_poll_interval``. ElementAll example:
    0.5 m/s on a 0.39 m wheel with 1:50 gearing and 2048 counts per motor turn is 41.8 k counts/s,
    so POSITION must be read at least every 0.78 s (the controller polls far faster).
    """

    def __init__(self, count=0):
        self.count = int(count)
        self._last = self.count & 0xFFFF

    def update(self, raw):
        raw = int(raw)
        if not 0 <= raw < RANGE16:
            raise ValueError(f"POSITION read {raw} is not a uint16 value")
        delta = ((raw - self._last + HALF16) & 0xFFFF) - HALF16     # signed 16-bit difference
        self._last = raw
        self.count += delta
        return self.count


def max_poll_interval(speed, wheel_radius, counts_per_wheel_rev):
    """Longest POSITION poll interval (s) that keeps ``Unwrap16`` exact at ground speed ``speed``."""
    counts_per_s = abs(speed) / (2.0 * math.pi * wheel_radius) * counts_per_wheel_rev
    return math.inf if counts_per_s == 0.0 else (HALF16 - 1) / counts_per_s


class Odometry:
    """Dead reckoning from unwrapped wheel counts through the layout's forward kinematics.

    ``update(counts)`` takes one unbounded count per wheel (layout wheel order, same sign as the
    layout's wheel speeds, i.e. already corrected for mirrored motors) at the motor shaft, as
    produced by ``Unwrap16``; ``counts_per_wheel_rev`` includes the gear ratio (2048 * 50 on the
    ElementAll). The wheel angle changes since the previous update give, through the linear forward
    kinematics, the body displacement (dx, dy, dyaw) for a constant body twist over the step, which
    is integrated exactly along the arc:

        world displacement = R(yaw + dyaw/2) (dx, dy) * sin(dyaw/2) / (dyaw/2)

    For the differential case this is the textbook x += (v/w)(sin(yaw + w dt) - sin(yaw)),
    y -= (v/w)(cos(yaw + w dt) - cos(yaw)) (sin(a+d) - sin(a) = 2 cos(a + d/2) sin(d/2)), without the
    cancellation of that form at small w dt; below |dyaw/2| = 1e-4 the sinc factor uses its series
    (error < 1e-18 relative), which tends to the straight-line step. The time step is not needed:
    the arc depends only on the displacements.
    """

    def __init__(self, layout, counts_per_wheel_rev, counts=None, pose=(0.0, 0.0, 0.0)):
        cpr = float(counts_per_wheel_rev)
        if not (math.isfinite(cpr) and cpr > 0.0):
            raise ValueError(f"counts_per_wheel_rev must be positive, got {counts_per_wheel_rev!r}")
        self.layout = layout
        self.counts_per_wheel_rev = counts_per_wheel_rev
        self._rad_per_count = 2.0 * math.pi / cpr
        self.reset(pose, counts)

    def reset(self, pose=(0.0, 0.0, 0.0), counts=None):
        """Set the pose and the reference counts (zeros if not given: the modules' reset value)."""
        counts = [0] * self.layout.wheels if counts is None else [int(c) for c in counts]
        if len(counts) != self.layout.wheels:
            raise ValueError(f"expected {self.layout.wheels} wheel counts, got {len(counts)}")
        self._last = counts
        x, y, yaw = pose
        self.x, self.y, self.yaw = float(x), float(y), wrap_angle(float(yaw))

    @property
    def pose(self):
        return (self.x, self.y, self.yaw)

    def update(self, counts):
        counts = [int(c) for c in counts]
        if len(counts) != self.layout.wheels:
            raise ValueError(f"expected {self.layout.wheels} wheel counts, got {len(counts)}")
        # Integer difference first, so large unbounded counts lose no precision.
        dphi = [(c - p) * self._rad_per_count for c, p in zip(counts, self._last)]
        self._last = counts
        dx, dy, dyaw = self.layout.forward(dphi)
        half = 0.5 * dyaw
        if abs(half) < 1e-4:
            k = 1.0 - half * half / 6.0
        else:
            k = math.sin(half) / half
        heading = self.yaw + half
        c, s = math.cos(heading), math.sin(heading)
        self.x += k * (c * dx - s * dy)
        self.y += k * (s * dx + c * dy)
        self.yaw = wrap_angle(self.yaw + dyaw)
        return self.pose
