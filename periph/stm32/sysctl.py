"""STM32F7 flash interface (ACR) and power controller (PWR CR1/CSR1), as far as start-up and HAL
code touch them (RM0385 §3.7, §4.4). Their reset values are the state SystemClock_Config leaves
for 216 MHz: 7 flash wait states, voltage scale 1 with over-drive on.

What they do not do here: wait states and the ART accelerator do not slow the core (the cycle
model of a compiled image is the profile's cycles_per_instruction); over-drive and the
regulator scale are stored, their ready flags follow their enables at once.
"""

from __future__ import annotations

from mcusim.registers import Field, Peripheral, Register


class Flash(Peripheral):
    SIZE = 0x400
    REGISTERS = (
        Register("ACR", 0x00, reset=0x7, fields=(Field("LATENCY", 0, 4), Field("PRFTEN", 8), Field("ARTEN", 9),
                                                 Field("ARTRST", 11))),
    )

    def __init__(self, name, mcu):
        super().__init__(name)


class Pwr(Peripheral):
    SIZE = 0x400
    REGISTERS = (
        Register("CR1", 0x00, reset=(0b11 << 14) | (1 << 16) | (1 << 17), fields=(
            Field("LPDS", 0, modelled=False), Field("PDDS", 1, modelled=False), Field("CSBF", 3, access="w"),
            Field("PVDE", 4, modelled=False), Field("PLS", 5, 3), Field("DBP", 8), Field("FPDS", 9, modelled=False),
            Field("VOS", 14, 2), Field("ODEN", 16), Field("ODSWEN", 17), Field("UDEN", 18, 2, modelled=False))),
        Register("CSR1", 0x04, on_read="_read_csr1", fields=(
            Field("VOSRDY", 14, access="r"), Field("ODRDY", 16, access="r"), Field("ODSWRDY", 17, access="r"))),
    )

    def __init__(self, name, mcu):
        super().__init__(name)

    def _read_csr1(self, stored):
        cr1 = self.value["CR1"]
        return ((1 << 14) if cr1 >> 14 & 3 else 0) | ((1 << 16) if cr1 >> 16 & 1 else 0) | \
            ((1 << 17) if cr1 >> 17 & 1 else 0)
