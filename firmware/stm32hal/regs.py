"""Register views: ``TIM1.CCR1 = 5`` / ``TIM1.CNT`` become 32-bit bus accesses, as CMSIS structs do."""

from __future__ import annotations

TIM_REGS = {"CR1": 0x00, "CR2": 0x04, "SMCR": 0x08, "DIER": 0x0C, "SR": 0x10, "EGR": 0x14, "CCMR1": 0x18,
            "CCMR2": 0x1C, "CCER": 0x20, "CNT": 0x24, "PSC": 0x28, "ARR": 0x2C, "RCR": 0x30, "CCR1": 0x34,
            "CCR2": 0x38, "CCR3": 0x3C, "CCR4": 0x40, "BDTR": 0x44}
GPIO_REGS = {"MODER": 0x00, "OTYPER": 0x04, "OSPEEDR": 0x08, "PUPDR": 0x0C, "IDR": 0x10, "ODR": 0x14,
             "BSRR": 0x18, "LCKR": 0x1C, "AFR0": 0x20, "AFR1": 0x24}
RCC_REGS = {"CFGR": 0x08, "AHB1ENR": 0x30, "APB1ENR": 0x40, "APB2ENR": 0x44, "DCKCFGR1": 0x8C}
SYSTICK_REGS = {"CTRL": 0x0, "LOAD": 0x4, "VAL": 0x8, "CALIB": 0xC}

TIM_BASES = {"TIM1": 0x40010000, "TIM8": 0x40010400, "TIM2": 0x40000000, "TIM3": 0x40000400,
             "TIM4": 0x40000800, "TIM5": 0x40000C00}
GPIO_BASES = {p: 0x40020000 + 0x400 * i for i, p in enumerate("ABCDEFGHIJK")}
RCC_BASE = 0x40023800
SYSTICK_BASE = 0xE000E010
NVIC_BASE = 0xE000E100
SCB_BASE = 0xE000ED00


class RegView:
    """A CMSIS-like peripheral struct over the bus."""

    __slots__ = ("_addr", "_base", "_bus", "_regs", "name")

    def __init__(self, bus, name, base, regs):
        object.__setattr__(self, "_bus", bus)
        object.__setattr__(self, "_base", base)
        object.__setattr__(self, "_regs", regs)
        object.__setattr__(self, "name", name)
        object.__setattr__(self, "_addr", {reg: base + off for reg, off in regs.items()})

    @property
    def base(self):
        return self._base

    def __getattr__(self, reg):
        try:
            address = self._addr[reg]
        except KeyError:
            raise AttributeError(f"{self.name} has no register {reg}") from None
        return self._bus.read(address, 4)

    def __setattr__(self, reg, value):
        try:
            address = self._addr[reg]
        except KeyError:
            raise AttributeError(f"{self.name} has no register {reg}") from None
        self._bus.write(address, value & 0xFFFFFFFF, 4)


class Stm32f7:
    """The device header: ``dev = Stm32f7(mcu.bus); dev.TIM1.ARR = 4319``."""

    def __init__(self, bus):
        self.bus = bus
        for name, base in TIM_BASES.items():
            setattr(self, name, RegView(bus, name, base, TIM_REGS))
        for port, base in GPIO_BASES.items():
            setattr(self, f"GPIO{port}", RegView(bus, f"GPIO{port}", base, GPIO_REGS))
        self.RCC = RegView(bus, "RCC", RCC_BASE, RCC_REGS)
        self.SysTick = RegView(bus, "SysTick", SYSTICK_BASE, SYSTICK_REGS)
