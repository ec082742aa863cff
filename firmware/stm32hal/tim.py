"""The timer part of the STM32F7 HAL (stm32f7xx_hal_tim.c v1.3.x), as register sequences.

Only what the ported firmware calls. The order of the writes that matter to the models follows
the C HAL: ``TIM_Base_SetConfig`` writes CR1, ARR, PSC, (RCR), then EGR.UG, then clears UIF
(HAL >= v1.3.1; ``clear_uif_after_ug=False`` gives the older behaviour, STM32CubeF7#110).

Where the port differs from ST's register sequence (what a register log shows, not what the timer
does): ``TIM_CCxChannelCmd``'s two CCER writes (clear, then set) are one; ``HAL_TIM_PWM_ConfigChannel``
writes CCMR once for OCxPE and OCxFE where the HAL does three read-modify-writes, and
``TIM_OCx_SetConfig``'s CR2 write (OISx, on TIM1/TIM8 also CCxNP/CCxNE) is left out; the UIF after UG
is cleared by writing ``~UIF`` to SR where the HAL uses ``CLEAR_BIT`` (a read-modify-write). The C
twin in ``firmware/controlmotor_c`` writes the same sequence as this port.
"""

from __future__ import annotations

from dataclasses import dataclass, field

# CR1
TIM_CR1_CEN, TIM_CR1_UDIS, TIM_CR1_URS, TIM_CR1_OPM, TIM_CR1_DIR = 1 << 0, 1 << 1, 1 << 2, 1 << 3, 1 << 4
TIM_CR1_CMS, TIM_CR1_ARPE, TIM_CR1_CKD, TIM_CR1_UIFREMAP = 3 << 5, 1 << 7, 3 << 8, 1 << 11
# DIER / SR / EGR
TIM_IT_UPDATE, TIM_IT_CC1, TIM_IT_CC2 = 1 << 0, 1 << 1, 1 << 2
TIM_FLAG_UPDATE = 1 << 0
TIM_EGR_UG = 1 << 0
TIM_CNT_UIFCPY = 1 << 31
# BDTR
TIM_BDTR_MOE = 1 << 15

TIM_COUNTERMODE_UP, TIM_COUNTERMODE_DOWN = 0x00, TIM_CR1_DIR
TIM_COUNTERMODE_CENTERALIGNED1, TIM_COUNTERMODE_CENTERALIGNED2 = 1 << 5, 2 << 5
TIM_COUNTERMODE_CENTERALIGNED3 = 3 << 5
TIM_CLOCKDIVISION_DIV1 = 0
TIM_AUTORELOAD_PRELOAD_DISABLE, TIM_AUTORELOAD_PRELOAD_ENABLE = 0, TIM_CR1_ARPE

TIM_CHANNEL_1, TIM_CHANNEL_2, TIM_CHANNEL_3, TIM_CHANNEL_4, TIM_CHANNEL_ALL = 0x0, 0x4, 0x8, 0xC, 0x3C
TIM_OCMODE_PWM1, TIM_OCMODE_PWM2 = 0x60, 0x70
TIM_OCPOLARITY_HIGH, TIM_OCPOLARITY_LOW = 0, 1 << 1
TIM_OCFAST_DISABLE = 0

TIM_ENCODERMODE_TI1, TIM_ENCODERMODE_TI2, TIM_ENCODERMODE_TI12 = 1, 2, 3
TIM_ICPOLARITY_RISING, TIM_ICPOLARITY_FALLING = 0, 1 << 1
TIM_ICSELECTION_DIRECTTI = 1
TIM_ICPSC_DIV1 = 0

_ADVANCED = ("TIM1", "TIM8")


@dataclass
class TIM_Base_InitTypeDef:
    Prescaler: int = 0
    CounterMode: int = TIM_COUNTERMODE_UP
    Period: int = 0
    ClockDivision: int = TIM_CLOCKDIVISION_DIV1
    RepetitionCounter: int = 0
    AutoReloadPreload: int = TIM_AUTORELOAD_PRELOAD_DISABLE


@dataclass
class TIM_HandleTypeDef:
    Instance: object  # a RegView of the timer
    Init: TIM_Base_InitTypeDef = field(default_factory=TIM_Base_InitTypeDef)
    clear_uif_after_ug: bool = True  # HAL >= v1.3.1 (commit 5c42485)


@dataclass
class TIM_OC_InitTypeDef:
    OCMode: int = TIM_OCMODE_PWM1
    Pulse: int = 0
    OCPolarity: int = TIM_OCPOLARITY_HIGH
    OCFastMode: int = TIM_OCFAST_DISABLE


@dataclass
class TIM_Encoder_InitTypeDef:
    EncoderMode: int = TIM_ENCODERMODE_TI12
    IC1Polarity: int = TIM_ICPOLARITY_RISING
    IC1Selection: int = TIM_ICSELECTION_DIRECTTI
    IC1Prescaler: int = TIM_ICPSC_DIV1
    IC1Filter: int = 0
    IC2Polarity: int = TIM_ICPOLARITY_RISING
    IC2Selection: int = TIM_ICSELECTION_DIRECTTI
    IC2Prescaler: int = TIM_ICPSC_DIV1
    IC2Filter: int = 0


def _is_advanced(htim):
    return htim.Instance.name in _ADVANCED


def TIM_Base_SetConfig(htim: TIM_HandleTypeDef) -> None:
    tim, init = htim.Instance, htim.Init
    cr1 = tim.CR1
    cr1 &= ~(TIM_CR1_DIR | TIM_CR1_CMS)
    cr1 |= init.CounterMode
    cr1 = (cr1 & ~TIM_CR1_CKD) | init.ClockDivision
    cr1 = (cr1 & ~TIM_CR1_ARPE) | init.AutoReloadPreload
    tim.CR1 = cr1
    tim.ARR = init.Period
    tim.PSC = init.Prescaler
    if _is_advanced(htim):
        tim.RCR = init.RepetitionCounter
    tim.EGR = TIM_EGR_UG
    if htim.clear_uif_after_ug and tim.SR & TIM_FLAG_UPDATE:
        tim.SR = ~TIM_FLAG_UPDATE & 0xFFFFFFFF


def HAL_TIM_PWM_Init(htim) -> None:
    TIM_Base_SetConfig(htim)


def HAL_TIM_Base_Init(htim) -> None:
    TIM_Base_SetConfig(htim)


def _ccmr_reg(channel):
    return ("CCMR1", 0) if channel in (TIM_CHANNEL_1, TIM_CHANNEL_2) else ("CCMR2", 0)


def HAL_TIM_PWM_ConfigChannel(htim, oc: TIM_OC_InitTypeDef, channel: int) -> None:
    """TIM_OCx_SetConfig then OCxPE and OCxFE, as the HAL does (the first CCR write is immediate)."""
    tim = htim.Instance
    k = channel // 4                       # 0..3
    ccer_e = 1 << (4 * k)
    tim.CCER = tim.CCER & ~ccer_e          # disable the channel
    reg = "CCMR1" if k < 2 else "CCMR2"
    sh = 8 * (k % 2)
    ccmr = getattr(tim, reg)
    ccmr &= ~((0x7 << (4 + sh)) | (1 << (16 + sh)) | (0x3 << sh))  # OCxM (4 bits) and CCxS
    ccmr |= (oc.OCMode & 0x70) << sh
    setattr(tim, reg, ccmr)
    ccer = tim.CCER
    ccer = (ccer & ~(TIM_OCPOLARITY_LOW << (4 * k))) | (oc.OCPolarity << (4 * k))
    setattr(tim, f"CCR{k + 1}", oc.Pulse)
    tim.CCER = ccer
    ccmr = getattr(tim, reg)
    ccmr |= (1 << 3) << sh                 # OCxPE: later CCR writes are preloaded
    ccmr = (ccmr & ~((1 << 2) << sh)) | (oc.OCFastMode << sh)
    setattr(tim, reg, ccmr)


def HAL_TIM_PWM_Start(htim, channel: int) -> None:
    tim = htim.Instance
    tim.CCER = tim.CCER | (1 << channel)   # CCxE: bit 4k == channel value for k = channel/4
    if _is_advanced(htim):
        tim.BDTR = tim.BDTR | TIM_BDTR_MOE
    tim.CR1 = tim.CR1 | TIM_CR1_CEN


def HAL_TIM_PWM_Stop(htim, channel: int) -> None:
    tim = htim.Instance
    tim.CCER = tim.CCER & ~(1 << channel)
    if tim.CCER & 0x1111 == 0:             # __HAL_TIM_MOE_DISABLE / __HAL_TIM_DISABLE
        if _is_advanced(htim):
            tim.BDTR = tim.BDTR & ~TIM_BDTR_MOE
        tim.CR1 = tim.CR1 & ~TIM_CR1_CEN


def HAL_TIM_Encoder_Init(htim, enc: TIM_Encoder_InitTypeDef) -> None:
    tim = htim.Instance
    tim.SMCR = tim.SMCR & ~(0x7 | (1 << 16) | (1 << 14))  # reset SMS and ECE before the base config
    TIM_Base_SetConfig(htim)
    smcr = tim.SMCR
    smcr |= enc.EncoderMode
    ccmr1 = tim.CCMR1
    ccmr1 &= ~(0x3 | (0x3 << 8))
    ccmr1 |= enc.IC1Selection | (enc.IC2Selection << 8)
    ccmr1 &= ~((0x3 << 2) | (0x3 << 10) | (0xF << 4) | (0xF << 12))
    ccmr1 |= enc.IC1Prescaler | (enc.IC2Prescaler << 8)
    ccmr1 |= (enc.IC1Filter << 4) | (enc.IC2Filter << 12)
    ccer = tim.CCER & ~((1 << 1) | (1 << 5) | (1 << 3) | (1 << 7))
    ccer |= enc.IC1Polarity | (enc.IC2Polarity << 4)
    tim.SMCR = smcr
    tim.CCMR1 = ccmr1
    tim.CCER = ccer


def HAL_TIM_Encoder_Start(htim, channel: int = TIM_CHANNEL_ALL) -> None:
    tim = htim.Instance
    tim.CCER = tim.CCER | (1 << 0) | (1 << 4)
    tim.CR1 = tim.CR1 | TIM_CR1_CEN


def HAL_TIM_Encoder_Stop(htim, channel: int = TIM_CHANNEL_ALL) -> None:
    tim = htim.Instance
    tim.CCER = tim.CCER & ~((1 << 0) | (1 << 4))
    tim.CR1 = tim.CR1 & ~TIM_CR1_CEN


def __HAL_TIM_ENABLE_IT(htim, it: int) -> None:
    htim.Instance.DIER = htim.Instance.DIER | it


def __HAL_TIM_DISABLE_IT(htim, it: int) -> None:
    htim.Instance.DIER = htim.Instance.DIER & ~it


def __HAL_TIM_SET_COMPARE(htim, channel: int, value: int) -> None:
    setattr(htim.Instance, f"CCR{channel // 4 + 1}", value)


def __HAL_TIM_GET_COMPARE(htim, channel: int) -> int:
    return getattr(htim.Instance, f"CCR{channel // 4 + 1}")


def __HAL_TIM_GET_AUTORELOAD(htim) -> int:
    return htim.Instance.ARR


def __HAL_TIM_GET_COUNTER(htim) -> int:
    return htim.Instance.CNT


def __HAL_TIM_SET_COUNTER(htim, value: int) -> None:
    htim.Instance.CNT = value


def __HAL_TIM_IS_TIM_COUNTING_DOWN(htim) -> bool:
    return bool(htim.Instance.CR1 & TIM_CR1_DIR)


def __HAL_TIM_UIFREMAP_ENABLE(htim) -> None:
    htim.Instance.CR1 = htim.Instance.CR1 | TIM_CR1_UIFREMAP


def HAL_TIM_IRQHandler(htim, period_elapsed_callback) -> None:
    """The update-event branch of HAL_TIM_IRQHandler (the only one the firmware enables)."""
    tim = htim.Instance
    if tim.SR & TIM_FLAG_UPDATE and tim.DIER & TIM_IT_UPDATE:
        tim.SR = ~TIM_FLAG_UPDATE & 0xFFFFFFFF
        period_elapsed_callback(htim)
