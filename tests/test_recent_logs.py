"""Observer logs keep the recent past only (mcusim.recent): memory stays flat in run length even
where a peripheral appends an entry per byte, per bus status or per conversion (the rover's
telemetry USART, its I2C controllers, the modules' current readings), while a short run still sees
the whole log."""

import collections

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import mcusim
import mcusim.recent
from mcusim.hostserial import BufferEndpoint
from mcusim.mavlink import MavlinkClient
from mcusim.recent import RecentBytes, RecentLog


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


@settings(max_examples=200, deadline=None)
@given(keep=st.integers(1, 40), chunks=st.lists(st.binary(max_size=30), max_size=20))
def test_recent_bytes_hold_the_last_bytes_in_order_at_least_keep_at_most_twice_that(keep, chunks):
    sent, everything = RecentBytes(keep=keep), b"".join(chunks)
    for b in everything:
        sent.append(b)
    assert sent.total == len(everything) and sent.dropped == len(everything) - len(sent)
    assert min(keep, len(everything)) <= len(sent) <= 2 * keep
    assert bytes(sent) == everything[sent.dropped:]


def test_a_buffer_endpoint_keeps_the_recent_bytes_it_was_sent_and_counts_them_all():
    ep = BufferEndpoint()
    for i in range(3 * mcusim.recent.KEEP):
        ep.transmit(i & 0xFF, 10 * i)
    n = 3 * mcusim.recent.KEEP
    assert ep.sent.total == ep.log.total == n
    assert bytes(ep.sent) == bytes(b for _, b in ep.log)             # the same tail in both
    assert ep.log[-1] == (10 * (n - 1), (n - 1) & 0xFF) and len(ep.log) <= 2 * mcusim.recent.KEEP


def test_a_ground_station_wait_sees_every_message_in_order_across_log_trims(monkeypatch):
    # the client's log keeps 5 messages; waits still return each heartbeat once and in order, and
    # a flush skips what was trimmed before a wait looked at it
    monkeypatch.setattr(mcusim.recent, "KEEP", 5)
    sim = mcusim.load("ciaa-edu")
    gcs = MavlinkClient(sim, "USART3", heartbeat_hz=0)
    seqs = [gcs.recv_match("HEARTBEAT", timeout="1.2s").get_seq() for _ in range(4)]
    assert gcs.log.dropped > 0                 # the log was trimmed on the way (telemetry, texts)
    assert seqs == sorted(seqs) and len(set(seqs)) == 4
    sim.run(seconds="2s")
    gcs.flush()
    assert gcs.recv_match(timeout="0.5s") is gcs.log[-1][1]   # the first one after the flush
    try:
        gcs.tick_of(object())
    except ValueError as exc:
        assert "recent ones" in str(exc)
    else:
        raise AssertionError("tick_of accepted a message the log does not hold")


def test_a_log_that_keeps_nothing_is_refused():
    for cls, what in ((RecentLog, "entry"), (RecentBytes, "byte")):
        try:
            cls(keep=0)
        except ValueError as exc:
            assert f"at least one {what}" in str(exc)
        else:
            raise AssertionError(f"{cls.__name__}(keep=0) accepted")


def _sequences(sim):
    """{id: (len, obj)} of every list and deque reachable from the simulation's own objects."""
    seen, out, todo = set(), {}, [sim]
    while todo:
        o = todo.pop()
        if id(o) in seen:
            continue
        seen.add(id(o))
        if isinstance(o, (list, collections.deque, bytearray)):
            out[id(o)] = (len(o), o)
            if len(o) < 64 and not isinstance(o, bytearray):
                todo.extend(o)
        elif isinstance(o, (dict, tuple)) and len(o) < 64:
            todo.extend(o.values() if isinstance(o, dict) else o)
        elif hasattr(o, "__dict__") and type(o).__module__.startswith(("mcusim", "periph", "firmware")):
            todo.extend(vars(o).values())
    return out


def _grown(board, overrides, seconds, gcs=None):
    sim = mcusim.load(board, overrides=overrides)
    if gcs:      # a ground station attached to the MAVLink port (its client and endpoint logs)
        MavlinkClient(sim, "USART3", member=gcs if gcs is not True else None)
    sim.run(seconds=seconds)
    before = _sequences(sim)
    sim.run(seconds=seconds)
    return [(n0, len(o), repr(o)[:120]) for k, (n0, o) in before.items() if len(o) > max(n0 + 50, 100)]


@pytest.mark.heavy
def test_no_list_reachable_from_a_run_grows_with_its_length(monkeypatch):
    # a small KEEP makes the bound show in short runs: at the default each log holds up to 20 000
    monkeypatch.setattr(mcusim.recent, "KEEP", 40)
    assert _grown("pro-mini", {"velocity": 20}, 0.6) == []
    assert _grown("elementall", {"cmd_vel.linear": 0.5, "cmd_vel.angular": 0.2}, 0.2) == []
    # the controller alone reports its modules missing and beeps that pattern for good: its buzzer
    # log grew by 3 entries a second before it was a RecentLog
    assert _grown("ciaa-edu", {}, 20.0) == []
    # a ground station left attached: its message log and the serial end's bytes grew for good
    assert _grown("ciaa-edu", {}, 1.0, gcs=True) == []
