/* Stacking with and without the FP frame. First IRQ0 is taken before any FP instruction
 * (CONTROL.FPCA = 0: an 8-word frame, EXC_RETURN 0xFFFFFFF9); then main loads s0..s15 with known
 * values and pends IRQ1 (FPCA = 1: a 26-word frame, EXC_RETURN 0xFFFFFFE9); IRQ1's handler
 * overwrites s0..s15; after the return main checks that its values came back. */
#include <stdint.h>
#define REG(a) (*(volatile uint32_t *)(a))
volatile uint32_t lr0, sp0, lr1, sp1, fp_ok, sp_main, control_main;

__attribute__((naked)) void IRQ0_Handler(void) {
    __asm volatile("ldr r0, =lr0\n str lr, [r0]\n ldr r0, =sp0\n str sp, [r0]\n bx lr\n .ltorg");
}

__attribute__((naked)) void IRQ1_Handler(void) {
    __asm volatile("ldr r0, =lr1\n str lr, [r0]\n ldr r0, =sp1\n str sp, [r0]\n"
                   "vmov.f32 s0, #1.0\n vmov.f32 s5, #1.0\n vmov.f32 s15, #1.0\n"
                   "bx lr\n .ltorg");
}

int main(void) {
    uint32_t sp;
    REG(0xE000E100) = 3;
    __asm volatile("mov %0, sp" : "=r"(sp));
    sp_main = sp;
    REG(0xE000E200) = 1;                 /* IRQ0: no FP context yet */
    __asm volatile(
        "vmov.f32 s0, #2.0\n vmov.f32 s5, #3.0\n vmov.f32 s15, #-4.0\n"
        "mrs r0, control\n ldr r1, =control_main\n str r0, [r1]\n"
        "ldr r0, =0xE000E200\n movs r1, #2\n str r1, [r0]\n"      /* IRQ1 with FP context live */
        "vmov r0, s0\n vmov r1, s5\n vmov r2, s15\n"
        "ldr r3, =0x40000000\n cmp r0, r3\n bne 1f\n"
        "ldr r3, =0x40400000\n cmp r1, r3\n bne 1f\n"
        "ldr r3, =0xC0800000\n cmp r2, r3\n bne 1f\n"
        "ldr r0, =fp_ok\n movs r1, #1\n str r1, [r0]\n"
        "1:\n" ::: "r0", "r1", "r2", "r3", "memory");
    for (;;) __asm volatile("wfi");
}
