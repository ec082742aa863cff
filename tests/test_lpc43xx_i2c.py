"""LPC4337 I2C0 master (periph/lpc43xx/i2c.py) and the NuttX-style driver over it
(firmware/nuttx/lpc43_i2c.py): status sequences, SCL timing from SCLH/SCLL, clock stretching,
register rules, and the driver against a MemorySlave and against an ATmega328P TWI + Wire slave
on the same kernel.

Time base: 204 MHz and 16 MHz give 816 MHz base ticks, so one PCLK cycle is 4 ticks and one AVR
cycle 51 ticks."""

import itertools

import pytest
from lpc_rig import bare_lpc4337
from mcusim.fw.arduino.core import ArduinoCore
from mcusim.fw.arduino.wire import TwoWire
from mcusim.fw.nuttx.lpc43_i2c import (
    EINVAL,
    EIO,
    ENXIO,
    ETIMEDOUT,
    I2C_M_NOSTART,
    I2C_M_READ,
    I2cMsg,
    lpc43_i2c_init,
)
from mcusim.periph.avr.cpu import AvrCpuRegs
from mcusim.periph.avr.port import AvrPort
from mcusim.periph.avr.twi import Twi
from mcusim.periph.cortexm.systick import SysTick
from mcusim.periph.lpc43xx.i2c import I2c

from mcusim.errors import BusFault, UnsupportedConfiguration
from mcusim.firmware import Cpu, Rtos
from mcusim.i2c import I2cBus, I2cMaster, I2cSlave, MemorySlave
from mcusim.irq import SYSTICK, AvrInterrupts
from mcusim.kernel import PRIO_CPU
from mcusim.mcu import Mcu
from mcusim.registers import Bus

BASE = 0x400A1000
CONSET, STAT, DAT, ADR0, SCLH, SCLL, CONCLR, MMCTRL, BUFR, MASK0 = (
    0x00, 0x04, 0x08, 0x0C, 0x10, 0x14, 0x18, 0x1C, 0x2C, 0x30)
AA, SI, STO, STA, I2EN = 0x04, 0x08, 0x10, 0x20, 0x40
T = 4            # base ticks per PCLK cycle (816 MHz / 204 MHz)
AVR_T = 51       # base ticks per AVR cycle


def make(cpu=False):
    mcu = bare_lpc4337(cpu=cpu, extra_hz=(16_000_000,))
    bus = I2cBus(mcu.kernel, "i2c0")
    bus.log = []
    i2c = I2c("I2C0", mcu, mcu.core_clock, bus, irq=18)
    mcu.bus.attach(BASE, i2c)
    return mcu, i2c, bus


def w(mcu, off, v):
    mcu.write32(BASE + off, v)


def r(mcu, off):
    return mcu.read32(BASE + off)


class Script:
    """Register-level master firmware without a CPU model: each rising SI line is answered
    ``delay`` ticks later by reading STAT and doing what the UM's master tables say for a write of
    ``wdata`` and/or a read of ``nread`` bytes (repeated START between them)."""

    def __init__(self, mcu, addr, wdata=b"", nread=0, delay=0):
        self.mcu, self.addr, self.wdata, self.nread, self.delay = mcu, addr, bytes(wdata), nread, delay
        self.log, self.data, self.k = [], bytearray(), 0
        mcu.nvic.line_listeners.append(self._line)

    def start(self, at=0):
        self.mcu.kernel.at(at, w, self.mcu, CONSET, I2EN | STA, prio=PRIO_CPU)

    def _line(self, irqn, level):
        if irqn == 18 and level:
            self.mcu.kernel.after(self.delay, self._react, prio=PRIO_CPU)

    def _react(self):
        m = self.mcu
        code = r(m, STAT)
        self.log.append((m.kernel.now, code))
        read_first = not self.wdata and self.nread
        if code in (0x08, 0x10):
            w(m, DAT, self.addr << 1 | (1 if code == 0x10 or read_first else 0))
            w(m, CONCLR, STA)
        elif code in (0x18, 0x28):
            if self.k < len(self.wdata):
                w(m, DAT, self.wdata[self.k])
                self.k += 1
            elif self.nread:
                w(m, CONSET, STA)
            else:
                w(m, CONSET, STO)
        elif code == 0x40:
            w(m, CONSET if self.nread > 1 else CONCLR, AA)
        elif code == 0x50:
            self.data.append(r(m, DAT))
            if len(self.data) >= self.nread - 1:
                w(m, CONCLR, AA)
        elif code == 0x58:
            self.data.append(r(m, DAT))
            w(m, CONSET, STO)
        else:
            w(m, CONSET, STO)
        w(m, CONCLR, SI)


def kinds(bus):
    return [kind for _, kind, _ in bus.log]


def tick_of(bus, kind, n=0):
    return [t for t, k, _ in bus.log if k == kind][n]


# --- registers ----------------------------------------------------------------------------------

def test_reset_values_and_register_access_rules():
    mcu, _i2c, _bus = make()
    assert r(mcu, STAT) == 0xF8 and r(mcu, SCLH) == 4 and r(mcu, SCLL) == 4 and r(mcu, CONSET) == 0
    w(mcu, CONSET, AA | I2EN)
    w(mcu, CONSET, 0)                          # writing 0 to CONSET changes nothing
    assert r(mcu, CONSET) == AA | I2EN
    w(mcu, CONCLR, AA)                         # CONCLR clears ...
    assert r(mcu, CONSET) == I2EN
    assert r(mcu, CONCLR) == 0                 # ... and is write-only: reads 0
    w(mcu, STAT, 0x08)                         # STAT is read-only
    assert r(mcu, STAT) == 0xF8
    w(mcu, DAT, 0x1A5)
    w(mcu, ADR0, 0x1FF)
    w(mcu, MASK0, 0xFF)
    assert (r(mcu, DAT), r(mcu, ADR0), r(mcu, MASK0)) == (0xA5, 0xFF, 0xFE)
    with pytest.raises(BusFault):
        mcu.read8(BASE + STAT)                 # 32-bit accesses only
    with pytest.raises(BusFault, match="0x400a1040"):
        r(mcu, 0x40)


def test_mmctrl_nonzero_and_software_si_raise_unsupported_configuration():
    mcu, _i2c, _bus = make()
    with pytest.raises(UnsupportedConfiguration) as e:
        w(mcu, MMCTRL, 1)
    assert (e.value.register, e.value.field) == ("MMCTRL", "MM_ENA")
    with pytest.raises(UnsupportedConfiguration) as e:
        w(mcu, CONSET, I2EN | SI)
    assert (e.value.register, e.value.field) == ("CONSET", "SI")
    assert r(mcu, CONSET) == 0 and r(mcu, MMCTRL) == 0     # refused writes left them as they were


def test_interrupt_line_is_si_and_i2en():
    mcu, _i2c, _bus = make()
    MemorySlave(_bus, 0x50)
    w(mcu, CONSET, I2EN | STA)
    mcu.kernel.run_until(10**5)
    assert r(mcu, CONSET) == I2EN | STA | SI and r(mcu, STAT) == 0x08
    assert mcu.nvic.lines[18] and 18 in mcu.nvic.pending
    w(mcu, CONSET, STO)
    w(mcu, CONCLR, SI | STA)
    assert not mcu.nvic.lines[18] and r(mcu, STAT) == 0xF8     # SI = 0: STAT reads 0xF8 at once


# --- status sequences ---------------------------------------------------------------------------

def test_master_transmitter_status_sequence_and_stop_without_si():
    mcu, i2c, bus = make()
    slave = MemorySlave(bus, 0x50)
    s = Script(mcu, 0x50, wdata=b"\x10\xAA\xBB")
    s.start()
    mcu.kernel.run_until(10**6)
    assert [c for _, c in s.log] == [0x08, 0x18, 0x28, 0x28, 0x28]
    assert slave.mem[0x10:0x12] == b"\xAA\xBB"
    assert kinds(bus) == ["start", "addr", "write", "write", "write", "stop"]
    # STO cleared itself at the STOP; no SI after a STOP in master mode; STAT 0xF8
    assert r(mcu, CONSET) == I2EN and r(mcu, STAT) == 0xF8 and len(i2c.status_log) == 5
    assert r(mcu, BUFR) == 0xBB                 # the last byte shifted on the bus


def test_master_receiver_status_sequence_aa_decides_ack():
    mcu, _i2c, bus = make()
    slave = MemorySlave(bus, 0x50)
    slave.mem[0:3] = b"\x11\x22\x33"
    s = Script(mcu, 0x50, nread=3)
    s.start()
    mcu.kernel.run_until(10**6)
    assert [c for _, c in s.log] == [0x08, 0x40, 0x50, 0x50, 0x58]
    assert s.data == b"\x11\x22\x33" and r(mcu, BUFR) == 0x33
    assert [v for _, k, v in bus.log if k == "read"] == [(0x11, True), (0x22, True), (0x33, False)]


def test_write_then_repeated_start_read_gives_0x10():
    mcu, _i2c, bus = make()
    slave = MemorySlave(bus, 0x50)
    slave.mem[0x20:0x22] = b"\x5A\xA5"
    s = Script(mcu, 0x50, wdata=b"\x20", nread=2)
    s.start()
    mcu.kernel.run_until(10**6)
    assert [c for _, c in s.log] == [0x08, 0x18, 0x28, 0x10, 0x40, 0x50, 0x58]
    assert s.data == b"\x5A\xA5"
    assert kinds(bus) == ["start", "addr", "write", "restart", "addr", "read", "read", "stop"]


class KeepSta(Script):
    """A hand-written driver that does not clear STA after the START (the UM's 0x08 procedure
    does; LPCOpen, NuttX and mbed do)."""

    def _react(self):
        m = self.mcu
        if r(m, STAT) in (0x08, 0x10):
            self.log.append((m.kernel.now, r(m, STAT)))
            w(m, DAT, self.addr << 1)
            w(m, CONCLR, SI)            # STA still set
            return
        super()._react()


def test_sta_left_set_after_a_start_still_sends_the_address():
    """UM10503 master transmitter table: in states 0x08 and 0x10 STA is X (don't care), and the
    next action is "SLA+W will be transmitted"; CONSET.STA: a repeated START is sent only "if
    already in master mode and data has been transmitted or received". The model sent repeated
    STARTs for as long as STA stayed set, and the address never went out. STA still set after the
    address (state 0x18) then does give a repeated START, as the 0x18 row says."""
    mcu, _i2c, bus = make()
    MemorySlave(bus, 0x50)
    s = KeepSta(mcu, 0x50, wdata=b"\x10")
    s.start()
    mcu.kernel.run_until(10**6)
    assert kinds(bus)[:3] == ["start", "addr", "restart"]
    assert [c for _, c in s.log][:3] == [0x08, 0x18, 0x10]


@pytest.mark.parametrize("nread,code", [(0, 0x20), (1, 0x48)])
def test_address_nack_gives_0x20_or_0x48_and_stop(nread, code):
    mcu, _i2c, bus = make()
    MemorySlave(bus, 0x50)
    s = Script(mcu, 0x51, wdata=b"" if nread else b"\x01", nread=nread)
    s.start()
    mcu.kernel.run_until(10**6)
    assert [c for _, c in s.log] == [0x08, code]
    assert kinds(bus) == ["start", "addr", "stop"] and r(mcu, CONSET) == I2EN


class NackSecond(I2cSlave):
    def __init__(self, bus):
        self.n = 0
        bus.attach(self)

    def i2c_address(self, addr7, read):
        return addr7 == 0x40

    def i2c_write(self, byte):
        self.n += 1
        return self.n < 2


def test_data_nack_gives_0x30():
    mcu, _i2c, bus = make()
    NackSecond(bus)
    s = Script(mcu, 0x40, wdata=b"\x01\x02\x03")
    s.start()
    mcu.kernel.run_until(10**6)
    assert [c for _, c in s.log] == [0x08, 0x18, 0x28, 0x30]


def test_sto_with_sta_sends_stop_then_start():
    mcu, i2c, bus = make()
    MemorySlave(bus, 0x50)
    w(mcu, CONSET, I2EN | STA)
    mcu.kernel.run_until(10**5)
    w(mcu, DAT, 0x50 << 1)
    w(mcu, CONCLR, STA | SI)
    mcu.kernel.run_until(2 * 10**5)
    assert r(mcu, STAT) == 0x18
    w(mcu, CONSET, STO | STA)
    w(mcu, CONCLR, SI)
    mcu.kernel.run_until(3 * 10**5)
    assert kinds(bus) == ["start", "addr", "stop", "start"]
    assert [c for _, c in i2c.status_log] == [0x08, 0x18, 0x08]     # a fresh START, not 0x10
    assert tick_of(bus, "start", 1) == tick_of(bus, "stop") + 4 * T  # t_BUF = SCLL (reset 4)


def test_si_signal_wakes_a_polled_driver_at_each_status():
    """A polled master (LPCOpen's blocking style) waits on ``i2c.si`` between register polls."""
    mcu, i2c, bus = make(cpu=True)
    slave = MemorySlave(bus, 0x50)
    seen = []

    async def polled():
        w(mcu, CONSET, I2EN | STA)
        for out in (0x50 << 1, 0x07, None):
            while not r(mcu, CONSET) & SI:
                await mcu.rtos.wait_signal(i2c.si)
            seen.append((mcu.kernel.now, r(mcu, STAT)))
            if out is None:
                w(mcu, CONSET, STO)
            else:
                w(mcu, DAT, out)
            w(mcu, CONCLR, STA | SI)
    mcu.rtos.create_task("polled", polled(), 1)
    mcu.kernel.run_until(10**6)
    assert seen == [(t, c) for t, c in i2c.status_log] and [c for _, c in seen] == [0x08, 0x18, 0x28]
    assert slave.received == [0x07] and kinds(bus)[-1] == "stop" and mcu.cpu.isr_count == {}


# --- SCL timing ---------------------------------------------------------------------------------

@pytest.mark.parametrize("sclh,scll", [(510, 510), (184, 325)])
def test_byte_takes_nine_periods_of_sclh_plus_scll(sclh, scll):
    """510 + 510 PCLK cycles at 204 MHz is 200 kHz; one byte (8 bits + ACK) is 9 SCL periods from
    SCL fall to SCL fall when SI is cleared within the low time."""
    mcu, _i2c, bus = make()
    MemorySlave(bus, 0x50)
    w(mcu, SCLH, sclh)
    w(mcu, SCLL, scll)
    s = Script(mcu, 0x50, wdata=b"\x00\x01\x02")
    s.start(at=1000)
    mcu.kernel.run_until(10**6)
    H, L = sclh * T, scll * T
    assert tick_of(bus, "start") == 1000
    si = [t for t, _ in s.log]
    assert si[0] == 1000 + H                                 # SCL falls H after the START
    assert [b - a for a, b in itertools.pairwise(si)] == [9 * (H + L)] * 4
    assert tick_of(bus, "stop") == si[-1] + L + H
    if sclh == 510:
        assert 9 * (H + L) == 36_720                         # 9 * 1020 cycles * 4 ticks


def test_late_si_clear_holds_scl_low_by_exactly_the_excess():
    mcu, i2c, bus = make()
    MemorySlave(bus, 0x50)
    w(mcu, SCLH, 510)
    w(mcu, SCLL, 510)
    delay = 510 * T + 960                      # firmware answers 960 ticks after the low time
    s = Script(mcu, 0x50, wdata=b"\x00\x01", delay=delay)
    s.start()
    mcu.kernel.run_until(10**6)
    si = [t for t, _ in i2c.status_log]
    assert [t for t, _ in s.log] == [t + delay for t in si]
    assert [b - a for a, b in itertools.pairwise(si)] == [36_720 + 960] * 3
    # the STOP's SCL rise is the late answer itself; SDA rises H later
    assert tick_of(bus, "stop") == si[-1] + delay + 510 * T


def test_slave_stretch_delays_the_master_by_exactly_the_stretch():
    mcu, _i2c, bus = make()
    w(mcu, SCLH, 510)
    w(mcu, SCLL, 510)
    MemorySlave(bus, 0x50, stretch_ticks=510 * T + 148)    # holds SCL 148 ticks past the low time
    s = Script(mcu, 0x50, wdata=b"\x00\x01\x02")
    s.start()
    mcu.kernel.run_until(10**6)
    si = [t for t, _ in s.log]
    assert si[1] - si[0] == 36_720                          # the address byte follows START: no stretch
    assert [b - a for a, b in itertools.pairwise(si[1:])] == [36_720 + 148] * 3
    assert tick_of(bus, "stop") == si[-1] + 148 + 510 * T + 510 * T


def test_scl_count_below_four_raises_when_a_start_is_requested():
    mcu, _i2c, _bus = make()
    w(mcu, SCLH, 3)                            # storing it is fine ...
    with pytest.raises(UnsupportedConfiguration) as e:
        w(mcu, CONSET, I2EN | STA)             # ... using it is not
    assert (e.value.register, e.value.value) == ("SCLH", 3)
    assert r(mcu, CONSET) == 0


# --- loud failures ------------------------------------------------------------------------------

def _after_first_read_byte(nread):
    mcu, i2c, bus = make()
    MemorySlave(bus, 0x50)
    w(mcu, CONSET, I2EN | STA)
    mcu.kernel.run_until(10**5)
    w(mcu, DAT, 0x50 << 1 | 1)
    w(mcu, CONCLR, STA | SI)
    mcu.kernel.run_until(2 * 10**5)
    assert r(mcu, STAT) == 0x40
    w(mcu, CONSET if nread > 1 else CONCLR, AA)
    w(mcu, CONCLR, SI)
    return mcu, i2c, bus


def test_clearing_si_after_0x58_without_sta_or_sto_raises():
    mcu, _i2c, _bus = _after_first_read_byte(1)
    mcu.kernel.run_until(3 * 10**5)
    assert r(mcu, STAT) == 0x58
    with pytest.raises(UnsupportedConfiguration) as e:
        w(mcu, CONCLR, SI)
    assert (e.value.register, e.value.field) == ("CONCLR", "SIC")
    assert r(mcu, CONSET) & SI and r(mcu, STAT) == 0x58     # nothing changed


def test_dat_write_while_a_byte_is_shifted_raises():
    mcu, _i2c, _bus = _after_first_read_byte(2)             # a read byte is under way, SI = 0
    with pytest.raises(UnsupportedConfiguration) as e:
        w(mcu, DAT, 0x12)
    assert e.value.register == "DAT"


def test_clearing_i2en_mid_transfer_raises_and_is_allowed_when_idle():
    mcu, _i2c, bus = _after_first_read_byte(2)
    with pytest.raises(UnsupportedConfiguration) as e:
        w(mcu, CONCLR, I2EN)
    assert (e.value.register, e.value.field) == ("CONCLR", "I2ENC")
    mcu.kernel.run_until(3 * 10**5)
    w(mcu, CONSET, STO)
    w(mcu, CONCLR, SI)
    mcu.kernel.run_until(4 * 10**5)
    w(mcu, CONCLR, I2EN)                       # idle: the block switches off
    assert r(mcu, CONSET) == AA and bus.owner is None
    w(mcu, CONSET, STO)                        # STO is forced to 0 while I2EN = 0 (it read back 1)
    assert r(mcu, CONSET) == AA and bus.owner is None


def test_addressed_as_slave_with_aa_raises_and_with_aa_clear_is_nacked():
    mcu, _i2c, bus = make()
    w(mcu, ADR0, 0x30 << 1)
    other = I2cMaster(mcu.kernel, bus, scl_hz=100_000)
    w(mcu, CONSET, I2EN)                       # AA = 0: not addressable
    tr = other.write(0x30, b"\x01")
    mcu.kernel.run_until(10**6)
    assert tr.addr_acks == [False]
    w(mcu, CONSET, AA)
    other.write(0x31, b"\x01")                 # another address: not matched, NACKed
    other.write(0x30, b"\x01")
    with pytest.raises(UnsupportedConfiguration) as e:
        mcu.kernel.run_until(2 * 10**6)
    assert (e.value.register, e.value.field, e.value.value) == ("ADR0", "Address", 0x30)
    assert other.transfers[1].addr_acks == [False]


# --- the NuttX driver ---------------------------------------------------------------------------

def run_app(mcu, *coros, until="20ms"):
    out = [None] * len(coros)

    def task(k, coro):
        async def body():
            out[k] = await coro
        return body()
    for k, c in enumerate(coros):
        mcu.rtos.create_task(f"app{k}", task(k, c), 1)
    mcu.kernel.run_until(mcu.kernel.timebase.ticks(until))
    return out


def with_systick(mcu):
    st = SysTick("SysTick", mcu, mcu.core_clock, mcu.core_clock)
    mcu.bus.attach(0xE000E010, st)
    mcu.cpu.vector(SYSTICK, mcu.rtos.systick_handler, cost=40)
    mcu.write32(0xE000E014, 204_000 - 1)       # LOAD: 1 kHz tick
    mcu.write32(0xE000E018, 0)
    mcu.write32(0xE000E010, 0b111)


@pytest.mark.parametrize("hz,sclh,scll", [(100_000, 1020, 1020), (400_000, 184, 325), (200_000, 368, 651),
                                           (1_000_000, 73, 130)])
def test_driver_setfrequency_uses_nuttx_integer_arithmetic(hz, sclh, scll):
    mcu, _i2c, _bus = make(cpu=True)
    dev = lpc43_i2c_init(mcu, frequency=hz)
    assert (r(mcu, SCLH), r(mcu, SCLL)) == (sclh, scll)
    assert r(mcu, CONSET) == I2EN and mcu.read32(0xE000E100) == 1 << 18
    assert dev.frequency == hz


def test_driver_write_read_against_memory_slave_status_walk_and_timing():
    mcu, i2c, bus = make(cpu=True)
    slave = MemorySlave(bus, 0x50)
    slave.mem[0x20:0x23] = b"\x01\x02\x03"
    dev = lpc43_i2c_init(mcu, frequency=100_000)
    ret, data = run_app(mcu, dev.write_read(0x50, b"\x20", 3))[0]
    assert (ret, data) == (0, b"\x01\x02\x03")
    assert [c for _, c in i2c.status_log] == [0x08, 0x18, 0x28, 0x10, 0x40, 0x50, 0x50, 0x58]
    assert kinds(bus) == ["start", "addr", "write", "restart", "addr", "read", "read", "read", "stop"]
    assert mcu.cpu.isr_count[18] == 8
    # the START follows the declared 200-cycle set-up; the handler clears SI 12 cycles after it
    # rises, well inside the 1020-cycle low time, so every byte is exactly 9 SCL periods
    H = L = 1020 * T
    assert tick_of(bus, "start") == 200 * T
    si = [t for t, _ in i2c.status_log]
    assert si[:3] == [200 * T + H, 200 * T + H + 9 * (H + L), 200 * T + H + 18 * (H + L)]
    assert si[3] == si[2] + L + 2 * H                       # Sr: rise, SDA falls H later, SCL H later
    assert [b - a for a, b in itertools.pairwise(si[3:])] == [9 * (H + L)] * 4
    assert tick_of(bus, "stop") == si[-1] + L + H


def test_driver_absent_address_returns_enxio():
    mcu, i2c, bus = make(cpu=True)
    MemorySlave(bus, 0x50)
    dev = lpc43_i2c_init(mcu, frequency=400_000)
    wr, (rd, data), ok = run_app(mcu, dev.write(0x51, b"\x00"), dev.read(0x52, 2), dev.write(0x50, b"\x00"))
    assert (wr, rd, data, ok) == (-ENXIO, -ENXIO, b"", 0)
    assert [c for _, c in i2c.status_log] == [0x08, 0x20, 0x08, 0x48, 0x08, 0x18, 0x28]
    assert kinds(bus).count("stop") == 3


def test_driver_data_nack_returns_eio():
    mcu, _i2c, bus = make(cpu=True)
    NackSecond(bus)
    dev = lpc43_i2c_init(mcu)
    assert run_app(mcu, dev.write(0x40, b"\x01\x02\x03"))[0] == -EIO
    assert [v[1] for _, k, v in bus.log if k == "write"] == [True, False]


def test_driver_nostart_continues_the_write_without_repeated_start():
    mcu, _i2c, bus = make(cpu=True)
    slave = MemorySlave(bus, 0x50)
    dev = lpc43_i2c_init(mcu)
    msgs = [I2cMsg(0x50, 0, b"\x30"), I2cMsg(0x50, I2C_M_NOSTART, b"\x0A\x0B")]
    bad = [I2cMsg(0x50, I2C_M_READ, 1), I2cMsg(0x50, I2C_M_NOSTART | I2C_M_READ, 1)]
    ret, einval = run_app(mcu, dev.transfer(msgs), dev.transfer(bad))
    assert ret == 0 and einval == -EINVAL
    assert slave.mem[0x30:0x32] == b"\x0A\x0B"
    assert kinds(bus) == ["start", "addr", "write", "write", "write", "stop"]


def test_driver_timeout_sends_stop_after_the_hung_byte_and_returns_etimedout():
    mcu, i2c, bus = make(cpu=True)
    with_systick(mcu)
    stretch = mcu.kernel.timebase.ticks("25ms")
    slave = MemorySlave(bus, 0x50, stretch_ticks=stretch)  # holds SCL 25 ms after the address byte
    dev = lpc43_i2c_init(mcu, frequency=100_000)
    seen = {}

    async def app():
        seen["first"] = await dev.write(0x50, b"\x01\x02")
        seen["t"] = mcu.kernel.now
        slave.stretch_ticks = 0
        seen["second"] = await dev.write(0x50, b"\x10\x55")
    mcu.rtos.create_task("app", app(), 1)
    mcu.kernel.run_until(mcu.kernel.timebase.ticks("60ms"))
    assert seen["first"] == -ETIMEDOUT and seen["second"] == 0
    # 20 RTOS ticks (I2C_TIMEOUT = 20 ms): the task runs after the 20th SysTick handler (12 + 40)
    assert seen["t"] == (20 * 204_000 + 12 + 40) * T
    H = L = 1020 * T
    t_addr = tick_of(bus, "addr")
    t_data = tick_of(bus, "write")
    assert t_data == t_addr + stretch + 9 * H + 8 * L      # the hung byte finishes ...
    t_stop = tick_of(bus, "stop")
    assert t_stop == t_data + L + H                        # ... then STOP instead of SI
    assert tick_of(bus, "start", 1) == t_stop + L          # the second transfer's START (t_BUF)
    assert slave.received == [0x01, 0x10, 0x55] and slave.mem[0x10] == 0x55
    assert [c for _, c in i2c.status_log] == [0x08, 0x18, 0x08, 0x18, 0x28, 0x28]


def test_driver_timeout_when_the_interrupt_is_never_serviced():
    mcu, _i2c, bus = make(cpu=True)
    with_systick(mcu)
    MemorySlave(bus, 0x50)
    dev = lpc43_i2c_init(mcu)
    mcu.write32(0xE000E180, 1 << 18)             # ICER: the I2C0 interrupt is disabled
    ret = run_app(mcu, dev.write(0x50, b"\x01"), until="30ms")[0]
    assert ret == -ETIMEDOUT and 18 not in mcu.cpu.isr_count
    t_ret = (20 * 204_000 + 12 + 40) * T
    assert kinds(bus) == ["start", "stop"]
    # SI (0x08) was left set, so SCL was low since the START: the STOP rises at once
    assert tick_of(bus, "stop") == t_ret + 184 * T and r(mcu, CONSET) & (SI | STO) == 0


def test_two_tasks_share_the_bus_one_transfer_at_a_time():
    mcu, _i2c, bus = make(cpu=True)
    slave = MemorySlave(bus, 0x50)
    slave.mem[0:2] = b"\x0F\xF0"
    dev = lpc43_i2c_init(mcu)
    a, b = run_app(mcu, dev.write_read(0x50, b"\x00", 1), dev.write_read(0x50, b"\x01", 1))
    assert a == (0, b"\x0F") and b == (0, b"\xF0")
    assert [k for k in kinds(bus) if k in ("start", "stop")] == ["start", "stop", "start", "stop"]


# --- the driver against an ATmega328P TWI slave running Wire, on the same kernel ----------------

class WireRegs:
    """A Wire slave sketch: the first byte written selects a register, further bytes are stored
    from it; a read returns four bytes from the selected register."""

    def __init__(self, core, addr):
        self.regs = bytearray(range(0x40, 0x80))
        self.ptr = 0
        self.wire = TwoWire(core)
        self.wire.on_receive(self.receive)
        self.wire.on_request(self.request)
        self.wire.begin(addr)

    def receive(self, n):
        self.ptr = self.wire.read()
        for _ in range(n - 1):
            self.regs[self.ptr] = self.wire.read()
            self.ptr += 1
        if n > 1:
            self.ptr -= n - 1

    def request(self):
        self.wire.write(self.regs[self.ptr:self.ptr + 4])


def avr_slave(lpc, bus, addr=0x08):
    k = lpc.kernel
    clock = k.timebase.clock("AVR", 16_000_000)
    avr = Mcu("atmega328p", k, Bus("avr.bus"), clock)
    avr.irq = avr.nvic = AvrInterrupts()
    avr.bus.attach_registers(0, AvrCpuRegs("CPU", avr))
    avr.bus.attach_registers(0x26, AvrPort("PORTC", avr, "C", pins=6))
    twi = Twi("TWI", avr, clock, bus)
    avr.bus.attach_registers(0, twi)
    avr.cpu = Cpu(k, clock, avr.irq, entry_latency=4)
    avr.rtos = Rtos(avr.cpu)
    core = ArduinoCore(avr)
    core.sei()
    return twi, WireRegs(core, addr)


def test_driver_against_avr_twi_and_wire_on_one_time_base():
    mcu, i2c, bus = make(cpu=True)
    twi, sketch = avr_slave(mcu, bus, 0x08)
    dev = lpc43_i2c_init(mcu, frequency=100_000)
    seen = {}

    async def app():
        seen["w"] = await dev.write(0x08, b"\x04\xDE\xAD")
        seen["wr"] = await dev.write_read(0x08, b"\x02", 4)
        seen["nack"] = await dev.write_read(0x09, b"\x02", 4)
    mcu.rtos.create_task("app", app(), 1)
    mcu.kernel.run_until(mcu.kernel.timebase.ticks("10ms"))
    assert seen == {"w": 0, "wr": (0, b"\x42\x43\xDE\xAD"), "nack": (-ENXIO, b"")}
    assert sketch.regs[4:6] == b"\xDE\xAD"
    assert [c for _, c in twi.status_log] == [0x60, 0x80, 0x80, 0x80, 0xA0,
                                              0x60, 0x80, 0xA0, 0xA8, 0xB8, 0xB8, 0xB8, 0xC0]
    lpc = [c for _, c in i2c.status_log]
    assert lpc == [0x08, 0x18, 0x28, 0x28, 0x28,
                   0x08, 0x18, 0x28, 0x10, 0x40, 0x50, 0x50, 0x50, 0x58,
                   0x08, 0x20]
    # Wire's handler answers 4 AVR cycles after TWINT (204 ticks), inside the master's 4080-tick
    # SCL low time: the slave never stretches, every byte is 9 periods of 2040 cycles
    si = [t for t, _ in i2c.status_log]
    assert all(b - a == 9 * 2040 * T for a, b in itertools.pairwise(si[1:5]))
    assert all(b - a == 9 * 2040 * T for a, b in itertools.pairwise(si[9:14]))
    assert next(t for t, c in twi.status_log if c == 0x60) == si[1]   # both see the byte end at once


@pytest.mark.parametrize("engine", ["reference", "fast"])
def test_a_clearing_of_si_refused_for_its_scl_rate_leaves_the_master_where_it_was(engine):
    """SCLL below 4 PCLK cycles is refused when SI is cleared for the next bus action; the refused
    write changes nothing (SI was cleared and STAT read 0xF8, and the master hung owning the bus):
    with the rate put right, the same clearing sends the address."""
    import mcusim
    from mcusim.i2c import MemorySlave
    sim = mcusim.load("ciaa-edu", firmware=False, engine=engine)
    m = sim.mcu
    i2c = m.periph["I2C0"]
    MemorySlave(i2c.bus, 0x21)
    base = 0x400A1000
    m.write32(base + 0x10, 102)
    m.write32(base + 0x14, 102)
    m.write32(base + 0x00, I2EN | STA)
    sim.run(cycles=2000)
    assert m.read32(base + 0x04) == 0x08
    m.write32(base + 0x08, 0x21 << 1)
    m.write32(base + 0x14, 3)
    with pytest.raises(UnsupportedConfiguration, match="SCLL"):
        m.write32(base + 0x18, SI | STA)
    assert m.read32(base + 0x00) & SI and m.read32(base + 0x04) == 0x08
    m.write32(base + 0x14, 102)
    m.write32(base + 0x18, SI | STA)
    sim.run(cycles=20000)
    assert m.read32(base + 0x04) == 0x18           # SLA+W sent, ACK received
    sim.close()
