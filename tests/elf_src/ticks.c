/* SysTick at 1 kHz counts ticks; main sleeps in WFI and counts wake-ups. TIM2 (a real peripheral
 * model) runs its update interrupt at 1 kHz and counts in tim2_count. */
#include <stdint.h>
#define REG(a) (*(volatile uint32_t *)(a))
volatile uint32_t ticks, wakeups, tim2_count;
volatile float set_point = 0.0f;
volatile uint32_t set_point_count;
volatile float doubled;

void SysTick_Handler(void) { ticks++; doubled = 2.0f * set_point; }

void TIM2_IRQHandler(void) {
    REG(0x40000010) = 0;          /* TIM2->SR = 0: clear UIF */
    tim2_count++;
}

int main(void) {
    REG(0xE000E014) = 216000 - 1;   /* SysTick LOAD: 1 ms at 216 MHz */
    REG(0xE000E018) = 0;
    REG(0xE000E010) = 7;            /* CLKSOURCE = core, TICKINT, ENABLE */
    REG(0x40000028) = 108 - 1;      /* TIM2 PSC: 1 MHz from 108 MHz */
    REG(0x4000002C) = 1000 - 1;     /* ARR: 1 kHz */
    REG(0x4000000C) = 1;            /* DIER.UIE */
    REG(0xE000E100) = 1u << 28;     /* NVIC ISER0: TIM2 */
    REG(0x40000000) = 1;            /* CR1.CEN */
    for (;;) {
        __asm volatile("wfi");
        wakeups++;
    }
}
