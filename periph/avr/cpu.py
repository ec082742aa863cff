"""The AVR status register SREG (0x5F) as seen on the data bus: bit 7 is the global I flag.

The other SREG bits (C, Z, N, V, S, H, T) belong to instructions the Python firmware does not
execute; they are stored and read back. Writing SREG (``SREG = oldSREG`` after ``cli()``, as the
Arduino core does) restores I.
"""

from __future__ import annotations

from mcusim.registers import Field, Peripheral, Register


class AvrCpuRegs(Peripheral):
    BUS_WIDTH = 1
    ACCESS_SIZES = (1,)          # the AVR data bus is 8 bits wide
    REGISTERS = (
        Register("SREG", 0x5F, width=8, on_read="_read_sreg", on_write="_write_sreg",
                 fields=tuple(Field(b, i) for i, b in enumerate("CZNVSHTI"))),
    )

    def __init__(self, name, mcu):
        super().__init__(name)
        self.irq = mcu.irq

    def _read_sreg(self, stored):
        return (stored & 0x7F) | (0x80 if self.irq.i_flag else 0)

    def _write_sreg(self, old, new):
        self.irq.set_i(bool(new & 0x80))
