/* HAL_RCC_Get*Freq and the timer-clock rule, read from the RCC registers (stm32f7xx_hal_rcc.c).
 * The clock tree is the one SystemClock_Config leaves on the nucleo-f746 (216 MHz from the PLL,
 * AHB /1, APB1 /4, APB2 /2); this image does not program the PLL itself (see README.md). */
#include "stm32f7xx_hal.h"

uint32_t SystemCoreClock = 216000000U;

/* RCC_CFGR_HPRE and PPREx codes -> divider, as ST's AHBPrescTable/APBPrescTable */
static uint32_t ahb_div(uint32_t hpre)
{
    static const uint16_t div[8] = {2, 4, 8, 16, 64, 128, 256, 512};
    return (hpre & 0x8U) ? div[hpre & 0x7U] : 1U;
}

static uint32_t apb_div(uint32_t ppre)
{
    return (ppre & 0x4U) ? (2U << (ppre & 0x3U)) : 1U;
}

uint32_t HAL_RCC_GetHCLKFreq(void)
{
    return SystemCoreClock / ahb_div((RCC->CFGR >> 4) & 0xFU);
}

uint32_t HAL_RCC_GetPCLK1Freq(void)
{
    return HAL_RCC_GetHCLKFreq() / apb_div((RCC->CFGR >> 10) & 0x7U);
}

uint32_t HAL_RCC_GetPCLK2Freq(void)
{
    return HAL_RCC_GetHCLKFreq() / apb_div((RCC->CFGR >> 13) & 0x7U);
}

/* RM0385 (DCKCFGR1.TIMPRE); ST's examples: "TIM3CLK = PCLK1*2" */
uint32_t timer_clock_freq(int apb)
{
    uint32_t hclk = HAL_RCC_GetHCLKFreq();
    uint32_t div = apb_div((RCC->CFGR >> (apb == 1 ? 10 : 13)) & 0x7U);
    uint32_t pclk = hclk / div;
    if (!((RCC->DCKCFGR1 >> 24) & 1U))
        return div == 1U ? pclk : 2U * pclk;
    return (div == 1U || div == 2U || div == 4U) ? hclk : 4U * pclk;
}
