"""Observer logs keep the recent past only (mcusim.recent): memory stays flat in run length even
where a peripheral appends an entry per byte, per bus status or per conversion (the rover's
telemetry USART, its I2C controllers, the modules' current readings), while a short run still sees
the whole log."""

import collections

from hypothesis import given, settings
from hypothesis import strategies as st

import mcusim
import mcusim.recent
from mcusim.recent import RecentLog


@settings(max_examples=200, deadline=None)
@given(keep=st.integers(1, 40), n=st.integers(0, 300), start=st.integers(0, 50))
def test_a_recent_log_holds_the_last_entries_in_order_at_least_keep_at_most_twice_that(keep, n, start):
    log = RecentLog(range(-start, 0), keep=keep)
    for i in range(n):
        log.append(i)
    everything = list(range(-start, n))
    assert log.total == len(everything)
    assert min(keep, len(everything)) <= len(log) <= 2 * keep
    assert log.dropped == len(everything) - len(log)
    assert log == everything[log.dropped:]          # the tail, in order, and it compares as a list


def test_a_log_that_keeps_nothing_is_refused():
    try:
        RecentLog(keep=0)
    except ValueError as exc:
        assert "at least one" in str(exc)
    else:
        raise AssertionError("keep=0 accepted")


def _sequences(sim):
    """{id: (len, obj)} of every list and deque reachable from the simulation's own objects."""
    seen, out, todo = set(), {}, [sim]
    while todo:
        o = todo.pop()
        if id(o) in seen:
            continue
        seen.add(id(o))
        if isinstance(o, (list, collections.deque)):
            out[id(o)] = (len(o), o)
            if len(o) < 64:
                todo.extend(o)
        elif isinstance(o, (dict, tuple)) and len(o) < 64:
            todo.extend(o.values() if isinstance(o, dict) else o)
        elif hasattr(o, "__dict__") and type(o).__module__.startswith(("mcusim", "periph", "firmware")):
            todo.extend(vars(o).values())
    return out


def _grown(board, overrides, seconds):
    sim = mcusim.load(board, overrides=overrides)
    sim.run(seconds=seconds)
    before = _sequences(sim)
    sim.run(seconds=seconds)
    return [(n0, len(o), repr(o)[:120]) for k, (n0, o) in before.items() if len(o) > max(n0 + 50, 100)]


def test_no_list_reachable_from_a_run_grows_with_its_length(monkeypatch):
    # a small KEEP makes the bound show in short runs: at the default each log holds up to 20 000
    monkeypatch.setattr(mcusim.recent, "KEEP", 40)
    assert _grown("pro-mini", {"velocity": 20}, 0.6) == []
    assert _grown("elementall", {"cmd_vel.linear": 0.5, "cmd_vel.angular": 0.2}, 0.2) == []
    # the controller alone reports its modules missing and beeps that pattern for good: its buzzer
    # log grew by 3 entries a second before it was a RecentLog
    assert _grown("ciaa-edu", {}, 20.0) == []
