"""Entry points: the shipped scenarios, loading a file (a path or a shipped name) into a checked
:class:`~.model.Scenario`, and running one."""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import ConfigError, McusimError, read_input
from ..params import fmt_duration
from ..time import parse_duration
from .model import Scenario
from .source import _Lines


def _shipped_dir() -> Path:
    """The folder of the shipped scenarios: ``scenarios/`` of the repository, installed as the
    package ``mcusim.scenarios`` (an editable install maps it back to the repository's folder)."""
    from importlib.resources import files
    return Path(str(files("mcusim.scenarios")))


SCENARIO_DIR = _shipped_dir()


def scenario_names() -> list[str]:
    """The example scenarios shipped in ``scenarios/``."""
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.toml")) if SCENARIO_DIR.is_dir() else []


def _resolve(path) -> Path:
    p = Path(path)
    if p.exists() or p.suffix == ".toml":
        return p
    shipped = SCENARIO_DIR / f"{path}.toml"
    return shipped if shipped.exists() else p


def load_scenario(path, duration=None) -> Scenario:
    """Parse and check a scenario file (a path, or the name of one in ``scenarios/``). Any
    mistake raises ConfigError ``<file>:<line>: <problem>``. ``duration``: the run's, where it is
    given instead of the file's (``--duration``): times up to the later end are the file's own."""
    if not isinstance(path, (str, os.PathLike)) or not str(path).strip():
        raise ConfigError(f"load_scenario({path!r:.60}): expected the path of a scenario file or the "
                          f"name of a shipped one ({', '.join(scenario_names())})")
    p = _resolve(path)
    try:
        data = read_input(p, "scenario", 4 << 20)
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise ConfigError(f"{p}:{line}: not a UTF-8 text file (byte {data[exc.start]:#04x} at offset "
                          f"{exc.start}); a scenario is TOML text") from None
    except OSError as exc:
        known = ", ".join(scenario_names())
        raise ConfigError(f"cannot read scenario {str(path)!r}: {exc.strerror}"
                          + (f" (shipped scenarios: {known})" if known else "")) from None
    from ..schema import parse_toml
    return Scenario(p, parse_toml(text, p), _Lines(text), run_for=duration)


def run_scenario(path, board: str | None = None, *, duration=None, overrides: dict | None = None,
                 firmware: bool = True, setup=None, runner=None, max_duration="600s", engine=None):
    """Load (or take) a scenario, build its board with ``[set]`` and ``overrides`` (``--set``
    pairs, which win), apply it, run it for its duration (or ``duration``) and return
    ``(sim, scenario)``. ``setup(sim)`` is called before the run (attach a VCD trace there);
    ``runner(sim, seconds)`` runs it (default ``sim.run(seconds=...)``); the simulation is closed
    afterwards. ``scenario.failed`` tells whether an expectation failed. A run longer than
    ``max_duration`` (600 s, as ``mcusim run --max-duration``) is refused: a guard against typos.
    ``engine``: ``"fast"`` (the default) or ``"reference"``, as ``mcusim.load`` takes it."""
    sc = path if isinstance(path, Scenario) else load_scenario(path, duration)
    if duration is not None:
        sc.duration = duration
    limit = parse_duration(max_duration)
    if sc.duration > limit:
        given = "duration" if duration is not None or sc._duration_given else f"{sc.path}:{sc.duration_line()}: duration"
        raise ConfigError(f"{given} {fmt_duration(sc.duration)} is longer than the limit of "
                          f"{fmt_duration(limit)} (raise it with max_duration=)")
    sim = sc.build(board, overrides, firmware, **({} if engine is None else {"engine": engine}))
    try:
        sc.apply(sim)
    except McusimError:
        sim.discard()
        raise
    try:
        if setup is not None:
            setup(sim)
        if runner is None:
            sim.run(seconds=sc.duration)
        else:
            runner(sim, sc.duration)
    finally:
        sim.close()
    return sim, sc
