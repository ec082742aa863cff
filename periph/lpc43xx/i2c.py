"""LPC4337 I2C0 (UM10503 chapter "I2C-bus interface"; the same block as LPC17xx/LPC11xx I2C) as a
bus **master** on an :class:`mcusim.i2c.I2cBus`.

Sources: NXP UM10503 and the EDU-CIAA-NXP schematic (I2C0 at 0x400A1000, IRQ 18, the
EDU-CIAA's dedicated pins P1.19/P1.21 with 2.2 kΩ pull-ups). The master-side twin of the ATmega TWI
slave in :mod:`mcusim.periph.avr.twi`: SI plays the role of TWINT.

Registers (offsets from the base; 32-bit accesses only)
=======================================================

=========== ====== ========================================================================
CONSET      0x00   AA (2), SI (3), STO (4), STA (5), I2EN (6): writing 1 sets, 0 has no effect;
                   reads return the control bits
STAT        0x04   status code (bits 7:3; bits 2:0 read 0); 0xF8 whenever SI = 0; read-only
DAT         0x08   data / address byte to send, byte received
ADR0..3     0x0C, 0x20, 0x24, 0x28   GC (0), Address (7:1): own slave addresses (see below)
SCLH, SCLL  0x10, 0x14   SCL high / low time in PCLK cycles (16 bits, reset 4)
CONCLR      0x18   AAC (2), SIC (3), STAC (5), I2ENC (6): writing 1 clears the CONSET bit.
                   Write-only: reads return 0 (the ``w`` access kind of mcusim.registers) [I]
MMCTRL      0x1C   monitor mode: not modelled, any non-zero value raises
DATA_BUFFER 0x2C   read-only: the byte of the last 9 bits shifted on the bus
MASK0..3    0x30..0x3C   address masks (7:1)
=========== ====== ========================================================================

Master transmitter / receiver
=============================
Status codes (the STAT value while SI = 1), each set at the SCL falling edge that ends the step:
0x08 START sent, 0x10 repeated START sent, 0x18/0x20 SLA+W sent, ACK/NACK received, 0x28/0x30
data sent, ACK/NACK received, 0x40/0x48 SLA+R sent, ACK/NACK received, 0x50/0x58 data received,
ACK/NACK returned. While SI = 1 the block holds SCL low: nothing happens on the bus until firmware
clears SI (CONCLR.SIC); the action then taken is the one of the UM's master state tables:

* STO = 1 (with or without STA): STOP. STO self-clears when the STOP is on the bus; STAT reads
  0xF8 and SI is **not** set after a STOP. With STA = 1 as well, a START follows the STOP (0x08).
* after 0x08/0x10: DAT is sent as the address byte (SLA+R/W, its bit 0 is the direction), whatever
  STA says (STA is X in these rows of the tables; the UM's procedure clears it here).
* otherwise STA = 1: repeated START (0x10). STA stays set until firmware clears it (CONCLR.STAC),
  as on the chip: clearing SI after the address with STA still set sends another repeated START.
* after 0x18/0x20/0x28/0x30: DAT is sent as a data byte (after a NACK the UM allows this too; the
  byte is then NACKed by nobody's ACK).
* after 0x40/0x50: a byte is received; AA at this instant decides whether the master ACKs it
  (0x50) or NACKs it (0x58).
* after 0x48/0x58 the UM defines only Sr, STOP or STOP+START: clearing SI with neither STA nor STO
  raises ``UnsupportedConfiguration`` (CONCLR.SIC).

Setting STA while the block is idle (I2EN = 1, SI = 0, not owning the bus) requests a START: at
once on a free bus, else after the bus-free time or after another master's STOP (mcusim.i2c). A
primitive issued late (firmware clearing SI after the SCL low time elapsed) holds SCL low, so the
bus's stretching rule gives the exact timing: one byte is ``9 * (SCLH + SCLL)`` PCLK cycles from
SCL fall to SCL fall when SI is cleared within the low time.

SI drives the interrupt line ``irq`` (level: SI AND I2EN, into the NVIC) and fires ``self.si``
(a :class:`mcusim.firmware.Signal`) for polled drivers.

Decisions (stated; [I] = inferred, not from the manual)
-------------------------------------------------------
* SCL timing: ``scl_high_ticks = SCLH * PCLK period``, ``scl_low_ticks = SCLL * PCLK period``, read
  at every bus primitive (a rate change takes effect at the next byte). The manual asks for SCLH
  and SCLL each >= 4 (the reset value; UM10360 §19.8.5 wording recalled, not re-verified here [I]):
  issuing a bus action with either below 4 raises ``UnsupportedConfiguration`` naming the register
  (checked where the value is used, so the order of the two writes does not matter).
* STO set while SI = 0 and a byte (or a START waiting for the bus) is under way: the byte finishes,
  then the STOP is sent instead of setting SI for that byte (its status is never seen) [I]. A
  driver giving up on a hung bus relies on this. STO set while not owning the bus is the UM's
  "recover from an error" case: it clears at once and nothing appears on the bus.
* Clearing I2EN (CONCLR.I2ENC) while the block owns the bus, has a primitive under way or a START
  requested raises ``UnsupportedConfiguration`` (on the chip it abandons the transfer without a
  STOP, leaving the slaves mid-transfer; the byte-level bus cannot express that). While idle it
  disables the block; STO is forced to 0 as the UM says (also a CONSET.STO written while I2EN = 0).
* Writing 1 to CONSET.SI raises (setting SI from software is not modelled). Writing DAT while a
  byte is being shifted (SI = 0) raises: the UM allows DAT access only while SI = 1.
* Clearing STA after a START was requested does not cancel it (the bus has no cancel) [I].
* DATA_BUFFER takes the byte at the end of every byte on the bus (address, sent and received data),
  which is when the UM says DAT's top 8 bits are copied to it [I for the sent bytes].
* Slave mode: the block listens on the bus only to refuse loudly. An address byte from another
  master that matches an own address (ADRn/MASKn, or the general call with ADRn.GC = 1) while
  I2EN = 1 and AA = 1 raises ``UnsupportedConfiguration`` (ADRn.Address), since the slave states
  0x60-0xC8 are not modelled. With the reset ADRn = 0 nothing matches, so a master-only driver that
  leaves AA = 1 (NuttX does, on every STOP) is never addressed.
* 0x38 (arbitration lost) cannot happen: the bus model has no arbitration, a second master waits
  for the STOP. 0x00 (bus error) is not modelled either.
"""

from __future__ import annotations

from mcusim.errors import UnsupportedConfiguration
from mcusim.firmware import Signal
from mcusim.recent import RecentLog
from mcusim.registers import Field, Peripheral, Register

from .cgu import BaseClockUser

AA, SI, STO, STA, I2EN = 0x04, 0x08, 0x10, 0x20, 0x40
CONTROL_BITS = AA | SI | STO | STA | I2EN
NO_INFO = 0xF8
SCL_MIN = 4

# status codes (UM master transmitter / receiver tables)
START, RESTART = 0x08, 0x10
SLAW_ACK, SLAW_NACK, DATA_TX_ACK, DATA_TX_NACK = 0x18, 0x20, 0x28, 0x30
ARB_LOST = 0x38
SLAR_ACK, SLAR_NACK, DATA_RX_ACK, DATA_RX_NACK = 0x40, 0x48, 0x50, 0x58


def _adr(name, offset):
    return Register(name, offset, fields=(Field("GC", 0), Field("Address", 1, 7)))


def _mask(name, offset):
    return Register(name, offset, fields=(Field("MASK", 1, 7),))


class I2c(BaseClockUser, Peripheral):
    i2c_slave = False   # a master: its slave mode is not modelled (refused when addressed)
    BUS_WIDTH = 4
    ACCESS_SIZES = (4,)
    REGISTERS = (
        Register("CONSET", 0x00, on_write="_write_conset",
                 fields=(Field("AA", 2), Field("SI", 3), Field("STO", 4), Field("STA", 5), Field("I2EN", 6))),
        Register("STAT", 0x04, reset=NO_INFO, fields=(Field("Status", 3, 5, access="r"),)),
        Register("DAT", 0x08, on_write="_write_dat", fields=(Field("Data", 0, 8),)),
        _adr("ADR0", 0x0C),
        Register("SCLH", 0x10, reset=4, fields=(Field("SCLH", 0, 16),)),
        Register("SCLL", 0x14, reset=4, fields=(Field("SCLL", 0, 16),)),
        Register("CONCLR", 0x18, on_write="_write_conclr",
                 fields=(Field("AAC", 2, access="w"), Field("SIC", 3, access="w"),
                         Field("STAC", 5, access="w"), Field("I2ENC", 6, access="w"))),
        Register("MMCTRL", 0x1C, fields=(Field("MM_ENA", 0, modelled=False), Field("ENA_SCL", 1, modelled=False),
                                         Field("MATCH_ALL", 2, modelled=False))),
        _adr("ADR1", 0x20),
        _adr("ADR2", 0x24),
        _adr("ADR3", 0x28),
        Register("DATA_BUFFER", 0x2C, fields=(Field("Data", 0, 8, access="r"),)),
        _mask("MASK0", 0x30),
        _mask("MASK1", 0x34),
        _mask("MASK2", 0x38),
        _mask("MASK3", 0x3C),
    )

    def __init__(self, name, mcu, clock, bus, irq=18, base_clock=""):
        super().__init__(name)
        self.mcu, self.kernel, self.nvic, self.clock = mcu, mcu.kernel, mcu.irq, clock
        self.bus, self.irq = bus, irq
        self._init_base_clock(base_clock)
        self.si = Signal()          # fired whenever hardware sets SI (for polled firmware)
        self.status_log = RecentLog()    # (tick, status) each time SI is set: the recent ones
        self._owner = False         # between our START and our STOP
        self._inflight = None       # "start" | "addr" | "write" | "read" | "stop" | None
        self._code = NO_INFO        # status of the step that set SI
        self._addr_read = False
        bus.attach(self)

    # --- SCL timing read by the bus at every primitive ----------------------------------------
    @property
    def scl_high_ticks(self) -> int:
        return self.value["SCLH"] * self.clock.period

    @property
    def scl_low_ticks(self) -> int:
        return self.value["SCLL"] * self.clock.period

    def _check_rate(self):
        for reg in ("SCLH", "SCLL"):
            v = self.value[reg]
            if v < SCL_MIN:
                raise UnsupportedConfiguration(self.name, reg, reg, v,
                                               f"is below the minimum of {SCL_MIN} PCLK cycles (UM: SCLH, "
                                               f"SCLL >= 4); a bus action was requested with it")

    # --- register side ------------------------------------------------------------------------
    @property
    def _con(self) -> int:
        return self.value["CONSET"]

    def _write_conset(self, old, new):
        set_bits = new & CONTROL_BITS & ~old
        self.value["CONSET"] = old | (new & CONTROL_BITS)   # writing 0 has no effect
        if set_bits & SI:
            raise UnsupportedConfiguration(self.name, "CONSET", "SI", 1,
                                           "(setting SI from software) is not modelled")
        con = self._con
        if not con & I2EN:
            self.clear_bits("CONSET", STO)   # forced to 0 while the block is disabled
            self._sync()
            return
        if con & STO and not self._owner and self._inflight is None:
            self.clear_bits("CONSET", STO)   # not in master mode: error recovery, nothing on the bus
        con = self._con
        if con & STA and not self._owner and self._inflight is None and not con & SI:
            try:
                self._check_base_clock()
                self._check_rate()
            except UnsupportedConfiguration:
                self.value["CONSET"] = old      # refused: CONSET as it was (the START not asked)
                raise
            self._issue_start()
        self._sync()

    def _write_conclr(self, old, new):
        con = self._con
        clear = new & (AA | SI | STA | I2EN)
        if clear & I2EN and con & I2EN and (self._owner or self._inflight is not None):
            raise UnsupportedConfiguration(self.name, "CONCLR", "I2ENC", 1,
                                           "while the master owns the bus or has a bus action under way "
                                           "(abandoning a transfer without a STOP) is not modelled")
        si_falls = bool(con & SI and clear & SI)
        after = con & ~clear
        action = None
        if si_falls and after & I2EN and self._owner:
            action = self._action(after)   # may raise: then nothing has changed
            if action is not None:
                self._check_rate()         # (the action checks it too, after the state changed)
        self.value["CONSET"] = after
        if not after & I2EN:
            self.clear_bits("CONSET", STO)
        if si_falls:
            self.value["STAT"] = NO_INFO
        self._sync()
        if action is not None:
            action()

    def _write_dat(self, old, new):
        if self._inflight in ("addr", "write", "read"):
            self.value["DAT"] = old
            raise UnsupportedConfiguration(self.name, "DAT", "Data", new,
                                           "written while a byte is being shifted (SI = 0): the UM allows "
                                           "DAT access only while SI = 1")

    def _sync(self):
        con = self._con
        self.nvic.set_line(self.irq, bool(con & SI and con & I2EN))

    # --- master state machine -------------------------------------------------------------------
    def _action(self, con):
        """The bus action for SI being cleared in master mode with control bits ``con``."""
        code = self._code
        if con & STO:
            return self._issue_stop
        if code in (START, RESTART):
            # the master tables give STA as X (don't care) in 0x08/0x10: the address goes out
            # whatever STA says (CONSET.STA: a repeated START only "if already in master mode and
            # data has been transmitted or received"); a STA left set acts after the address
            return self._issue_addr
        if con & STA:
            return self._issue_start
        if code in (SLAW_ACK, SLAW_NACK, DATA_TX_ACK, DATA_TX_NACK):
            return self._issue_write
        if code in (SLAR_ACK, DATA_RX_ACK):
            return self._issue_read
        raise UnsupportedConfiguration(self.name, "CONCLR", "SIC", 1,
                                       f"after status {code:#04x} with neither STA nor STO: the UM defines "
                                       f"only repeated START, STOP or STOP+START here")

    def _issue_start(self):
        self._check_base_clock()
        self._check_rate()
        repeated = self._owner
        self._inflight = "start"
        self.bus.start(self, lambda: self._started(repeated))

    def _issue_addr(self):
        self._check_rate()
        byte = self.value["DAT"] & 0xFF
        self._addr_read = bool(byte & 1)
        self._inflight = "addr"
        self.bus.write_byte(self, byte, lambda ack: self._addr_done(byte, ack))

    def _issue_write(self):
        self._check_rate()
        byte = self.value["DAT"] & 0xFF
        self._inflight = "write"
        self.bus.write_byte(self, byte, lambda ack: self._write_done(byte, ack))

    def _issue_read(self):
        self._check_rate()
        ack = bool(self._con & AA)
        self._inflight = "read"
        self.bus.read_byte(self, ack, lambda value: self._read_done(value, ack))

    def _issue_stop(self):
        self._check_rate()
        self._inflight = "stop"
        self.bus.stop(self, self._stopped)

    def _started(self, repeated):
        self._owner = True
        self._step_done(RESTART if repeated else START)

    def _addr_done(self, byte, ack):
        self.value["DATA_BUFFER"] = byte
        if self._addr_read:
            self._step_done(SLAR_ACK if ack else SLAR_NACK)
        else:
            self._step_done(SLAW_ACK if ack else SLAW_NACK)

    def _write_done(self, byte, ack):
        self.value["DATA_BUFFER"] = byte
        self._step_done(DATA_TX_ACK if ack else DATA_TX_NACK)

    def _read_done(self, value, ack):
        self.value["DAT"] = value
        self.value["DATA_BUFFER"] = value
        self._step_done(DATA_RX_ACK if ack else DATA_RX_NACK)

    def _step_done(self, code):
        self._inflight = None
        if self._con & STO:          # STO requested while the step ran: STOP instead of SI [I]
            self._issue_stop()
            return
        self._code = code
        self.value["STAT"] = code
        self.set_bits("CONSET", SI)
        self.status_log.append((self.kernel.now, code))
        self._sync()
        self.si.fire()

    def _stopped(self):
        self._inflight = None
        self._owner = False
        self._code = NO_INFO
        self.clear_bits("CONSET", STO)
        self.value["STAT"] = NO_INFO
        con = self._con
        if con & STA and con & I2EN:
            self._issue_start()      # STO + STA: a START follows the STOP

    # --- slave side: refuse loudly ---------------------------------------------------------------
    def i2c_address(self, addr7, read):
        if self.bus.owner is self:
            return False             # our own address byte
        con = self._con
        if not (con & I2EN and con & AA):
            return False
        for k in range(4):
            adr, mask = self.value[f"ADR{k}"], self.value[f"MASK{k}"]
            if addr7 == 0:
                hit = not read and bool(adr & 1)
            else:
                hit = not ((addr7 ^ (adr >> 1)) & ~(mask >> 1) & 0x7F)
            if hit:
                raise UnsupportedConfiguration(self.name, f"ADR{k}", "Address", adr >> 1,
                                               f"matched address {addr7:#04x} from another master with "
                                               f"AA = 1: I2C slave mode is not modelled")
        return False
