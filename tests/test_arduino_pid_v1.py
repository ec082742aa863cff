"""PID_v1 v1.2.1 as built for AVR (double = binary32): gain scaling, timing, modes, bit-exact output.

Golden vectors are computed here step by step with numpy.float32 from the algorithm in
avr_arduino.md §4, independently of the port, and compared bit for bit.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mcusim.fw.arduino.pid_v1 import AUTOMATIC, DIRECT, MANUAL, P_ON_E, P_ON_M, PID, REVERSE

f32 = np.float32


def bits(x) -> bytes:
    return f32(x).tobytes()


class Clock:
    def __init__(self, t=0):
        self.t = t

    def __call__(self):
        return self.t


def make(kp, ki, kd, p_on=P_ON_E, direction=DIRECT, t=0, limits=None):
    clock = Clock(t)
    pid = PID(kp, ki, kd, p_on=p_on, direction=direction, millis=clock)
    if limits is not None:
        pid.set_output_limits(*limits)
    return pid, clock


# ---- gain scaling --------------------------------------------------------------------------

def test_set_sample_time_rescales_ki_and_kd_in_float32_vector_19():
    pid, _ = make(2.0, 5.0, 1.0)
    tenth = f32(100) / f32(1000)                      # SampleTimeInSec, float32 0.1
    assert bits(pid.ki) == bits(f32(5) * tenth) and pid.ki == f32(0.5)
    assert bits(pid.kd) == bits(f32(1) / tenth) and pid.kd == f32(10.0)
    pid.set_sample_time(50)
    assert bits(pid.ki) == bits(f32(0.25))
    assert bits(pid.kd) == bits(f32(20.0))
    assert pid.sample_time == 50


def test_display_gains_are_the_user_values_and_negative_gains_are_silently_rejected():
    pid, _ = make(1.5, 0.25, 0.125)
    pid.set_tunings(-1.0, 3.0, 3.0)
    assert (pid.get_kp(), pid.get_ki(), pid.get_kd()) == (1.5, 0.25, 0.125)
    assert pid.kp == f32(1.5)
    pid.set_tunings(2.0, 3.0, 4.0)     # 3-argument overload keeps POn
    assert (pid.get_kp(), pid.get_ki(), pid.get_kd()) == (2.0, 3.0, 4.0)
    assert pid.p_on_e


def test_non_positive_sample_time_is_ignored_and_int_parameter_is_16_bit():
    pid, _ = make(1.0, 1.0, 1.0)
    pid.set_sample_time(0)
    pid.set_sample_time(-5)
    pid.set_sample_time(40000)          # int on AVR: wraps to -25536, rejected
    assert pid.sample_time == 100


# ---- timing ---------------------------------------------------------------------------------

def test_compute_fires_at_millis_0_100_200_in_a_tight_loop():
    pid, clock = make(1.0, 1.0, 0.0)
    pid.set_mode(AUTOMATIC)
    fired = []
    for ms in range(1101):
        clock.t = ms
        if pid.compute():
            fired.append(ms)
    assert fired == list(range(0, 1101, 100))


def test_last_time_is_now_so_late_computes_slip():
    pid, clock = make(1.0, 1.0, 0.0)
    pid.set_mode(AUTOMATIC)
    fired = []
    for ms in range(0, 400, 7):        # loop period 7 ms: each compute comes up to 6 ms late
        clock.t = ms
        if pid.compute():
            fired.append(ms)
    assert fired == [0, 105, 210, 315]  # lastTime += SampleTime would give 0, 105, 203, 301


def test_millis_difference_wraps_modulo_2_32():
    pid, clock = make(1.0, 1.0, 0.0, t=2**32 - 50)
    pid.set_mode(AUTOMATIC)
    assert pid.compute()                # lastTime = now - 100 (unsigned), fires at once
    clock.t = 2**32 - 1
    assert not pid.compute()
    clock.t = 49                        # 99 ms later across the wrap
    assert not pid.compute()
    clock.t = 50
    assert pid.compute()


def test_manual_mode_never_computes():
    pid, _ = make(1.0, 1.0, 1.0)
    pid.output = 42.0
    pid.input, pid.setpoint = 1.0, 100.0
    assert not pid.compute()
    assert pid.output == 42.0 and pid.get_mode() == MANUAL


# ---- algorithm ------------------------------------------------------------------------------

def test_p_on_e_and_p_on_m_differ_by_where_kp_acts():
    (e, _), (m, m_clock) = make(2.0, 0.0, 0.0, p_on=P_ON_E), make(2.0, 0.0, 0.0, p_on=P_ON_M)
    for pid in (e, m):
        pid.setpoint = 10.0
        pid.input = 0.0
        pid.set_mode(AUTOMATIC)
        pid.input = 4.0
        assert pid.compute()
    assert e.output == 2.0 * 6.0 and e.output_sum == 0.0     # kp·error, nothing integrated
    assert m.output == 0.0 and m.output_sum == 0.0           # −kp·dInput = −8, clamped at outMin 0
    m.set_output_limits(-100, 100)
    m.input = 5.0
    m.setpoint = 50.0                                         # setpoint step: no kick with P_ON_M
    m_clock.t = 100
    assert m.compute()
    assert m.output_sum == -2.0 and m.output == -2.0


def test_reverse_negates_the_internal_gains_with_int_zero_minus():
    pid, _ = make(2.0, 1.0, 0.5, direction=REVERSE, limits=(-100, 100))
    assert (pid.kp, pid.ki, pid.kd) == (f32(-2.0), f32(-0.1), f32(-5.0))
    assert (pid.get_kp(), pid.get_direction()) == (2.0, REVERSE)
    pid.setpoint = 10.0
    pid.set_mode(AUTOMATIC)
    pid.compute()
    assert pid.output < 0
    zero, _ = make(0.0, 0.0, 0.0, direction=REVERSE)
    assert bits(zero.kp) == bits(0.0)    # 0 - 0.0f is +0.0, not -0.0


def test_direction_change_negates_only_in_automatic():
    pid, _ = make(2.0, 0.0, 0.0)
    pid.set_controller_direction(REVERSE)          # MANUAL: stored, gains untouched
    assert pid.kp == f32(2.0) and pid.get_direction() == REVERSE
    pid.set_tunings(2.0, 0.0, 0.0)                 # next SetTunings applies it
    assert pid.kp == f32(-2.0)
    pid.set_mode(AUTOMATIC)
    pid.set_controller_direction(DIRECT)
    assert pid.kp == f32(2.0)
    pid.set_controller_direction(DIRECT)           # no change, no negation
    assert pid.kp == f32(2.0)


def test_manual_to_automatic_is_bumpless():
    pid, _ = make(1.0, 2.0, 0.0)
    pid.setpoint = 50.0
    pid.input = 50.0
    pid.output = 123.0                             # the user drove the output by hand
    pid.set_mode(AUTOMATIC)
    assert pid.output_sum == 123.0 and pid.last_input == 50.0
    assert pid.compute()
    assert pid.output == 123.0                     # zero error: output continues where it was
    pid.set_mode(MANUAL)
    pid.output = 300.0
    pid.set_mode(AUTOMATIC)                        # Initialize clamps outputSum, not *out
    assert pid.output_sum == 255.0 and pid.output == 300.0
    pid.set_mode(AUTOMATIC)                        # AUTOMATIC → AUTOMATIC: no re-initialise
    pid.output_sum = f32(7.0)
    pid.set_mode(AUTOMATIC)
    assert pid.output_sum == 7.0


def test_set_output_limits_clamps_output_and_sum_in_automatic_only():
    pid, _ = make(1.0, 1.0, 0.0)
    pid.output = 200.0
    pid.set_output_limits(0, 100)                  # MANUAL: not clamped
    assert pid.output == 200.0
    pid.set_output_limits(5, 5)                    # min >= max ignored
    assert (pid.out_min, pid.out_max) == (0.0, 100.0)
    pid.set_mode(AUTOMATIC)
    assert pid.output_sum == 100.0
    pid.set_output_limits(-10, 20)
    assert pid.output == 20.0 and pid.output_sum == 20.0


# ---- bit-exact float32 golden vectors -------------------------------------------------------

GOLDEN_CASES = [
    # kp, ki, kd, setpoint, inputs, p_on
    (2.7, 0.35, 0.013, 100.3, [3.7, 12.9, 25.1], P_ON_E),
    (0.83, 2.9, 0.011, 33.3, [0.7, 4.1, 7.9], P_ON_E),
    (1.3, 0.7, 0.05, 47.9, [1.1, 5.3, 9.7], P_ON_M),
]
LIMITS = (-1000.0, 1000.0)


def golden_float32(kp, ki, kd, sp, inputs, p_on):
    """Compute() by hand, one float32-rounded operation at a time (SampleTime = 100 ms)."""
    sec = f32(100) / f32(1000)
    kp, ki, kd = f32(kp), f32(ki) * sec, f32(kd) / sec
    lo, hi = f32(LIMITS[0]), f32(LIMITS[1])
    sp = f32(sp)
    output_sum, last_input, outs = f32(0), f32(0), []   # Initialize: *out = 0, *in = 0
    for x in inputs:
        x = f32(x)
        error = sp - x
        d_input = x - last_input
        output_sum = output_sum + ki * error
        if p_on == P_ON_M:
            output_sum = output_sum - kp * d_input
        output_sum = min(max(output_sum, lo), hi)
        out = (kp * error if p_on == P_ON_E else f32(0)) + (output_sum - kd * d_input)
        outs.append(min(max(out, lo), hi))
        last_input = x
    return outs


def float64_port(kp, ki, kd, sp, inputs, p_on):
    """What a port with Python doubles would produce (rounded to float32 at the very end)."""
    ki, kd = ki * 0.1, kd / 0.1
    output_sum, last_input, outs = 0.0, 0.0, []
    for x in inputs:
        error, d_input = sp - x, x - last_input
        output_sum += ki * error
        if p_on == P_ON_M:
            output_sum -= kp * d_input
        output_sum = min(max(output_sum, LIMITS[0]), LIMITS[1])
        out = (kp * error if p_on == P_ON_E else 0.0) + output_sum - kd * d_input
        outs.append(f32(min(max(out, LIMITS[0]), LIMITS[1])))
        last_input = x
    return outs


def run_port(kp, ki, kd, sp, inputs, p_on):
    pid, clock = make(kp, ki, kd, p_on=p_on, limits=LIMITS)
    pid.setpoint = sp
    pid.set_mode(AUTOMATIC)
    outs = []
    for i, x in enumerate(inputs):
        clock.t = 100 * i
        pid.input = x
        assert pid.compute()
        outs.append(pid.output)
    return outs


@pytest.mark.parametrize("case", GOLDEN_CASES, ids=["p_on_e_a", "p_on_e_b", "p_on_m"])
def test_output_is_bit_exact_with_float32_arithmetic(case):
    port = run_port(*case)
    golden = golden_float32(*case)
    assert [bits(x) for x in port] == [bits(g) for g in golden]


def test_golden_vector_would_catch_a_float64_port():
    case = GOLDEN_CASES[1]
    golden = golden_float32(*case)
    wide = float64_port(*case)
    assert all(bits(g) != bits(w) for g, w in zip(golden, wide))
    assert bits(golden[0]) == bits(f32(36.43499755859375))   # the float32 value pinned literally


# ---- anti-windup property -------------------------------------------------------------------

finite = st.floats(min_value=-1e4, max_value=1e4, allow_nan=False, allow_infinity=False)
gain = st.floats(min_value=0, max_value=100, allow_nan=False, allow_infinity=False)


@st.composite
def limits(draw):
    lo = draw(st.floats(min_value=-1e4, max_value=1e4))
    hi = draw(st.floats(min_value=-1e4, max_value=1e4))
    if f32(lo) >= f32(hi):
        lo, hi = min(lo, hi) - 1.0, max(lo, hi) + 1.0
    return lo, hi


step = st.one_of(
    st.tuples(st.just("input"), finite),
    st.tuples(st.just("setpoint"), finite),
    st.tuples(st.just("limits"), limits()),
    st.tuples(st.just("tunings"), st.tuples(gain, gain, gain, st.sampled_from([P_ON_E, P_ON_M]))),
    st.tuples(st.just("direction"), st.sampled_from([DIRECT, REVERSE])),
    st.tuples(st.just("sample_time"), st.integers(min_value=-10, max_value=500)),
    st.tuples(st.just("manual"), finite),
)


@settings(max_examples=150, deadline=None)
@given(gain, gain, gain, st.sampled_from([P_ON_E, P_ON_M]), st.sampled_from([DIRECT, REVERSE]),
       limits(), st.lists(step, max_size=60))
def test_output_and_output_sum_stay_within_limits(kp, ki, kd, p_on, direction, lim, steps):
    pid, clock = make(kp, ki, kd, p_on=p_on, direction=direction, limits=lim)
    pid.set_mode(AUTOMATIC)

    def within(x):
        return pid.out_min <= x <= pid.out_max

    for kind, arg in steps:
        if kind == "input":
            pid.input = arg
        elif kind == "setpoint":
            pid.setpoint = arg
        elif kind == "limits":
            pid.set_output_limits(*arg)
            assert within(pid.output)         # clamped at once in AUTOMATIC
        elif kind == "tunings":
            pid.set_tunings(*arg)
        elif kind == "direction":
            pid.set_controller_direction(arg)
        elif kind == "sample_time":
            pid.set_sample_time(arg)
        elif kind == "manual":               # the user takes over, writes the output, hands back
            pid.set_mode(MANUAL)
            pid.output = arg
            pid.set_mode(AUTOMATIC)
        clock.t += 100_000                     # every compute fires, whatever the sample time
        if pid.compute():
            assert within(pid.output)
        assert within(pid.output_sum)


def test_the_constructor_follows_the_c_overloads_a_lone_fourth_argument_is_the_direction():
    """PID_v1.h declares PID(..., Kp, Ki, Kd, POn, ControllerDirection) and PID(..., Kp, Ki, Kd,
    ControllerDirection): ``PID(2, 5, 1, REVERSE)`` is a reverse-acting P_ON_E controller. The
    port's fourth positional argument had been POn, so that call gave a direct P_ON_M one (REVERSE
    lost; and ``PID(2, 5, 1, DIRECT)`` proportional on measurement: 2.5 after a step of 5, where
    P_ON_E gives kp·e + ki·Ts·e = 12.5)."""
    from mcusim.fw.arduino.pid_v1 import AUTOMATIC, DIRECT, P_ON_E, P_ON_M, PID, REVERSE
    t = [0]
    a = PID(2, 5, 1, REVERSE, millis=lambda: t[0])
    assert a.p_on == P_ON_E and a.controller_direction == REVERSE
    b = PID(2, 5, 1, P_ON_M, DIRECT, millis=lambda: t[0])
    assert b.p_on == P_ON_M and b.controller_direction == DIRECT
    c = PID(2, 5, 1, DIRECT, millis=lambda: t[0])
    c.set_output_limits(-1000, 1000)
    c.set_mode(AUTOMATIC)
    c.setpoint = 5.0
    t[0] = 100
    c.compute()
    assert float(c.output) == 12.5           # P_ON_E: kp·e + ki·Ts·e
    with pytest.raises(TypeError):
        PID(2, 5, 1, P_ON_E, DIRECT, 0, millis=lambda: t[0])
