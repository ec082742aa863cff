"""HAL_NVIC_* and HAL_SYSTICK_Config over the NVIC/SCB/SysTick registers (stm32f7xx_hal_cortex.c)."""

from __future__ import annotations

from .regs import NVIC_BASE, SCB_BASE

__NVIC_PRIO_BITS = 4
SysTick_IRQn = -1


def HAL_NVIC_SetPriority(dev, irqn: int, preempt_priority: int, sub_priority: int = 0) -> None:
    # NVIC_PRIORITYGROUP_4 (the HAL default in HAL_Init): all 4 bits are preemption priority
    value = (preempt_priority << (8 - __NVIC_PRIO_BITS)) & 0xFF
    if irqn >= 0:
        dev.bus.write(NVIC_BASE + 0x300 + irqn, value, 1)  # IP[n] is byte-accessible
    elif irqn == SysTick_IRQn:
        dev.bus.write(SCB_BASE + 0x23, value, 1)  # SHPR3[31:24]


def HAL_NVIC_EnableIRQ(dev, irqn: int) -> None:
    dev.bus.write(NVIC_BASE + 4 * (irqn >> 5), 1 << (irqn & 31), 4)  # ISER


def HAL_NVIC_DisableIRQ(dev, irqn: int) -> None:
    dev.bus.write(NVIC_BASE + 0x80 + 4 * (irqn >> 5), 1 << (irqn & 31), 4)  # ICER


def HAL_SYSTICK_Config(dev, ticks: int) -> None:
    """SysTick_Config: LOAD = ticks-1, lowest priority, VAL = 0, processor clock, TICKINT, ENABLE."""
    if ticks - 1 > 0xFFFFFF:
        raise ValueError("SysTick reload does not fit 24 bits")
    dev.SysTick.LOAD = ticks - 1
    HAL_NVIC_SetPriority(dev, SysTick_IRQn, (1 << __NVIC_PRIO_BITS) - 1)
    dev.SysTick.VAL = 0
    dev.SysTick.CTRL = 0b111
