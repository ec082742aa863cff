"""The :class:`Scenario`: a parsed and checked scenario file (the tables and their order, the
``[set]`` overrides, the duration), which builds its board and applies its actions (:mod:`.actions`),
expectations and report (:mod:`.expect`) to a simulation."""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

from ..errors import ConfigError
from ..kernel import PRIO_INPUT
from ..time import parse_duration
from .actions import ACTION_KINDS, ACTIONS
from .check import Checker, _fmt_time
from .expect import (
    REPORT_FIELDS,
    ExpectResult,
    _Expect,
    check_report_path,
    format_results,
    parse_expect,
    plan_expect,
    plan_follow,
)
from .mavlink import MavlinkExpect
from .source import _Lines

TABLES = ("scenario", "set", "at", "expect", "report")
SCENARIO_KEYS = ("board", "duration", "description")


@dataclass
class _Step:
    index: int
    time: Fraction
    line: int
    actions: list          # [(name, spec dict, line)]


class Scenario(Checker):
    """A parsed and checked scenario (see the module and ``docs/scenarios.md``).

    Attributes: ``path``, ``name`` (file stem), ``description``, ``board`` (or None),
    ``duration`` (exact seconds, a Fraction; assignable, e.g. ``sc.duration = "1s"`` for a shorter
    run), ``overrides`` (the ``[set]`` table, flattened to ``--set`` keys). After :meth:`apply`
    and a run: ``results`` (:class:`ExpectResult` per ``[[expect]]``, in file order), ``failed``,
    ``report`` (the ``[report]`` measurements), ``log`` ((tick, text) of every action done).
    """

    def __init__(self, path, data: dict, lines: _Lines, run_for=None):
        self.path = str(path)
        self.name = Path(path).stem
        self._lines = lines
        self._run_for = None if run_for is None else parse_duration(run_for)   # --duration, if given
        self._check(data)
        self._sim = None
        self.log: list[tuple[int, str]] = []
        self._follow = None

    # --- parsing --------------------------------------------------------------------------------
    def _check(self, data: dict) -> None:
        for k in data:
            if k not in TABLES:
                raise self._err(self._line(None, None, k),
                                f"unknown table or key {k!r} (known: [scenario], [set], [[at]], [[expect]], [report])")
        head = data.get("scenario")
        if not isinstance(head, dict):
            raise self._err(self._line("scenario") if head is not None else 1,
                            "missing [scenario] table (with duration = \"...\")")
        self._unknown("scenario", None, head, SCENARIO_KEYS)
        self.board = self._value("scenario", None, ("board",), head["board"], "str") if "board" in head else None
        desc = head.get("description", "")
        # free text: any string, the empty one too
        self.description = desc if desc == "" else self._value("scenario", None, ("description",), desc, "str")
        if "duration" not in head:
            raise self._err(self._line("scenario"), "[scenario]: missing duration = \"...\" (e.g. \"2s\")")
        self._duration = self._value("scenario", None, ("duration",), head["duration"], "duration")
        if self._duration <= 0:
            raise self._err(self._line("scenario", None, "duration"), "[scenario]: duration must be positive")
        self.file_duration = self._duration
        self._duration_given = False     # set by --duration or the API instead of the file
        # times in the file may reach the end of the run it is given: its own duration, or a longer
        # --duration (a shorter one leaves the later expectations not reached, as documented)
        self._horizon = max(self._duration, self._run_for or 0)

        self.overrides: dict = {}
        self._set_lines: dict = {}
        sets = data.get("set", {})
        if not isinstance(sets, dict):
            raise self._err(self._line(None, None, "set"), "set must be a table [set]")
        self._flatten_set(sets, ())

        self.steps: list[_Step] = []
        prev = None
        for i, entry in enumerate(self._array(data, "at")):
            step = self._parse_at(i, entry)
            if prev is not None and step.time < prev.time:
                raise self._err(self._line("at", i, "time"),
                                f"[[at]] #{i + 1}: time {_fmt_time(step.time)} is before the time of "
                                f"[[at]] #{prev.index + 1} ({_fmt_time(prev.time)}, line {prev.line}): "
                                f"[[at]] tables must be in time order")
            self.steps.append(step)
            prev = step
        self.expects: list = [MavlinkExpect(self, i, e) if isinstance(e, dict) and "mavlink" in e
                              else parse_expect(self, i, e) for i, e in enumerate(self._array(data, "expect"))]

        self.report_spec: dict = {}
        rep = data.get("report", {})
        if not isinstance(rep, dict):
            raise self._err(self._line(None, None, "report"), "report must be a table [report]")
        self._unknown("report", None, rep, tuple(REPORT_FIELDS))
        for name, fields in REPORT_FIELDS.items():
            if name in rep:
                self.report_spec[name] = self._fields("report", None, (name,), rep[name], fields)
        t0 = self.report_spec.get("follow", {}).get("from")
        if t0 is not None and t0 > self._horizon:     # as [[at]] and [[expect]] times are checked
            raise self._err(self._line("report", None, "follow", "from"), f"[report] follow: from "
                            f"{_fmt_time(t0)} is after the end of the run (duration "
                            f"{_fmt_time(self._horizon)}): the report would have no sample")
        for e in self.expects:
            if isinstance(e, _Expect) and e.source[0] == "report":
                check_report_path(self, e)

    def _array(self, data, name) -> list:
        arr = data.get(name, [])
        if not isinstance(arr, list) or not all(isinstance(x, dict) for x in arr):
            raise self._err(self._line(name), f"{name} must be an array of tables: [[{name}]]")
        return arr

    def _flatten_set(self, d: dict, path: tuple) -> None:
        for k, v in d.items():
            key = path + (k,)
            if isinstance(v, dict):      # unquoted dotted keys: motor1.load_inertia = 2e-5
                self._flatten_set(v, key)
                continue
            name = ".".join(key)
            line = self._line("set", None, *key)
            scalar = (bool, int, float, str)
            if not name or not (isinstance(v, scalar) or isinstance(v, list) and v
                                and all(isinstance(x, scalar) and not isinstance(x, bool) for x in v)):
                raise self._err(line, f"[set]: {name} = {v!r}: expected a number, true/false, a string or "
                                "a list of numbers or strings (as --set's 8,9)")
            if name in self.overrides:      # "motor1.R" = 2.5 and motor1.R = 3: one key written twice
                raise self._err(line, f"[set]: {name} is set twice (also at line {self._set_lines[name]}, "
                                "quoted or dotted); keep one")
            self.overrides[name] = v
            self._set_lines[name] = line

    def _parse_at(self, i: int, entry: dict) -> _Step:
        where = f"[[at]] #{i + 1}"
        self._unknown("at", i, entry, ("time",) + ACTIONS)
        if "time" not in entry:
            raise self._err(self._line("at", i), f"{where}: missing time = \"...\"")
        t = self._value("at", i, ("time",), entry["time"], "duration")
        if t > self._horizon:
            raise self._err(self._line("at", i, "time"), f"{where}: time {_fmt_time(t)} is after the end "
                            f"of the run (duration {_fmt_time(self._horizon)})")
        actions = [(name, ACTION_KINDS[name].parse(self, i, name, spec), self._line("at", i, name))
                   for name, spec in entry.items() if name != "time"]
        if not actions:
            raise self._err(self._line("at", i), f"{where}: no action (one or more of {', '.join(ACTIONS)})")
        return _Step(i, t, self._line("at", i, "time"), actions)

    @property
    def uses_mavlink(self) -> bool:
        """Whether the scenario sends or expects MAVLink (it then holds the MAVLink UART)."""
        return (any(name == "mavlink" for step in self.steps for name, _, _ in step.actions)
                or any(isinstance(e, MavlinkExpect) for e in self.expects))

    # --- duration ---------------------------------------------------------------------------------
    @property
    def duration(self) -> Fraction:
        return self._duration

    @duration.setter
    def duration(self, value) -> None:
        from ..sim import unitless
        if unitless(value):     # "0.3", True: refused as run(seconds=...) refuses them
            raise ConfigError(f"{self.path}: duration = {value!r:.40}: expected a number of seconds or a "
                              "duration with a unit (\"300ms\"), as the command line and scenarios take it")
        d = parse_duration(value)
        if d <= 0:
            raise ConfigError(f"{self.path}: duration must be positive, not {value!r}")
        self._duration = d
        self._duration_given = True

    def duration_line(self) -> int:
        """The line of ``duration`` in the file (for messages about it)."""
        return self._line("scenario", None, "duration")

    # --- building and applying ------------------------------------------------------------------------
    def _no_such_board(self) -> str:
        """A hint where the scenario's board is no shipped board (a typo, or a board of the user's)."""
        from ..board import board_names
        names = board_names()
        return "" if self.board in names else (f" (no shipped board is called {self.board!r}: "
                                               f"{', '.join(names)}; a profile of your own is matched by "
                                               "the name in its [board] table)")

    def check_board(self, board: str) -> None:
        """ConfigError if the scenario names a board and ``board`` (a name or a profile path) is
        another one."""
        if self.board is None or board == self.board:
            return
        from ..board import read_profile
        profile = read_profile(board)[0]
        name = (profile.get("board") or profile.get("system") or {}).get("name")
        if name != self.board:
            which = repr(board) if board == name else f"{board} (its [board] name is {name!r})"
            raise self._err(self._line("scenario", None, "board"),
                            f"the scenario is meant for board {self.board!r}, not {which}{self._no_such_board()}")

    def build(self, board: str | None = None, overrides: dict | None = None, firmware: bool = True,
              engine: str = "fast"):
        """``mcusim.load(board or self.board, overrides={**self.overrides, **overrides})``; a
        mistake in ``[set]`` is reported with the file and the line of its key."""
        from ..sim import load
        board = board or self.board
        if board is None:
            raise self._err(self._line("scenario"), "the scenario names no board (board = \"...\" in "
                            "[scenario]); give one")
        self.check_board(board)
        if overrides is not None and not isinstance(overrides, Mapping):
            raise ConfigError(f"overrides = {overrides!r:.60}: expected a mapping of --set keys to values, "
                              f'e.g. {{"motor1.R": 2.0}}')
        extra = dict(overrides or {})
        sets = {**self.overrides, **extra}
        try:
            return load(board, firmware=firmware, overrides=sets, engine=engine)
        except ConfigError as exc:
            msg = str(exc)

            def names(k):       # the key as a whole word of the message, not inside a longer one
                return re.search(rf"(?<![\w.]){re.escape(k)}(?![\w.])", msg) is not None
            if any(names(k) for k in extra):
                raise           # about a --set of the command line: its message names it
            mine = [k for k in self.overrides if k not in extra]
            hits = [k for k in mine if names(k)] or \
                   [k for k in mine if "." in k and repr(k.rpartition(".")[2]) in msg]
            if len(hits) == 1:
                msg = msg.removeprefix(f"--set {hits[0]}: ")
                raise self._err(self._set_lines[hits[0]], f"[set] {hits[0]}: {msg}") from None
            if not extra and mine:
                raise self._err(self._line("set"), f"[set]: {msg}") from None
            raise

    def apply(self, sim) -> None:
        """Check the scenario against a built simulation (board, parts, topics, whole ticks) and
        schedule its actions, report samplers and expectations. Nothing is scheduled if anything
        is wrong. Times are absolute simulated times (apply before running)."""
        if self._sim is not None:
            raise ConfigError(f"{self.path}: this scenario is already applied to a simulation")
        if self.board is not None and sim.board_name != self.board:
            raise self._err(self._line("scenario", None, "board"),
                            f"the scenario is meant for board {self.board!r}, not {sim.board_name!r}"
                            f"{self._no_such_board()}")
        tb, kernel = sim.timebase, sim.kernel
        if not self._duration_given:      # (a --duration is checked where it is given)
            self._ticks(tb, self._duration, self.duration_line(), "[scenario]: duration")
        end = tb.ticks(self._duration, rounding=True)
        plan = []                                    # (tick, prio, fn): scheduled once all is checked
        self._turns, self._stalls, self._sag_loads = {}, {}, {}
        for step in self.steps:
            tick = self._ticks(tb, step.time, step.line, f"[[at]] #{step.index + 1}: time")
            if tick < kernel.now:
                raise self._err(step.line, f"[[at]] #{step.index + 1}: time {_fmt_time(step.time)} is "
                                f"already past (the simulation is at {sim.time_s:g} s)")
            for name, spec, line in step.actions:
                fn = ACTION_KINDS[name].prepare(self, sim, spec, line, f"[[at]] #{step.index + 1}: {name}")
                plan.append((tick, PRIO_INPUT, fn))
        follow = self.report_spec.get("follow")
        self._follow = None
        if follow is not None:
            plan.extend(plan_follow(self, sim, follow, end))
        plan.extend(plan_expect(self, sim, e, end) if isinstance(e, _Expect) else e.plan(self, sim, end)
                    for e in self.expects)
        self._sim = sim
        self.log = []
        for tick, prio, fn in plan:
            kernel.at(tick, fn, prio=prio)

    def _done(self, text):
        """Log an action done now (for the actions of :mod:`.actions`)."""
        self.log.append((self._sim.kernel.now, text))

    # --- outcomes -------------------------------------------------------------------------------------
    @property
    def report(self) -> dict:
        """The ``[report]`` measurements so far: ``{"follow": {leader, follower, from_s, samples,
        max_abs_error_rad, rms_error_rad, final_abs_error_rad}}`` (empty without ``[report]``)."""
        if self._follow is None:
            return {}
        return {"follow": {k: v for k, v in self._follow.items() if not k.startswith("_")}}

    @property
    def results(self) -> list[ExpectResult]:
        """One :class:`ExpectResult` per ``[[expect]]``; one not checked yet (the run ended
        before its time) has ``time = None``, ``got = None`` and ``passed = False``."""
        return [e.result or ExpectResult(e.name, None, e.expected, None, False, e.line) for e in self.expects]

    @property
    def failed(self) -> bool:
        return any(not r.passed for r in self.results)

    def reads_summary(self, path: str) -> bool:
        """Whether an expectation checks the summary entry ``path`` (or a part of it) at the end
        of the run: the run's verdict on that entry is then the scenario's (``mcusim run`` leaves
        firmware faults to a scenario that checks ``firmware.faults``; one checked earlier says
        nothing of a fault that comes later)."""
        return any(not isinstance(e, MavlinkExpect) and e.source[0] == "summary"
                   and (e.source[1] == path or e.source[1].startswith(path + "."))
                   and (e.time is None or e.time >= self._duration) for e in self.expects)

    def report_entries(self) -> dict:
        """``{"scenario": {...}}`` for the run summary: file, board, duration, passed, the
        expectations and the report."""
        return {"scenario": {"file": self.path, "name": self.name, "board": self.board,
                             "duration_s": float(self._duration), "passed": not self.failed,
                             "expectations": [r.as_dict() for r in self.results], "report": self.report}}

    def format_results(self) -> list[str]:
        """One line per expectation (PASS/FAIL, name, value, expected, line) and the report."""
        return format_results(self.results, self.report, self.path)
