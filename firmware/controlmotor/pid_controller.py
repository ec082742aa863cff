"""pid_controller.c: a discrete PID per bridge with anti-windup.

    u[k] = Kp · ( e[k] + τD·(e[k] − e[k−1])/T + (T/τI)·Σe )

with Σe, the running sum of the errors, clamped to ±windup_limit (the anti-windup: the integral
never exceeds its limit, so it cannot hold the output saturated after the error reverses), and u
clamped to ±100 % duty. Note the thesis's parameter order: ``pid_set_parameters(bridge, kp, kd,
ki, windup_limit)`` where kd is τD (s) and ki is τI (s); ki = 0 disables the integral.
The thesis does not state which quantity its windup limit bounds; bounding Σe is our reading.

The C computes in ``float``, IEEE binary32 on the STM32F746's single-precision FPU: every value
here is a ``numpy.float32`` and every operation one float32 operation, in the C's order (the C
twin is built with -std=c11, so nothing is contracted into a fused multiply-add). In binary64 the
port had put an occasional output one compare count away from the chip's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

BRIDGE_A, BRIDGE_B = 0, 1
OUTPUT_LIMIT = 100.0  # percent duty

_f32 = np.float32
_LIMIT = _f32(OUTPUT_LIMIT)
_ZERO = _f32(0)
_PERIOD = _f32(0.005)


@dataclass
class Pid:
    kp: np.float32 = _ZERO
    kd: np.float32 = _ZERO          # τD, seconds
    ki: np.float32 = _ZERO          # τI, seconds (0: no integral action)
    windup_limit: np.float32 = _ZERO
    set_point: np.float32 = _ZERO
    period: np.float32 = _PERIOD    # T, seconds
    prev_error: np.float32 = _ZERO
    error_sum: np.float32 = _ZERO
    first: bool = True


class PidController:
    """The statics of pid_controller.c (one Pid per bridge), with its functions as methods.

    One instance per simulated MCU, so that two simulations in one process do not share state.
    """

    def __init__(self):
        self.pids = {BRIDGE_A: Pid(), BRIDGE_B: Pid()}

    def pid_set_parameters(self, bridge: int, kp: float, kd: float, ki: float, windup_limit: float) -> None:
        p = self.pids[bridge]
        p.kp, p.kd, p.ki, p.windup_limit = _f32(kp), _f32(kd), _f32(ki), _f32(windup_limit)

    def pid_set_point(self, bridge: int, set_point: float) -> None:
        self.pids[bridge].set_point = _f32(set_point)

    def pid_set_period(self, bridge: int, period: float) -> None:
        self.pids[bridge].period = _f32(period)

    def pid_reset(self, bridge: int) -> None:
        p = self.pids[bridge]
        p.prev_error, p.error_sum, p.first = _ZERO, _ZERO, True

    def pid_apply(self, bridge: int, measured: float) -> float:
        """One controller step; returns the output in percent duty, clamped to ±100 (the float32
        value, as a Python float)."""
        p = self.pids[bridge]
        error = p.set_point - _f32(measured)
        if p.first:  # no derivative kick on the first sample after a reset
            p.prev_error, p.first = error, False
        p.error_sum = p.error_sum + error
        if p.error_sum > p.windup_limit:
            p.error_sum = p.windup_limit
        elif p.error_sum < -p.windup_limit:
            p.error_sum = -p.windup_limit
        derivative = p.kd * (error - p.prev_error) / p.period
        integral = (p.period / p.ki) * p.error_sum if p.ki != _ZERO else _ZERO
        p.prev_error = error
        u = p.kp * (error + derivative + integral)
        if u > _LIMIT:
            return OUTPUT_LIMIT
        if u < -_LIMIT:
            return -OUTPUT_LIMIT
        return float(u)
