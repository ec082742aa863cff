"""ATmega328P TWI slave on the shared I2C bus: status codes (vectors #22, #23), slave transmitter,
NACK on an absent address, clock stretching while TWINT = 1, byte timing, register rules.

The firmware side is a Python rendering of the slave part of Arduino's twi.c ISR, bound to vector 24
through mcusim.firmware.Cpu (the real Wire port is elsewhere)."""

import itertools

import pytest
from avr_rig import bare_atmega328p
from hypothesis import given, settings
from hypothesis import strategies as st
from mcusim.periph.avr.twi import Twi

from mcusim.errors import UnsupportedConfiguration
from mcusim.i2c import I2cBus, I2cMaster
from mcusim.kernel import PRIO_CPU

TWBR, TWSR, TWAR, TWDR, TWCR, TWAMR = 0xB8, 0xB9, 0xBA, 0xBB, 0xBC, 0xBD
TWINT, TWEA, TWSTA, TWSTO, TWWC, TWEN, TWIE = 0x80, 0x40, 0x20, 0x10, 0x08, 0x04, 0x01
BUFFER_LENGTH = 32


class WireSlave:
    """twi.c slave ISR (ArduinoCore-avr), including its TWEA = 0 on 0x88 (issues #116/#242).

    ``clear_delay`` > 0 models ISR work before the TWCR write: the write happens that many CPU
    cycles after entry instead of at entry (it must be less than ``cost``)."""

    def __init__(self, mcu, addr=0x08, reply=b"", cost=120, clear_delay=0):
        self.mcu, self.reply_bytes, self.clear_delay = mcu, reply, clear_delay
        self.rx, self.rx_index = bytearray(BUFFER_LENGTH), 0
        self.tx, self.tx_index, self.tx_len = bytearray(BUFFER_LENGTH), 0, 0
        self.statuses, self.received, self.requests = [], [], 0
        mcu.cpu.vector(24, self.isr, cost=cost)
        mcu.irq.set_i(True)
        # Wire.begin(addr): twi_init + twi_setAddress
        mcu.write8(TWSR, 0)
        mcu.write8(TWBR, ((16_000_000 // 100_000) - 16) // 2)
        mcu.write8(TWCR, TWEN | TWIE | TWEA)
        mcu.write8(TWAR, addr << 1)

    def _twcr(self, v):
        if self.clear_delay:
            k = self.mcu.kernel
            k.after(self.clear_delay * self.mcu.core_clock.period, self.mcu.write8, TWCR, v, prio=PRIO_CPU)
        else:
            self.mcu.write8(TWCR, v)

    def reply(self, ack):
        self._twcr(TWEN | TWIE | TWINT | (TWEA if ack else 0))

    def on_request(self):                     # user onRequest: Wire.write(reply)
        self.requests += 1
        for b in self.reply_bytes[:BUFFER_LENGTH]:
            self.tx[self.tx_len] = b
            self.tx_len += 1

    def isr(self):
        m = self.mcu
        assert m.read8(TWCR) & TWINT            # TWINT is not cleared on vector entry
        status = m.read8(TWSR) & 0xF8
        self.statuses.append(status)
        if status in (0x60, 0x68, 0x70, 0x78):
            self.rx_index = 0
            self.reply(1)
        elif status in (0x80, 0x90):
            if self.rx_index < BUFFER_LENGTH:
                self.rx[self.rx_index] = m.read8(TWDR)
                self.rx_index += 1
                self.reply(1)
            else:
                self.reply(0)
        elif status == 0xA0:
            self._twcr(TWEN | TWIE | TWEA | TWINT)  # twi_releaseBus
            self.received.append(bytes(self.rx[:self.rx_index]))  # onReceive(rx, count)
            self.rx_index = 0
        elif status in (0x88, 0x98):
            self.reply(0)
        elif status in (0xA8, 0xB0, 0xB8):
            if status != 0xB8:
                self.tx_index = self.tx_len = 0
                self.on_request()
                if self.tx_len == 0:
                    self.tx_len, self.tx[0] = 1, 0x00
            m.write8(TWDR, self.tx[self.tx_index])
            self.tx_index += 1
            self.reply(self.tx_index < self.tx_len)
        elif status in (0xC0, 0xC8):
            self.reply(1)
        elif status == 0x00:
            self._twcr(TWEN | TWIE | TWEA | TWINT | TWSTO)


def make(scl_hz=100_000):
    mcu = bare_atmega328p(cpu=True)
    k, bus, clock = mcu.kernel, mcu.bus, mcu.core_clock
    i2c = I2cBus(k, "i2c")
    twi = Twi("TWI", mcu, clock, i2c)
    bus.attach_registers(0, twi)
    master = I2cMaster(k, i2c, scl_hz=scl_hz)
    return mcu, twi, i2c, master


def test_vector22_wire_slave_receives_three_bytes():
    mcu, twi, _i2c, m = make()
    w = WireSlave(mcu, 0x08)
    assert mcu.read8(TWAR) == 0x10 and mcu.read8(TWBR) == 72
    tr = m.write(0x08, b"\x01\x02\x03")
    mcu.kernel.run_until(10**6)
    assert tr.addr_acks == [True] and tr.acks == [True, True, True]
    assert w.statuses == [0x60, 0x80, 0x80, 0x80, 0xA0]
    assert w.received == [b"\x01\x02\x03"]
    # TWINT set at each byte end and at the STOP instant
    assert [t for t, _ in twi.status_log] == [e[0] for e in tr.byte_ends] + [tr.t_stop]
    assert mcu.read8(TWSR) & 0xF8 == 0xF8 and not mcu.read8(TWCR) & TWINT


def test_vector23_more_than_32_bytes_makes_wire_slave_deaf():
    mcu, _twi, _i2c, m = make()
    w = WireSlave(mcu, 0x08)
    data = bytes(range(1, 41))
    tr = m.write(0x08, data)
    again = m.write(0x08, b"\x55")
    mcu.kernel.run_until(10**7)
    assert tr.acks == [True] * 33 + [False]   # 33rd ACKed but dropped, 34th NACKed, master stops
    assert w.statuses == [0x60] + [0x80] * 33 + [0x88]
    assert w.received == []                   # no 0xA0: onReceive never called
    assert again.addr_acks == [False]         # TWEA = 0: the slave ignores its own address


@pytest.mark.parametrize("n,reply,statuses,data", [
    (3, b"\x11\x22\x33", [0xA8, 0xB8, 0xB8, 0xC0], b"\x11\x22\x33"),
    (4, b"\x11\x22\x33", [0xA8, 0xB8, 0xB8, 0xC8], b"\x11\x22\x33\xff"),
    (2, b"\x11\x22\x33", [0xA8, 0xB8, 0xC0], b"\x11\x22"),
    (1, b"\x42", [0xA8, 0xC0], b"\x42"),
    (2, b"", [0xA8, 0xC8], b"\x00\xff"),      # nothing written in onRequest: Wire sends 0x00
])
def test_slave_transmitter(n, reply, statuses, data):
    mcu, _twi, _i2c, m = make()
    w = WireSlave(mcu, 0x08, reply=reply)
    tr = m.read(0x08, n)
    mcu.kernel.run_until(10**6)
    assert tr.addr_acks == [True] and tr.data == data
    assert w.statuses == statuses and w.requests == 1


def test_write_read_with_repeated_start_gives_a0_then_a8():
    mcu, _twi, _i2c, m = make()
    w = WireSlave(mcu, 0x08, reply=b"\x99\x98")
    tr = m.write_read(0x08, b"\x07", 2)
    mcu.kernel.run_until(10**6)
    assert tr.ok and tr.data == b"\x99\x98"
    assert w.statuses == [0x60, 0x80, 0xA0, 0xA8, 0xB8, 0xC0]
    assert w.received == [b"\x07"]


def test_absent_address_is_nacked():
    mcu, twi, _i2c, m = make()
    w = WireSlave(mcu, 0x08)
    tr = m.write(0x09, b"\x01")
    rd = m.read(0x10, 1)
    mcu.kernel.run_until(10**6)
    assert tr.addr_acks == [False] and rd.addr_acks == [False] and rd.data == b""
    assert w.statuses == [] and twi.status_log == []


def test_twi_disabled_or_twea_clear_does_not_answer():
    mcu, _twi, _i2c, m = make()
    mcu.write8(TWAR, 0x10)
    mcu.write8(TWCR, TWEA)                    # TWEN = 0
    t1 = m.write(0x08, b"")
    mcu.kernel.run_until(10**6)
    mcu.write8(TWCR, TWEN)                    # TWEA = 0
    t2 = m.write(0x08, b"")
    mcu.kernel.run_until(2 * 10**6)
    assert t1.addr_acks == [False] and t2.addr_acks == [False]


def test_general_call_and_address_mask():
    mcu, _twi, _i2c, m = make()
    w = WireSlave(mcu, 0x08)
    t0 = m.write(0x00, b"\x01")               # TWGCE = 0: general call ignored
    mcu.kernel.run_until(10**6)
    mcu.write8(TWAR, 0x10 | 1)                # TWGCE = 1
    mcu.write8(TWAMR, 0x02)                   # address bit 0 is don't-care: 0x08 and 0x09 match
    t1 = m.write(0x00, b"\x05")
    t2 = m.write(0x09, b"\x06")
    mcu.kernel.run_until(2 * 10**6)
    assert t0.addr_acks == [False] and t1.ok and t2.ok
    assert w.statuses == [0x70, 0x90, 0xA0, 0x60, 0x80, 0xA0]
    assert w.received == [b"\x05", b"\x06"]


def respond_late(mcu, delay, log):
    """No CPU model: firmware reacting to TWINT ``delay`` ticks after it is set (Wire replies)."""
    k = mcu.kernel

    def on_line(vector, level):
        if vector == 24 and level:
            k.after(delay, handle)

    def handle():
        status = mcu.read8(TWSR) & 0xF8
        log.append((k.now, status))
        mcu.write8(TWCR, TWEN | TWIE | TWEA | TWINT)
    mcu.irq.line_listeners.append(on_line)
    mcu.write8(TWAR, 0x10)
    mcu.write8(TWCR, TWEN | TWIE | TWEA)


@pytest.mark.parametrize("delay", [0, 79, 80, 81, 500, 5000])
def test_clock_stretch_delays_next_byte_by_exactly_the_late_time(delay):
    mcu, twi, _i2c, m = make()
    log = []
    respond_late(mcu, delay, log)
    tr = m.write(0x08, b"\x01\x02\x03")
    mcu.kernel.run_until(10**7)
    excess = max(0, delay - 80)               # SCL low time at 100 kHz is 80 ticks
    ends = [e[0] for e in tr.byte_ends]
    assert [b - a for a, b in itertools.pairwise(ends)] == [1440 + excess] * 3
    assert ends[0] == tr.t_start + 80 + 1440  # the first byte follows START: not stretched
    assert tr.t_stop == ends[-1] + excess + 160
    assert [s for _, s in log] == [0x60, 0x80, 0x80, 0x80, 0xA0]
    # TWINT was cleared exactly ``delay`` after it was set
    assert [t for t, _ in log] == [t + delay for t, _ in twi.status_log]


def test_pending_a0_stretches_the_next_address_byte():
    mcu, _twi, _i2c, m = make()
    mcu.write8(TWAR, 0x10)
    mcu.write8(TWCR, TWEN | TWEA)             # polled firmware, no interrupt
    k = mcu.kernel
    held = []

    def poll():                                # clear every TWINT at once, except the first 0xA0
        if mcu.read8(TWCR) & TWINT:
            status = mcu.read8(TWSR) & 0xF8
            if status == 0xA0 and not held:
                held.append(k.now)
                k.at(50_000, mcu.write8, TWCR, TWEN | TWEA | TWINT)
            elif status != 0xA0 or k.now >= 50_000:
                mcu.write8(TWCR, TWEN | TWEA | TWINT)
        k.after(1, poll, prio=PRIO_CPU)
    k.at(0, poll, prio=PRIO_CPU)
    a = m.write(0x08, b"\x01")
    b = m.write(0x08, b"\x02")
    k.run_until(100_000)
    assert a.ok and b.ok and held == [a.t_stop]
    # b's START is not delayed (SCL is high), but its address byte's first SCL rise waits for 50000
    assert b.t_start == a.t_stop + 80
    assert b.byte_ends[0][0] == 50_000 + 9 * 80 + 8 * 80


@pytest.mark.parametrize("scl_hz,period", [(100_000, 160), (400_000, 40)])
def test_byte_time_is_nine_scl_periods_with_a_fast_isr(scl_hz, period):
    mcu, _twi, _i2c, m = make(scl_hz)
    w = WireSlave(mcu, 0x08, reply=b"\x01\x02\x03\x04")
    tw = m.write(0x08, b"\x0A\x0B\x0C\x0D")
    tr = m.read(0x08, 4)
    mcu.kernel.run_until(10**6)
    for t in (tw, tr):
        ends = [e[0] for e in t.byte_ends]
        assert [b - a for a, b in itertools.pairwise(ends)] == [9 * period] * 4
    assert tr.data == b"\x01\x02\x03\x04" and w.received == [b"\x0A\x0B\x0C\x0D"]


def test_register_rules():
    mcu, _twi, _i2c, _m = make()
    assert mcu.read8(TWSR) == 0xF8 and mcu.read8(TWAR) == 0xFE and mcu.read8(TWDR) == 0xFF
    mcu.write8(TWSR, 0xFF)                    # only TWPS is writable
    assert mcu.read8(TWSR) == 0xFB
    mcu.write8(TWSR, 0)
    mcu.write8(TWCR, TWEN)
    mcu.write8(TWDR, 0x12)                    # TWINT = 0: write ignored, TWWC set
    assert mcu.read8(TWDR) == 0xFF and mcu.read8(TWCR) & TWWC
    with pytest.raises(UnsupportedConfiguration) as e:
        mcu.write8(TWCR, TWEN | TWSTA | TWINT)
    assert (e.value.register, e.value.field) == ("TWCR", "TWSTA")
    assert mcu.read8(TWCR) & ~TWWC == TWEN    # refused write left TWCR as it was
    mcu.write8(TWCR, TWEN | TWSTO)            # slave-mode recovery: TWSTO reads back 0
    assert not mcu.read8(TWCR) & TWSTO


def test_twdr_writable_while_twint_set_clears_twwc():
    mcu, _twi, _i2c, m = make()
    mcu.write8(TWAR, 0x10)
    mcu.write8(TWCR, TWEN | TWEA)
    mcu.write8(TWDR, 0x01)                    # TWWC
    tr = m.read(0x08, 1)
    k = mcu.kernel
    k.run_until(10**6, stop=lambda: bool(mcu.read8(TWCR) & TWINT))
    assert mcu.read8(TWSR) & 0xF8 == 0xA8
    mcu.write8(TWDR, 0x5A)
    assert not mcu.read8(TWCR) & TWWC
    t_clear = k.now + 1000                    # firmware answers 1000 ticks later
    k.at(t_clear, mcu.write8, TWCR, TWEN | TWINT)   # TWEA = 0: last byte
    k.run_until(t_clear + 1, stop=None)
    k.run_until(10**6, stop=lambda: bool(mcu.read8(TWCR) & TWINT))
    assert mcu.read8(TWSR) & 0xF8 == 0xC0     # master NACKs its only byte
    mcu.write8(TWCR, TWEN | TWEA | TWINT)
    k.run_until(10**6)
    assert tr.data == b"\x5a"
    # the read byte started when TWINT was cleared (the slave released SCL)
    assert tr.byte_ends[1][0] == t_clear + 9 * 80 + 8 * 80


def test_clearing_twen_releases_the_bus():
    mcu, _twi, i2c, m = make()
    mcu.write8(TWAR, 0x10)
    mcu.write8(TWCR, TWEN | TWEA)
    tr = m.write(0x08, b"\x01\x02")
    k = mcu.kernel
    k.run_until(10**6, stop=lambda: bool(mcu.read8(TWCR) & TWINT))
    assert i2c.stretched
    k.at(k.now + 3000, mcu.write8, TWCR, 0)   # firmware gives up: TWEN = 0
    k.run_until(10**7)
    assert tr.done and tr.acks == [False]     # the TWI no longer answers


def expected(kind, wdata, n, reply):
    st_ = []
    if kind in ("write", "write_read"):
        st_ += [0x60] + [0x80] * len(wdata) + [0xA0]
    data = b""
    if kind in ("read", "write_read"):
        eff = reply or b"\x00"
        st_.append(0xA8)
        for k in range(1, n + 1):
            if k > len(eff):
                data += b"\xff"
                continue
            data += eff[k - 1:k]
            if k == n:
                st_.append(0xC0)
            elif k == len(eff):
                st_.append(0xC8)
            else:
                st_.append(0xB8)
    return st_, data


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(["write", "read", "write_read"]),
                          st.binary(max_size=BUFFER_LENGTH), st.integers(1, 6)), min_size=1, max_size=5),
       st.binary(max_size=6), st.sampled_from([100_000, 400_000]), st.integers(20, 400),
       st.sampled_from([0, 0, 30, 200]))
def test_any_transaction_sequence_follows_the_datasheet(ops, reply, scl_hz, cost, clear_delay):
    mcu, twi, _i2c, m = make(scl_hz)
    # the TWCR write happens inside the handler (before RETI), else TWINT would re-enter it
    w = WireSlave(mcu, 0x08, reply=reply, cost=max(cost, clear_delay + 1), clear_delay=clear_delay)
    for kind, wdata, n in ops:
        if kind == "write":
            m.write(0x08, wdata)
        elif kind == "read":
            m.read(0x08, n)
        else:
            m.write_read(0x08, wdata, n)
    mcu.kernel.run_until(10**8)
    exp_status, exp_rx = [], []
    period = 16_000_000 // scl_hz
    for (kind, wdata, n), tr in zip(ops, m.transfers):
        s, data = expected(kind, wdata, n, reply)
        exp_status += s
        if kind != "read":
            exp_rx.append(wdata)
            assert tr.acks == [True] * len(wdata)
        assert tr.done and all(tr.addr_acks)
        assert bytes(tr.data) == data
        ends = [e[0] for e in tr.byte_ends]
        assert all(b - a >= 9 * period for a, b in itertools.pairwise(ends))
    assert w.statuses == exp_status
    assert w.received == exp_rx
    assert [s for _, s in twi.status_log] == exp_status


def test_twdr_holds_the_address_byte_received_at_a_match():
    """Datasheet (TWDR): the latest byte received on the bus, so SLA+W (0x60), SLA+R (0xA8) or the
    general call address (0x70) after a match; firmware answering several addresses through TWAMR
    reads which one from it (it read the reset value 0xFF)."""
    mcu, _twi, _i2c, m = make()
    seen = []

    def on_line(vector, level):
        if vector == 24 and level:
            seen.append((mcu.read8(TWSR) & 0xF8, mcu.read8(TWDR)))
            mcu.kernel.after(0, mcu.write8, TWCR, TWEN | TWIE | TWEA | TWINT)
    mcu.irq.line_listeners.append(on_line)
    mcu.write8(TWAR, (0x08 << 1) | 1)          # TWGCE = 1
    mcu.write8(TWAMR, 0x02 << 1)               # address bit 1 is don't-care: 0x08 and 0x0A match
    mcu.write8(TWCR, TWEN | TWIE | TWEA)
    m.write(0x0A, b"\x05")
    m.write(0x00, b"\x06")
    m.read(0x08, 1)
    mcu.kernel.run_until(3 * 10**6)
    firsts = [x for x in seen if x[0] in (0x60, 0x70, 0xA8)]
    assert firsts == [(0x60, 0x0A << 1), (0x70, 0x00), (0xA8, (0x08 << 1) | 1)]
