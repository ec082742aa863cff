/* Armv7-M rules the review of the core found broken (Armv7-M ARM B1.5): which case runs is chosen
 * by the host through `which`; results go to res[]. */
#include <stdint.h>
#define R(a) (*(volatile uint32_t *)(a))
#define R8(a) (*(volatile uint8_t *)(a))
#define ICSR R(0xE000ED04)
#define AIRCR R(0xE000ED0C)
#define SHCSR R(0xE000ED24)
#define FPCCR R(0xE000EF34)
#define DEMCR R(0xE000EDFC)
#define DWT_CTRL R(0xE0001000)
#define CYCCNT R(0xE0001004)
#define SYST_CSR R(0xE000E010)
#define SYST_RVR R(0xE000E014)
#define SYST_CVR R(0xE000E018)
#define ISER0 R(0xE000E100)
#define ISPR0 R(0xE000E200)
volatile uint32_t which = 0, delay = 0;
volatile uint32_t res[16], olog[8], nlog, ticks, wakes;
static void L(uint32_t x) { olog[nlog++] = x; }

/* 1, 2: SVC from thread mode with CONTROL = r0 (1: unprivileged); the handler leaves CONTROL.nPRIV
 * = (which == 2). res[2]: SP before the SVC, res[3]: SP after, res[4]: CONTROL after. */
__attribute__((naked, noinline)) void svc_with_control(uint32_t control) {
    __asm volatile("msr control, r0\n isb\n ldr r1, =res\n mov r2, sp\n str r2, [r1, #8]\n"
                   "svc #0\n"
                   ".global svc_next\n svc_next: mov r2, sp\n str r2, [r1, #12]\n"
                   "mrs r2, control\n str r2, [r1, #16]\n bx lr\n .ltorg");
}
/* res[0]: MSP in the handler, res[1]: the stacked return address */
__attribute__((naked)) void SVC_Handler(void) {
    __asm volatile("mrs r0, msp\n ldr r1, =res\n str r0, [r1]\n ldr r2, [r0, #24]\n str r2, [r1, #4]\n"
                   "ldr r2, =which\n ldr r2, [r2]\n cmp r2, #2\n ite eq\n moveq r3, #1\n movne r3, #0\n"
                   "msr control, r3\n isb\n bx lr\n .ltorg");
}

void IRQ1_Handler(void) { L(0xA); }
void IRQ2_Handler(void) {                 /* 6: raising PRIGROUP's split lets IRQ1 preempt at once */
    ISPR0 = 1u << 1; L(0xB0);
    AIRCR = 0x05FA0000 | (3u << 8);       /* 5 -> 3: IRQ1 0x40 (group 2) now preempts IRQ2 0x70 (group 3) */
    __asm volatile("dsb; isb; nop; nop");
    L(0xB1);
}
void IRQ3_Handler(void) { __asm volatile("cpsid f"); res[7]++; }   /* 3: FAULTMASK set, then return */
/* 12: IRQ0 and SysTick record the return address in their frame (res[0], res[1]); SysTick also
 * ICSR (res[2]), the first time */
__attribute__((naked)) void IRQ0_Handler(void) {
    __asm volatile("mrs r1, msp\n ldr r2, [r1, #24]\n ldr r0, =res\n str r2, [r0]\n bx lr\n .ltorg");
}
__attribute__((naked)) void SysTick_Handler(void) {
    __asm volatile("ldr r0, =ticks\n ldr r1, [r0]\n adds r1, #1\n str r1, [r0]\n"
                   "ldr r0, =res\n ldr r3, [r0, #4]\n cbnz r3, 1f\n mrs r1, msp\n ldr r2, [r1, #24]\n"
                   "str r2, [r0, #4]\n ldr r2, =0xE000ED04\n ldr r2, [r2]\n str r2, [r0, #8]\n"
                   "1: bx lr\n .ltorg");
}
/* 5, 7, 9: PendSV records MSP, SHCSR and EXC_RETURN */
__attribute__((naked)) void PendSV_Handler(void) {
    __asm volatile("ldr r1, =res\n mrs r0, msp\n str r0, [r1, #36]\n ldr r0, =0xE000ED24\n ldr r0, [r0]\n"
                   "str r0, [r1, #40]\n str lr, [r1, #44]\n bx lr\n .ltorg");
}
static void pendsv(void) { ICSR = 1u << 28; __asm volatile("dsb; isb; nop"); }

int main(void) {
    while (which == 0) {}
    DEMCR = 1u << 24; DWT_CTRL = 1;
    switch (which) {
    case 1: svc_with_control(1); break;
    case 2: svc_with_control(0); break;
    case 3: {                             /* FAULTMASK is cleared by the return of IRQ3's handler */
        uint32_t fm;
        ISER0 = 1u << 3; ISPR0 = 1u << 3; __asm volatile("dsb; isb; nop");
        __asm volatile("mrs %0, faultmask" : "=r"(fm));
        res[6] = fm;
        break;
    }
    case 4: {                             /* SEV; WFE (goes on: event set); WFE (sleeps to the tick); YIELD */
        uint32_t t0, t1, t2;
        SYST_RVR = 999; SYST_CVR = 0; SYST_CSR = 7;
        t0 = CYCCNT;
        __asm volatile("sev\n wfe");
        t1 = CYCCNT; res[8] = ticks;
        __asm volatile("wfe");
        t2 = CYCCNT; res[9] = ticks;
        __asm volatile("yield");
        SYST_CSR = 0;
        res[5] = t1 - t0; res[6] = t2 - t1; res[7] = 0x600d;
        break;
    }
    case 5:                               /* a frame across the DTCM/SRAM1 seam at 0x20010000 */
        __asm volatile("mov r4, sp\n movw r0, #0x0010\n movt r0, #0x2001\n mov sp, r0\n"
                       "movw r0, #0xED04\n movt r0, #0xE000\n"
                       "mov r1, #0x10000000\n str r1, [r0]\n dsb\n isb\n nop\n mov sp, r4"
                       ::: "r0", "r1", "r4", "memory");
        res[7] = 0x600d;
        break;
    case 6:
        R8(0xE000E401) = 0x40; R8(0xE000E402) = 0x70; ISER0 = 6;
        AIRCR = 0x05FA0000 | (5u << 8);   /* group = bits [7:6]: 0x40 and 0x70 are one group */
        ISPR0 = 1u << 2; __asm volatile("dsb; isb; nop");
        break;
    case 7: pendsv(); res[12] = SHCSR; break;
    case 8: {                             /* CYCCNT stands still while DEMCR.TRCENA = 0 */
        DEMCR = 0; CYCCNT = 0; DWT_CTRL = 1;
        for (volatile int i = 0; i < 10; i++) {}
        res[5] = CYCCNT;
        DEMCR = 1u << 24;
        for (volatile int i = 0; i < 10; i++) {}
        res[6] = CYCCNT;
        break;
    }
    case 9: {                             /* the FP frame follows FPCCR.ASPEN */
        float x = 3.0f;
        __asm volatile("vadd.f32 %0, %0, %0" : "+t"(x));
        pendsv(); res[13] = res[11];
        FPCCR &= ~(1u << 31);
        __asm volatile("vadd.f32 %0, %0, %0" : "+t"(x));
        pendsv(); res[14] = res[11];
        break;
    }
    case 10:                              /* TIM2 free running; the loop's only peripheral access is CNT */
        R(0x40023840) |= 1; R(0x4000002C) = 0xFFFFFFFF; R(0x40000000) = 1;
        for (;;) { res[0] = res[1]; res[1] = R(0x40000024); }
    case 12:                              /* SysTick (priority 0) comes `delay` loops after IRQ0 (0x80) */
        R8(0xE000ED23) = 0x00; R8(0xE000E400) = 0x80; ISER0 = 1;
        SYST_RVR = 199; SYST_CVR = 0; SYST_CSR = 7;
        for (volatile uint32_t i = 0; i < delay; i++) {}
        R(0xE000EF00) = 0;                /* STIR: pend IRQ0 */
        __asm volatile("nop; nop; nop; nop");
        for (volatile int i = 0; i < 100; i++) {}
        SYST_CSR = 0;
        break;
    case 13: {                            /* SCR.SLEEPONEXIT: the thread never runs again */
        uint32_t sp;
        __asm volatile("mov %0, sp" : "=r"(sp));
        res[3] = sp;
        SYST_RVR = 999; SYST_CVR = 0; SYST_CSR = 7;
        R(0xE000ED10) = 2;
        for (;;) wakes++;
    }
    case 11:                              /* WFI with no interrupt enabled: never wakes */
        SYST_RVR = 9; SYST_CVR = 0; SYST_CSR = 5;
        for (;;) { __asm volatile("wfi"); wakes++; }
    }
    for (;;) {}
}
