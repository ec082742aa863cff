/* IRQ0..IRQ3 each append their number to trace[]; main sleeps in WFI. The host sets priorities
 * and pends interrupts through the NVIC: the order they run in is the NVIC's. */
#include <stdint.h>
volatile uint32_t trace[64], n_trace;

static void log_irq(uint32_t n) { if (n_trace < 64) trace[n_trace++] = n; }
void IRQ0_Handler(void) { log_irq(0); }
void IRQ1_Handler(void) { log_irq(1); }
void IRQ2_Handler(void) { log_irq(2); }
void IRQ3_Handler(void) { log_irq(3); }

int main(void) {
    *(volatile uint32_t *)0xE000E100 = 0xF;     /* NVIC ISER0: IRQ0..3 */
    for (;;) __asm volatile("wfi");
}
