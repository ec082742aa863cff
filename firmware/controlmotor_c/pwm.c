/* pwm.c: one bridge of the L6206 driven by two channels of one timer.
 *
 * The sign of the duty picks the direction: the forward channel gets CCR and the reverse channel 0
 * (PWM mode 1, CCR = 0 holds the output low), so the bridge alternates drive and low-side brake.
 * EN, a plain GPIO output, is driven by pwm_enable.
 *
 * Corrected: ARR from the timer's real kernel clock (TIM1 216 MHz -> 4319, TIM2 108 MHz -> 2159).
 * Thesis (CONTROLMOTOR_THESIS): ARR = 4319 for both timers, so bridge B runs at 25 kHz. */
#include "pwm.h"
#include "config.h"

/* Python's round(): to nearest, ties to even (x >= 0) */
static uint32_t round_half_even(float x)
{
    uint32_t i = (uint32_t)x;
    float frac = x - (float)i;
    if (frac > 0.5f || (frac == 0.5f && (i & 1U)))
        i++;
    return i;
}

/* Edge-aligned PWM mode 1 at PWM_FREQUENCY_HZ on both channels, started. */
void pwm_timn_start(Pwm *pwm)
{
    uint32_t dev_clock = timer_clock_freq(pwm->apb);
    uint32_t period;
#if CONTROLMOTOR_THESIS
    (void)dev_clock;
    period = THESIS_ARR;
#else
    period = dev_clock / PWM_FREQUENCY_HZ - 1U;         /* ARR from the timer's kernel clock */
#endif
    TIM_HandleTypeDef *h = pwm->htim;
    h->Init.Prescaler = 0U;
    h->Init.CounterMode = TIM_COUNTERMODE_UP;
    h->Init.Period = period;
    h->Init.ClockDivision = TIM_CLOCKDIVISION_DIV1;
    h->Init.RepetitionCounter = 0U;
    h->Init.AutoReloadPreload = TIM_AUTORELOAD_PRELOAD_ENABLE;
    HAL_TIM_PWM_Init(h);
    TIM_OC_InitTypeDef oc = {.OCMode = TIM_OCMODE_PWM1, .Pulse = 0U, .OCPolarity = TIM_OCPOLARITY_HIGH,
                             .OCFastMode = TIM_OCFAST_DISABLE};
    HAL_TIM_PWM_ConfigChannel(h, &oc, pwm->ch_fwd);
    HAL_TIM_PWM_Start(h, pwm->ch_fwd);
    HAL_TIM_PWM_ConfigChannel(h, &oc, pwm->ch_rev);
    HAL_TIM_PWM_Start(h, pwm->ch_rev);
    pwm->duty = 0.0f;
}

void pwm_enable(Pwm *pwm, bool enable)
{
    HAL_GPIO_WritePin(pwm->en_port, pwm->en_pin, enable ? GPIO_PIN_SET : GPIO_PIN_RESET);
}

/* duty in percent, [-100, 100]; CCR = |duty|*(ARR+1)/100, so 100 % is CCR = ARR+1 (always high) */
void pwm_timn_set_duty(Pwm *pwm, float duty)
{
    if (duty > 100.0f)
        duty = 100.0f;
    else if (duty < -100.0f)
        duty = -100.0f;
    TIM_HandleTypeDef *h = pwm->htim;
    uint32_t top = __HAL_TIM_GET_AUTORELOAD(h) + 1U;
    uint32_t ccr = round_half_even((duty < 0.0f ? -duty : duty) * (float)top / 100.0f);
    uint32_t fwd = duty >= 0.0f ? ccr : 0U;
    uint32_t rev = duty >= 0.0f ? 0U : ccr;
    __HAL_TIM_SET_COMPARE(h, pwm->ch_fwd, fwd);
    __HAL_TIM_SET_COMPARE(h, pwm->ch_rev, rev);
    pwm->duty = duty;
}

float pwm_timn_get_duty(Pwm *pwm)
{
    TIM_HandleTypeDef *h = pwm->htim;
    uint32_t top = __HAL_TIM_GET_AUTORELOAD(h) + 1U;
    int32_t fwd = (int32_t)__HAL_TIM_GET_COMPARE(h, pwm->ch_fwd);
    int32_t rev = (int32_t)__HAL_TIM_GET_COMPARE(h, pwm->ch_rev);
    return 100.0f * (float)(fwd - rev) / (float)top;
}

void pwm_timn_stop(Pwm *pwm)
{
    HAL_TIM_PWM_Stop(pwm->htim, pwm->ch_fwd);
    HAL_TIM_PWM_Stop(pwm->htim, pwm->ch_rev);
}
