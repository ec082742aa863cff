"""ControlMotorROS on nucleo-f746: firmware + STM32 timers + L6206 + Pololu motors, closed loop.

Tolerances: one encoder count is 2π/1920 rad = 3.27 mrad at the output shaft; "settled" means
within 3 counts of the set point (stiction and Coulomb friction leave a small dead band that the
integral walks through).
"""

import itertools
import math

import pytest

import mcusim

COUNT = 2 * math.pi / 1920


@pytest.fixture(scope="module")
def settled():
    sim = mcusim.load("nucleo-f746", overrides={"/motor1/set_pos": 1.57, "/motor2/set_pos": -2.0})
    sim.run(seconds=1.5)
    return sim


def test_both_motors_settle_at_their_set_positions(settled):
    m1, m2 = settled.part("motor1"), settled.part("motor2")
    assert abs(m1.output_angle - 1.57) <= 3 * COUNT
    assert abs(m2.output_angle + 2.0) <= 3 * COUNT
    assert abs(m1.speed) < 1.0 and abs(m2.speed) < 1.0  # motor shaft, rad/s: at rest


def test_published_position_matches_the_true_angle_within_one_count(settled):
    for n in (1, 2):
        assert abs(settled.topic(f"/motor{n}/get_pos") - settled.part(f"motor{n}").output_angle) <= COUNT


def test_summary_reports_angles_set_points_and_peak_currents(settled):
    s = settled.summary()
    assert set(s) >= {"simulated_s", "wall_s", "realtime_factor", "events", "motors"}
    assert s["motors"]["motor1"]["setpoint_rad"] == 1.57
    assert 0 < s["motors"]["motor1"]["peak_current_a"] < 5.6  # below the L6206 OCD threshold


def test_disabled_motor_coasts_with_bridge_off():
    sim = mcusim.load("nucleo-f746", overrides={"/motor1/set_pos": 100.0})
    sim.run(seconds=0.3)
    m = sim.part("motor1")
    speed_before = m.speed
    assert speed_before > 500  # rad/s at the motor shaft: spinning
    sim.publish("/motor1/enable", False)
    sim.run(seconds=0.02)  # the executor takes the message within 10 ms
    assert sim.pin("PF15").level == 0          # EN-A low: all bridge switches off
    assert m.current == 0.0                    # current decayed through the diodes and stays 0
    s1 = m.speed
    sim.run(seconds=0.05)
    assert 0 <= m.speed < s1 < speed_before    # coasting down on friction alone


def test_ten_turn_step_wraps_the_encoder_counter_and_position_stays_continuous():
    target = 10 * 2 * math.pi
    sim = mcusim.load("nucleo-f746", overrides={"/motor1/set_pos": target})
    positions = []
    for _ in range(250):
        sim.run(seconds=0.01)
        positions.append(sim.topic("/motor1/get_pos"))
    # 10 turns at ARR = 1919 wrap the counter ten times, each an update interrupt of TIM3 (IRQ 29)
    assert sim.mcu.cpu.isr_count[29] >= 10
    # no jump at the wraps: the output shaft turns at most ~35 rad/s at 12 V, 0.35 rad per 10 ms
    steps = [b - a for a, b in itertools.pairwise(positions) if a is not None]
    assert max(abs(d) for d in steps) < 40 * 0.01
    sim.run(seconds=0.5)  # arrives after ~2 s; the integral then walks it through the stiction band
    assert abs(sim.part("motor1").output_angle - target) <= 3 * COUNT
    assert abs(sim.topic("/motor1/get_pos") - sim.part("motor1").output_angle) <= COUNT


def test_reversing_at_full_speed_trips_the_l6206_overcurrent_protection():
    sim = mcusim.load("nucleo-f746", overrides={"/motor1/set_pos": 1000.0})
    sim.run(seconds=0.4)
    bridge = sim.part("bridgeA")
    assert bridge.ocd_trips == 0
    sim.publish("/motor1/set_pos", -1000.0)
    sim.run(seconds=0.05)
    assert bridge.ocd_trips >= 1
    assert sim.part("motor1").peak_current >= 5.6


def _pwm_period(sim, pin, n=4):
    rises = []
    sim.pin(pin).listen(lambda net: rises.append(sim.now) if net.level else None)
    sim.run(seconds=0.0002)  # 10 periods at 50 kHz, 5 at 25 kHz
    assert len(rises) >= n
    return {b - a for a, b in itertools.pairwise(rises)}


@pytest.mark.parametrize("variant,period_b", [("correct", 4320), ("thesis", 8640)])
def test_thesis_arr_runs_bridge_b_at_25khz(variant, period_b):
    """ARR = 4319 on TIM2 (108 MHz) gives 40 µs = 8640 base ticks; the fix gives 20 µs on both.

    A 0.05 rad step asks for 20 % duty (Kp = 400 %/rad), so both bridges carry PWM edges."""
    sim = mcusim.load("nucleo-f746", overrides={"/motor1/set_pos": 0.05, "/motor2/set_pos": 0.05,
                                                "firmware.variant": variant})
    sim.run(seconds=0.012)  # the executor has delivered the set points and the PID has run
    assert _pwm_period(sim, "PE9") == {4320}
    assert _pwm_period(sim, "PA5") == {period_b}


def test_thesis_position_formula_drives_motor_to_the_wrong_angle():
    """Thesis: pos = rev + CNT/ARR·2π with ARR = 1920 (a turn is 1921 counts). To reach 8 rad the
    firmware must see rev = 2 and CNT·2π/1920 = 6, i.e. true angle 2π·(2·1921 + 6·1920/2π)/1920."""
    sim = mcusim.load("nucleo-f746", overrides={"/motor1/set_pos": 8.0, "firmware.variant": "thesis"})
    sim.run(seconds=1.5)
    expected = 2 * math.pi * (2 * 1921 + 6 * 1920 / (2 * math.pi)) / 1920
    assert abs(sim.part("motor1").output_angle - expected) <= 4 * COUNT
    correct = mcusim.load("nucleo-f746", overrides={"/motor1/set_pos": 8.0})
    correct.run(seconds=1.5)
    assert abs(correct.part("motor1").output_angle - 8.0) <= 3 * COUNT
