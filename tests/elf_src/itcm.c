/* Code in the ITCM RAM at address 0 (linked there, copied there by main as start-up code would):
 * it runs as any other code. */
#include <stdint.h>
extern uint32_t _siitcm, _sitcm, _eitcm;
volatile uint32_t calls, sink;
__attribute__((section(".itcm"), noinline)) void fast(void) { calls++; }
int main(void) {
    uint32_t *s = &_siitcm, *d = &_sitcm;
    while (d < &_eitcm) *d++ = *s++;
    for (int i = 0; i < 3; i++) fast();
    sink = 1;
    for (;;) __asm volatile("wfi");
}
