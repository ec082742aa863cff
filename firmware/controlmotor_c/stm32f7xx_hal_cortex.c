/* HAL_NVIC_* and HAL_SYSTICK_Config over the NVIC, SCB and SysTick registers
 * (stm32f7xx_hal_cortex.c with CMSIS's NVIC_SetPriority / SysTick_Config). */
#include "stm32f7xx_hal.h"

/* NVIC_PRIORITYGROUP_4 (HAL_Init's default): all four bits are preemption priority */
void HAL_NVIC_SetPriority(int irqn, uint32_t preempt_priority, uint32_t sub_priority)
{
    (void)sub_priority;
    uint8_t value = (uint8_t)(preempt_priority << (8U - __NVIC_PRIO_BITS));
    if (irqn >= 0)
        NVIC->IP[irqn] = value;                 /* byte store */
    else if (irqn == SysTick_IRQn)
        SCB->SHPR[11] = value;                  /* SHPR3[31:24] */
}

void HAL_NVIC_EnableIRQ(int irqn)
{
    NVIC->ISER[(uint32_t)irqn >> 5] = 1U << ((uint32_t)irqn & 31U);
}

void HAL_NVIC_DisableIRQ(int irqn)
{
    NVIC->ICER[(uint32_t)irqn >> 5] = 1U << ((uint32_t)irqn & 31U);
    __DSB();
    __ISB();
}

/* SysTick_Config: LOAD = ticks-1, lowest priority, VAL = 0, processor clock, TICKINT, ENABLE */
uint32_t HAL_SYSTICK_Config(uint32_t ticks)
{
    if (ticks - 1U > 0xFFFFFFU)
        return 1U;
    SysTick->LOAD = ticks - 1U;
    HAL_NVIC_SetPriority(SysTick_IRQn, (1U << __NVIC_PRIO_BITS) - 1U, 0U);
    SysTick->VAL = 0U;
    SysTick->CTRL = 0x7U;
    return 0U;
}
