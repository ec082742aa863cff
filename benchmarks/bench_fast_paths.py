"""What each of the fast engine's shortcuts buys, measured in one process with it on and off.

    python benchmarks/bench_fast_paths.py [--repeat 3]

* counted runs of served encoder edges (``mcusim.engine.served``): pro-mini at 20 rpm, 1 s;
* held chunks screened at their ends, with their states in closed form
  (``PeriodPlan._stuck_ends``, ``_held_states``): nucleo-f746 holding its position, 3 s to 6 s;
* the modal test of moving chunks (``mcusim.engine.modal``): nucleo-f746 moving to its set-points
  (its first second), and the rover at speed (0.2 s from 1 s on).

Each case runs the same simulation alternately with the shortcut on and off (``--repeat`` times
each) and prints the median wall times and their ratio; the results are the same either way (the
tests hold them to it). Speed is measured here, never in tests; single runs move by 10-20 % with the
machine's other work, the ratio of medians much less.
"""

from __future__ import annotations

import argparse
import statistics
import time

import mcusim
from mcusim.engine import screening, served


def _counted(on: bool):
    served.COUNT_MIN = 4 if on else 10**12


def _held(on: bool):
    screening.STUCK_ENDS = on
    screening.PeriodPlan._held_states_on = on


def _modal(on: bool):
    screening.MODAL = on


def _run(board, overrides, warm: float, seconds: float) -> float:
    sim = mcusim.load(board, overrides=overrides)
    sim.run(seconds=warm)
    t0 = time.perf_counter()
    sim.run(seconds=seconds)
    wall = time.perf_counter() - t0
    sim.close()
    return wall


CASES = [
    ("counted runs (pro-mini, 20 rpm, 1 s)", _counted, "pro-mini", {"velocity": 20}, 0.1, 1.0),
    ("held chunks (nucleo-f746 holding, 3 s)", _held, "nucleo-f746",
     {"/motor1/set_pos": 9.42477796076938, "/motor2/set_pos": -1.5707963267948966}, 3.0, 3.0),
    ("modal test (nucleo-f746 moving, 1 s)", _modal, "nucleo-f746",
     {"/motor1/set_pos": 9.42477796076938, "/motor2/set_pos": -1.5707963267948966}, 0.0, 1.0),
    ("modal test (elementall at speed, 0.2 s)", _modal, "elementall",
     {"cmd_vel.linear": 0.5, "cmd_vel.angular": 0.2}, 1.0, 0.2),
]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    keep_min, keep_stuck, keep_modal = served.COUNT_MIN, screening.STUCK_ENDS, screening.MODAL
    held_states = screening.PeriodPlan._held_states

    def gated(self, x0, n):
        return held_states(self, x0, n) if getattr(screening.PeriodPlan, "_held_states_on", True) else None
    screening.PeriodPlan._held_states = gated
    try:
        for name, switch, board, overrides, warm, seconds in CASES:
            walls = {True: [], False: []}
            for _ in range(a.repeat):
                for on in (True, False):
                    switch(on)
                    walls[on].append(_run(board, overrides, warm, seconds))
            on, off = statistics.median(walls[True]), statistics.median(walls[False])
            print(f"{name}: {on:.2f} s with it, {off:.2f} s without: {off / on:.2f}x")
    finally:
        served.COUNT_MIN, screening.STUCK_ENDS, screening.MODAL = keep_min, keep_stuck, keep_modal
        screening.PeriodPlan._held_states = held_states
        if "_held_states_on" in vars(screening.PeriodPlan):
            del screening.PeriodPlan._held_states_on


if __name__ == "__main__":
    main()
