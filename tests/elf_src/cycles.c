/* The cycle model: DWT CYCCNT read twice around ten NOPs differs by 11 (1 cycle per instruction);
 * SysTick handler entries recorded by CYCCNT while main sleeps in WFI are exactly one SysTick
 * period apart. */
#include <stdint.h>
#define REG(a) (*(volatile uint32_t *)(a))
volatile uint32_t c0, c1, entries[8], n_entries;

__attribute__((naked)) void SysTick_Handler(void) {
    __asm volatile(
        "ldr r0, =0xE0001004\n ldr r1, [r0]\n"           /* CYCCNT at the 2nd handler instruction */
        "ldr r0, =n_entries\n ldr r2, [r0]\n cmp r2, #8\n bge 1f\n"
        "ldr r3, =entries\n str r1, [r3, r2, lsl #2]\n adds r2, #1\n str r2, [r0]\n"
        "1: bx lr\n .ltorg");
}

int main(void) {
    REG(0xE000EDFC) |= 1u << 24;                          /* DEMCR.TRCENA */
    REG(0xE0001000) |= 1;                                 /* DWT CYCCNTENA */
    __asm volatile(
        "ldr r0, =0xE0001004\n ldr r1, [r0]\n"
        "nop\n nop\n nop\n nop\n nop\n nop\n nop\n nop\n nop\n nop\n"
        "ldr r2, [r0]\n ldr r3, =c0\n str r1, [r3]\n ldr r3, =c1\n str r2, [r3]\n .ltorg"
        ::: "r0", "r1", "r2", "r3", "memory");
    REG(0xE000E014) = 10000 - 1;
    REG(0xE000E018) = 0;
    REG(0xE000E010) = 7;
    for (;;) __asm volatile("wfi");
}
