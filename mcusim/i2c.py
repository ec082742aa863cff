"""A shared I2C bus at byte granularity, with exact SCL timing and clock stretching.

The bus lives on the kernel's event queue. It does not simulate single bits: each byte (8 data bits
plus the ACK bit) is one step with a start (the first SCL rising edge of the byte) and an end (the
SCL falling edge after the 9th clock), so a byte costs two events. Its duration follows from the
SCL low/high times of the master that clocks it, plus any clock stretching.

Parties
=======

* **Masters** call the bus primitives below, one at a time, each with a completion callback. The
  scripted :class:`I2cMaster` is one; a model of a hardware master (the LPC4337 I2C block, whose SI
  flag holds SCL low exactly like an AVR TWINT) is another: it calls the next primitive when its
  firmware clears SI. A master object must have the attributes ``scl_low_ticks`` and
  ``scl_high_ticks`` (base ticks), read at every primitive, so a master may change its rate between
  transfers.
* **Slaves** are attached with :meth:`I2cBus.attach` and implement the slave protocol (duck-typed;
  :class:`I2cSlave` is the documented base with do-nothing defaults).

Master primitives (``cb`` is called at the instant named, at :data:`~mcusim.kernel.PRIO_HW`)
=========================================================================================

``bus.start(master, cb)``
    From an idle bus: START (SDA falls) at ``t0 = max(now, bus free time)``; SCL falls at
    ``t0 + high``, then ``cb()``. If the master already owns the bus this is a **repeated START**:
    SCL rises at ``r`` (see "SCL rise" below), SDA falls at ``r + high`` (the Sr instant), SCL falls
    at ``r + 2*high``, then ``cb()``. If another master owns the bus, the request waits until that
    master's STOP (no arbitration is modelled).
``bus.write_byte(master, byte, cb)``
    The first byte after a (repeated) START is the address byte ``addr7 << 1 | R/W``. The byte's 9
    clocks run from the SCL rise ``r`` to ``end = r + 9*high + 8*low``; at ``end`` the slaves are
    told (``i2c_address`` / ``i2c_write``) and ``cb(ack)`` follows. ``ack`` is the wired-AND of the
    slaves' answers: an address nobody claims, or data no selected slave accepts, is NACKed.
``bus.read_byte(master, ack, cb)``
    Only after an address byte with R/W = 1 was ACKed (or NACKed: then nobody drives SDA and the
    byte reads 0xFF). At the rise ``r`` the selected slave is asked for its byte (``i2c_read()``,
    ``None`` = not driving = 0xFF); ``ack`` is what the master will send on the 9th clock (True =
    ACK, False = NACK for the last byte). At ``end`` the slave gets ``i2c_read_done(ack)``, then
    ``cb(byte)``.
``bus.stop(master, cb)``
    SCL rises at ``r``; SDA rises (STOP) at ``r + high``: the slaves get ``i2c_stop()``, then
    ``cb()``. The bus is free again ``low`` ticks later (t_BUF).

SCL rise and clock stretching
-----------------------------
After a byte or a START, SCL is low from its falling edge ``e``. The next primitive's first SCL rise
is at ``r = max(e + low, t_issue, t_release)``: the master's own low time, the time the master
issued the primitive (a slow master holds SCL low too) and the time the last slave holding SCL let
go. A slave holds SCL low with ``bus.hold(slave)`` and lets go with ``bus.release(slave)``; a hold
taken while SCL is high (e.g. a TWI that sets TWINT on a STOP) applies at the next rise. So a slave
that releases ``d`` ticks after the master's low time has elapsed delays everything after it by
exactly ``d`` ticks.

Slave protocol (all optional; calls happen at the bus instants above)
====================================================================

=================================  ==============================================================
``i2c_start(repeated)``             a START (``False``) or repeated START (``True``) on the bus
``i2c_address(addr7, read) -> bool`` address byte complete; return True to ACK (claim) it
``i2c_write(byte) -> bool``          data byte from the master complete (selected slaves only);
                                    return True to ACK
``i2c_read() -> int | None``        a read byte begins: the byte to shift out, or None (not driving)
``i2c_read_done(ack)``              the read byte ended with the master's ACK (True) or NACK
``i2c_stop()``                      a STOP on the bus
=================================  ==============================================================

Every attached slave sees START/STOP; address bytes go to every slave; data bytes go to the slaves
that ACKed the address. Two slaves claiming a read address is bus contention and raises
:class:`~mcusim.errors.McusimError`. ``bus.log``, if set to a list, receives
``(tick, kind, value)`` tuples (``start``, ``restart``, ``addr``, ``write``, ``read``, ``stop``).

Nets: the optional ``sda``/``scl`` :class:`~mcusim.signals.Net` objects (give them ``pull=1``) get a
coarse trace only: SDA falls at START/Sr, SCL is shown low from the START's SCL fall, and both are
released at STOP. Bit-by-bit waveforms are not generated.

Not modelled: bit-level timing inside a byte (the ACK is decided at the byte's end), multi-master
arbitration, 10-bit addresses, set-up/hold times other than those stated above.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction

from .errors import McusimError, TimeError
from .kernel import PRIO_HW
from .recent import RecentLog


class I2cSlave:
    """Base class documenting the slave protocol; every method is optional for duck-typed slaves."""

    def i2c_start(self, repeated: bool) -> None:
        pass

    def i2c_address(self, addr7: int, read: bool) -> bool:
        return False

    def i2c_write(self, byte: int) -> bool:
        return False

    def i2c_read(self) -> int | None:
        return None

    def i2c_read_done(self, ack: bool) -> None:
        pass

    def i2c_stop(self) -> None:
        pass


def _call(slave, method, *args, default=None):
    fn = getattr(slave, method, None)
    return default if fn is None else fn(*args)


class I2cBus:
    def __init__(self, kernel, name: str = "i2c", sda=None, scl=None):
        self.kernel, self.name = kernel, name
        self.sda, self.scl = sda, scl
        self.slaves: list = []
        self.owner = None           # master owning the bus between START and STOP
        self.free_at = 0            # earliest tick for the next START (after t_BUF)
        self._waiting_masters = []  # (master, cb) wanting the bus
        self._e = 0                 # tick of the last SCL falling edge (SCL low since then)
        self._scl_high = True
        self._holders: set = set()
        self._pending = None        # (earliest rise, fn) waiting for the holders to release
        self._busy = False          # a primitive is in progress
        self._expect_address = False
        self._selected: list = []
        self._read = False
        self.log = None
        self.bytes_done = 0
        self._drive(1, 1)

    # --- slaves ------------------------------------------------------------------------------
    def attach(self, slave) -> None:
        if slave not in self.slaves:
            self.slaves.append(slave)

    def detach(self, slave) -> None:
        self.slaves.remove(slave)
        self.release(slave)

    def hold(self, slave) -> None:
        """``slave`` holds SCL low (clock stretching) until :meth:`release`."""
        self._holders.add(slave)

    def release(self, slave) -> None:
        if slave not in self._holders:
            return
        self._holders.discard(slave)
        if not self._holders and self._pending is not None:
            r0, fn = self._pending
            self._pending = None
            self.kernel.at(max(r0, self.kernel.now), self._rise, fn, prio=PRIO_HW)

    @property
    def stretched(self) -> bool:
        return bool(self._holders)

    # --- master primitives -----------------------------------------------------------------
    def start(self, master, cb) -> None:
        if self.owner is None:
            self._begin_busy()
            self.owner = master
            self.kernel.at(max(self.kernel.now, self.free_at), self._start_idle, master, cb, prio=PRIO_HW)
        elif self.owner is master:
            self._begin_busy()
            self._after_rise(master, lambda r: self._restart(master, r, cb))
        else:
            self._waiting_masters.append((master, cb))

    def write_byte(self, master, byte: int, cb) -> None:
        self._check_owner(master, "write_byte")
        if not 0 <= byte <= 0xFF:
            raise McusimError(f"{self.name}: byte {byte!r} out of range")
        self._begin_busy()
        self._after_rise(master, lambda r: self._write_rise(master, byte, r, cb))

    def read_byte(self, master, ack: bool, cb) -> None:
        self._check_owner(master, "read_byte")
        if self._expect_address:
            raise McusimError(f"{self.name}: read_byte right after START: the address byte comes first")
        if not self._read:
            raise McusimError(f"{self.name}: read_byte in a write transfer (address R/W bit was 0)")
        self._begin_busy()
        self._after_rise(master, lambda r: self._read_rise(master, bool(ack), r, cb))

    def stop(self, master, cb=None) -> None:
        self._check_owner(master, "stop")
        self._begin_busy()
        self._after_rise(master, lambda r: self._stop_rise(master, r, cb))

    # --- internals ----------------------------------------------------------------------------
    def _check_owner(self, master, what):
        if self.owner is not master:
            raise McusimError(f"{self.name}: {what} by a master that does not own the bus (no START)")

    def _begin_busy(self):
        if self._busy:
            raise McusimError(f"{self.name}: a master primitive was issued while the previous one runs")
        self._busy = True

    def _log(self, kind, value=None):
        if self.log is not None:
            self.log.append((self.kernel.now, kind, value))

    def _drive(self, sda, scl):
        # coarse trace: levels at START/STOP/byte boundaries (not bit by bit)
        if self.sda is not None:
            self.sda.set(self.name, None if sda else 0)
        if self.scl is not None:
            self.scl.set(self.name, None if scl else 0)

    def _after_rise(self, master, fn):
        """Run ``fn(r)`` at the next SCL rise: max(e + low, now, release of every holder)."""
        r0 = max(self._e + master.scl_low_ticks, self.kernel.now)
        self.kernel.at(r0, self._try_rise, r0, fn, prio=PRIO_HW)

    def _try_rise(self, r0, fn):
        if self._holders:
            self._pending = (r0, fn)
        else:
            self._rise(fn)

    def _rise(self, fn):
        self._scl_high = True
        fn(self.kernel.now)

    def _fall(self):
        self._e = self.kernel.now
        self._scl_high = False

    def _start_idle(self, master, cb):
        self._log("start")
        self._drive(0, 1)
        for s in list(self.slaves):
            _call(s, "i2c_start", False)
        self._expect_address, self._selected, self._read = True, [], False
        self.kernel.at(self.kernel.now + master.scl_high_ticks, self._start_done, cb, prio=PRIO_HW)

    def _restart(self, master, r, cb):
        self.kernel.at(r + master.scl_high_ticks, self._restart_cond, master, cb, prio=PRIO_HW)

    def _restart_cond(self, master, cb):
        self._log("restart")
        for s in list(self.slaves):
            _call(s, "i2c_start", True)
        self._expect_address, self._selected, self._read = True, [], False
        self.kernel.at(self.kernel.now + master.scl_high_ticks, self._start_done, cb, prio=PRIO_HW)

    def _start_done(self, cb):
        self._fall()
        self._drive(0, 0)
        self._busy = False
        cb()

    def _byte_end_tick(self, master, r):
        return r + 9 * master.scl_high_ticks + 8 * master.scl_low_ticks

    def _write_rise(self, master, byte, r, cb):
        self.kernel.at(self._byte_end_tick(master, r), self._write_end, byte, cb, prio=PRIO_HW)

    def _write_end(self, byte, cb):
        self._fall()
        self.bytes_done += 1
        if self._expect_address:
            self._expect_address = False
            addr7, read = byte >> 1, bool(byte & 1)
            self._read = read
            self._selected = [s for s in list(self.slaves) if _call(s, "i2c_address", addr7, read, default=False)]
            if read and len(self._selected) > 1:
                raise McusimError(f"{self.name}: {len(self._selected)} slaves claim read address {addr7:#04x}")
            ack = bool(self._selected)
            self._log("addr", (byte, ack))
        else:
            answers = [bool(_call(s, "i2c_write", byte, default=False)) for s in self._selected]
            ack = any(answers)
            self._log("write", (byte, ack))
        self._busy = False
        cb(ack)

    def _read_rise(self, master, ack, r, cb):
        value = None
        if self._selected:
            value = _call(self._selected[0], "i2c_read")
        value = 0xFF if value is None else value & 0xFF
        self.kernel.at(self._byte_end_tick(master, r), self._read_end, value, ack, cb, prio=PRIO_HW)

    def _read_end(self, value, ack, cb):
        self._fall()
        self.bytes_done += 1
        for s in self._selected:
            _call(s, "i2c_read_done", ack)
        self._log("read", (value, ack))
        self._busy = False
        cb(value)

    def _stop_rise(self, master, r, cb):
        self.kernel.at(r + master.scl_high_ticks, self._stop_cond, master, cb, prio=PRIO_HW)

    def _stop_cond(self, master, cb):
        self._log("stop")
        self._drive(1, 1)
        self._scl_high = True
        self.owner = None
        self._selected, self._expect_address, self._read = [], False, False
        self.free_at = self.kernel.now + master.scl_low_ticks
        self._busy = False
        for s in list(self.slaves):
            _call(s, "i2c_stop")
        if cb is not None:
            cb()
        if self.owner is None and self._waiting_masters:
            m, mcb = self._waiting_masters.pop(0)
            self.start(m, mcb)


# --- scripted master ------------------------------------------------------------------------------

@dataclass
class I2cTransfer:
    """One scripted transaction and what happened on the bus."""
    kind: str                      # "write" | "read" | "write_read"
    addr: int
    wdata: bytes = b""
    nread: int = 0
    addr_acks: list = field(default_factory=list)   # ACK of each address byte (two for write_read)
    acks: list = field(default_factory=list)        # ACK of each data byte written
    data: bytearray = field(default_factory=bytearray)  # bytes read
    byte_ends: list = field(default_factory=list)   # (tick, "addr"|"write"|"read", byte, ack)
    t_start: int | None = None     # START instant
    t_stop: int | None = None      # STOP instant
    done: bool = False

    @property
    def ok(self) -> bool:
        return all(self.addr_acks) and all(self.acks) and len(self.data) == self.nread


class I2cMaster:
    """A scripted bus master for tests and scenarios (START, address, data, Sr, STOP).

    ``scl_hz`` sets SCL low = ceil(period / 2) and high = floor(period / 2) base ticks; the period
    must be a whole number of base ticks (``TimeError`` otherwise) unless ``scl_low_ticks`` and
    ``scl_high_ticks`` are given. Transactions queue and run back to back. Writes stop at the first
    NACK (as the Arduino Wire master does), reads ACK every byte but the last, and a NACKed address
    ends the transaction with a STOP.
    """

    def __init__(self, kernel, bus: I2cBus, scl_hz=100_000, *, scl_low_ticks: int | None = None,
                 scl_high_ticks: int | None = None, name: str = "master"):
        self.kernel, self.bus, self.name = kernel, bus, name
        if scl_low_ticks is None or scl_high_ticks is None:
            period = Fraction(kernel.timebase.base_hz) / Fraction(scl_hz)
            if period.denominator != 1:
                raise TimeError(f"{name}: SCL {scl_hz} Hz is not a whole number of base ticks "
                                f"at {kernel.timebase.base_hz} Hz")
            period = int(period)
            if period < 2:
                raise TimeError(f"{name}: SCL {scl_hz} Hz is too fast for the base tick")
            scl_high_ticks, scl_low_ticks = period // 2, period - period // 2
        self.scl_low_ticks, self.scl_high_ticks = int(scl_low_ticks), int(scl_high_ticks)
        self._queue: list = []
        self._current = None
        self.transfers: RecentLog = RecentLog()     # the recent ones (mcusim.recent)

    @property
    def busy(self) -> bool:
        return self._current is not None or bool(self._queue)

    # --- user API ---------------------------------------------------------------------------
    def write(self, addr: int, data: bytes, callback=None) -> I2cTransfer:
        return self._submit(I2cTransfer("write", addr, bytes(data)), callback)

    def read(self, addr: int, n: int, callback=None) -> I2cTransfer:
        return self._submit(I2cTransfer("read", addr, nread=n), callback)

    def write_read(self, addr: int, data: bytes, n: int, callback=None) -> I2cTransfer:
        """Write ``data``, repeated START, read ``n`` bytes, STOP."""
        return self._submit(I2cTransfer("write_read", addr, bytes(data), nread=n), callback)

    # --- engine -------------------------------------------------------------------------------
    def _submit(self, tr: I2cTransfer, callback):
        if not 0 <= tr.addr <= 0x7F:
            raise McusimError(f"{self.name}: I2C address {tr.addr!r} is not 7-bit")
        if tr.nread < 0 or (tr.kind != "write" and tr.nread == 0):
            raise McusimError(f"{self.name}: a read needs at least one byte")
        self.transfers.append(tr)
        self._queue.append((tr, callback))
        if self._current is None:
            self._next()
        return tr

    def _next(self):
        if not self._queue:
            self._current = None
            return
        self._current = self._queue.pop(0)
        tr = self._current[0]
        self._steps = self._plan(tr)
        self._do_step()

    @staticmethod
    def _plan(tr):
        steps = ["start"]
        if tr.kind in ("write", "write_read"):
            steps.append(("addr", tr.addr << 1))
            steps += [("w", b) for b in tr.wdata]
        if tr.kind == "write_read":
            steps.append("restart")
        if tr.kind in ("read", "write_read"):
            steps.append(("addr", tr.addr << 1 | 1))
            steps += [("r", k < tr.nread - 1) for k in range(tr.nread)]
        steps.append("stop")
        return steps

    def _do_step(self):
        step = self._steps.pop(0)
        bus = self.bus
        if step == "start":
            bus.start(self, self._started)
        elif step == "restart":
            bus.start(self, self._step_done)
        elif step == "stop":
            bus.stop(self, self._stopped)
        elif step[0] == "addr":
            bus.write_byte(self, step[1], lambda ack, b=step[1]: self._addr_done(b, ack))
        elif step[0] == "w":
            bus.write_byte(self, step[1], lambda ack, b=step[1]: self._write_done(b, ack))
        else:
            bus.read_byte(self, step[1], lambda v, a=step[1]: self._read_done(v, a))

    def _started(self):
        # the START instant was high ticks before this SCL fall
        self._current[0].t_start = self.kernel.now - self.scl_high_ticks
        self._do_step()

    def _step_done(self):
        self._do_step()

    def _abort(self):
        self._steps = ["stop"]
        self._do_step()

    def _addr_done(self, byte, ack):
        tr = self._current[0]
        tr.addr_acks.append(ack)
        tr.byte_ends.append((self.kernel.now, "addr", byte, ack))
        self._abort() if not ack else self._do_step()

    def _write_done(self, byte, ack):
        tr = self._current[0]
        tr.acks.append(ack)
        tr.byte_ends.append((self.kernel.now, "write", byte, ack))
        self._abort() if not ack else self._do_step()

    def _read_done(self, value, ack):
        tr = self._current[0]
        tr.data.append(value)
        tr.byte_ends.append((self.kernel.now, "read", value, ack))
        self._do_step()

    def _stopped(self):
        tr, cb = self._current
        tr.t_stop, tr.done = self.kernel.now, True
        self._current = None
        if cb is not None:
            cb(tr)
        if self._current is None:
            self._next()


# --- a simple slave for tests and scenarios ------------------------------------------------------

class MemorySlave(I2cSlave):
    """A register-file slave (like an EEPROM/sensor): the first byte written sets the pointer,
    further bytes are stored at it (auto-increment); reads return bytes from the pointer.
    ``stretch_ticks`` > 0 holds SCL that long after every byte it ACKs (for tests)."""

    def __init__(self, bus: I2cBus, addr: int, size: int = 256, stretch_ticks: int = 0):
        self.bus, self.addr = bus, addr
        self.mem = bytearray(size)
        self.ptr = 0
        self.stretch_ticks = stretch_ticks
        self.received: list[int] = []
        self._first = False
        bus.attach(self)

    def _stretch(self):
        if self.stretch_ticks:
            self.bus.hold(self)
            self.bus.kernel.after(self.stretch_ticks, self.bus.release, self)

    def i2c_address(self, addr7, read):
        if addr7 != self.addr:
            return False
        self._first = not read
        self._stretch()
        return True

    def i2c_write(self, byte):
        self.received.append(byte)
        if self._first:
            self.ptr, self._first = byte % len(self.mem), False
        else:
            self.mem[self.ptr] = byte
            self.ptr = (self.ptr + 1) % len(self.mem)
        self._stretch()
        return True

    def i2c_read(self):
        v = self.mem[self.ptr]
        self.ptr = (self.ptr + 1) % len(self.mem)
        return v
