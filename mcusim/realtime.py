"""``--realtime``: keep simulated time in step with the wall clock.

The run is cut into slices of ``step`` simulated time (10 ms by default; the event order does not
depend on where a run pauses). After each slice, if simulated time is ahead of the wall-clock
schedule, the host sleeps the difference; if it is behind (the simulation is slower than real
time), it does not sleep and the schedule is re-anchored at the present: time lost is not made up
later by running faster than real time (a ground station would see a burst of heartbeats). The
total lag (wall minus simulated time, the sum of what was lost) is reported: every
``report_every`` wall seconds on ``stream`` while it exceeds ``warn_lag`` (followed by ``note()``, e.g.
the host link's dropped bytes), and in the result.
Nothing here decides what happens inside the simulation: pacing only stretches the wall time.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass


@dataclass
class Pacing:
    simulated_s: float = 0.0
    wall_s: float = 0.0
    slept_s: float = 0.0
    max_lag_s: float = 0.0

    @property
    def lag_s(self) -> float:
        return max(0.0, self.wall_s - self.simulated_s)

    def line(self) -> str:
        rate = self.simulated_s / self.wall_s if self.wall_s else 0.0
        if self.max_lag_s <= 0.05:
            return (f"real time: kept pace ({self.simulated_s:.3f} s simulated in {self.wall_s:.3f} s wall, "
                    f"{self.slept_s:.3f} s asleep)")
        return (f"real time: behind by {self.lag_s:.3f} s at the end (at most {self.max_lag_s:.3f} s); the "
                f"simulation ran at {rate:.3f}x real time")


def run_realtime(sim, duration, *, step="10ms", stream=None, report_every: float = 5.0,
                 warn_lag: float = 0.25, clock=time.monotonic, sleep=time.sleep, note=None) -> Pacing:
    stream = sys.stderr if stream is None else stream
    start = sim.kernel.now
    end = start + sim.timebase.ticks(duration, rounding=True)
    slice_ = max(1, sim.timebase.ticks(step, rounding=True))
    hz = sim.timebase.base_hz
    pace = Pacing()
    t0 = clock()
    last_report = t0
    lost = 0.0                           # wall seconds the schedule has been moved on by
    while sim.kernel.now < end:
        sim.run(until_tick=min(end, sim.kernel.now + slice_))
        pace.simulated_s = (sim.kernel.now - start) / hz
        ahead = pace.simulated_s - (clock() - t0 - lost)
        if ahead > 0:
            sleep(ahead)
            pace.slept_s += ahead
        else:
            lost -= ahead                # re-anchor: no catching up later
        now = clock()
        pace.wall_s = now - t0
        pace.max_lag_s = max(pace.max_lag_s, pace.lag_s)
        if pace.lag_s > warn_lag and now - last_report >= report_every:
            last_report = now
            stream.write(f"mcusim: real time: {pace.lag_s:.2f} s behind at simulated t = "
                         f"{sim.kernel.now / hz:.2f} s ({pace.simulated_s / pace.wall_s:.3f}x real time)\n")
            if note is not None:
                stream.write(f"mcusim: {note()}\n")
            stream.flush()
    return pace
