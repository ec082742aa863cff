"""Expectations (``[[expect]]``) and the follow-error report (``[report]``).

An expectation reads one value (a reader per source in :data:`READERS`: topic, part, summary,
report) and checks it (a test per check in :data:`CHECKS`) after everything else of its tick
(``PRIO_CHECK``), the end ones at the run's last tick. The follow report samples the angle error
between two motors every ``REPORT_SAMPLE`` at ``PRIO_OBSERVE``. The functions get the
:class:`~.model.Scenario` for its checked-value and name methods (:class:`~.check.Checker`)."""

from __future__ import annotations

import inspect
import math
from dataclasses import dataclass
from fractions import Fraction

from ..kernel import PRIO_OBSERVE
from ..params import _show
from .check import _fmt_time, _is_number

PRIO_CHECK = PRIO_OBSERVE + 1      # expectations: after the observers (report samplers) of a tick
REPORT_SAMPLE = "1ms"              # follow-error sampling period

EXPECT_SOURCES = ("topic", "part", "summary", "report")
EXPECT_CHECKS = ("approx", "min", "max", "equals", "contains")
EXPECT_KEYS = ("name", "time", "attr", "tol") + EXPECT_SOURCES + EXPECT_CHECKS
REPORT_FIELDS = {"follow": {"leader": ("str", True), "follower": ("str", True), "from": ("duration", False)}}
FOLLOW_REPORT_KEYS = ("leader", "follower", "from_s", "samples", "max_abs_error_rad", "rms_error_rad",
                      "final_abs_error_rad")


def _plain(value):
    """A JSON-friendly copy of a value read from the simulation."""
    if isinstance(value, (bool, int, str)) or value is None:
        return value
    if isinstance(value, float):
        return value
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, Fraction):
        return float(value)
    return repr(value)


@dataclass
class ExpectResult:
    """The outcome of one ``[[expect]]``: ``time`` (s) is when it was checked (None: the run ended
    before its time came), ``expected`` a description, ``got`` the value read."""

    name: str
    time: float | None
    expected: str
    got: object
    passed: bool
    line: int

    def as_dict(self) -> dict:
        return {"name": self.name, "time_s": self.time, "expected": self.expected, "got": _plain(self.got),
                "passed": self.passed, "line": self.line}


@dataclass
class _Expect:
    index: int
    name: str
    time: Fraction | None
    line: int
    source: tuple          # ("topic", name) | ("part", name, attr) | ("summary", path) | ("report", path)
    check: dict
    expected: str
    result: ExpectResult | None = None


# --- parsing ----------------------------------------------------------------------------------------
def parse_expect(sc, i: int, e: dict) -> _Expect:
    """The checked ``[[expect]]`` #i+1 of a scenario whose duration is ``sc.duration``."""
    where = f"[[expect]] #{i + 1}"
    sc._unknown("expect", i, e, EXPECT_KEYS)
    line = sc._line("expect", i)
    t = sc._value("expect", i, ("time",), e["time"], "duration") if "time" in e else None
    if t is not None and t > sc._horizon:
        raise sc._err(sc._line("expect", i, "time"), f"{where}: time {_fmt_time(t)} is after the end "
                      f"of the run (duration {_fmt_time(sc._horizon)}); leave time out for the end")
    sources = [k for k in EXPECT_SOURCES if k in e]
    if len(sources) != 1:
        raise sc._err(sc._line("expect", i, *sources[1:2]), f"{where}: give exactly one of "
                      f"{', '.join(EXPECT_SOURCES)} (what to read)")
    src = sources[0]
    value = sc._value("expect", i, (src,), e[src], "str")
    if src == "part":
        if "attr" not in e:
            raise sc._err(line, f"{where}: part = {value!r} needs attr = \"...\" (e.g. output_angle)")
        source = ("part", value, sc._value("expect", i, ("attr",), e["attr"], "str"))
    else:
        if "attr" in e:
            raise sc._err(sc._line("expect", i, "attr"), f"{where}: attr goes with part = \"...\"")
        source = (src, value)
    checks = [k for k in EXPECT_CHECKS if k in e]
    if not checks or (len(checks) > 1 and set(checks) != {"min", "max"}):
        raise sc._err(sc._line("expect", i, *checks[1:2]), f"{where}: give one check: approx (with "
                      "tol), min and/or max, equals or contains")
    check = {k: e[k] for k in checks}
    for k in ("approx", "min", "max"):
        if k in check:
            sc._value("expect", i, (k,), check[k], "number")
    if "approx" in check:
        if "tol" not in e:
            raise sc._err(sc._line("expect", i, "approx"), f"{where}: approx needs tol = (the allowed "
                          "difference)")
        check["tol"] = sc._value("expect", i, ("tol",), e["tol"], "number")
        if check["tol"] < 0:
            raise sc._err(sc._line("expect", i, "tol"), f"{where}: tol must not be negative")
        expected = f"{check['approx']:g} ± {check['tol']:g}"
    elif "tol" in e:
        raise sc._err(sc._line("expect", i, "tol"), f"{where}: tol goes with approx = ...")
    elif "equals" in check:
        expected = f"== {check['equals']!r}"
    elif "contains" in check:
        expected = f"contains {check['contains']!r}"
    elif len(check) == 2:
        if check["min"] > check["max"]:
            raise sc._err(sc._line("expect", i, "max"), f"{where}: max is below min")
        expected = f"in [{check['min']:g}, {check['max']:g}]"
    else:
        expected = f">= {check['min']:g}" if "min" in check else f"<= {check['max']:g}"
    label = ".".join(source[1:])
    name = (sc._value("expect", i, ("name",), e["name"], "str") if "name" in e
            else f"{label} @ {_fmt_time(t)}")
    return _Expect(i, name, t, line, source, check, expected)


def check_report_path(sc, e: _Expect) -> None:
    """``report = "<report>.<field>"`` names a field of a report that ``sc.report_spec`` has."""
    head, _, field = e.source[1].partition(".")
    line = sc._line("expect", e.index, "report")
    if head not in REPORT_FIELDS:
        raise sc._err(line, f"[[expect]] #{e.index + 1}: report = {e.source[1]!r}: reports: "
                      f"{', '.join(f'{r}.<field>' for r in REPORT_FIELDS)}")
    if head not in sc.report_spec:
        raise sc._err(line, f"[[expect]] #{e.index + 1}: report = {e.source[1]!r}, but [report] has "
                      f"no {head} = {{ ... }}")
    if field not in FOLLOW_REPORT_KEYS:
        raise sc._err(line, f"[[expect]] #{e.index + 1}: report = {e.source[1]!r}: fields: "
                      f"{', '.join(FOLLOW_REPORT_KEYS)}")


# --- readers: what an expectation reads, checked against the simulation ------------------------------
def _read_topic(sc, sim, e, line, where):
    fw, name = sc._firmware_for(sim, e.source[1], line, where)
    sc._check_output(fw, name, line, where)
    return lambda: fw.topic(name)


def _read_part(sc, sim, e, line, where):
    _, name, attr = e.source
    part = sim.parts.get(name)
    if part is None:
        raise sc._err(line, f"{where}: no part {name!r} on {sim.board_name} "
                      f"(parts: {', '.join(sim.parts)})")
    if attr.startswith("_") or not hasattr(part, attr):
        raise sc._err(sc._line("expect", e.index, "attr"),
                      f"{where}: part {name!r} has no attribute {attr!r}")
    readers = getattr(part, "READERS", ())
    if callable(inspect.getattr_static(part, attr)) and attr not in readers:
        # a method acts on the simulation (glitch, apply_load_torque) or needs arguments: an
        # expectation only reads, and calls only the methods a part declares as values
        raise sc._err(sc._line("expect", e.index, "attr"),
                      f"{where}: part {name!r}: {attr!r} is a method, not a value to read "
                      f"(values: {', '.join(_values_of(part))})")
    values = _values_of(part)
    if attr not in values:
        # an object the part holds (its kernel, the motor an encoder reads): no value to compare,
        # and its repr, with a memory address, would land in the summary
        raise sc._err(sc._line("expect", e.index, "attr"),
                      f"{where}: part {name!r}: {attr!r} is not a value to read (values: {', '.join(values)})")

    def read():
        v = getattr(part, attr)
        return v() if attr in readers else v
    return read


def _values_of(part) -> list[str]:
    """The names an expectation can read from ``part``: its properties, its plain public number
    and flag attributes, and the methods it declares as values (``READERS``)."""
    names = set(getattr(part, "READERS", ()))
    for cls in type(part).__mro__:
        names.update(k for k, v in vars(cls).items() if isinstance(v, property) and not k.startswith("_"))
    names.update(k for k, v in vars(part).items()
                 if not k.startswith("_") and isinstance(v, (bool, int, float, str)) and k != "name")
    return sorted(names)


# summary entries of the wall clock: known only after the run, and different on every machine
_SUMMARY_OF_THE_MACHINE = ("wall_s", "realtime_factor")

# summary entries that are there only when they have something to say (checked as empty before)
_SUMMARY_WHEN_ANY = {"warnings": []}


def _summary_keys(v, parts):
    """The keys a dotted path names in the summary ``v``: at each level the longest run of the
    path's parts that is a key there, so that keys holding a dot are reachable (a system's
    motors: ``motors.mcm1.motor.speed_rpm``). Returns (keys, None, _), or (keys so far, the
    value where no key matched, the index of the first part left)."""
    keys, i = [], 0
    while i < len(parts):
        if not isinstance(v, dict):
            return keys, v, i
        for j in range(len(parts), i, -1):
            k = ".".join(parts[i:j])
            if k in v:
                keys.append(k)
                v, i = v[k], j
                break
        else:
            return keys, v, i
    return keys, None, i


def _read_summary(sc, sim, e, line, where):
    path = e.source[1]
    parts = path.split(".")
    if parts[0] in _SUMMARY_OF_THE_MACHINE:
        raise sc._err(line, f"{where}: summary {path!r} is measured on the machine that runs the "
                      "simulation after it ends, not simulated: no expectation can check it")
    if path in _SUMMARY_WHEN_ANY:
        return lambda: sim.summary().get(path, _SUMMARY_WHEN_ANY[path])
    keys, stuck, done = _summary_keys(sim.summary(), parts)
    if stuck is not None:
        there = ", ".join(stuck) if isinstance(stuck, dict) else "none"
        raise sc._err(line, f"{where}: summary has no {'.'.join(parts[:done + 1])!r} (keys there: {there})")

    def read():
        v = sim.summary()
        for k in keys:
            v = v[k]
        return v
    return read


def _read_report(sc, sim, e, line, where):
    field = e.source[1].partition(".")[2]
    return lambda: sc.report["follow"][field]


READERS = {"topic": _read_topic, "part": _read_part, "summary": _read_summary, "report": _read_report}


# --- checks: the test of a value read; the first key of an expectation's check names it ------------
def _approx(got, c):
    return _is_number(got) and abs(got - c["approx"]) <= c["tol"]


def _in_range(got, c):
    return _is_number(got) and ("min" not in c or got >= c["min"]) and ("max" not in c or got <= c["max"])


def _equals(got, c):
    got, want = _plain(got), c["equals"]
    if isinstance(got, bool) != isinstance(want, bool):
        return False        # true is no number here: equals = 1 does not match a flag that is true
    return got == want


def _contains(got, c):
    try:
        return c["contains"] in got
    except TypeError:
        return False


CHECKS = {"approx": _approx, "min": _in_range, "max": _in_range, "equals": _equals, "contains": _contains}


def plan_expect(sc, sim, e: _Expect, end: int) -> tuple:
    """Check ``e`` against ``sim``: ``(tick, PRIO_CHECK, check)``, ``check`` setting ``e.result``;
    ``end`` is the run's last tick."""
    e.result = None
    where = f"[[expect]] #{e.index + 1}"
    read = READERS[e.source[0]](sc, sim, e, sc._line("expect", e.index, e.source[0]), where)
    if e.time is None:
        tick = end
    else:
        tick = sc._ticks(sim.timebase, e.time, sc._line("expect", e.index, "time"), f"{where}: time")
    if tick < sim.kernel.now:
        raise sc._err(e.line, f"{where}: time {_fmt_time(e.time)} is already past")
    test = CHECKS[next(iter(e.check))]
    kind = next(iter(e.check))
    numeric = kind in ("approx", "min", "max")
    if e.source[0] in ("topic", "part", "summary"):
        # (topics and part values are read without side effects; the summary before the run has
        # its shape and the types of its values: a flag stays a flag, a table a table, text text;
        # a value not known yet, None, may be anything at the end)
        now = read()
        label = ".".join(e.source[1:])
        line = sc._line("expect", e.index, e.source[0])
        if kind == "contains" and isinstance(now, (int, float)):
            raise sc._err(line, f"{where}: {label} is {'true or false' if isinstance(now, bool) else 'a number'}, "
                          f"and contains needs text or a list: check it with "
                          f"{'equals' if isinstance(now, bool) else 'min, max or approx'}")
        if numeric and isinstance(now, str):
            raise sc._err(line, f"{where}: {label} is text ({_show(now)}), and {kind} needs a number: "
                          f"check it with equals or contains")
        if numeric and isinstance(now, (list, tuple)):
            raise sc._err(line, f"{where}: {label} is a list, and {kind} needs a number: check it with "
                          "equals or contains")
        if kind == "contains" and isinstance(now, dict):
            raise sc._err(line, f"{where}: {label} is a table ({', '.join(map(str, now))}), and contains "
                          "needs text or a list: check one field with its dotted path")
    if numeric and e.source[0] in ("topic", "part", "summary"):
        if isinstance(now, bool):
            raise sc._err(sc._line("expect", e.index, e.source[0]),
                          f"{where}: {label} is true or false, and {next(iter(e.check))} needs a number: "
                          f"check it with equals = true or equals = false")
        if isinstance(now, dict):
            fields = ", ".join(map(str, now))
            raise sc._err(sc._line("expect", e.index, e.source[0]),
                          f"{where}: {label} is a table ({fields}), and {next(iter(e.check))} needs a "
                          f"number: check one field, summary = \"{label}.{next(iter(now), 'x')}\" if the "
                          "summary has it (mcusim run ... --summary shows its paths)")

    def check():
        got = read()
        e.result = ExpectResult(e.name, sim.time_s, e.expected, _plain(got), bool(test(got, e.check)), e.line)
    return tick, PRIO_CHECK, check


# --- the follow-error report --------------------------------------------------------------------------
def plan_follow(sc, sim, follow: dict, end: int) -> list:
    """Check the ``[report] follow`` table against ``sim`` and start its report ``sc._follow``
    (updated as it samples): ``[(tick, PRIO_OBSERVE, sample)]``, none if it starts after
    ``end``, the run's last tick."""
    tb, kernel = sim.timebase, sim.kernel
    where, line = "[report] follow", sc._line("report", None, "follow")
    leader = sc._part(sim, follow["leader"], "motor", line, where)
    follower = sc._part(sim, follow["follower"], "motor", line, where)
    t0 = follow.get("from", Fraction(0))
    rep = sc._follow = {"leader": follow["leader"], "follower": follow["follower"], "from_s": float(t0),
           "samples": 0, "max_abs_error_rad": None, "rms_error_rad": None,
           "final_abs_error_rad": None, "_sq": 0.0}
    every = tb.ticks(REPORT_SAMPLE)
    start = max(sc._ticks(tb, t0, line, f"{where}: from"), kernel.now)

    def sample():
        d = abs(leader.output_angle - follower.output_angle)
        rep["samples"] += 1
        rep["_sq"] += d * d
        rep["max_abs_error_rad"] = d if rep["max_abs_error_rad"] is None else max(rep["max_abs_error_rad"], d)
        rep["rms_error_rad"] = math.sqrt(rep["_sq"] / rep["samples"])
        rep["final_abs_error_rad"] = d
        if kernel.now + every <= end:
            kernel.at(kernel.now + every, sample, prio=PRIO_OBSERVE)
    return [(start, PRIO_OBSERVE, sample)] if start <= end else []


def format_results(results: list, report: dict, path: str) -> list[str]:
    """One line per expectation (PASS/FAIL, name, value, expected, line) and the report."""
    out = []
    for r in results:
        got = f"{r.got:.6g}" if isinstance(r.got, float) else repr(r.got)
        when = "not reached" if r.time is None else f"at {r.time:g} s"
        out.append(f"{'PASS' if r.passed else 'FAIL'}  {r.name}: {got}, expected {r.expected} "
                   f"({when}; {path}:{r.line})")
    f = report.get("follow")
    if f is not None and f["samples"]:
        out.append(f"follow error {f['follower']} vs {f['leader']} from {f['from_s']:g} s: max "
                   f"{f['max_abs_error_rad']:.4f} rad, rms {f['rms_error_rad']:.4f} rad, final "
                   f"{f['final_abs_error_rad']:.4f} rad ({f['samples']} samples)")
    return out
