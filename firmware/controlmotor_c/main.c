/* main.c of the ControlMotorROS firmware: pin and timer setup, the two PID tasks and the micro-ROS
 * executor with the topics /motorN/set_pos (rad, subscribed), /motorN/enable (bool, subscribed)
 * and /motorN/get_pos (rad, published), N = 1, 2.
 *
 * Board wiring (thesis pin table): bridge A = TIM1 CH1/CH2 on PE9/PE11, EN-A on PF15; bridge B =
 * TIM2 CH1/CH4 on PA5/PA3, EN-B on PF5; motor 1 encoder = TIM3 on PB4/PB5; motor 2 encoder = TIM4
 * on PD12/PD13.
 *
 * The thesis runs FreeRTOS; this image has a SysTick-driven scheduler with the same timing: a
 * 1 kHz tick, the two PID tasks (priority 3) every PID_PERIOD_MS and the executor (priority 2)
 * every EXECUTOR_PERIOD_MS, all first released at tick 0, each woken as vTaskDelayUntil would, the
 * highest-priority ready task first; the core sleeps in WFI when no task is ready.
 *
 * Topics are globals (see controlmotor.topics.toml): the host writes a subscribed value, then
 * increments its _count; the executor takes every topic whose count changed at its next spin, as
 * rclc_executor_spin_some would call the subscription callback. */
#include <stdbool.h>
#include <stdint.h>

#include "config.h"
#include "encoder.h"
#include "pid_controller.h"
#include "pwm.h"
#include "stm32f7xx_hal.h"

/* ---- topics (globals the host reads and writes by symbol) -------------------------------- */
volatile float motor1_set_pos, motor2_set_pos;              /* sub, rad */
volatile uint32_t motor1_set_pos_count, motor2_set_pos_count;
volatile bool motor1_enable = true, motor2_enable = true;   /* sub */
volatile uint32_t motor1_enable_count, motor2_enable_count;
volatile float motor1_get_pos, motor2_get_pos;              /* pub, rad */

/* which build this is, for tools and gdb */
#if CONTROLMOTOR_THESIS
const char controlmotor_variant[] = "thesis";
#else
const char controlmotor_variant[] = "correct";
#endif

/* ---- hardware handles --------------------------------------------------------------------- */
TIM_HandleTypeDef htim1 = {.Instance = TIM1};
TIM_HandleTypeDef htim2 = {.Instance = TIM2};
TIM_HandleTypeDef htim3 = {.Instance = TIM3};
TIM_HandleTypeDef htim4 = {.Instance = TIM4};

Pwm pwm[2] = {
    [BRIDGE_A] = {.htim = &htim1, .apb = 2, .ch_fwd = TIM_CHANNEL_1, .ch_rev = TIM_CHANNEL_2,
                  .en_port = GPIOF, .en_pin = GPIO_PIN(15)},
    [BRIDGE_B] = {.htim = &htim2, .apb = 1, .ch_fwd = TIM_CHANNEL_1, .ch_rev = TIM_CHANNEL_4,
                  .en_port = GPIOF, .en_pin = GPIO_PIN(5)},
};
Encoder enc[2] = {
    [BRIDGE_A] = {.htim = &htim3, .counts_per_turn = COUNTS_PER_TURN, .irqn = TIM3_IRQn,
                  .filter = ENCODER_FILTER},
    [BRIDGE_B] = {.htim = &htim4, .counts_per_turn = COUNTS_PER_TURN, .irqn = TIM4_IRQn,
                  .filter = ENCODER_FILTER},
};
bool enabled[2] = {true, true};

volatile uint32_t uwTick;                   /* the RTOS tick count */

static void MX_GPIO_Init(void)
{
    RCC->AHB1ENR = RCC->AHB1ENR | 0x3FU;    /* GPIOA..F clocks */
    RCC->APB2ENR = RCC->APB2ENR | 0x1U;     /* TIM1 */
    RCC->APB1ENR = RCC->APB1ENR | 0x7U;     /* TIM2, TIM3, TIM4 */
    static const struct { GPIO_TypeDef *port; uint16_t pin; } en[] = {{GPIOF, GPIO_PIN(15)}, {GPIOF, GPIO_PIN(5)}};
    for (unsigned i = 0; i < 2U; i++) {
        GPIO_InitTypeDef out = {.Pin = en[i].pin, .Mode = GPIO_MODE_OUTPUT_PP, .Pull = GPIO_NOPULL,
                                .Speed = GPIO_SPEED_FREQ_LOW};
        HAL_GPIO_WritePin(en[i].port, en[i].pin, GPIO_PIN_RESET);
        HAL_GPIO_Init(en[i].port, &out);
    }
    static const struct { GPIO_TypeDef *port; uint16_t pin; uint8_t af; } afp[] = {
        {GPIOE, GPIO_PIN(9), GPIO_AF1_TIM1}, {GPIOE, GPIO_PIN(11), GPIO_AF1_TIM1},
        {GPIOA, GPIO_PIN(5), GPIO_AF1_TIM2}, {GPIOA, GPIO_PIN(3), GPIO_AF1_TIM2},
        {GPIOB, GPIO_PIN(4), GPIO_AF2_TIM3}, {GPIOB, GPIO_PIN(5), GPIO_AF2_TIM3},
        {GPIOD, GPIO_PIN(12), GPIO_AF2_TIM4}, {GPIOD, GPIO_PIN(13), GPIO_AF2_TIM4},
    };
    for (unsigned i = 0; i < sizeof afp / sizeof afp[0]; i++) {
        GPIO_InitTypeDef init = {.Pin = afp[i].pin, .Mode = GPIO_MODE_AF_PP, .Pull = GPIO_NOPULL,
                                 .Speed = GPIO_SPEED_FREQ_VERY_HIGH, .Alternate = afp[i].af};
        HAL_GPIO_Init(afp[i].port, &init);
    }
}

/* ---- interrupts ----------------------------------------------------------------------------- */
void SysTick_Handler(void)
{
    uwTick++;
}

void TIM3_IRQHandler(void)
{
    HAL_TIM_IRQHandler(&htim3);
}

void TIM4_IRQHandler(void)
{
    HAL_TIM_IRQHandler(&htim4);
}

void HAL_TIM_PeriodElapsedCallback(TIM_HandleTypeDef *htim)
{
    if (htim == &htim3)
        encoder_update_callback(&enc[BRIDGE_A]);
    else if (htim == &htim4)
        encoder_update_callback(&enc[BRIDGE_B]);
}

/* ---- tasks ---------------------------------------------------------------------------------- */
static void set_enable(int bridge, bool enable)
{
    if (enable && !enabled[bridge])
        pid_reset(bridge);
    if (!enable)
        pwm_timn_set_duty(&pwm[bridge], 0.0f);
    pwm_enable(&pwm[bridge], enable);
    enabled[bridge] = enable;
}

/* one pass of a PID task's loop */
static void pid_task(int bridge)
{
    if (enabled[bridge]) {
        float position = encoder_get_position(&enc[bridge]);
        float duty = pid_apply(bridge, position);
        pwm_timn_set_duty(&pwm[bridge], duty);
    }
}

static uint32_t seen_set_pos[2], seen_enable[2];

/* one executor spin: subscription callbacks, then the publishers */
static void microros_task(int unused)
{
    (void)unused;
    volatile float *const set_pos[2] = {&motor1_set_pos, &motor2_set_pos};
    volatile uint32_t *const set_pos_count[2] = {&motor1_set_pos_count, &motor2_set_pos_count};
    volatile bool *const enable[2] = {&motor1_enable, &motor2_enable};
    volatile uint32_t *const enable_count[2] = {&motor1_enable_count, &motor2_enable_count};
    for (int b = BRIDGE_A; b <= BRIDGE_B; b++) {
        uint32_t n = *set_pos_count[b];     /* the count first: the host writes it last */
        if (n != seen_set_pos[b]) {
            seen_set_pos[b] = n;
            pid_set_point(b, *set_pos[b]);
        }
        n = *enable_count[b];
        if (n != seen_enable[b]) {
            seen_enable[b] = n;
            set_enable(b, *enable[b]);
        }
    }
    motor1_get_pos = encoder_get_position(&enc[BRIDGE_A]);
    motor2_get_pos = encoder_get_position(&enc[BRIDGE_B]);
}

/* ---- scheduler: the timing of the FreeRTOS tasks ------------------------------------------ */
typedef struct {
    void (*step)(int);
    int arg;
    uint32_t period;            /* ticks */
    uint32_t wake;              /* tick of the next release */
} Task;

#define TICKS(ms) ((ms) * configTICK_RATE_HZ / 1000U)

static Task tasks[] = {         /* highest priority first */
    {pid_task, BRIDGE_A, TICKS(PID_PERIOD_MS), 0U},
    {pid_task, BRIDGE_B, TICKS(PID_PERIOD_MS), 0U},
    {microros_task, 0, TICKS(EXECUTOR_PERIOD_MS), 0U},
};
#define NTASKS (sizeof tasks / sizeof tasks[0])

static Task *ready_task(void)
{
    uint32_t now = uwTick;
    for (unsigned i = 0; i < NTASKS; i++)
        if ((int32_t)(now - tasks[i].wake) >= 0)
            return &tasks[i];
    return 0;
}

__attribute__((noreturn)) static void scheduler(void)
{
    for (;;) {
        Task *t = ready_task();
        if (t) {
            t->step(t->arg);
            t->wake += t->period;           /* vTaskDelayUntil */
            continue;
        }
        /* sleep until an interrupt: masked, so that a tick between the check and the WFI still
         * wakes the core (WFI wakes on a pending interrupt even with PRIMASK set) */
        __disable_irq();
        if (!ready_task())
            __WFI();
        __enable_irq();
    }
}

int main(void)
{
    MX_GPIO_Init();
    for (int b = BRIDGE_A; b <= BRIDGE_B; b++) {
        pwm_timn_start(&pwm[b]);
        pwm_enable(&pwm[b], true);
        pid_set_parameters(b, PID_KP, PID_KD, PID_KI, PID_WINDUP_LIMIT);
        pid_set_period(b, (float)PID_PERIOD_MS / 1000.0f);
        pid_reset(b);
    }
    for (int b = BRIDGE_A; b <= BRIDGE_B; b++) {
        HAL_NVIC_SetPriority(enc[b].irqn, 5U, 0U);
        HAL_NVIC_EnableIRQ(enc[b].irqn);
        encoder_timn_start(&enc[b]);
    }
    HAL_SYSTICK_Config(SystemCoreClock / configTICK_RATE_HZ);
    scheduler();
}
