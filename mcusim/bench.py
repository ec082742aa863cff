"""``bench``: how fast a board simulates, as the ``mcusim bench`` command and ``benchmarks/`` measure it.

The board runs the fixed command of its profile's ``[bench.set]`` table (else ``[run.set]``) for a
simulated duration, ``repeat`` times; the figures are those of the median run (wall time of
``run()`` only: loading and building the board are not counted). ``faults`` lists what the firmware
reported in any run (``mcusim bench`` then exits with status 1: such figures are not the board's
usual work).
"""

from __future__ import annotations

import statistics
import time

from .engine import DEFAULT_ENGINE, ENGINES
from .errors import ConfigError, McusimError, TimeError
from .params import fmt_duration_exact


def bench(board: str, duration, repeat: int = 3, engine: str = DEFAULT_ENGINE, firmware=True,
          on_run=None, warm: bool = True) -> dict:
    """Run the profile's fixed ``[bench.set]`` scenario ``repeat`` times; figures of the median run.
    ``engine="both"`` runs the fast and the reference engine alternately in this process and adds
    ``reference_realtime_factor`` and ``speedup`` (fast over reference). ``on_run(engine)``, if
    given, is called before each run (outside the timing): a progress display."""
    if engine == "both":
        fast, ref = {}, {}
        runs = [bench(board, duration, 1, e, firmware, on_run, warm=not i)
                for i in range(repeat) for e in ENGINES]
        fast = _median_of([r for r in runs if r["engine"] == "fast"])
        ref = _median_of([r for r in runs if r["engine"] == "reference"])
        fast["reference_realtime_factor"] = ref["realtime_factor"]
        fast["reference_wall_s_median"] = ref["wall_s_median"]
        fast["speedup"] = fast["realtime_factor"] / ref["realtime_factor"]
        fast["faults"] = sorted(set(fast["faults"]) | set(ref["faults"]))
        fast["engine"] = "both"
        return fast
    from .board import read_profile
    from .sim import load
    profile = read_profile(board)[0]
    scenario = profile.get("bench", {}).get("set") or profile.get("run", {}).get("set", {})
    runs = []
    table = "[bench.set]" if profile.get("bench", {}).get("set") else "[run.set]"
    if warm:
        _warm_up(board, scenario, engine, firmware)
    for _ in range(repeat):
        if on_run is not None:
            on_run(engine)
        try:
            sim = load(board, overrides=dict(scenario), engine=engine, firmware=firmware)
        except ConfigError as exc:
            key = next((k for k in scenario if str(exc).startswith(k) or repr(k) in str(exc)), None)
            if firmware is None or not scenario or key is None:
                raise       # not about the bench command (a bad --firmware image, say)
            msg = (f"the bench sends the board profile's {table} command ({', '.join(scenario)}) to the "
                   f"firmware: {exc}")
            if hasattr(profile, "err"):      # the mistake is in the file: its line
                raise profile.err(msg, table.strip("[]").split(".")[0], None, "set", key) from None
            raise ConfigError(msg) from None
        try:
            sim.timebase.ticks(duration)     # exact, as the other commands' --duration
        except TimeError:
            sim.close()
            raise ConfigError(f"--duration {fmt_duration_exact(duration)}: not a whole number of base ticks "
                              f"(1/{sim.timebase.base_hz} s); try 1s or 100ms") from None
        t0 = time.perf_counter()
        try:
            sim.run(seconds=duration)
        finally:
            sim.close()
        wall = time.perf_counter() - t0
        summary = sim.summary()
        eng = summary["engine"]
        runs.append((wall, sim.kernel.events, sim.time_s, eng["fast_fraction"],
                     getattr(sim.mcu.cpu, "instructions", None), eng["served_isrs"],
                     list((summary.get("firmware") or {}).get("faults") or [])))
    walls = [r[0] for r in runs]
    wall = statistics.median_low(walls)       # (a run that happened, for an even repeat too)
    events, sim_s = runs[0][1], runs[0][2]
    return {"board": board, "scenario": ", ".join(f"{k}={v:g}" if isinstance(v, (int, float)) else f"{k}={v}"
                                                  for k, v in scenario.items()),
            "simulated_s": sim_s, "wall_s_median": wall, "wall_s_min": min(walls), "wall_s_max": max(walls),
            "realtime_factor": sim_s / wall, "events": events, "events_per_wall_s": events / wall,
            "repeat": repeat, "engine": engine, "fast_fraction": runs[0][3], "served_isrs": runs[0][5],
            # what the firmware reported (a fault stops the work the bench means to measure)
            "faults": sorted({f for r in runs for f in r[6]}),
            **({"instructions": runs[0][4], "instructions_per_wall_s": runs[0][4] / wall}
               if runs[0][4] is not None else {})}


def _median_of(runs: list) -> dict:
    """The figures of the median run of ``runs`` (the lower of the two middle ones for an even
    number: a run that happened), with the spread of all of them."""
    walls = sorted(r["wall_s_median"] for r in runs)
    wall = statistics.median_low(walls)
    out = dict(next(r for r in runs if r["wall_s_median"] == wall))
    out.update(wall_s_median=wall, wall_s_min=walls[0], wall_s_max=walls[-1], repeat=len(runs),
               realtime_factor=out["simulated_s"] / wall, events_per_wall_s=out["events"] / wall)
    if "instructions" in out:
        out["instructions_per_wall_s"] = out["instructions"] / wall
    return out


def _warm_up(board: str, scenario: dict, engine: str, firmware) -> None:
    """One short untimed run (10 ms), so that the timed ones do not pay what a process pays once:
    its first imports of the models, the plant's and the engine's modules, numpy's routines. The
    first engine timed had carried it alone (0.3x for a 100 ms --engine both --repeat 1)."""
    from .sim import load
    try:
        sim = load(board, overrides=dict(scenario), engine=engine, firmware=firmware)
    except ConfigError:
        return              # (the timed run names the mistake)
    try:
        sim.run(until_tick=sim.timebase.ticks("10ms", rounding=True))
    except McusimError:
        pass                # (a fault shows in the timed runs, as it does without a warm-up)
    finally:
        sim.close()
