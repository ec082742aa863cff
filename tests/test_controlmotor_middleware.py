"""pwm.c and encoder.c functions on the simulated board: duty round trip, stop, reset, positions."""

import math

from hypothesis import given, settings
from hypothesis import strategies as st
from mcusim.fw.controlmotor.encoder import encoder_get_position, encoder_set_reset, encoder_timn_stop
from mcusim.fw.controlmotor.pid_controller import BRIDGE_A, BRIDGE_B
from mcusim.fw.controlmotor.pwm import pwm_timn_get_duty, pwm_timn_set_duty, pwm_timn_stop

import mcusim

SIM = mcusim.load("nucleo-f746")
FW = SIM.firmware


@settings(max_examples=60, deadline=None)
@given(st.floats(min_value=-100, max_value=100, allow_nan=False), st.sampled_from([BRIDGE_A, BRIDGE_B]))
def test_get_duty_returns_set_duty_quantised_to_one_count(duty, bridge):
    pwm = FW.pwm[bridge]
    pwm_timn_set_duty(pwm, duty)
    top = SIM.mcu.read32(pwm.htim.Instance.base + 0x2C) + 1
    assert abs(pwm_timn_get_duty(pwm) - duty) <= 100 / top / 2 + 1e-9


def test_correct_arr_follows_each_timer_clock():
    # TIM1 at 216 MHz and TIM2 at 108 MHz, both at 50 kHz: ARR+1 = 4320 and 2160
    assert SIM.mcu.read32(0x4001002C) == 4319
    assert SIM.mcu.read32(0x4000002C) == 2159


def test_direction_channel_is_held_at_zero():
    pwm = FW.pwm[BRIDGE_A]
    pwm_timn_set_duty(pwm, -25.0)
    assert SIM.mcu.read32(0x40010034) == 0            # TIM1.CCR1, forward channel
    assert SIM.mcu.read32(0x40010038) == 1080         # TIM1.CCR2 = 25 % of 4320


def test_pwm_stop_disables_outputs_and_counter():
    sim = mcusim.load("nucleo-f746")
    pwm = sim.firmware.pwm[BRIDGE_A]
    sim.run(seconds=0.001)
    pwm_timn_stop(pwm)
    assert sim.mcu.read32(0x40010020) & 0x11 == 0     # CC1E, CC2E cleared
    assert not sim.mcu.read32(0x40010044) & (1 << 15)  # MOE cleared
    assert not sim.mcu.read32(0x40010000) & 1           # CEN cleared
    sim.discard()


def test_encoder_reset_and_stop():
    sim = mcusim.load("nucleo-f746", overrides={"/motor1/set_pos": 3.0})
    sim.run(seconds=0.2)
    enc = sim.firmware.enc[BRIDGE_A]
    assert encoder_get_position(enc) > 0.5
    encoder_set_reset(enc)
    assert encoder_get_position(enc) == 0.0
    encoder_timn_stop(enc)
    assert not sim.mcu.read32(0x40000400) & 1           # TIM3 CEN cleared
    before = sim.mcu.read32(0x40000424)
    sim.run(seconds=0.01)
    assert sim.mcu.read32(0x40000424) == before         # the motor still turns; the counter does not


def test_position_formula_variants_agree_below_one_turn_and_differ_above():
    """Correct: 2π(rev + CNT/(ARR+1)); thesis: rev + CNT/ARR·2π (ARR = 1920); in float (binary32)
    as the C computes them, so to float32's precision (rel 1e-7)."""
    from mcusim.fw.controlmotor.encoder import Encoder
    from mcusim.fw.stm32hal import tim as hal_tim

    class FakeTim:  # registers as the encoder functions read them
        def __init__(self, cnt, arr, down=False):
            self.CNT, self.ARR, self.CR1 = cnt, arr, (hal_tim.TIM_CR1_DIR if down else 0)
    correct = Encoder(hal_tim.TIM_HandleTypeDef(FakeTim(960, 1919)), 1920, 29, "correct", revolutions=2)
    thesis = Encoder(hal_tim.TIM_HandleTypeDef(FakeTim(960, 1920)), 1920, 29, "thesis", revolutions=2)
    assert math.isclose(encoder_get_position(correct), 2 * math.pi * 2.5, rel_tol=1e-7)
    assert math.isclose(encoder_get_position(thesis), 2 + 960 / 1920 * 2 * math.pi, rel_tol=1e-7)
    pending = Encoder(hal_tim.TIM_HandleTypeDef(FakeTim(hal_tim.TIM_CNT_UIFCPY | 3, 1919)), 1920, 29, "correct",
                      revolutions=2)
    assert math.isclose(encoder_get_position(pending), 2 * math.pi * (3 + 3 / 1920), rel_tol=1e-7)  # wrap not counted


def test_the_duty_to_compare_value_is_computed_in_float_as_on_the_f746():
    """pwm.c computes round_half_even(|duty|·(float)top/100.0f) in binary32 (the F746's
    single-precision FPU; the C twin, built with -std=c11, does not contract it into an FMA).
    The port had computed in binary64: for a duty of 62.858795166015625 % (a float) at top =
    4320 the float product rounds to 2715.5 and the compare value to 2716 (ties to even), where
    binary64 gives 2715.499... and 2715."""
    from mcusim.fw.controlmotor.pwm import Pwm, pwm_timn_set_duty
    from mcusim.fw.stm32hal import tim as hal_tim

    class FakeTim:
        def __init__(self):
            self.ARR, self.CCR1, self.CCR2 = 4319, 0, 0
    h = hal_tim.TIM_HandleTypeDef(FakeTim())
    pwm = Pwm(h, 2, hal_tim.TIM_CHANNEL_1, hal_tim.TIM_CHANNEL_2, None, 0)
    pwm_timn_set_duty(pwm, 62.858795166015625)
    assert (h.Instance.CCR1, h.Instance.CCR2) == (2716, 0)
    pwm_timn_set_duty(pwm, -62.858795166015625)
    assert (h.Instance.CCR1, h.Instance.CCR2) == (0, 2716)
