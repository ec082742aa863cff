"""The byte-level I2C bus: timing (9 SCL periods per byte), NACK on absent address, repeated START,
clock stretching by slaves and by slow masters, queuing, protocol errors."""

import itertools

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcusim.errors import McusimError, TimeError
from mcusim.i2c import I2cBus, I2cMaster, MemorySlave
from mcusim.kernel import Kernel
from mcusim.signals import Net
from mcusim.time import TimeBase


def make(scl_hz=100_000, **slave_kw):
    k = Kernel(TimeBase([16_000_000]))
    bus = I2cBus(k, "i2c0")
    slave = MemorySlave(bus, 0x50, **slave_kw)
    master = I2cMaster(k, bus, scl_hz=scl_hz)
    return k, bus, slave, master


@pytest.mark.parametrize("scl_hz,period", [(100_000, 160), (400_000, 40)])
def test_write_timing_is_nine_scl_periods_per_byte(scl_hz, period):
    k, _bus, slave, m = make(scl_hz)
    k.run_until(1000)
    done = []
    tr = m.write(0x50, b"\x10\xAA\xBB", done.append)
    k.run_until(10**6)
    H, L = period // 2, period - period // 2
    assert done == [tr] and tr.ok
    assert tr.t_start == 1000
    ends = [e[0] for e in tr.byte_ends]
    # START at 1000, SCL falls at 1000 + H, then each byte (address + 3 data) takes 9 periods
    assert ends == [1000 + H + 9 * period * n for n in (1, 2, 3, 4)]
    assert tr.t_stop == ends[-1] + L + H
    assert slave.mem[0x10:0x12] == b"\xAA\xBB" and slave.received == [0x10, 0xAA, 0xBB]
    assert [e[1:] for e in tr.byte_ends] == [("addr", 0xA0, True), ("write", 0x10, True),
                                             ("write", 0xAA, True), ("write", 0xBB, True)]


def test_absent_address_is_nacked_and_the_master_stops():
    k, _bus, slave, m = make()
    tr = m.write(0x51, b"\x01\x02")
    rd = m.read(0x22, 3)
    k.run_until(10**6)
    assert tr.addr_acks == [False] and tr.acks == [] and not tr.ok
    assert tr.t_stop == tr.byte_ends[0][0] + 160      # STOP right after the address byte
    assert rd.addr_acks == [False] and rd.data == b""
    assert slave.received == []


def test_write_read_with_repeated_start():
    k, bus, slave, m = make()
    slave.mem[0x20:0x23] = b"\x01\x02\x03"
    bus.log = []
    tr = m.write_read(0x50, b"\x20", 3)
    k.run_until(10**6)
    assert tr.ok and tr.data == b"\x01\x02\x03"
    assert [e[1] for e in tr.byte_ends] == ["addr", "write", "addr", "read", "read", "read"]
    assert [e[3] for e in tr.byte_ends[3:]] == [True, True, False]    # master NACKs the last byte
    e = tr.byte_ends[1][0]
    kinds = [(kind, t) for t, kind, _ in bus.log]
    assert ("restart", e + 80 + 80) in kinds                         # SCL rise e+L, Sr after H
    assert tr.byte_ends[2][0] == e + 80 + 2 * 80 + 9 * 160           # SCL falls H after Sr
    assert [kind for kind, _ in kinds] == ["start", "addr", "write", "restart", "addr", "read", "read",
                                           "read", "stop"]


def test_read_continues_from_the_slave_pointer():
    k, _bus, slave, m = make()
    slave.mem[0:2] = b"\x07\x08"
    tr = m.read(0x50, 2)
    k.run_until(10**6)
    assert tr.data == b"\x07\x08"


def test_reading_after_a_nacked_address_gives_ff_from_the_pull_up():
    k = Kernel(TimeBase([16_000_000]))
    bus = I2cBus(k)
    m = I2cMaster(k, bus)                          # used as a low-level master through the primitives
    got = []
    bus.start(m, lambda: bus.write_byte(m, 0x51 << 1 | 1, lambda ack: (
        got.append(ack), bus.read_byte(m, False, lambda v: (got.append(v), bus.stop(m))))))
    k.run_until(10**6)
    assert got == [False, 0xFF] and bus.owner is None


def test_slave_clock_stretch_delays_next_byte_by_exactly_the_excess():
    k, _bus, _slave, m = make(stretch_ticks=80 + 37)     # holds 37 ticks beyond the master's low time
    tr = m.write(0x50, b"\x00\x01\x02")
    k.run_until(10**6)
    ends = [e[0] for e in tr.byte_ends]
    assert [b - a for a, b in itertools.pairwise(ends)] == [1440 + 37] * 3
    assert tr.t_stop == ends[-1] + 37 + 80 + 80


def test_short_stretch_within_low_time_costs_nothing():
    k, _bus, _slave, m = make(stretch_ticks=50)
    tr = m.write(0x50, b"\x00\x01")
    k.run_until(10**6)
    ends = [e[0] for e in tr.byte_ends]
    assert [b - a for a, b in itertools.pairwise(ends)] == [1440, 1440]


class SlowMaster:
    """A master in the style of a hardware block whose firmware answers late (LPC SI flag)."""

    def __init__(self, k, bus, delay):
        self.k, self.bus, self.delay = k, bus, delay
        self.scl_low_ticks = self.scl_high_ticks = 80
        self.ends = []

    def run(self, addr, data):
        seq = [addr << 1, *data]

        def next_byte(*_):
            self.ends.append(self.k.now)
            if seq:
                b = seq.pop(0)
                self.k.after(self.delay, self.bus.write_byte, self, b, next_byte)
            else:
                self.k.after(self.delay, self.bus.stop, self, lambda: self.ends.append(("stop", self.k.now)))
        self.bus.start(self, next_byte)


def test_slow_master_stretches_low_phase_itself():
    k = Kernel(TimeBase([16_000_000]))
    bus = I2cBus(k)
    slave = MemorySlave(bus, 0x50)
    sm = SlowMaster(k, bus, delay=200)
    sm.run(0x50, b"\x05\x06")
    k.run_until(10**6)
    # START at 0, SCL falls at 80; each primitive issued 200 ticks after the previous fall: the rise
    # is at fall + 200 (> fall + 80), the byte ends 9H + 8L later
    assert sm.ends[:4] == [80, 80 + 200 + 1360, 80 + 2 * 1560, 80 + 3 * 1560]
    assert sm.ends[4] == ("stop", 80 + 3 * 1560 + 200 + 80)
    assert slave.received == [5, 6]


def test_second_master_waits_for_stop_and_bus_free_time():
    k = Kernel(TimeBase([16_000_000]))
    bus = I2cBus(k)
    MemorySlave(bus, 0x50)
    a, b = I2cMaster(k, bus, name="a"), I2cMaster(k, bus, scl_hz=400_000, name="b")
    ta = a.write(0x50, b"\x00\x01")
    tb = b.write(0x50, b"\x02\x03")
    k.run_until(10**6)
    assert ta.ok and tb.ok
    assert tb.t_start == ta.t_stop + 80                # t_BUF = the first master's low time
    ends = [e[0] for e in tb.byte_ends]
    assert [y - x for x, y in itertools.pairwise(ends)] == [360, 360]


def test_queued_transfers_run_back_to_back():
    k, _bus, _slave, m = make()
    t1 = m.write(0x50, b"\x00\x11")
    t2 = m.write_read(0x50, b"\x00", 1)
    k.run_until(10**6)
    assert t2.data == b"\x11" and t2.t_start == t1.t_stop + 80


def test_protocol_errors_raise():
    k = Kernel(TimeBase([16_000_000]))
    bus = I2cBus(k)
    m = I2cMaster(k, bus)
    with pytest.raises(McusimError):
        bus.write_byte(m, 0xA0, lambda ack: None)      # no START
    bus.start(m, lambda: None)
    k.run_until(1000)
    with pytest.raises(McusimError):
        bus.read_byte(m, True, lambda v: None)         # address first
    bus.write_byte(m, 0xA0, lambda ack: None)
    with pytest.raises(McusimError):
        bus.write_byte(m, 0x00, lambda ack: None)      # previous primitive still running
    k.run_until(5000)
    with pytest.raises(McusimError):
        bus.read_byte(m, True, lambda v: None)         # R/W was 0
    with pytest.raises(TimeError):
        I2cMaster(k, bus, scl_hz=300_001)
    with pytest.raises(McusimError):
        m.write(0x80, b"")


def test_two_slaves_claiming_a_read_address_is_contention():
    k = Kernel(TimeBase([16_000_000]))
    bus = I2cBus(k)
    MemorySlave(bus, 0x50)
    MemorySlave(bus, 0x50)
    m = I2cMaster(k, bus)
    m.read(0x50, 1)
    with pytest.raises(McusimError, match="claim"):
        k.run_until(10**6)


def test_optional_nets_show_start_and_stop_levels():
    k = Kernel(TimeBase([16_000_000]))
    sda, scl = Net("SDA", pull=1), Net("SCL", pull=1)
    bus = I2cBus(k, sda=sda, scl=scl)
    MemorySlave(bus, 0x50)
    changes = []
    sda.listen(lambda n: changes.append((k.now, "SDA", n.level)))
    m = I2cMaster(k, bus)
    tr = m.write(0x50, b"")
    k.run_until(10**6)
    assert changes[0] == (0, "SDA", 0) and changes[-1] == (tr.t_stop, "SDA", 1)
    assert sda.level == 1 and scl.level == 1


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(["write", "read", "write_read"]), st.integers(0, 255),
                          st.binary(min_size=0, max_size=6), st.integers(1, 5)), min_size=1, max_size=6),
       st.sampled_from([100_000, 400_000, 1_000_000]), st.integers(0, 300))
def test_memory_model_and_timing_for_any_transaction_sequence(ops, scl_hz, stretch):
    k, _bus, slave, m = make(scl_hz, stretch_ticks=stretch)
    for kind, ptr, data, n in ops:
        if kind == "write":
            m.write(0x50, bytes([ptr]) + data)
        elif kind == "read":
            m.read(0x50, n)
        else:
            m.write_read(0x50, bytes([ptr]), n)
    k.run_until(10**8)
    assert all(tr.done and tr.ok for tr in m.transfers)
    per = k.timebase.base_hz // scl_hz
    high, low = per // 2, per - per // 2
    excess = max(0, stretch - low)           # MemorySlave stretches after each byte it ACKs
    model, p = bytearray(256), 0
    prev_stop = None
    for (kind, ptr, data, n), tr in zip(ops, m.transfers):
        if kind == "write":
            p = ptr
            for b in data:
                model[p] = b
                p = (p + 1) % 256
        else:
            if kind == "write_read":
                p = ptr
            assert tr.data == bytes(model[(p + i) % 256] for i in range(n))
            p = (p + n) % 256
        # exact timing: START -> first byte end = H + 9T; bytes 9T apart plus the stretch excess
        # after a byte the slave ACKed; a repeated START costs L + 2H more
        if prev_stop is not None:
            assert tr.t_start == prev_stop + low
        assert tr.byte_ends[0][0] == tr.t_start + high + 9 * per
        for (t0, k0, _, _), (t1, k1, _, _) in zip(tr.byte_ends, tr.byte_ends[1:]):
            stretched = excess if k0 in ("addr", "write") else 0
            restart = low + 2 * high if k1 == "addr" else 0
            assert t1 - t0 == 9 * per + stretched + restart
        last_kind = tr.byte_ends[-1][1]
        assert tr.t_stop == tr.byte_ends[-1][0] + (excess if last_kind != "read" else 0) + low + high
        prev_stop = tr.t_stop
    assert slave.mem == model
