/* A thin register-level HAL written like ST's stm32f7xx_hal_{rcc,gpio,tim,cortex}.c: only what
 * ControlMotorROS calls, with ST's names, writing the registers in ST's order (the Python port in
 * mcusim.fw.stm32hal writes the same sequence, so the two register logs can be compared). */
#ifndef STM32F7XX_HAL_H
#define STM32F7XX_HAL_H

#include <stdint.h>
#include "stm32f7.h"

/* ---- RCC ---------------------------------------------------------------------------------- */
extern uint32_t SystemCoreClock;
uint32_t HAL_RCC_GetHCLKFreq(void);
uint32_t HAL_RCC_GetPCLK1Freq(void);
uint32_t HAL_RCC_GetPCLK2Freq(void);
uint32_t timer_clock_freq(int apb);     /* TIMxCLK of a timer on APB1 or APB2 (TIMPRE rule) */

/* ---- GPIO --------------------------------------------------------------------------------- */
#define GPIO_PIN(n)               ((uint16_t)(1U << (n)))
#define GPIO_MODE_INPUT           0x00U
#define GPIO_MODE_OUTPUT_PP       0x01U
#define GPIO_MODE_OUTPUT_OD       0x11U
#define GPIO_MODE_AF_PP           0x02U
#define GPIO_NOPULL               0U
#define GPIO_SPEED_FREQ_LOW       0U
#define GPIO_SPEED_FREQ_VERY_HIGH 3U
#define GPIO_AF1_TIM1             1U
#define GPIO_AF1_TIM2             1U
#define GPIO_AF2_TIM3             2U
#define GPIO_AF2_TIM4             2U

typedef enum { GPIO_PIN_RESET = 0, GPIO_PIN_SET = 1 } GPIO_PinState;

typedef struct {
    uint32_t Pin;        /* mask of GPIO_PIN(n) */
    uint32_t Mode;
    uint32_t Pull;
    uint32_t Speed;
    uint32_t Alternate;
} GPIO_InitTypeDef;

void HAL_GPIO_Init(GPIO_TypeDef *port, const GPIO_InitTypeDef *init);
void HAL_GPIO_WritePin(GPIO_TypeDef *port, uint16_t pin, GPIO_PinState state);

/* ---- TIM ---------------------------------------------------------------------------------- */
#define TIM_CR1_CEN        (1U << 0)
#define TIM_CR1_DIR        (1U << 4)
#define TIM_CR1_CMS        (3U << 5)
#define TIM_CR1_ARPE       (1U << 7)
#define TIM_CR1_CKD        (3U << 8)
#define TIM_CR1_UIFREMAP   (1U << 11)
#define TIM_IT_UPDATE      (1U << 0)
#define TIM_FLAG_UPDATE    (1U << 0)
#define TIM_EGR_UG         (1U << 0)
#define TIM_CNT_UIFCPY     (1U << 31)
#define TIM_BDTR_MOE       (1U << 15)

#define TIM_COUNTERMODE_UP             0x00U
#define TIM_CLOCKDIVISION_DIV1         0x00U
#define TIM_AUTORELOAD_PRELOAD_DISABLE 0x00U
#define TIM_AUTORELOAD_PRELOAD_ENABLE  TIM_CR1_ARPE

#define TIM_CHANNEL_1   0x00U
#define TIM_CHANNEL_2   0x04U
#define TIM_CHANNEL_3   0x08U
#define TIM_CHANNEL_4   0x0CU
#define TIM_CHANNEL_ALL 0x3CU
#define TIM_OCMODE_PWM1 0x60U
#define TIM_OCPOLARITY_HIGH 0x00U
#define TIM_OCFAST_DISABLE  0x00U
#define TIM_ENCODERMODE_TI12 3U
#define TIM_ICPOLARITY_RISING 0x00U
#define TIM_ICSELECTION_DIRECTTI 1U
#define TIM_ICPSC_DIV1 0U

typedef struct {
    uint32_t Prescaler;
    uint32_t CounterMode;
    uint32_t Period;
    uint32_t ClockDivision;
    uint32_t RepetitionCounter;
    uint32_t AutoReloadPreload;
} TIM_Base_InitTypeDef;

typedef struct {
    TIM_TypeDef *Instance;
    TIM_Base_InitTypeDef Init;
} TIM_HandleTypeDef;

typedef struct {
    uint32_t OCMode;
    uint32_t Pulse;
    uint32_t OCPolarity;
    uint32_t OCFastMode;
} TIM_OC_InitTypeDef;

typedef struct {
    uint32_t EncoderMode;
    uint32_t IC1Polarity, IC1Selection, IC1Prescaler, IC1Filter;
    uint32_t IC2Polarity, IC2Selection, IC2Prescaler, IC2Filter;
} TIM_Encoder_InitTypeDef;

void HAL_TIM_PWM_Init(TIM_HandleTypeDef *htim);
void HAL_TIM_PWM_ConfigChannel(TIM_HandleTypeDef *htim, const TIM_OC_InitTypeDef *oc, uint32_t channel);
void HAL_TIM_PWM_Start(TIM_HandleTypeDef *htim, uint32_t channel);
void HAL_TIM_PWM_Stop(TIM_HandleTypeDef *htim, uint32_t channel);
void HAL_TIM_Encoder_Init(TIM_HandleTypeDef *htim, const TIM_Encoder_InitTypeDef *enc);
void HAL_TIM_Encoder_Start(TIM_HandleTypeDef *htim, uint32_t channel);
void HAL_TIM_Encoder_Stop(TIM_HandleTypeDef *htim, uint32_t channel);
void HAL_TIM_IRQHandler(TIM_HandleTypeDef *htim);
void HAL_TIM_PeriodElapsedCallback(TIM_HandleTypeDef *htim);   /* provided by the application */

#define __HAL_TIM_ENABLE_IT(h, it)      ((h)->Instance->DIER = (h)->Instance->DIER | (it))
#define __HAL_TIM_DISABLE_IT(h, it)     ((h)->Instance->DIER = (h)->Instance->DIER & ~(it))
#define __HAL_TIM_GET_AUTORELOAD(h)     ((h)->Instance->ARR)
#define __HAL_TIM_GET_COUNTER(h)        ((h)->Instance->CNT)
#define __HAL_TIM_SET_COUNTER(h, v)     ((h)->Instance->CNT = (v))
#define __HAL_TIM_IS_TIM_COUNTING_DOWN(h) (((h)->Instance->CR1 & TIM_CR1_DIR) == TIM_CR1_DIR)
#define __HAL_TIM_UIFREMAP_ENABLE(h)    ((h)->Instance->CR1 = (h)->Instance->CR1 | TIM_CR1_UIFREMAP)
#define __HAL_TIM_CCR(h, ch)            (*(&(h)->Instance->CCR1 + ((ch) >> 2)))
#define __HAL_TIM_SET_COMPARE(h, ch, v) (__HAL_TIM_CCR(h, ch) = (v))
#define __HAL_TIM_GET_COMPARE(h, ch)    (__HAL_TIM_CCR(h, ch))

/* ---- Cortex (NVIC, SysTick) --------------------------------------------------------------- */
void HAL_NVIC_SetPriority(int irqn, uint32_t preempt_priority, uint32_t sub_priority);
void HAL_NVIC_EnableIRQ(int irqn);
void HAL_NVIC_DisableIRQ(int irqn);
uint32_t HAL_SYSTICK_Config(uint32_t ticks);

#endif
