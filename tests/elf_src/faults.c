/* Faults the core reports: a read of unmapped memory, an undefined instruction, a store to flash,
 * SVC where it cannot preempt. Which one runs is chosen by the host through `which`. */
#include <stdint.h>
volatile uint32_t which = 0, sink;

__attribute__((noinline)) void bad_read(void) { sink = *(volatile uint32_t *)0x60000000; }
__attribute__((noinline)) void bad_insn(void) { __asm volatile("udf #7"); }
__attribute__((noinline)) void flash_write(void) { *(volatile uint32_t *)0x08000100 = 1; }
__attribute__((noinline)) void svc_masked(void) { __asm volatile("cpsid i\n svc #1"); }
void SVC_Handler(void) {}

int main(void) {
    while (which == 0) {}
    if (which == 1) bad_read();
    if (which == 2) bad_insn();
    if (which == 3) flash_write();
    if (which == 4) svc_masked();
    if (which == 5) sink = *(volatile uint32_t *)0x400003F0;   /* TIM2: no register there */
    for (;;) __asm volatile("wfi");
}
