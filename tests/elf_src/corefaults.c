/* Faults of the instruction stream and of device accesses the core reports: a call through a
 * function pointer the host sets (`target`: a peripheral, PPB or external address, the end of a
 * memory, an address with bit 0 clear, NULL), an unaligned access to a peripheral register.
 * The host chooses the case through `which`. */
#include <stdint.h>
volatile uint32_t which = 0, target = 0, sink;
typedef void (*fn)(void);

__attribute__((noinline)) void call_target(void) { ((fn)target)(); sink = 1; }
__attribute__((noinline)) void landing(void) { sink = 2; }
__attribute__((noinline)) void unaligned_read(void) { sink = *(volatile uint32_t *)0x40000402; }
__attribute__((noinline)) void unaligned_write(void) { *(volatile uint16_t *)0x40000405 = 1; }

int main(void) {
    while (which == 0) {}
    if (which == 1) call_target();
    if (which == 2) unaligned_read();
    if (which == 3) unaligned_write();
    sink = (uint32_t)landing;
    for (;;) __asm volatile("wfi");
}
