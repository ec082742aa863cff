/* Idle loops (a branch to itself) with the work in interrupt handlers, for the core's fast-forward
 * through them (mcusim.elf.idle). SysTick (every 100 us) toggles PF15 (bridgeA.EN: in the VCD) and
 * reads DWT CYCCNT (in the register log); TIM2 (every 250 us) counts. `which` chooses the loop:
 * 1: `for (;;) {}` (B, T2); 2: the same with PRIMASK set; 3: `1: b.w 1b` (B.W, T4) while the
 * handlers change variables the loop does not read; 4: BASEPRI masks TIM2 but not SysTick. */
#include <stdint.h>
#define REG(a) (*(volatile uint32_t *)(a))
volatile uint32_t which, ticks, tim2_count, stamp[64];

void SysTick_Handler(void) {
    REG(0x40021414) ^= 1u << 15;               /* GPIOF ODR: toggle PF15 */
    stamp[ticks++ & 63] = REG(0xE0001004);     /* DWT CYCCNT */
}

void TIM2_IRQHandler(void) {
    REG(0x40000010) = 0;                       /* TIM2 SR: clear UIF */
    tim2_count++;
}

int main(void) {
    REG(0x40023830) |= 1u << 5;                /* RCC AHB1ENR: GPIOF */
    REG(0x40021400) |= 1u << 30;               /* GPIOF MODER15: output */
    REG(0xE000EDFC) |= 1u << 24;               /* DEMCR.TRCENA */
    REG(0xE0001000) |= 1;                      /* DWT_CTRL.CYCCNTENA */
    REG(0xE000ED20) = 0x40u << 24;             /* SHPR3: SysTick priority 4 */
    REG(0xE000E41C) = 0x80u;                   /* NVIC IPR7 byte 0 (IRQ 28): TIM2 priority 8 */
    REG(0xE000E014) = 21600 - 1;               /* SysTick LOAD: 100 us at 216 MHz */
    REG(0xE000E018) = 0;
    REG(0xE000E010) = 7;
    REG(0x40000028) = 108 - 1;                 /* TIM2 PSC: 1 MHz */
    REG(0x4000002C) = 250 - 1;                 /* ARR: 250 us */
    REG(0x4000000C) = 1;                       /* DIER.UIE */
    REG(0xE000E100) = 1u << 28;                /* NVIC ISER0: TIM2 */
    REG(0x40000000) = 1;                       /* CR1.CEN */
    if (which == 2) __asm volatile("cpsid i");
    if (which == 3) __asm volatile("1: b.w 1b");
    if (which == 4) __asm volatile("msr basepri, %0" :: "r"(0x80u));
    for (;;) {}
}
