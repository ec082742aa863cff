"""ATmega328P TWI (two-wire interface, datasheet §22 "2-wire Serial Interface") as an I2C **slave**.

Sources: the ATmega328P data sheet (TWI chapter; vectors 22-23) and ArduinoCore-avr's Wire/twi.c.

Registers (data space): TWBR 0xB8, TWSR 0xB9 (TWS7:3 read-only status, TWPS1:0), TWAR 0xBA
(TWA6:0, TWGCE), TWDR 0xBB, TWCR 0xBC (TWINT, TWEA, TWSTA, TWSTO, TWWC, TWEN, TWIE), TWAMR 0xBD.
The TWI attaches itself to an :class:`mcusim.i2c.I2cBus` as a slave (protocol in that module).

Modelled
--------
* Address recognition: own address when ``(addr ^ TWA) & ~TWAM == 0`` (TWAMR bits set = "don't
  care"), the general call (address 0, write) when TWGCE = 1; only while TWEN = 1 and TWEA = 1.
  Address 0 is only ever the general call.
* Slave receiver: 0x60 (own SLA+W, ACK), 0x70 (general call, ACK), 0x80/0x90 (data, ACK returned),
  0x88/0x98 (data, NACK returned: the TWI then switches to the not-addressed mode, so later bytes
  are NACKed by nobody's ACK and no 0xA0 follows), 0xA0 (STOP or repeated START while addressed).
  The ACK for a data byte is TWEA at the end of the byte.
* Slave transmitter: 0xA8 (own SLA+R, ACK), 0xB8 (byte sent, ACK received), 0xC0 (byte sent, NACK
  received), 0xC8 (last byte sent, TWEA was 0, ACK received). The byte shifted out is TWDR when the
  byte's clocks start (the slave releases SCL); "last byte" means TWEA = 0 at that moment. After
  0xC0/0xC8 the TWI is not addressed and the master reads 0xFF (nobody drives SDA).
* TWINT is set at the end of each byte's 9th clock (or at the STOP/Sr instant for 0xA0), requests
  vector ``vector`` (24) while TWIE = 1, is cleared only by writing 1 (NOT on vector entry), and
  while it is 1 (and TWEN = 1) the TWI **holds SCL low**: the bus does not clock the next byte, Sr
  or STOP until firmware writes TWINT = 1 (clock stretching; see mcusim.i2c for the exact timing).
  A TWINT left set from a 0xA0 also stretches the address byte of the next transfer, whoever it is
  for. TWSR reads 0xF8 ("no relevant state") while TWINT = 0.
* TWDR is writable only while TWINT = 1; a write while TWINT = 0 is ignored and sets TWWC (cleared
  by a later TWDR write with TWINT = 1).
* TWSTO = 1 in slave mode recovers from an error: the TWI goes to the not-addressed state (no STOP
  is sent); TWSTO reads back 0.
* ``twi.twint`` (a :class:`mcusim.firmware.Signal`) fires each time hardware sets TWINT, for
  firmware that polls TWINT instead of using the interrupt.
* Clearing TWEN abandons the transfer (not addressed, SCL released).

Not modelled (raise or stated)
------------------------------
* Master mode: writing TWSTA = 1 raises UnsupportedConfiguration (so 0x08-0x58 and the
  arbitration-lost codes 0x38, 0x68, 0x78, 0xB0 never occur). TWBR/TWPS are stored; they only set
  the bit rate of master mode.
* Bus error (0x00), the 16x CPU-clock minimum over SCL, slew limiting, the TWI pins' port override
  (the bus is a separate object, not the PC4/PC5 nets).
"""

from __future__ import annotations

from mcusim.errors import UnsupportedConfiguration
from mcusim.firmware import Signal
from mcusim.recent import RecentLog
from mcusim.registers import Field, Peripheral, Register

TWINT, TWEA, TWSTA, TWSTO, TWWC, TWEN, TWIE = 0x80, 0x40, 0x20, 0x10, 0x08, 0x04, 0x01
NO_INFO = 0xF8


class Twi(Peripheral):
    i2c_slave = True    # answers a master on its bus (the scenario fault i2c_silent can silence it)
    BUS_WIDTH = 1
    ACCESS_SIZES = (1,)
    REGISTERS = (
        Register("TWBR", 0xB8, width=8),
        Register("TWSR", 0xB9, width=8, reset=NO_INFO,
                 fields=(Field("TWPS", 0, 2), Field("TWS", 3, 5, access="r"))),
        Register("TWAR", 0xBA, width=8, reset=0xFE, fields=(Field("TWGCE", 0), Field("TWA", 1, 7))),
        Register("TWDR", 0xBB, width=8, reset=0xFF, on_write="_write_twdr"),
        Register("TWCR", 0xBC, width=8, on_write="_write_twcr",
                 fields=(Field("TWIE", 0), Field("TWEN", 2), Field("TWWC", 3, access="r"),
                         Field("TWSTO", 4), Field("TWSTA", 5), Field("TWEA", 6),
                         Field("TWINT", 7, access="w1c"))),
        Register("TWAMR", 0xBD, width=8, fields=(Field("TWAM", 1, 7),)),
    )

    def __init__(self, name, mcu, clock, bus, vector=24):
        super().__init__(name)
        self.mcu, self.kernel, self.irq, self.clock = mcu, mcu.kernel, mcu.irq, clock
        self.bus, self.vector = bus, vector
        self.state = "idle"     # idle (not addressed) | sr (addressed receiver) | st (transmitter)
        self.general_call = False
        self._tx_last = False
        self.status_log = RecentLog()   # (tick, status) each time TWINT is set: the recent ones
        self._holding = False
        self.twint = Signal()   # fired whenever hardware sets TWINT (for polled firmware)
        bus.attach(self)

    # --- register side ------------------------------------------------------------------------
    def _write_twdr(self, old, new):
        if not self.value["TWCR"] & TWINT:
            self.value["TWDR"] = old
            self.set_bits("TWCR", TWWC)
        else:
            self.clear_bits("TWCR", TWWC)

    def _write_twcr(self, old, new):
        if new & TWSTA:
            raise UnsupportedConfiguration(self.name, "TWCR", "TWSTA", 1,
                                           "(TWI master mode, START) is not modelled: slave only")
        if new & TWSTO:
            self.clear_bits("TWCR", TWSTO)
            self.state = "idle"  # slave-mode error recovery: not addressed, no STOP on the bus
        if not new & TWEN:
            self.state = "idle"
        if old & TWINT and not new & TWINT:
            self.value["TWSR"] = (self.value["TWSR"] & 0x03) | NO_INFO
        self._sync()

    def _sync(self):
        cr = self.value["TWCR"]
        hold = bool(cr & TWINT and cr & TWEN)
        if hold != self._holding:
            self._holding = hold
            (self.bus.hold if hold else self.bus.release)(self)
        self.irq.set_line(self.vector, bool(cr & TWINT and cr & TWIE))

    def _status(self, code):
        self.value["TWSR"] = (self.value["TWSR"] & 0x03) | code
        self.set_bits("TWCR", TWINT)
        self.status_log.append((self.kernel.now, code))
        self._sync()
        self.twint.fire()

    def _enabled(self):
        return bool(self.value["TWCR"] & TWEN)

    def _ea(self):
        return bool(self.value["TWCR"] & TWEA)

    # --- I2C slave protocol (mcusim.i2c) -------------------------------------------------------
    def i2c_start(self, repeated):
        if self._enabled() and self.state == "sr":
            self._status(0xA0)
        self.state = "idle"

    def i2c_stop(self):
        if self._enabled() and self.state == "sr":
            self._status(0xA0)
        self.state = "idle"

    def i2c_address(self, addr7, read):
        if not (self._enabled() and self._ea()):
            return False
        twa = self.value["TWAR"] >> 1
        if addr7 == 0:
            if read or not self.value["TWAR"] & 1:
                return False
            self.state, self.general_call = "sr", True
            self.value["TWDR"] = 0x00           # the byte received: the general call address
            self._status(0x70)
            return True
        if (addr7 ^ twa) & ~(self.value["TWAMR"] >> 1) & 0x7F:
            return False
        self.general_call = False
        # TWDR holds the latest byte received, here SLA+R/W: a slave answering several addresses
        # (TWAMR) reads which one from it
        self.value["TWDR"] = (addr7 << 1) | (1 if read else 0)
        if read:
            self.state = "st"
            self._status(0xA8)
        else:
            self.state = "sr"
            self._status(0x60)
        return True

    def i2c_write(self, byte):
        if self.state != "sr" or not self._enabled():
            return False
        self.value["TWDR"] = byte
        ack = self._ea()
        if ack:
            self._status(0x90 if self.general_call else 0x80)
        else:
            self.state = "idle"  # NOT ACK returned: switched to the not-addressed slave mode
            self._status(0x98 if self.general_call else 0x88)
        return ack

    def i2c_read(self):
        if self.state != "st" or not self._enabled():
            return None
        self._tx_last = not self._ea()
        return self.value["TWDR"]

    def i2c_read_done(self, ack):
        if self.state != "st" or not self._enabled():
            return
        if not ack:
            self.state = "idle"
            self._status(0xC0)
        elif self._tx_last:
            self.state = "idle"
            self._status(0xC8)
        else:
            self._status(0xB8)
