"""LPC43xx reset generation unit (RGU; UM10503 chapter 10), as LPCOpen's Chip_RGU_TriggerReset
and Chip_RGU_InReset use it.

RESET_CTRL0/1 are write-only: a 1 in bit n requests reset n (n = 32 · register + bit, LPCOpen's
RGU_xxx_RST numbers). The reset completes at once: RESET_ACTIVE_STATUS0/1 (a bit reads 1 while
that peripheral is *not* in reset) never shows it, so ``while (Chip_RGU_InReset(...))`` ends at
its first read, and RESET_STATUSn records it as a software reset (code 0b11 in the two bits of
reset n). RESET_EXT_STATn are stored.

What a reset does to the modelled blocks:

* GPIO, ADC0, ADC1, SCU and CREG are reset (their models' reset: registers to their reset
  values, the GPIO's pins released, a conversion in progress dropped);
* I2C0/I2C1 and the USARTs are refused by name: their models hold transfer state a register
  reset does not clear;
* a reset of the core or the chip (CORE_RST, PERIPH_RST, MASTER_RST, BUS_RST, M4_RST) is refused;
* a reset of a block the board does not model does nothing (an access to it is a bus fault);
* the Cortex-M0 cores (M0SUB_RST 12, M0APP_RST 56) are not modelled: M0APP stays in reset
  (RESET_ACTIVE_STATUS1 bit 24 reads 0) whatever RESET_CTRL1 says. LPCOpen's TriggerReset writes
  0 to that bit with every reset it requests, so a 0 there is not refused.
"""

from __future__ import annotations

from mcusim.errors import UnsupportedConfiguration
from mcusim.registers import Peripheral, Register

# reset number -> (name, base address of the block on the LPC43xx memory map)
BLOCKS = {5: ("CREG_RST", 0x40043000), 9: ("SCU_RST", 0x40086000), 28: ("GPIO_RST", 0x400F4000),
          40: ("ADC0_RST", 0x400E3000), 41: ("ADC1_RST", 0x400E4000), 44: ("USART0_RST", 0x40081000),
          45: ("UART1_RST", 0x40082000), 46: ("USART2_RST", 0x400C1000), 47: ("USART3_RST", 0x400C2000),
          48: ("I2C0_RST", 0x400A1000), 49: ("I2C1_RST", 0x400E0000)}
CHIP_RESETS = {0: "CORE_RST", 1: "PERIPH_RST", 2: "MASTER_RST", 8: "BUS_RST", 13: "M4_RST"}
M0_RESETS = (12, 56)
M0APP_RST = 56
# the reset numbers the manual defines (RESET_EXT_STATn exists for these)
EXT_STAT = (0, 1, 2, 4, 5, 8, 9, 12, 13, 16, 17, 18, 19, 20, 21, 22, 25, 27, 28, 29, *range(32, 43),
            *range(44, 59), 60)


class Rgu(Peripheral):
    SIZE = 0x1000
    REGISTERS = (
        Register("RESET_CTRL0", 0x100, access="w", on_write="_write_ctrl0"),
        Register("RESET_CTRL1", 0x104, access="w", on_write="_write_ctrl1"),
        *(Register(f"RESET_STATUS{k}", 0x110 + 4 * k) for k in range(4)),
        Register("RESET_ACTIVE_STATUS0", 0x150, reset=0xFFFF_FFFF, access="r"),
        Register("RESET_ACTIVE_STATUS1", 0x154, reset=0xFFFF_FFFF & ~(1 << (M0APP_RST - 32)), access="r"),
        *(Register(f"RESET_EXT_STAT{n}", 0x400 + 4 * n) for n in EXT_STAT),
    )

    def __init__(self, name, mcu):
        super().__init__(name)
        self.mcu = mcu
        self.reset_count = 0                         # resets done since the start

    def _write_ctrl0(self, old, new):
        self._request(0, new)

    def _write_ctrl1(self, old, new):
        self._request(1, new)

    def _request(self, word: int, bits: int) -> None:
        reg = f"RESET_CTRL{word}"
        todo = []
        for bit in range(32):
            if not bits >> bit & 1:
                continue
            n = 32 * word + bit
            if n in CHIP_RESETS:
                raise UnsupportedConfiguration(self.name, reg, CHIP_RESETS[n], 1,
                                               "(a reset of the core or the chip) is not modelled")
            if n in M0_RESETS:
                continue
            name, base = BLOCKS.get(n, (f"reset {n}", None))
            hit = self.mcu.bus.peripheral_at(base) if base is not None else None
            if hit is not None:
                periph = hit[0]
                if not getattr(periph, "RGU_RESET", False):
                    raise UnsupportedConfiguration(
                        self.name, reg, name, 1,
                        f"resets {periph.name}, whose model has no reset that clears its transfer state: "
                        "not modelled")
                todo.append((n, name, periph))
            else:
                todo.append((n, name, None))
        for n, _name, periph in todo:
            if periph is not None:
                periph.reset()
            k, shift = divmod(n, 16)
            self.value[f"RESET_STATUS{k}"] |= 0b11 << (2 * shift)      # reset by software
            self.reset_count += 1
