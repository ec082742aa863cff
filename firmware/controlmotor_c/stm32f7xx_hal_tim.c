/* The timer part of the STM32F7 HAL (stm32f7xx_hal_tim.c v1.3.x), as register sequences: only
 * what ControlMotorROS calls. TIM_Base_SetConfig writes CR1, ARR, PSC, (RCR), then EGR.UG, then
 * clears the UIF that UG set (HAL >= v1.3.1, STM32CubeF7#110). */
#include "stm32f7xx_hal.h"

static void TIM_Base_SetConfig(TIM_HandleTypeDef *htim)
{
    TIM_TypeDef *tim = htim->Instance;
    const TIM_Base_InitTypeDef *init = &htim->Init;
    uint32_t cr1 = tim->CR1;
    cr1 &= ~(TIM_CR1_DIR | TIM_CR1_CMS);
    cr1 |= init->CounterMode;
    cr1 = (cr1 & ~TIM_CR1_CKD) | init->ClockDivision;
    cr1 = (cr1 & ~TIM_CR1_ARPE) | init->AutoReloadPreload;
    tim->CR1 = cr1;
    tim->ARR = init->Period;
    tim->PSC = init->Prescaler;
    if (IS_ADVANCED_TIM(tim))
        tim->RCR = init->RepetitionCounter;
    tim->EGR = TIM_EGR_UG;
    if (tim->SR & TIM_FLAG_UPDATE)
        tim->SR = ~TIM_FLAG_UPDATE;
}

void HAL_TIM_PWM_Init(TIM_HandleTypeDef *htim)
{
    TIM_Base_SetConfig(htim);
}

/* TIM_OCx_SetConfig, then OCxPE and OCxFE as HAL_TIM_PWM_ConfigChannel does: the first CCR write
 * takes effect at once, later ones are preloaded. */
void HAL_TIM_PWM_ConfigChannel(TIM_HandleTypeDef *htim, const TIM_OC_InitTypeDef *oc, uint32_t channel)
{
    TIM_TypeDef *tim = htim->Instance;
    uint32_t k = channel >> 2;                          /* 0..3 */
    __IO uint32_t *ccmr_reg = k < 2U ? &tim->CCMR1 : &tim->CCMR2;
    uint32_t sh = 8U * (k & 1U);
    tim->CCER = tim->CCER & ~(1U << (4U * k));          /* disable the channel */
    uint32_t ccmr = *ccmr_reg;
    ccmr &= ~((0x7U << (4U + sh)) | (1U << (16U + sh)) | (0x3U << sh));   /* OCxM (4 bits), CCxS */
    ccmr |= (oc->OCMode & 0x70U) << sh;
    *ccmr_reg = ccmr;
    uint32_t ccer = tim->CCER;
    ccer = (ccer & ~((1U << 1) << (4U * k))) | (oc->OCPolarity << (4U * k));
    (&tim->CCR1)[k] = oc->Pulse;
    tim->CCER = ccer;
    ccmr = *ccmr_reg;
    ccmr |= (1U << 3) << sh;                            /* OCxPE */
    ccmr = (ccmr & ~((1U << 2) << sh)) | (oc->OCFastMode << sh);
    *ccmr_reg = ccmr;
}

void HAL_TIM_PWM_Start(TIM_HandleTypeDef *htim, uint32_t channel)
{
    TIM_TypeDef *tim = htim->Instance;
    tim->CCER = tim->CCER | (1U << channel);            /* CCxE: bit 4k, and channel = 4k */
    if (IS_ADVANCED_TIM(tim))
        tim->BDTR = tim->BDTR | TIM_BDTR_MOE;
    tim->CR1 = tim->CR1 | TIM_CR1_CEN;
}

void HAL_TIM_PWM_Stop(TIM_HandleTypeDef *htim, uint32_t channel)
{
    TIM_TypeDef *tim = htim->Instance;
    tim->CCER = tim->CCER & ~(1U << channel);
    if ((tim->CCER & 0x1111U) == 0U) {                  /* __HAL_TIM_MOE_DISABLE, __HAL_TIM_DISABLE */
        if (IS_ADVANCED_TIM(tim))
            tim->BDTR = tim->BDTR & ~TIM_BDTR_MOE;
        tim->CR1 = tim->CR1 & ~TIM_CR1_CEN;
    }
}

void HAL_TIM_Encoder_Init(TIM_HandleTypeDef *htim, const TIM_Encoder_InitTypeDef *enc)
{
    TIM_TypeDef *tim = htim->Instance;
    tim->SMCR = tim->SMCR & ~(0x7U | (1U << 16) | (1U << 14));   /* reset SMS and ECE */
    TIM_Base_SetConfig(htim);
    uint32_t smcr = tim->SMCR;
    smcr |= enc->EncoderMode;
    uint32_t ccmr1 = tim->CCMR1;
    ccmr1 &= ~(0x3U | (0x3U << 8));
    ccmr1 |= enc->IC1Selection | (enc->IC2Selection << 8);
    ccmr1 &= ~((0x3U << 2) | (0x3U << 10) | (0xFU << 4) | (0xFU << 12));
    ccmr1 |= enc->IC1Prescaler | (enc->IC2Prescaler << 8);
    ccmr1 |= (enc->IC1Filter << 4) | (enc->IC2Filter << 12);
    uint32_t ccer = tim->CCER & ~((1U << 1) | (1U << 5) | (1U << 3) | (1U << 7));
    ccer |= enc->IC1Polarity | (enc->IC2Polarity << 4);
    tim->SMCR = smcr;
    tim->CCMR1 = ccmr1;
    tim->CCER = ccer;
}

void HAL_TIM_Encoder_Start(TIM_HandleTypeDef *htim, uint32_t channel)
{
    (void)channel;                                      /* TIM_CHANNEL_ALL */
    TIM_TypeDef *tim = htim->Instance;
    tim->CCER = tim->CCER | (1U << 0) | (1U << 4);
    tim->CR1 = tim->CR1 | TIM_CR1_CEN;
}

void HAL_TIM_Encoder_Stop(TIM_HandleTypeDef *htim, uint32_t channel)
{
    (void)channel;
    TIM_TypeDef *tim = htim->Instance;
    tim->CCER = tim->CCER & ~((1U << 0) | (1U << 4));
    tim->CR1 = tim->CR1 & ~TIM_CR1_CEN;
}

/* The update-event branch of HAL_TIM_IRQHandler (the only interrupt the firmware enables). */
void HAL_TIM_IRQHandler(TIM_HandleTypeDef *htim)
{
    TIM_TypeDef *tim = htim->Instance;
    if ((tim->SR & TIM_FLAG_UPDATE) && (tim->DIER & TIM_IT_UPDATE)) {
        tim->SR = ~TIM_FLAG_UPDATE;
        HAL_TIM_PeriodElapsedCallback(htim);
    }
}
