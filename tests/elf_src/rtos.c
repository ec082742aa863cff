/* A two-task round robin as an RTOS does it: threads on the process stack (PSP), SysTick pends
 * PendSV, PendSV (lowest priority) saves r4-r11 on the task's stack and switches PSP; SVC starts
 * the first task. Each task counts; both must make progress and keep their own registers. */
#include <stdint.h>
#define REG(a) (*(volatile uint32_t *)(a))
volatile uint32_t count_a, count_b, switches, ticks, svc_calls, errors;
uint32_t stack_a[128] __attribute__((aligned(8)));
uint32_t stack_b[128] __attribute__((aligned(8)));
uint32_t *sp_of[2];
volatile uint32_t current;

static void task(volatile uint32_t *counter, uint32_t seed) {
    register uint32_t r4 __asm("r4") = seed, r5 __asm("r5") = seed * 3u, r11 __asm("r11") = seed ^ 0x55u;
    for (;;) {
        __asm volatile("" : "+r"(r4), "+r"(r5), "+r"(r11));
        if (r5 != r4 * 3u || r11 != (r4 ^ 0x55u)) errors++;
        (*counter)++;
    }
}
void task_a(void) { task(&count_a, 0x1000); }
void task_b(void) { task(&count_b, 0x2000); }

static uint32_t *init_stack(uint32_t *top, void (*fn)(void)) {
    top -= 16;                           /* r4-r11, then r0-r3, r12, lr, pc, xpsr */
    for (int i = 0; i < 16; i++) top[i] = 0;
    top[8 + 6] = (uint32_t)fn;           /* pc */
    top[8 + 7] = 1u << 24;               /* xPSR: thumb */
    return top;
}

void SysTick_Handler(void) { ticks++; REG(0xE000ED04) = 1u << 28; }   /* ICSR.PENDSVSET */

__attribute__((naked)) void SVC_Handler(void) {
    __asm volatile(
        "ldr r0, =svc_calls\n ldr r1, [r0]\n adds r1, #1\n str r1, [r0]\n"
        "ldr r0, =sp_of\n ldr r0, [r0]\n"          /* task A's saved stack */
        "ldmia r0!, {r4-r11}\n msr psp, r0\n"
        "ldr lr, =0xFFFFFFFD\n bx lr\n .ltorg");    /* return to thread mode on PSP */
}

__attribute__((naked)) void PendSV_Handler(void) {
    __asm volatile(
        "mrs r0, psp\n stmdb r0!, {r4-r11}\n"
        "ldr r1, =current\n ldr r2, [r1]\n ldr r3, =sp_of\n str r0, [r3, r2, lsl #2]\n"
        "eor r2, r2, #1\n str r2, [r1]\n ldr r0, [r3, r2, lsl #2]\n"
        "ldmia r0!, {r4-r11}\n msr psp, r0\n"
        "ldr r0, =switches\n ldr r1, [r0]\n adds r1, #1\n str r1, [r0]\n"
        "bx lr\n .ltorg");
}

int main(void) {
    sp_of[0] = init_stack(stack_a + 128, task_a);
    sp_of[1] = init_stack(stack_b + 128, task_b);
    current = 0;
    REG(0xE000ED20) = (0xFFu << 16) | (0x80u << 24);   /* SHPR3: PendSV lowest, SysTick 0x80 */
    REG(0xE000E014) = 21600 - 1;                       /* SysTick: 100 us */
    REG(0xE000E018) = 0;
    REG(0xE000E010) = 7;
    __asm volatile("svc #0");
    for (;;) {}
}
