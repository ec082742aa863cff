/* encoder.c: a timer in encoder mode (x4, TI1 and TI2) and a revolution count kept by its update
 * ISR.
 *
 * Corrected: ARR = counts per turn - 1 (one turn is ARR+1 counts), position =
 * 2*pi*(revolutions + CNT/(ARR+1)), and CNT is read with UIFREMAP so that a wrap whose ISR has
 * not run yet (entry latency plus the handler) is still counted; CNT and the revolutions are read
 * with interrupts masked, so that the ISR cannot count the same wrap in between.
 * Thesis (CONTROLMOTOR_THESIS): ARR = counts per turn and position = revolutions + CNT/ARR*2*pi
 * (the 2*pi misses the revolutions), read without either guard. */
#include "encoder.h"
#include "config.h"

#define TWO_PI 6.28318530717958647692f

void encoder_timn_start(Encoder *enc)
{
    TIM_HandleTypeDef *h = enc->htim;
#if CONTROLMOTOR_THESIS
    uint32_t arr = enc->counts_per_turn;
#else
    uint32_t arr = enc->counts_per_turn - 1U;
#endif
    h->Init.Prescaler = 0U;
    h->Init.CounterMode = TIM_COUNTERMODE_UP;
    h->Init.Period = arr;
    h->Init.ClockDivision = TIM_CLOCKDIVISION_DIV1;
    h->Init.RepetitionCounter = 0U;
    h->Init.AutoReloadPreload = TIM_AUTORELOAD_PRELOAD_DISABLE;
    TIM_Encoder_InitTypeDef cfg = {
        .EncoderMode = TIM_ENCODERMODE_TI12,
        .IC1Polarity = TIM_ICPOLARITY_RISING, .IC1Selection = TIM_ICSELECTION_DIRECTTI,
        .IC1Prescaler = TIM_ICPSC_DIV1, .IC1Filter = enc->filter,
        .IC2Polarity = TIM_ICPOLARITY_RISING, .IC2Selection = TIM_ICSELECTION_DIRECTTI,
        .IC2Prescaler = TIM_ICPSC_DIV1, .IC2Filter = enc->filter,
    };
    HAL_TIM_Encoder_Init(h, &cfg);
#if !CONTROLMOTOR_THESIS
    __HAL_TIM_UIFREMAP_ENABLE(h);
#endif
    enc->revolutions = 0;
    __HAL_TIM_ENABLE_IT(h, TIM_IT_UPDATE);
    HAL_TIM_Encoder_Start(h, TIM_CHANNEL_ALL);
}

/* HAL_TIM_PeriodElapsedCallback for an encoder timer: one wrap in the counting direction. */
void encoder_update_callback(Encoder *enc)
{
    if (__HAL_TIM_IS_TIM_COUNTING_DOWN(enc->htim))
        enc->revolutions--;
    else
        enc->revolutions++;
}

/* Output-shaft angle in radians. */
float encoder_get_position(Encoder *enc)
{
    TIM_HandleTypeDef *h = enc->htim;
#if CONTROLMOTOR_THESIS
    uint32_t cnt = __HAL_TIM_GET_COUNTER(h);
    uint32_t arr = __HAL_TIM_GET_AUTORELOAD(h);
    return (float)enc->revolutions + (float)cnt / (float)arr * TWO_PI;
#else
    __disable_irq();
    uint32_t cnt = __HAL_TIM_GET_COUNTER(h);
    uint32_t arr = __HAL_TIM_GET_AUTORELOAD(h);
    int32_t revolutions = enc->revolutions;
    if (cnt & TIM_CNT_UIFCPY) {            /* a wrap happened and its ISR has not run yet */
        revolutions += __HAL_TIM_IS_TIM_COUNTING_DOWN(h) ? -1 : 1;
        cnt &= ~TIM_CNT_UIFCPY;
    }
    __enable_irq();
    return TWO_PI * ((float)revolutions + (float)cnt / (float)(arr + 1U));
#endif
}

void encoder_set_reset(Encoder *enc)
{
    __HAL_TIM_SET_COUNTER(enc->htim, 0U);
    enc->revolutions = 0;
}

void encoder_timn_stop(Encoder *enc)
{
    __HAL_TIM_DISABLE_IT(enc->htim, TIM_IT_UPDATE);
    HAL_TIM_Encoder_Stop(enc->htim, TIM_CHANNEL_ALL);
}
