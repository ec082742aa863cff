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


class DbgMcu(Peripheral):
    """DBGMCU (0xE0042000, RM0385 §40.16): IDCODE with DEV_ID 0x449 (STM32F74x/75x) and REV_ID
    0x1001 (revision Z, the NUCLEO-F746ZG's; revision A reads 0x1000), CR and the APB freeze
    registers. Their bits act only while a debugger halts the core or the core sleeps under a
    debugger: stored."""
    SIZE = 0x10
    REGISTERS = (
        Register("IDCODE", 0x0, reset=0x10016449, access="r", fields=(
            Field("DEV_ID", 0, 12, access="r"), Field("REV_ID", 16, 16, access="r"))),
        Register("CR", 0x4, fields=(Field("DBG_SLEEP", 0), Field("DBG_STOP", 1), Field("DBG_STANDBY", 2),
                                    Field("TRACE_IOEN", 5), Field("TRACE_MODE", 6, 2))),
        Register("APB1_FZ", 0x8),
        Register("APB2_FZ", 0xC),
    )

    def __init__(self, name, mcu):
        super().__init__(name)


class DeviceId(Peripheral):
    """The device electronic signature in system memory (0x1FF0F420, RM0385 §41): the 96-bit
    unique ID (UID0-2; on the chip, wafer coordinates, wafer and lot number; here the profile's
    ``uid``) and the flash size in Kbytes (the half-word at 0x1FF0F442). Read only."""
    SIZE = 0x24
    REGISTERS = (
        Register("UID0", 0x00, access="r"), Register("UID1", 0x04, access="r"),
        Register("UID2", 0x08, access="r"),
        Register("FLASH_SIZE", 0x20, access="r", fields=(Field("F_SIZE", 16, 16, access="r"),)),
    )

    def __init__(self, name, mcu, uid=(0x0020001F, 0x3236510E, 0x33363138), flash_kb=1024):
        super().__init__(name)
        for k, word in enumerate(uid):
            self.value[f"UID{k}"] = word
        self.value["FLASH_SIZE"] = flash_kb << 16
