/* BASEPRI and PRIMASK. With BASEPRI = 0x40, IRQ0 (priority 0x80) stays pending while IRQ1 (0x20)
 * is taken; clearing BASEPRI takes IRQ0 right after the MSR (its stacked return address is the
 * next instruction). Under PRIMASK (cpsid i) even IRQ1 waits; cpsie takes it at once. */
#include <stdint.h>
#define REG(a) (*(volatile uint32_t *)(a))
volatile uint32_t trace[8], n_trace, ret_irq0, ret_irq1;

__attribute__((naked)) void IRQ0_Handler(void) {
    __asm volatile("ldr r0, [sp, #24]\n ldr r1, =ret_irq0\n str r0, [r1]\n"
                   "ldr r1, =n_trace\n ldr r2, [r1]\n ldr r3, =trace\n movs r0, #0x10\n"
                   "str r0, [r3, r2, lsl #2]\n adds r2, #1\n str r2, [r1]\n bx lr\n .ltorg");
}

__attribute__((naked)) void IRQ1_Handler(void) {
    __asm volatile("ldr r0, [sp, #24]\n ldr r1, =ret_irq1\n str r0, [r1]\n"
                   "ldr r1, =n_trace\n ldr r2, [r1]\n ldr r3, =trace\n movs r0, #0x11\n"
                   "str r0, [r3, r2, lsl #2]\n adds r2, #1\n str r2, [r1]\n bx lr\n .ltorg");
}

__attribute__((naked, noinline)) void steps(void) {
    __asm volatile(
        "push {r4, lr}\n"
        "ldr r4, =n_trace\n ldr r3, =trace\n"
        "movs r0, #0x40\n msr basepri, r0\n"
        "ldr r0, =0xE000E200\n movs r1, #3\n str r1, [r0]\n"     /* pend IRQ0 and IRQ1 */
        "ldr r2, [r4]\n movs r1, #1\n str r1, [r3, r2, lsl #2]\n adds r2, #1\n str r2, [r4]\n"
        "movs r1, #0\n msr basepri, r1\n"
        ".global after_basepri\n after_basepri: nop\n"
        "cpsid i\n movs r1, #2\n str r1, [r0]\n"                   /* pend IRQ1 under PRIMASK */
        "ldr r2, [r4]\n movs r1, #2\n str r1, [r3, r2, lsl #2]\n adds r2, #1\n str r2, [r4]\n"
        "cpsie i\n"
        ".global after_cpsie\n after_cpsie: nop\n"
        "pop {r4, pc}\n .ltorg");
}

int main(void) {
    REG(0xE000E400) = (0x20u << 8) | 0x80u;      /* IRQ0 0x80, IRQ1 0x20 */
    REG(0xE000E100) = 3;
    steps();
    for (;;) __asm volatile("wfi");
}
