"""ATmega328P I/O ports B, C, D (datasheet §14 "I/O-Ports"): PINx, DDRx, PORTx.

* DDxn = 1: the pin is an output driven by PORTxn, unless an alternate function that overrides
  it (a timer's OC1A/OC1B with COM1x != 0) is connected: then the timer's waveform drives it. As
  the datasheet says, OC1x reaches the pin only while DDR makes it an output.
  Under the fast engine a timer's steady waveform passes through to the pin's net as it is.
* DDxn = 0: input; PORTxn = 1 enables the pull-up (the net reads 1 when nothing drives it).
* Reading PINx returns the pin levels (0 for a pin whose digital input the ADC's DIDR0 turned off).
  Writing 1 to PINxn toggles PORTxn.

Not modelled: the input synchroniser's 1.5-cycle delay on PINx reads (reads see the level of the
current tick), PUD in MCUCR (pull-ups are always allowed), and the pins' analog functions.
"""

from __future__ import annotations

from mcusim.registers import Field, Peripheral, Register
from mcusim.signals import pack_levels


def _bits(prefix, access="rw"):
    return tuple(Field(f"{prefix}{n}", n, access=access) for n in range(8))


class AvrPort(Peripheral):
    BUS_WIDTH = 1
    ACCESS_SIZES = (1,)          # the AVR data bus is 8 bits wide
    # offsets are relative to the port's PINx address (PINB 0x23, PINC 0x26, PIND 0x29)
    REGISTERS = (
        Register("PIN", 0, width=8, on_read="_read_pin", on_write="_write_pin", fields=_bits("PIN", "w")),
        Register("DDR", 1, width=8, on_write="_update", fields=_bits("DD")),
        Register("PORT", 2, width=8, on_write="_update", fields=_bits("PORT")),
    )

    def __init__(self, name, mcu, port: str, pins: int = 8):
        super().__init__(name)
        self.mcu, self.port = mcu, port
        self.pins = [mcu.add_pin(f"P{port}{n}") for n in range(pins)]
        self.overrides: dict[int, object] = {}  # pin -> Port of an alternate function (OC1A ...)
        self.inputs_off = 0     # pins whose digital input buffer is off (DIDR0 for port C): PIN reads 0

    def connect_override(self, n: int, port) -> None:
        """Let a peripheral output (a ``Port``, value None = not driving) take over pin ``n``."""
        self.overrides[n] = port
        # a change of the alternate function's output concerns pin n only (the other pins' drive
        # depends on DDR/PORT, and every write of those updates them all)
        # fast engine: a steady waveform (a timer's PWM) passes through an output pin as it is
        port.listen(lambda _p, n=n: self._update_pin(n, self.value["DDR"], self.value["PORT"]), waves=True)
        self._update(0, 0)

    def _read_pin(self, stored):
        return pack_levels(self.pins) & ~self.inputs_off

    def _write_pin(self, old, new):
        self.value["PORT"] ^= new & 0xFF  # writing 1 to PINxn toggles PORTxn
        self._update(0, 0)

    def _update(self, old, new):
        ddr, port = self.value["DDR"], self.value["PORT"]
        for n in range(len(self.pins)):
            self._update_pin(n, ddr, port)

    def _update_pin(self, n, ddr, port):
        net = self.pins[n]
        out = (ddr >> n) & 1
        level = None
        if out:
            alt = self.overrides.get(n)
            if alt is not None and alt.wave is not None:
                net.pull = None
                net.set_wave(self.name, alt.wave)
                return
            level = alt.value if alt is not None and alt.value is not None else (port >> n) & 1
        net.pull = 1 if (not out and (port >> n) & 1) else None
        net.set(self.name, level)
