/* For the LPC4337 (ciaa-edu): the clock, pin and reset set-up of an LPCOpen image, register by
 * register as lpc_chip_43xx does it (Chip_SetupCoreClock(CLKIN_CRYSTAL, 204 MHz), Chip_Clock_Enable,
 * Chip_SCU_PinMuxSet, Chip_RGU_TriggerReset / InReset); `done` counts the steps that finished. */
#include <stdint.h>
#define REG(a) (*(volatile uint32_t *)(a))
#define CGU(o) REG(0x40050000u + (o))
#define XTAL_OSC_CTRL CGU(0x18)
#define PLL1_STAT CGU(0x40)
#define PLL1_CTRL CGU(0x44)
#define BASE_M4_CLK CGU(0x6C)
#define CCU1_TIMER0_CFG REG(0x40051520u)
#define CCU1_TIMER0_STAT REG(0x40051524u)
#define SFSP6_1 REG(0x40086304u)
#define RGU_RESET_CTRL1 REG(0x40053104u)
#define RGU_ACTIVE1 REG(0x40053154u)

volatile uint32_t done;
volatile uint32_t chipid;

static void delay(uint32_t n) { for (volatile uint32_t i = n; i; i--) {} }

int main(void) {
    XTAL_OSC_CTRL &= ~2u;                                    /* no bypass */
    XTAL_OSC_CTRL &= ~1u;                                    /* crystal on */
    delay(1000);
    BASE_M4_CLK = (BASE_M4_CLK & ~((0x1Fu << 24) | 1u | (1u << 11))) | (1u << 11) | (6u << 24);
    PLL1_CTRL |= 1;                                          /* PLL1 off */
    done = 1;
    /* 204 MHz = 17 x 12 MHz: first at half (DIRECT clear, P = 1: /2), then direct */
    uint32_t pll = PLL1_CTRL & ~((0x1Fu << 24) | 3u | (1u << 6) | (1u << 7) | (3u << 8) | (0xFFu << 16) | (3u << 12));
    pll |= (6u << 24) | (16u << 16);
    PLL1_CTRL = pll;
    while (!(PLL1_STAT & 1)) {}
    BASE_M4_CLK = (BASE_M4_CLK & ~((0x1Fu << 24) | 1u | (1u << 11))) | (1u << 11) | (9u << 24);
    delay(1000);
    PLL1_CTRL = pll | (1u << 7);                             /* DIRECT: 204 MHz */
    done = 2;
    CCU1_TIMER0_CFG = 0;                                     /* branch clock off, then on */
    while (CCU1_TIMER0_STAT & 1) {}
    CCU1_TIMER0_CFG = 1 | (1u << 1);
    while (!(CCU1_TIMER0_STAT & 1)) {}
    done = 3;
    SFSP6_1 = 0x0 | (1u << 6) | (1u << 4);                   /* P6_1: GPIO3[0], input buffer, no pull-up */
    if (SFSP6_1 != 0x50) for (;;) {}
    done = 4;
    RGU_RESET_CTRL1 = 1u << (32 - 32);                       /* TIMER0_RST (32): not on this board */
    while (!(RGU_ACTIVE1 & (1u << 0))) {}
    RGU_RESET_CTRL1 = 1u << (40 - 32);                       /* ADC0_RST (40) */
    while (!(RGU_ACTIVE1 & (1u << 8))) {}
    chipid = REG(0x40043200u);
    done = 5;
    for (;;) __asm volatile("wfi");
}
