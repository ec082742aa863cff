/* Nesting by priority and tail-chaining: IRQ0 (priority 0xC0) pends IRQ1 (0x40, preempts at once)
 * and IRQ2 (0xE0, waits and tail-chains after IRQ0). Each handler appends to trace[]. Also: the
 * return address the core stacked for IRQ0 is the instruction right after the store that pended it. */
#include <stdint.h>
#define REG(a) (*(volatile uint32_t *)(a))
#define NVIC_ISER0 0xE000E100
#define NVIC_ISPR0 0xE000E200
#define NVIC_IPR0 0xE000E400
volatile uint32_t trace[16], n_trace;
volatile uint32_t ipsr_in_irq1, lr_in_irq0, stacked_pc, pend_site;
volatile uint32_t r4_after = 0;

static void log_event(uint32_t v) { trace[n_trace++] = v; }

void IRQ0_Handler(void) {
    uint32_t lr, sp;
    __asm volatile("mov %0, lr\n mov %1, sp" : "=r"(lr), "=r"(sp));
    lr_in_irq0 = lr;
    log_event(0x10);
    REG(NVIC_ISPR0) = 1u << 1;          /* IRQ1: more urgent, nests here */
    log_event(0x11);
    REG(NVIC_ISPR0) = 1u << 2;          /* IRQ2: less urgent, tail-chains after this handler */
    log_event(0x12);
}

void IRQ1_Handler(void) {
    uint32_t ipsr;
    __asm volatile("mrs %0, ipsr" : "=r"(ipsr));
    ipsr_in_irq1 = ipsr;
    log_event(0x20);
}

void IRQ2_Handler(void) { log_event(0x30); }

__attribute__((naked)) void IRQ3_Handler(void) {
    /* MSP frame: stacked PC at [sp, #24] */
    __asm volatile("ldr r0, [sp, #24]\n ldr r1, =stacked_pc\n str r0, [r1]\n bx lr\n .ltorg");
}

__attribute__((naked, noinline)) void pend_irq3(void) {
    __asm volatile(
        "ldr r0, =0xE000E200\n movs r1, #8\n"
        "str r1, [r0]\n"                    /* pends IRQ3: taken right after this store */
        ".global pend_irq3_next\n"
        "pend_irq3_next: nop\n nop\n bx lr\n .ltorg");
}

int main(void) {
    /* priorities: IRQ0 0xC0, IRQ1 0x40 (more urgent), IRQ2 0xE0 (less urgent), IRQ3 0x20 */
    REG(NVIC_IPR0) = (0x20u << 24) | (0xE0u << 16) | (0x40u << 8) | 0xC0u;
    REG(NVIC_ISER0) = 0xF;
    REG(NVIC_ISPR0) = 1u << 0;
    log_event(0x01);
    pend_irq3();
    log_event(0x02);
    for (;;) __asm volatile("wfi");
}
