/* Reset and vector table for the STM32F746: copy .data from flash, zero .bss, enable the FPU
 * (CPACR: CP10 and CP11 full access) and point VTOR at the table in flash, as ST's SystemInit
 * does, then main. The clock tree is not programmed here (see README.md). */
#include <stdint.h>
#include "stm32f7.h"

#define NUM_IRQS 98

extern uint32_t _estack, _sidata, _sdata, _edata, _sbss, _ebss;
int main(void);

void Reset_Handler(void);
/* An unexpected exception or interrupt sleeps for good: nothing of lower priority runs any more,
 * and a simulator spends no time on it (on the chip, a debugger finds the core here). */
void Default_Handler(void)
{
    for (;;)
        __WFI();
}

#define WEAK_DEFAULT __attribute__((weak, alias("Default_Handler")))
void NMI_Handler(void) WEAK_DEFAULT;
void HardFault_Handler(void) WEAK_DEFAULT;
void MemManage_Handler(void) WEAK_DEFAULT;
void BusFault_Handler(void) WEAK_DEFAULT;
void UsageFault_Handler(void) WEAK_DEFAULT;
void SVC_Handler(void) WEAK_DEFAULT;
void DebugMon_Handler(void) WEAK_DEFAULT;
void PendSV_Handler(void) WEAK_DEFAULT;
void SysTick_Handler(void) WEAK_DEFAULT;
void TIM3_IRQHandler(void) WEAK_DEFAULT;
void TIM4_IRQHandler(void) WEAK_DEFAULT;

typedef void (*vector_t)(void);

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Woverride-init"
__attribute__((section(".isr_vector"), used))
const vector_t g_pfnVectors[16 + NUM_IRQS] = {
    [0] = (vector_t)&_estack,
    [1] = Reset_Handler,
    [2] = NMI_Handler,
    [3] = HardFault_Handler,
    [4] = MemManage_Handler,
    [5] = BusFault_Handler,
    [6] = UsageFault_Handler,
    [11] = SVC_Handler,
    [12] = DebugMon_Handler,
    [14] = PendSV_Handler,
    [15] = SysTick_Handler,
    [16 ... 16 + NUM_IRQS - 1] = Default_Handler,
    [16 + TIM3_IRQn] = TIM3_IRQHandler,
    [16 + TIM4_IRQn] = TIM4_IRQHandler,
};
#pragma GCC diagnostic pop

__attribute__((noreturn)) void Reset_Handler(void)
{
    uint32_t *src = &_sidata, *dst = &_sdata;
    while (dst < &_edata)
        *dst++ = *src++;
    for (dst = &_sbss; dst < &_ebss;)
        *dst++ = 0U;
    SCB->CPACR = SCB->CPACR | (0xFU << 20);     /* CP10, CP11: full access */
    SCB->VTOR = FLASH_BASE;
    __DSB();
    __ISB();
    main();
    for (;;)
        __WFI();
}
