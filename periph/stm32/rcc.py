"""STM32F7 RCC, as far as the timers need it (RM0385 §5; bit positions from stm32f746xx.h).

Modelled: the APB prescalers in CFGR (PPRE1, PPRE2), TIMPRE in DCKCFGR1 and the clock enable
registers (stored; they do not gate access, see below). HPRE must stay /1: an AHB prescaler would
slow the core, SysTick and the DWT cycle counter too, which run on SYSCLK here (refused). The PLL is not modelled: SYSCLK is
the board's ``sysclk`` and the register reset values are the state *after* the board's
SystemClock_Config (216 MHz from the PLL, AHB /1, APB1 /4, APB2 /2), as if the startup code ran.

Timer kernel clocks (HAL ``stm32f7xx_hal_rcc_ex.h``, TIMPRE description; sheet §2.2):

* TIMPRE = 0: TIMxCLK = PCLKx if the APBx prescaler is 1, else 2 × PCLKx;
* TIMPRE = 1: TIMxCLK = HCLK if the APBx prescaler is 1, 2 or 4, else 4 × PCLKx.

So TIM1/TIM8 (APB2) count at 216 MHz and TIM2–TIM5 (APB1) at 108 MHz unless TIMPRE is set.
Peripherals register for a clock by name (``APB1_TIM``, ``APB2_TIM``); when firmware changes the
prescalers, each user's ``set_kernel_clock`` is called at that instant.

Not modelled: clock gating by the enable bits (a timer whose clock is off still responds), the
PLL/oscillator registers (not mapped: touching them is a bus fault).
"""

from __future__ import annotations

from fractions import Fraction

from mcusim.errors import TimeError, UnsupportedConfiguration
from mcusim.registers import Field, Peripheral, Register

_AHB_DIV = {0b1000: 2, 0b1001: 4, 0b1010: 8, 0b1011: 16, 0b1100: 64, 0b1101: 128, 0b1110: 256, 0b1111: 512}
_APB_DIV = {0b100: 2, 0b101: 4, 0b110: 8, 0b111: 16}


def _enables(name, offset, bits, reset=0):
    return Register(name, offset, reset=reset, fields=tuple(Field(b, i) for i, b in bits.items()))


class Rcc(Peripheral):
    SIZE = 0x400
    REGISTERS = (
        # CR and PLLCFGR as SystemClock_Config leaves them on the NUCLEO-F746ZG: HSE bypass (8 MHz from
        # the ST-LINK), PLL M = 8, N = 432, P = 2, Q = 9 -> 216 MHz. A ready flag follows its enable at
        # once (oscillator and PLL start-up times are not modelled).
        Register("CR", 0x00, reset=0x0307_0083, on_read="_read_cr", fields=(
            Field("HSION", 0), Field("HSIRDY", 1, access="r"), Field("HSITRIM", 3, 5), Field("HSICAL", 8, 8, access="r"),
            Field("HSEON", 16), Field("HSERDY", 17, access="r"), Field("HSEBYP", 18), Field("CSSON", 19, modelled=False),
            Field("PLLON", 24), Field("PLLRDY", 25, access="r"), Field("PLLI2SON", 26, modelled=False),
            Field("PLLI2SRDY", 27, access="r"), Field("PLLSAION", 28, modelled=False), Field("PLLSAIRDY", 29, access="r"))),
        Register("PLLCFGR", 0x04, reset=0x0940_6C08, on_write="_write_pllcfgr", fields=(
            Field("PLLM", 0, 6), Field("PLLN", 6, 9), Field("PLLP", 16, 2), Field("PLLSRC", 22),
            Field("PLLQ", 24, 4), Field("PLLR", 28, 3))),
        Register("CFGR", 0x08, reset=(0b100 << 13) | (0b101 << 10) | (0b10 << 2) | 0b10,
                 on_write="_write_cfgr", fields=(
                     Field("SW", 0, 2, modelled=False), Field("SWS", 2, 2, access="r"),
                     Field("HPRE", 4, 4), Field("PPRE1", 10, 3), Field("PPRE2", 13, 3),
                     Field("RTCPRE", 16, 5, modelled=False), Field("MCO1", 21, 2, modelled=False),
                     Field("I2SSCR", 23, modelled=False), Field("MCO1PRE", 24, 3, modelled=False),
                     Field("MCO2PRE", 27, 3, modelled=False), Field("MCO2", 30, 2, modelled=False))),
        # every enable bit of stm32f746xx.h, stored (a write of USART2EN reads back); none gates
        # a clock (module doc). DTCMRAMEN is set out of reset (RM0385 reset value 0x0010_0000)
        _enables("AHB1ENR", 0x30, {0: "GPIOAEN", 1: "GPIOBEN", 2: "GPIOCEN", 3: "GPIODEN", 4: "GPIOEEN",
                                   5: "GPIOFEN", 6: "GPIOGEN", 7: "GPIOHEN", 8: "GPIOIEN", 9: "GPIOJEN",
                                   10: "GPIOKEN", 12: "CRCEN", 18: "BKPSRAMEN", 20: "DTCMRAMEN", 21: "DMA1EN",
                                   22: "DMA2EN", 23: "DMA2DEN", 25: "ETHMACEN", 26: "ETHMACTXEN",
                                   27: "ETHMACRXEN", 28: "ETHMACPTPEN", 29: "OTGHSEN", 30: "OTGHSULPIEN"},
                 reset=1 << 20),
        _enables("AHB2ENR", 0x34, {0: "DCMIEN", 4: "CRYPEN", 5: "HASHEN", 6: "RNGEN", 7: "OTGFSEN"}),
        _enables("AHB3ENR", 0x38, {0: "FMCEN", 1: "QSPIEN"}),
        _enables("APB1ENR", 0x40, {0: "TIM2EN", 1: "TIM3EN", 2: "TIM4EN", 3: "TIM5EN", 4: "TIM6EN", 5: "TIM7EN",
                                   6: "TIM12EN", 7: "TIM13EN", 8: "TIM14EN", 9: "LPTIM1EN", 11: "WWDGEN",
                                   14: "SPI2EN", 15: "SPI3EN", 16: "SPDIFRXEN", 17: "USART2EN", 18: "USART3EN",
                                   19: "UART4EN", 20: "UART5EN", 21: "I2C1EN", 22: "I2C2EN", 23: "I2C3EN",
                                   24: "I2C4EN", 25: "CAN1EN", 26: "CAN2EN", 27: "CECEN", 28: "PWREN",
                                   29: "DACEN", 30: "UART7EN", 31: "UART8EN"}),
        _enables("APB2ENR", 0x44, {0: "TIM1EN", 1: "TIM8EN", 4: "USART1EN", 5: "USART6EN", 8: "ADC1EN",
                                   9: "ADC2EN", 10: "ADC3EN", 11: "SDMMC1EN", 12: "SPI1EN", 13: "SPI4EN",
                                   14: "SYSCFGEN", 16: "TIM9EN", 17: "TIM10EN", 18: "TIM11EN", 20: "SPI5EN",
                                   21: "SPI6EN", 22: "SAI1EN", 23: "SAI2EN", 26: "LTDCEN"}),
        Register("DCKCFGR1", 0x8C, on_write="_write_dckcfgr1", fields=(Field("TIMPRE", 24),)),
    )

    def __init__(self, name, mcu, sysclk_hz):
        super().__init__(name)
        self.mcu = mcu
        self.sysclk_hz = Fraction(sysclk_hz)
        self._publish()

    # --- clock tree ----------------------------------------------------------------------
    def frequencies(self) -> dict[str, Fraction]:
        hpre, ppre1, ppre2 = (self.field("CFGR", f) for f in ("HPRE", "PPRE1", "PPRE2"))
        hclk = self.sysclk_hz / _AHB_DIV.get(hpre, 1)
        out = {"SYSCLK": self.sysclk_hz, "HCLK": hclk}
        timpre = self.field("DCKCFGR1", "TIMPRE")
        for bus, ppre in (("APB1", ppre1), ("APB2", ppre2)):
            div = _APB_DIV.get(ppre, 1)
            pclk = hclk / div
            out[bus] = pclk
            if not timpre:
                out[f"{bus}_TIM"] = pclk if div == 1 else 2 * pclk
            else:
                out[f"{bus}_TIM"] = hclk if div in (1, 2, 4) else 4 * pclk
        return out

    def _publish(self):
        """Make the clocks available to the MCU; tell users of a clock that changed."""
        tb = self.mcu.kernel.timebase
        for name, hz in self.frequencies().items():
            old = self.mcu.clocks.get(name)
            if old is not None and old.hz == hz:
                continue
            try:
                clock = tb.clock(name, hz)
            except TimeError as exc:  # the time base must contain every clock
                raise UnsupportedConfiguration(self.name, "CFGR", None, self.value["CFGR"],
                                               f"gives {name} = {hz} Hz, not in the time base: {exc}") from None
            self.mcu.clocks[name] = clock
            if old is not None:
                for user in self.mcu.clock_users.get(name, ()):
                    user.set_kernel_clock(clock)

    def _read_cr(self, stored):
        for on, rdy in ((0, 1), (16, 17), (24, 25)):          # HSI, HSE, PLL: ready as soon as on
            stored = stored | (1 << rdy) if stored >> on & 1 else stored & ~(1 << rdy)
        return stored

    def _write_pllcfgr(self, old, new):
        """The PLL may be programmed, but only to the board's SYSCLK (the time base is fixed)."""
        m, n, p = new & 0x3F, (new >> 6) & 0x1FF, 2 * (((new >> 16) & 3) + 1)
        src = 8_000_000 if new >> 22 & 1 else 16_000_000        # HSE (ST-LINK MCO, 8 MHz) or HSI
        hz = Fraction(src, m) * n / p if m else Fraction(0)
        if hz != self.sysclk_hz:
            raise UnsupportedConfiguration(self.name, "PLLCFGR", None, new,
                                           f"gives a {hz / 1e6:g} MHz PLL output; the board runs at "
                                           f"{self.sysclk_hz / 1e6:g} MHz ([clocks] sysclk)")

    def _write_cfgr(self, old, new):
        hpre = (new >> 4) & 0xF
        if hpre in _AHB_DIV:
            # the timers would follow HCLK (frequencies()), but the core, SysTick and the DWT
            # cycle counter count SYSCLK cycles: refused rather than half applied
            self.value["CFGR"] = old
            raise UnsupportedConfiguration(self.name, "CFGR", "HPRE", hpre,
                                           f"(AHB prescaler /{_AHB_DIV[hpre]}) is not modelled: the core, "
                                           "SysTick and DWT run on SYSCLK; only /1 (HPRE = 0b0xxx)")
        self._publish()

    def _write_dckcfgr1(self, old, new):
        self._publish()
