"""pid_controller.c: a discrete PID per bridge with anti-windup.

    u[k] = Kp · ( e[k] + τD·(e[k] − e[k−1])/T + (T/τI)·Σe )

with Σe, the running sum of the errors, clamped to ±windup_limit (the anti-windup: the integral
never exceeds its limit, so it cannot hold the output saturated after the error reverses), and u
clamped to ±100 % duty. Note the thesis's parameter order: ``pid_set_parameters(bridge, kp, kd,
ki, windup_limit)`` where kd is τD (s) and ki is τI (s); ki = 0 disables the integral.
The thesis does not state which quantity its windup limit bounds; bounding Σe is our reading.
"""

from __future__ import annotations

from dataclasses import dataclass

BRIDGE_A, BRIDGE_B = 0, 1
OUTPUT_LIMIT = 100.0  # percent duty


@dataclass
class Pid:
    kp: float = 0.0
    kd: float = 0.0          # τD, seconds
    ki: float = 0.0          # τI, seconds (0: no integral action)
    windup_limit: float = 0.0
    set_point: float = 0.0
    period: float = 0.005    # T, seconds
    prev_error: float = 0.0
    error_sum: float = 0.0
    first: bool = True


class PidController:
    """The statics of pid_controller.c (one Pid per bridge), with its functions as methods.

    One instance per simulated MCU, so that two simulations in one process do not share state.
    """

    def __init__(self):
        self.pids = {BRIDGE_A: Pid(), BRIDGE_B: Pid()}

    def pid_set_parameters(self, bridge: int, kp: float, kd: float, ki: float, windup_limit: float) -> None:
        p = self.pids[bridge]
        p.kp, p.kd, p.ki, p.windup_limit = kp, kd, ki, windup_limit

    def pid_set_point(self, bridge: int, set_point: float) -> None:
        self.pids[bridge].set_point = set_point

    def pid_set_period(self, bridge: int, period: float) -> None:
        self.pids[bridge].period = period

    def pid_reset(self, bridge: int) -> None:
        p = self.pids[bridge]
        p.prev_error, p.error_sum, p.first = 0.0, 0.0, True

    def pid_apply(self, bridge: int, measured: float) -> float:
        """One controller step; returns the output in percent duty, clamped to ±100."""
        p = self.pids[bridge]
        error = p.set_point - measured
        if p.first:  # no derivative kick on the first sample after a reset
            p.prev_error, p.first = error, False
        p.error_sum += error
        if p.error_sum > p.windup_limit:
            p.error_sum = p.windup_limit
        elif p.error_sum < -p.windup_limit:
            p.error_sum = -p.windup_limit
        derivative = p.kd * (error - p.prev_error) / p.period
        integral = (p.period / p.ki) * p.error_sum if p.ki else 0.0
        p.prev_error = error
        u = p.kp * (error + derivative + integral)
        return max(-OUTPUT_LIMIT, min(OUTPUT_LIMIT, u))
