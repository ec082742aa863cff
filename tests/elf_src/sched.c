/* An access that schedules a peripheral event before the quantum's end: enabling TIM2 (PSC 0,
 * ARR 99: an update 100 timer ticks later, 200 core cycles at 108 MHz) while polling its UIF.
 * The poll must see UIF the first time it reads SR at or after the update, so the CYCCNT
 * difference between the enabling write and that read is 200 plus at most one poll loop. */
#include <stdint.h>
#define REG(a) (*(volatile uint32_t *)(a))
volatile uint32_t t_start, t_seen, polls;

int main(void) {
    REG(0xE000EDFC) |= 1u << 24;
    REG(0xE0001000) |= 1;
    REG(0x40000028) = 0;            /* TIM2 PSC */
    REG(0x4000002C) = 99;           /* ARR */
    REG(0x40000010) = 0;            /* SR */
    uint32_t n = 0;
    t_start = REG(0xE0001004);
    REG(0x40000000) = 1;            /* CR1.CEN: the update is now scheduled */
    while (!(REG(0x40000010) & 1)) n++;
    t_seen = REG(0xE0001004);
    polls = n;
    for (;;) __asm volatile("wfi");
}
