"""A progress bar on stderr for runs that take more than a moment of wall time.

The run is cut into slices of simulated time (the event order does not depend on where a run
pauses); after each slice the bar is redrawn if stderr is a terminal and the run has already
taken ``after`` wall seconds. Nothing is drawn for quick runs, in pipes, or with ``quiet``.
"""

from __future__ import annotations

import sys
import time


def _clock(seconds: float) -> str:
    seconds = int(seconds)
    return f"{seconds // 60}m{seconds % 60:02d}s" if seconds >= 60 else f"{seconds}s"


def run_with_progress(sim, duration, *, quiet: bool = False, stream=None, after: float = 1.5,
                      slices: int = 200, width: int = 30) -> None:
    """``sim.run(seconds=duration)`` with a progress bar on ``stream`` (stderr)."""
    stream = sys.stderr if stream is None else stream
    show = not quiet and getattr(stream, "isatty", lambda: False)()
    if not show:
        sim.run(seconds=duration)
        return
    start = sim.kernel.now
    end = start + sim.timebase.ticks(duration, rounding=True)
    step = max(1, (end - start) // slices)
    t0 = time.perf_counter()
    drawn = False
    hz = sim.timebase.base_hz
    while sim.kernel.now < end:
        sim.run(until_tick=min(end, sim.kernel.now + step))
        wall = time.perf_counter() - t0
        if wall < after:
            continue
        frac = (sim.kernel.now - start) / (end - start)
        sim_s = (sim.kernel.now - start) / hz
        rtf = sim_s / wall if wall else 0.0
        eta = wall * (1 - frac) / frac if frac else 0.0
        bar = "#" * int(width * frac)
        stream.write(f"\r[{bar:<{width}}] {100 * frac:5.1f}%  {sim_s:.3f}/{(end - start) / hz:.3f} s simulated"
                     f"  {rtf:.3f}x real time  ETA {_clock(eta)} ")
        stream.flush()
        drawn = True
    if drawn:
        stream.write("\n")
        stream.flush()
