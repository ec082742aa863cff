"""pwm.c: one bridge of the L6206 driven by two channels of one timer.

The sign of the duty picks the direction: the forward channel gets CCR and the reverse channel 0
(PWM mode 1, CCR = 0 holds the output low), so the bridge alternates drive and low-side brake.
EN (the bridge's enable, a plain GPIO output) is driven by ``pwm_enable``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mcusim.fw.stm32hal import gpio as hal_gpio
from mcusim.fw.stm32hal import tim as hal_tim
from mcusim.fw.stm32hal.rcc import timer_clock_freq

_f32 = np.float32
_HUNDRED = _f32(100)

PWM_FREQUENCY_HZ = 50_000
THESIS_ARR = 4319  # the thesis's value for every PWM timer: 216 MHz / 50 kHz - 1


@dataclass
class Pwm:
    htim: hal_tim.TIM_HandleTypeDef
    apb: int                 # 1 or 2: which bus clocks the timer
    ch_fwd: int              # TIM_CHANNEL_x at CCR for positive duty
    ch_rev: int              # TIM_CHANNEL_x at CCR for negative duty
    en_port: object          # GPIO RegView of the EN pin
    en_pin: int
    variant: str = "correct"
    duty: float = 0.0        # last duty set, percent in [-100, 100]


def pwm_timn_start(pwm: Pwm) -> None:
    """Configure the timer for edge-aligned PWM mode 1 at PWM_FREQUENCY_HZ and start both channels."""
    dev_clock = timer_clock_freq(_dev(pwm), pwm.apb)
    if pwm.variant == "thesis":
        period = THESIS_ARR
    else:
        period = dev_clock // PWM_FREQUENCY_HZ - 1  # ARR from the timer's real kernel clock
    h = pwm.htim
    h.Init = hal_tim.TIM_Base_InitTypeDef(Prescaler=0, CounterMode=hal_tim.TIM_COUNTERMODE_UP, Period=period,
                                          AutoReloadPreload=hal_tim.TIM_AUTORELOAD_PRELOAD_ENABLE)
    hal_tim.HAL_TIM_PWM_Init(h)
    oc = hal_tim.TIM_OC_InitTypeDef(OCMode=hal_tim.TIM_OCMODE_PWM1, Pulse=0)
    for ch in (pwm.ch_fwd, pwm.ch_rev):
        hal_tim.HAL_TIM_PWM_ConfigChannel(h, oc, ch)
        hal_tim.HAL_TIM_PWM_Start(h, ch)
    pwm.duty = 0.0


def pwm_enable(pwm: Pwm, enable: bool) -> None:
    hal_gpio.HAL_GPIO_WritePin(pwm.en_port, pwm.en_pin, hal_gpio.GPIO_PIN_SET if enable else hal_gpio.GPIO_PIN_RESET)


def pwm_timn_set_duty(pwm: Pwm, duty: float) -> None:
    """duty in percent, [-100, 100]; CCR = |duty|·(ARR+1)/100, so 100 % is CCR = ARR+1 (always high)."""
    duty = _f32(max(-100.0, min(100.0, duty)))
    h = pwm.htim
    top = hal_tim.__HAL_TIM_GET_AUTORELOAD(h) + 1
    # float in the C: |duty|·(float)top/100.0f rounded once per operation, then to nearest (ties
    # to even: the C's round_half_even)
    ccr = round(float(abs(duty) * _f32(top) / _HUNDRED))
    fwd, rev = (ccr, 0) if duty >= 0 else (0, ccr)
    hal_tim.__HAL_TIM_SET_COMPARE(h, pwm.ch_fwd, fwd)
    hal_tim.__HAL_TIM_SET_COMPARE(h, pwm.ch_rev, rev)
    pwm.duty = float(duty)


def pwm_timn_get_duty(pwm: Pwm) -> float:
    h = pwm.htim
    top = hal_tim.__HAL_TIM_GET_AUTORELOAD(h) + 1
    fwd = hal_tim.__HAL_TIM_GET_COMPARE(h, pwm.ch_fwd)
    rev = hal_tim.__HAL_TIM_GET_COMPARE(h, pwm.ch_rev)
    return float(_HUNDRED * _f32(fwd - rev) / _f32(top))


def pwm_timn_stop(pwm: Pwm) -> None:
    for ch in (pwm.ch_fwd, pwm.ch_rev):
        hal_tim.HAL_TIM_PWM_Stop(pwm.htim, ch)


def _dev(pwm):
    from mcusim.fw.stm32hal.regs import Stm32f7
    return Stm32f7(pwm.htim.Instance._bus)
