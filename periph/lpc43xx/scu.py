"""LPC43xx system control unit (SCU, pin configuration; UM10503 chapter 16) and configuration
registers (CREG; chapter 11), as LPCOpen's Chip_SCU_* and Chip_CREG_* and its start-up touch them.

SCU: every register is stored and reads back as written: the pin configuration registers
SFSPx_y of ports 0-9 and A-F (offset 0x80 per port, 4 per pin), SFSCLK0-3, SFSUSB, SFSI2C0,
ENAIO0-2, EMCDELAYCLK, SDDELAY, PINTSEL0-1. Pin function selection is not modelled beyond
storing: a GPIO, ADC, I2C or USART pin works whatever function its SFS register selects (the
board profile wires the pins), and the pull-ups, slew rate and input buffer bits change nothing.
Reset values are 0 (function 0, pull-up on, input buffer off: the manual's for most pins).

CREG: CREG0, M4MEMMAP (the boot shadow), CREG5, DMAMUX, FLASHCFGA/B, CREG6, M4TXEVENT,
CHIPID, M0APPTXEVENT, M0APPMEMMAP, USB0FLADJ, USB1FLADJ. Stored, but for:

* M4MEMMAP: the shadow at 0x00000000 is the board's ([[memory]] aliases = [0]: flash bank A
  on ``ciaa-edu``, 0x1A000000, where the boot ROM leaves it). A write moving it anywhere else is
  refused, since the memory map does not change;
* CHIPID reads 0x4906002B, the ID of the LPC43xx parts with on-chip flash (UM10503, CHIPID:
  LPC4337 included), read only;
* FLASHCFGA/B read the flash wait states LPCOpen sets for 204 MHz (FLASHTIM = 9); wait states
  do not slow the core (docs/firmware.md, the cycle model).

CREG1-4 are the LPC18xx's (LPCOpen declares them for CHIP_LPC18XX only; UM10503 lists them as
reserved): on the LPC4337 an access to them is a bus fault.
"""

from __future__ import annotations

from mcusim.errors import UnsupportedConfiguration
from mcusim.registers import Field, Peripheral, Register

# pins of each port on the largest LPC43xx package (UM10503, pin description): P0_0..P0_1 ...
SCU_PORTS = {"0": 2, "1": 21, "2": 14, "3": 9, "4": 11, "5": 8, "6": 13, "7": 8, "8": 9, "9": 7,
             "A": 5, "B": 7, "C": 15, "D": 17, "E": 16, "F": 12}
_SFS_FIELDS = (Field("MODE", 0, 3), Field("EPD", 3), Field("EPUN", 4), Field("EHS", 5), Field("EZI", 6),
               Field("ZIF", 7), Field("EHD", 8, 2))


def _scu_registers():
    regs = []
    for k, (port, pins) in enumerate(SCU_PORTS.items()):
        for pin in range(pins):
            regs.append(Register(f"SFSP{port}_{pin}", 0x80 * k + 4 * pin, fields=_SFS_FIELDS))
    regs += [Register(f"SFSCLK{n}", 0xC00 + 4 * n, fields=_SFS_FIELDS) for n in range(4)]
    regs += [Register("SFSUSB", 0xC80), Register("SFSI2C0", 0xC84)]
    regs += [Register(f"ENAIO{n}", 0xC88 + 4 * n) for n in range(3)]
    regs += [Register("EMCDELAYCLK", 0xD00), Register("SDDELAY", 0xD80),
             Register("PINTSEL0", 0xE00), Register("PINTSEL1", 0xE04)]
    return tuple(regs)


class Scu(Peripheral):
    RGU_RESET = True  # the RGU may call reset() (periph/lpc43xx/rgu.py)
    SIZE = 0x1000
    REGISTERS = _scu_registers()

    def __init__(self, name, mcu):
        super().__init__(name)


CHIPID_LPC43XX_FLASH = 0x4906002B
BOOT_SHADOW = 0x1A000000          # flash bank A: the boot ROM's M4MEMMAP when it boots from it


class Creg(Peripheral):
    RGU_RESET = True  # the RGU may call reset() (periph/lpc43xx/rgu.py)
    SIZE = 0x1000
    REGISTERS = (
        # 32 kHz oscillator and its 1 kHz output off, in reset, as at power-up; BOD, wake-up: stored
        Register("CREG0", 0x004, reset=0x0000_000C, fields=(
            Field("EN1KHZ", 0), Field("EN32KHZ", 1), Field("RESET32KHZ", 2), Field("PD32KHZ", 3),
            Field("USB0PHY", 5), Field("ALARMCTRL", 6, 2), Field("BODLVL1", 8, 2), Field("BODLVL2", 10, 2),
            Field("SAMPLECTRL", 12, 2), Field("WAKEUP0CTRL", 14, 2), Field("WAKEUP1CTRL", 16, 2))),
        Register("M4MEMMAP", 0x100, reset=BOOT_SHADOW, on_write="_write_m4memmap",
                 fields=(Field("M4MAP", 12, 20),)),
        Register("CREG5", 0x118),
        Register("DMAMUX", 0x11C),
        Register("FLASHCFGA", 0x120, reset=0x8000_903A),
        Register("FLASHCFGB", 0x124, reset=0x8000_903A),
        Register("CREG6", 0x12C),
        Register("M4TXEVENT", 0x130, fields=(Field("TXEVCLR", 0),)),
        Register("CHIPID", 0x200, reset=CHIPID_LPC43XX_FLASH, access="r"),
        Register("M0APPTXEVENT", 0x400, fields=(Field("TXEVCLR", 0),)),
        Register("M0APPMEMMAP", 0x404, reset=0x2000_0000, fields=(Field("M0APPMAP", 12, 20),)),
        Register("USB0FLADJ", 0x500, reset=0x20, fields=(Field("FLTV", 0, 6),)),
        Register("USB1FLADJ", 0x600, reset=0x20, fields=(Field("FLTV", 0, 6),)),
    )

    def __init__(self, name, mcu):
        super().__init__(name)
        self.mcu = mcu

    def shadow_base(self) -> int:
        """The base of the memory the board shows at 0x00000000 (its alias), else flash bank A."""
        hit = self.mcu.bus.peripheral_at(0)
        base = getattr(hit[0], "base", None) if hit is not None else None
        return BOOT_SHADOW if base is None else base

    def _write_m4memmap(self, old, new):
        shadow = self.shadow_base()
        if new != shadow:
            raise UnsupportedConfiguration(
                self.name, "M4MEMMAP", "M4MAP", new,
                f"moves the boot shadow at 0x00000000 to {new:#010x}; the board maps {shadow:#010x} there "
                "([[memory]] aliases) and the memory map does not change while running")
