#ifndef PWM_H
#define PWM_H

#include <stdbool.h>
#include "stm32f7xx_hal.h"

#define PWM_FREQUENCY_HZ 50000U
#define THESIS_ARR 4319U        /* the thesis's value for every PWM timer: 216 MHz / 50 kHz - 1 */

/* One bridge of the L6206 driven by two channels of one timer, and its EN pin. */
typedef struct {
    TIM_HandleTypeDef *htim;
    int apb;                    /* 1 or 2: which bus clocks the timer */
    uint32_t ch_fwd;            /* TIM_CHANNEL_x given CCR for positive duty */
    uint32_t ch_rev;            /* TIM_CHANNEL_x given CCR for negative duty */
    GPIO_TypeDef *en_port;
    uint16_t en_pin;            /* GPIO_PIN(n) */
    float duty;                 /* last duty set, percent in [-100, 100] */
} Pwm;

void pwm_timn_start(Pwm *pwm);
void pwm_enable(Pwm *pwm, bool enable);
void pwm_timn_set_duty(Pwm *pwm, float duty);
float pwm_timn_get_duty(Pwm *pwm);
void pwm_timn_stop(Pwm *pwm);

#endif
