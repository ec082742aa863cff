/* For the LPC4337 (ciaa-edu, Cortex-M4F): SysTick at 1 kHz from the 204 MHz core clock counts
 * ticks in .data-initialised and .bss variables; main sleeps in WFI. */
#include <stdint.h>
#define REG(a) (*(volatile uint32_t *)(a))
volatile uint32_t ticks;
volatile uint32_t base = 1000;          /* .data: copied from flash by the start-up code */

void SysTick_Handler(void) { ticks += base / 1000; }

int main(void) {
    REG(0xE000E014) = 204000 - 1;
    REG(0xE000E018) = 0;
    REG(0xE000E010) = 7;
    for (;;) __asm volatile("wfi");
}
