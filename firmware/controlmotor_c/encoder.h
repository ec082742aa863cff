#ifndef ENCODER_H
#define ENCODER_H

#include <stdint.h>
#include "stm32f7xx_hal.h"

/* A timer in encoder mode (x4 on TI1 and TI2) and the revolutions counted by its update ISR. */
typedef struct {
    TIM_HandleTypeDef *htim;
    uint32_t counts_per_turn;   /* quadrature counts per output-shaft turn (64 CPR x 30 = 1920) */
    int irqn;
    volatile int32_t revolutions;
    uint32_t filter;            /* ICxF */
} Encoder;

void encoder_timn_start(Encoder *enc);
void encoder_update_callback(Encoder *enc);
float encoder_get_position(Encoder *enc);
void encoder_set_reset(Encoder *enc);
void encoder_timn_stop(Encoder *enc);

#endif
