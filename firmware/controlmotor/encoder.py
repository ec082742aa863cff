"""encoder.c: a timer in encoder mode (x4, TI1 and TI2) and a revolution count kept by its update ISR.

The correct variant sets ARR = counts per turn − 1 (one turn = ARR+1 counts), computes
position = 2π·(revolutions + CNT/(ARR+1)) and reads CNT with UIFREMAP so that a wrap whose ISR
has not yet run (12-cycle entry latency plus the handler) is still counted. The thesis variant sets
ARR = counts per turn and computes ``revolutions + CNT/ARR·2π``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mcusim.fw.stm32hal import tim as hal_tim

_f32 = np.float32
_TWO_PI = _f32(6.28318530717958647692)      # the C's TWO_PI, a float literal


@dataclass
class Encoder:
    htim: hal_tim.TIM_HandleTypeDef
    counts_per_turn: int      # quadrature counts per output-shaft turn (64 CPR × 30 = 1920)
    irqn: int
    variant: str = "correct"
    revolutions: int = 0
    filter: int = 0           # ICxF


def encoder_timn_start(enc: Encoder) -> None:
    h = enc.htim
    arr = enc.counts_per_turn if enc.variant == "thesis" else enc.counts_per_turn - 1
    h.Init = hal_tim.TIM_Base_InitTypeDef(Prescaler=0, CounterMode=hal_tim.TIM_COUNTERMODE_UP, Period=arr)
    cfg = hal_tim.TIM_Encoder_InitTypeDef(EncoderMode=hal_tim.TIM_ENCODERMODE_TI12,
                                          IC1Filter=enc.filter, IC2Filter=enc.filter)
    hal_tim.HAL_TIM_Encoder_Init(h, cfg)
    if enc.variant != "thesis":
        hal_tim.__HAL_TIM_UIFREMAP_ENABLE(h)
    enc.revolutions = 0
    hal_tim.__HAL_TIM_ENABLE_IT(h, hal_tim.TIM_IT_UPDATE)
    hal_tim.HAL_TIM_Encoder_Start(h, hal_tim.TIM_CHANNEL_ALL)


def encoder_update_callback(enc: Encoder) -> None:
    """HAL_TIM_PeriodElapsedCallback for an encoder timer: one wrap in the counting direction."""
    if hal_tim.__HAL_TIM_IS_TIM_COUNTING_DOWN(enc.htim):
        enc.revolutions -= 1
    else:
        enc.revolutions += 1


def encoder_get_position(enc: Encoder) -> float:
    """Output-shaft angle in radians."""
    h = enc.htim
    cnt = hal_tim.__HAL_TIM_GET_COUNTER(h)
    arr = hal_tim.__HAL_TIM_GET_AUTORELOAD(h)
    # float (binary32) in the C, one rounding per operation; returned as a Python float
    if enc.variant == "thesis":
        return float(_f32(enc.revolutions) + _f32(cnt) / _f32(arr) * _TWO_PI)
    revolutions = enc.revolutions
    if cnt & hal_tim.TIM_CNT_UIFCPY:  # a wrap happened and its ISR has not run yet
        revolutions += -1 if hal_tim.__HAL_TIM_IS_TIM_COUNTING_DOWN(h) else 1
        cnt &= ~hal_tim.TIM_CNT_UIFCPY
    return float(_TWO_PI * (_f32(revolutions) + _f32(cnt) / _f32(arr + 1)))


def encoder_set_reset(enc: Encoder) -> None:
    hal_tim.__HAL_TIM_SET_COUNTER(enc.htim, 0)
    enc.revolutions = 0


def encoder_timn_stop(enc: Encoder) -> None:
    hal_tim.__HAL_TIM_DISABLE_IT(enc.htim, hal_tim.TIM_IT_UPDATE)
    hal_tim.HAL_TIM_Encoder_Stop(enc.htim, hal_tim.TIM_CHANNEL_ALL)
