"""Helpers for testing firmware against a simulation: wait for a condition, a pin edge, a duration.

Every wait is in *simulated* time and ends at the exact base tick where it is satisfied::

    from mcusim.testing import wait_until, wait_for_pin, run_for

    t = wait_until(sim, lambda: sim.topic("velocity") > 9.5, timeout="2s")
    t = wait_for_pin(sim, "PB1", 1, timeout="10ms")
    run_for(sim, "50ms")

When the timeout passes first, :class:`SimTimeout` (an ``AssertionError``) is raised, so pytest
reports a failure that names the condition, the timeout and the simulated time reached.

This module imports nothing heavy (no numpy, no board or plant models): the pytest plugin
re-exports it at pytest start.
"""

from __future__ import annotations

import ast
import inspect
import textwrap

from .errors import McusimError
from .signals import _level

__all__ = ["SimTimeout", "describe_condition", "run_for", "wait_for_pin", "wait_until"]


class SimTimeout(AssertionError):
    """A wait reached its timeout (simulated time) before its condition held.

    Attributes: ``condition`` (the description used in the message), ``timeout`` (as given),
    ``time_s`` (the simulated time reached, seconds) and ``start_s`` (when the wait began).
    """

    def __init__(self, condition: str, timeout, time_s: float, start_s: float):
        self.condition, self.timeout, self.time_s, self.start_s = condition, timeout, time_s, start_s
        super().__init__(
            f"timed out after {_fmt_duration(timeout)} of simulated time waiting for {condition} "
            f"(simulated time reached {time_s:.9g} s; the wait began at {start_s:.9g} s)")


def _fmt_duration(value) -> str:
    if isinstance(value, str):
        return value.strip()
    return f"{float(value):g} s"


def describe_condition(condition) -> str:
    """A readable name for a condition callable: the lambda's source text when it can be found,
    else the function's qualified name, else its repr."""
    name = getattr(condition, "__name__", None)
    if name == "<lambda>":
        text = _lambda_source(condition)
        if text:
            return text
    if name and not name.startswith("<"):
        return getattr(condition, "__qualname__", name)
    return repr(condition)


def _lambda_source(fn) -> str | None:
    try:
        src = textwrap.dedent(inspect.getsource(fn)).strip()
    except (OSError, TypeError):
        return None
    lines = src.splitlines() or [""]
    # getsource gives the lines of the statement holding the lambda; parse as much as parses
    for end in range(len(lines), 0, -1):
        chunk = "\n".join(lines[:end])
        try:
            tree = ast.parse(chunk)
        except SyntaxError:
            continue
        lambdas = [n for n in ast.walk(tree) if isinstance(n, ast.Lambda)]
        if len(lambdas) > 1:      # several on the statement (one inside another): the one that is fn
            lambdas = _lambda_of(fn, lambdas, lines)
        if len(lambdas) == 1:
            seg = ast.get_source_segment(chunk, lambdas[0])
            if seg:
                return " ".join(seg.split())
        break
    first = " ".join(lines[0].split())
    return first[:200] or None


def _lambda_of(fn, lambdas, lines) -> list:
    """Of the lambdas of a statement, the innermost whose body holds ``fn``'s first instruction
    (its position in the source, relative to the statement's first line)."""
    try:
        start = inspect.getsourcelines(fn)[1]
        pos = next(p for p in fn.__code__.co_positions()
                   if p[0] is not None and p[2] is not None and p[3] is not None and p[3] > p[2])
    except (OSError, TypeError, StopIteration):
        return lambdas
    # dedent shifted the columns of every line by the same amount
    first = inspect.getsourcelines(fn)[0][0]
    shift = len(first) - len(first.lstrip()) - (len(lines[0]) - len(lines[0].lstrip()))
    line, col = pos[0] - start + 1, pos[2] - shift
    inside = [n for n in lambdas if (n.body.lineno, n.body.col_offset) <= (line, col)
              <= (n.body.end_lineno, n.body.end_col_offset)]
    return [max(inside, key=lambda n: (n.body.lineno, n.body.col_offset))] if inside else lambdas


def _ticks(sim, duration, what: str = "timeout") -> int:
    """Seconds or a duration string ("500ms") to base ticks, rounded to the nearest tick; a bool or
    a string without a unit ("2") is refused, as ``run(seconds=...)`` refuses it."""
    from .sim import unitless
    if unitless(duration):
        raise McusimError(f"{what}={duration!r}: expected a number of seconds or a duration with a unit "
                          "(\"2ms\"), as run(seconds=...), the command line and scenarios take it")
    return sim.timebase.ticks(duration, rounding=True)


def _advance(sim, t_end: int, stop=None) -> None:
    sim.run(until_tick=t_end, stop=stop)


def _check_sim(sim, what: str) -> None:
    """McusimError where ``sim`` is no simulation (None, the fixture's factory, a board name)."""
    if not hasattr(sim, "kernel") or not hasattr(sim, "run"):
        raise McusimError(f"{what}(sim, ...): sim = {sim!r:.60} is not a simulation (mcusim.load(...), "
                          "or what the mcusim_sim fixture returns when called)")


def run_for(sim, duration):
    """Advance the simulation by ``duration`` (seconds, or a string such as ``"20ms"``).
    The same as ``sim.run(seconds=duration)``; returns the simulation."""
    _check_sim(sim, "run_for")
    return sim.run(seconds=duration)


def wait_until(sim, condition, timeout="1s", poll=None, *, message: str | None = None) -> float:
    """Advance simulated time until ``condition()`` is true; return the simulated time (seconds)
    at which it became true. ``sim.now`` is then that exact base tick.

    Without ``poll`` the condition is checked after every kernel event, so the run stops at the
    event that made it true (exact to the base tick). That holds for what changes at events: a
    topic, a register or pin the firmware writes, an interrupt count. A plant variable (a shaft
    angle, a current), a counter read from it (an encoder position, an STM32 encoder timer's CNT)
    or the time itself move between events, and the fast engine has fewer of those: such a
    condition is seen at the first event after it became true, which differs between the engines;
    give ``poll`` for it. With ``poll`` (``"1ms"``, 0.001) it is
    checked only every ``poll`` of simulated time: cheaper for an expensive condition, and the
    returned time is the first poll instant at which it held. A condition already true returns
    at once without running. Stopping at an event means that events of the same tick ordered
    after it (the firmware's reaction, for one) have not run yet; they run on the next advance.

    Raises :class:`SimTimeout` (an ``AssertionError``) if ``timeout`` of simulated time passes
    first; the simulation is then at ``start + timeout``. ``message`` names the condition in that
    error (default: the lambda's source, or the function's name).
    """
    __tracebackhide__ = True    # pytest: show the failure at the caller's line
    _check_sim(sim, "wait_until")
    if not callable(condition):
        raise McusimError(f"wait_until(sim, {condition!r:.60}): the condition is a function to call, "
                          "such as lambda: sim.topic('/motor1/get_pos') > 1.0")
    start = sim.kernel.now
    end = start + _ticks(sim, timeout)
    if condition():
        return sim.time_s
    if poll is None:
        hit = False

        def stop():
            nonlocal hit
            hit = bool(condition())
            return hit

        _advance(sim, end, stop=stop)
        if hit or condition():          # or true at the end without an event (a time condition)
            return sim.time_s
    else:
        step = _ticks(sim, poll, "poll")
        if step <= 0:
            raise McusimError(f"poll interval {poll!r} is shorter than one base tick")
        while sim.kernel.now < end:
            _advance(sim, min(sim.kernel.now + step, end))
            if condition():
                return sim.time_s
    raise SimTimeout(message or describe_condition(condition), timeout, sim.time_s,
                     start / sim.timebase.base_hz)


def _net(sim, pin):
    if not isinstance(pin, str):
        return pin                      # a Net (anything with .level and .listen)
    member, dot, rest = pin.partition(".")
    members = getattr(sim, "members", {})
    if dot and member in members and len(members) > 1:   # a system's board pin: "rcm.GPIO3_3"
        return members[member]["mcu"].pin(rest)
    return sim.pin(pin)


def wait_for_pin(sim, pin, level, timeout="1s", *, message: str | None = None) -> float:
    """Advance simulated time until the first edge of ``pin`` to ``level`` (0 or 1); return its
    simulated time in seconds (``sim.now`` is then the tick of that edge).

    ``pin`` is a pin name (``"PB1"``; in a system ``"member.PIN"``) or a Net. Only an edge counts:
    a pin already at ``level`` is waited on until it leaves that level and comes back.
    Raises :class:`SimTimeout` if no such edge comes within ``timeout`` of simulated time.
    """
    __tracebackhide__ = True
    _check_sim(sim, "wait_for_pin")
    net = _net(sim, pin)
    want = _level(level, "wait_for_pin")
    start = sim.kernel.now
    end = start + _ticks(sim, timeout)
    hit = []

    def on_change(n):
        if not hit and n.level == want:
            hit.append(sim.kernel.now)

    net.listen(on_change)
    try:
        _advance(sim, end, stop=lambda: bool(hit))
    finally:
        listeners = getattr(net, "_listeners", None)   # Net has listen() but no unlisten()
        if listeners is not None and on_change in listeners:
            listeners.remove(on_change)
    if hit:
        return hit[0] / sim.timebase.base_hz
    name = getattr(net, "name", pin)
    raise SimTimeout(message or f"an edge of pin {name} to {want}", timeout, sim.time_s,
                     start / sim.timebase.base_hz)
