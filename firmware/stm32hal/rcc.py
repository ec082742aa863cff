"""HAL_RCC_Get*Freq and the timer-clock rule, read from the RCC registers (stm32f7xx_hal_rcc.c)."""

from __future__ import annotations

SystemCoreClock = 216_000_000  # set by SystemClock_Config on the nucleo-f746 profile
_AHB = {0b1000: 2, 0b1001: 4, 0b1010: 8, 0b1011: 16, 0b1100: 64, 0b1101: 128, 0b1110: 256, 0b1111: 512}
_APB = {0b100: 2, 0b101: 4, 0b110: 8, 0b111: 16}


def HAL_RCC_GetHCLKFreq(dev) -> int:
    return SystemCoreClock // _AHB.get((dev.RCC.CFGR >> 4) & 0xF, 1)


def HAL_RCC_GetPCLK1Freq(dev) -> int:
    return HAL_RCC_GetHCLKFreq(dev) // _APB.get((dev.RCC.CFGR >> 10) & 0x7, 1)


def HAL_RCC_GetPCLK2Freq(dev) -> int:
    return HAL_RCC_GetHCLKFreq(dev) // _APB.get((dev.RCC.CFGR >> 13) & 0x7, 1)


def timer_clock_freq(dev, apb: int) -> int:
    """TIMxCLK of a timer on APB1 or APB2 (RM0385: TIMPRE rule; ST examples: 'TIM3CLK = PCLK1*2')."""
    hclk = HAL_RCC_GetHCLKFreq(dev)
    div = _APB.get((dev.RCC.CFGR >> (10 if apb == 1 else 13)) & 0x7, 1)
    pclk = hclk // div
    if not (dev.RCC.DCKCFGR1 >> 24) & 1:
        return pclk if div == 1 else 2 * pclk
    return hclk if div in (1, 2, 4) else 4 * pclk
