"""Wire (TwoWire) in slave mode with its driver twi.c (ArduinoCore-avr), over the TWI registers.

``TwoWire(core)``: ``begin(address)``, ``on_receive(fn)``, ``on_request(fn)``, ``available()``,
``read()``, ``write(data)``; 32-byte buffers (BUFFER_LENGTH = TWI_BUFFER_LENGTH = 32).
``twi_isr`` is ``ISR(TWI_vect)``, bound to vector 24 with a declared cost. The user callbacks run
inside the ISR, while the slave stretches the clock, as on the chip.

Known bug kept reachable (ArduinoCore-avr #116/#242, reference sheet §6): on status 0x88/0x98 (a
data byte the slave NACKed because its buffer was full) twi.c answers with TWEA = 0, so the slave
stops recognising its own address. ``variant="core"`` runs it; the default re-arms TWEA.
"""

from __future__ import annotations

TWBR, TWSR, TWAR, TWDR, TWCR = 0xB8, 0xB9, 0xBA, 0xBB, 0xBC
TWINT, TWEA, TWSTA, TWSTO, TWWC, TWEN, TWIE = 0x80, 0x40, 0x20, 0x10, 0x08, 0x04, 0x01
TWI_vect = 24
TWI_BUFFER_LENGTH = BUFFER_LENGTH = 32
TWI_ISR_CYCLES = 120  # declared: twi.c's ISR with the dispatch, without the user callbacks
TWI_FREQ = 100_000
F_CPU = 16_000_000

# status codes (util/twi.h)
TW_SR_SLA_ACK, TW_SR_ARB_LOST_SLA_ACK, TW_SR_GCALL_ACK, TW_SR_ARB_LOST_GCALL_ACK = 0x60, 0x68, 0x70, 0x78
TW_SR_DATA_ACK, TW_SR_DATA_NACK, TW_SR_GCALL_DATA_ACK, TW_SR_GCALL_DATA_NACK = 0x80, 0x88, 0x90, 0x98
TW_SR_STOP = 0xA0
TW_ST_SLA_ACK, TW_ST_ARB_LOST_SLA_ACK, TW_ST_DATA_ACK, TW_ST_DATA_NACK, TW_ST_LAST_DATA = 0xA8, 0xB0, 0xB8, 0xC0, 0xC8
TW_NO_INFO, TW_BUS_ERROR = 0xF8, 0x00
TWI_READY, TWI_SRX, TWI_STX = 0, 3, 4


class TwoWire:
    def __init__(self, core, variant: str = "fixed", isr_cycles: int = TWI_ISR_CYCLES):
        if variant not in ("fixed", "core"):
            raise ValueError("Wire variant must be 'fixed' or 'core'")
        self.core, self.bus, self.variant = core, core.bus, variant
        # Wire.cpp
        self.rx_buffer, self.rx_buffer_index, self.rx_buffer_length = bytearray(BUFFER_LENGTH), 0, 0
        self.tx_buffer_length = 0
        self.user_on_receive = None
        self.user_on_request = None
        # twi.c
        self.twi_state = TWI_READY
        self.twi_rx_buffer, self.twi_rx_buffer_index = bytearray(TWI_BUFFER_LENGTH), 0
        self.twi_tx_buffer, self.twi_tx_buffer_index, self.twi_tx_buffer_length = bytearray(TWI_BUFFER_LENGTH), 0, 0
        core.cpu.vector(TWI_vect, self.twi_isr, cost=isr_cycles)

    # --- Wire.cpp ---------------------------------------------------------------------------
    def begin(self, address: int) -> None:
        """Wire.cpp begin(address): begin() (twi_init, the slave callbacks), then twi_setAddress."""
        self.twi_init()
        self.twi_set_address(address)

    def on_receive(self, fn) -> None:
        self.user_on_receive = fn

    def on_request(self, fn) -> None:
        self.user_on_request = fn

    def available(self) -> int:
        return self.rx_buffer_length - self.rx_buffer_index

    def read(self) -> int:
        if self.rx_buffer_index < self.rx_buffer_length:
            v = self.rx_buffer[self.rx_buffer_index]
            self.rx_buffer_index += 1
            return v
        return -1

    def write(self, data) -> int:
        """In slave mode (inside on_request): append to the TWI transmit buffer. Returns the count
        given, as Wire.cpp does, whether or not twi_transmit took the bytes (a full buffer, or not
        in a slave transmit state)."""
        data = bytes([data]) if isinstance(data, int) else bytes(data)
        self.twi_transmit(data)
        return len(data)

    def _on_receive_service(self, in_bytes, num_bytes) -> None:
        if self.user_on_receive is None:
            return
        if self.rx_buffer_index < self.rx_buffer_length:
            return  # the user has not read a previous requestFrom's data: do not bump it
        self.rx_buffer[:num_bytes] = in_bytes[:num_bytes]
        self.rx_buffer_index, self.rx_buffer_length = 0, num_bytes
        self.user_on_receive(num_bytes)

    def _on_request_service(self) -> None:
        if self.user_on_request is None:
            return
        self.user_on_request()

    # --- twi.c ------------------------------------------------------------------------------
    def twi_init(self) -> None:
        self.twi_state = TWI_READY
        self.core.digital_write(18, 1)   # internal pull-ups on SDA (A4) and SCL (A5)
        self.core.digital_write(19, 1)
        self.bus.write8(TWSR, self.bus.read8(TWSR) & ~0b01)  # cbi(TWSR, TWPS0)
        self.bus.write8(TWSR, self.bus.read8(TWSR) & ~0b10)  # cbi(TWSR, TWPS1)
        self.bus.write8(TWBR, ((F_CPU // TWI_FREQ) - 16) // 2)
        self.bus.write8(TWCR, TWEN | TWIE | TWEA)

    def twi_set_address(self, address: int) -> None:
        self.bus.write8(TWAR, (address << 1) & 0xFF)

    def twi_transmit(self, data: bytes) -> int:
        if TWI_BUFFER_LENGTH < self.twi_tx_buffer_length + len(data):
            return 1
        if self.twi_state != TWI_STX:
            return 2
        for b in data:
            self.twi_tx_buffer[self.twi_tx_buffer_length] = b
            self.twi_tx_buffer_length += 1
        return 0

    def twi_reply(self, ack: bool) -> None:
        self.bus.write8(TWCR, TWEN | TWIE | TWINT | (TWEA if ack else 0))

    def twi_release_bus(self) -> None:
        self.bus.write8(TWCR, TWEN | TWIE | TWEA | TWINT)
        self.twi_state = TWI_READY

    def twi_isr(self) -> None:
        status = self.bus.read8(TWSR) & 0xF8
        if status in (TW_SR_SLA_ACK, TW_SR_GCALL_ACK, TW_SR_ARB_LOST_SLA_ACK, TW_SR_ARB_LOST_GCALL_ACK):
            self.twi_state = TWI_SRX
            self.twi_rx_buffer_index = 0
            self.twi_reply(True)
        elif status in (TW_SR_DATA_ACK, TW_SR_GCALL_DATA_ACK):
            if self.twi_rx_buffer_index < TWI_BUFFER_LENGTH:
                self.twi_rx_buffer[self.twi_rx_buffer_index] = self.bus.read8(TWDR)
                self.twi_rx_buffer_index += 1
                self.twi_reply(True)
            else:
                self.twi_reply(False)
        elif status == TW_SR_STOP:
            self.twi_release_bus()
            n = self.twi_rx_buffer_index
            if n < TWI_BUFFER_LENGTH:
                self.twi_rx_buffer[n] = 0
            self._on_receive_service(bytes(self.twi_rx_buffer), n)
            self.twi_rx_buffer_index = 0
        elif status in (TW_SR_DATA_NACK, TW_SR_GCALL_DATA_NACK):
            # twi.c: twi_reply(0), which leaves TWEA = 0: the slave goes deaf (issue #116)
            self.twi_reply(self.variant == "fixed")
        elif status in (TW_ST_SLA_ACK, TW_ST_ARB_LOST_SLA_ACK, TW_ST_DATA_ACK):
            if status != TW_ST_DATA_ACK:
                self.twi_state = TWI_STX
                self.twi_tx_buffer_index = 0
                self.twi_tx_buffer_length = 0
                self._on_request_service()
                if self.twi_tx_buffer_length == 0:
                    self.twi_tx_buffer_length = 1
                    self.twi_tx_buffer[0] = 0x00
            self.bus.write8(TWDR, self.twi_tx_buffer[self.twi_tx_buffer_index])
            self.twi_tx_buffer_index += 1
            self.twi_reply(self.twi_tx_buffer_index < self.twi_tx_buffer_length)
        elif status in (TW_ST_DATA_NACK, TW_ST_LAST_DATA):
            self.twi_reply(True)
            self.twi_state = TWI_READY
        elif status == TW_BUS_ERROR:
            self.bus.write8(TWCR, TWEN | TWIE | TWEA | TWINT | TWSTO)  # twi_stop
            self.twi_state = TWI_READY
