"""Rover body (skid-steer kinematics, turning and rolling resistance as wheel loads, pose) and the
emergency-stop button.

The kinematic rules are checked with wheels whose motion is prescribed (constant output speeds:
every expected pose is a closed-form line or circle); the coupling to real motors with a drive
(inertia split, loads felt by the motors, hardware cut of the E-stop) with DcMotor + BTS7960.
"""

import math
from types import SimpleNamespace

import pytest

from mcusim.errors import ConfigError
from mcusim.kernel import Kernel
from mcusim.plant.bts7960 import Bts7960Bridge, Bts7960Params
from mcusim.plant.dcmotor import DcMotor, MotorParams
from mcusim.plant.estop import EStop
from mcusim.plant.presets import motor_preset
from mcusim.plant.rover import G, RoverBody, wrap_angle
from mcusim.signals import Net
from mcusim.time import TimeBase

FS = 16_000_000
MS = FS // 1000
PRESET = "openrover-100w-50"
P = MotorParams.from_mapping(motor_preset(PRESET))
BR = Bts7960Params()
R = 0.195                      # wheel radius, m (0.39 m wheels)
B, L_WB, M = 0.55, 0.45, 50.0  # track, wheelbase, mass (RoverBody defaults)


class Wheel:
    """A wheel shaft turning at a prescribed constant output speed ``w`` (rad/s) from angle 0; it
    records the loads and inertia the body sets on it."""

    def __init__(self, k, w):
        self.k, self.w = k, float(w)
        self.params = SimpleNamespace(load_torque=0.0, load_inertia=0.0, efficiency=P.efficiency)
        self.loads = []

    @property
    def output_angle(self):
        return self.w * self.k.now / FS

    @property
    def output_speed(self):
        return self.w

    def set_params(self, **kw):
        for key, v in kw.items():
            setattr(self.params, key, v)

    def apply_load_torque(self, tau):
        self.params.load_torque = tau
        self.loads.append((self.k.now, tau))


def kin_rover(speeds, sides="LRLR", **kw):
    k = Kernel(TimeBase([FS]))
    wheels = [Wheel(k, w) for w in speeds]
    body = RoverBody(k, motors=wheels, sides=sides, **kw)
    return k, wheels, body


def circle(v, wz, t, psi0=0.0):
    """Pose after t s of constant (v, ω_z) from the origin: the analytic circle (or line)."""
    if wz == 0.0:
        return v * t, 0.0, 0.0
    rho = v / wz
    return rho * math.sin(wz * t), rho * (1.0 - math.cos(wz * t)), wz * t


# ---- kinematics and pose --------------------------------------------------------------------------------

def test_straight_run_with_equal_wheel_speeds_has_zero_yaw_and_x_equal_r_phi():
    w = 4.0                                                          # 0.78 m/s
    k, wheels, body = kin_rover([w] * 4)
    k.run_until(2 * FS)
    x, y, yaw = body.pose
    phi = wheels[0].output_angle
    assert (y, yaw) == (0.0, 0.0)
    assert x == pytest.approx(R * phi, rel=1e-12) and body.distance == pytest.approx(R * phi, rel=1e-12)
    assert body.velocity == pytest.approx((R * w, 0.0))


def test_straight_run_with_real_coasting_motors_x_is_r_times_the_motor_output_angle():
    k = Kernel(TimeBase([FS]))
    motors = [DcMotor(k, f"m{j}", preset=PRESET, speed=100.0) for j in range(4)]   # no driver: coast
    body = RoverBody(k, motors=motors, sides=["L", "R", "L", "R"])
    k.run_until(round(0.3 * FS) + 123)                              # between two steps
    x, y, yaw = body.pose_at_now()
    assert (y, yaw) == (0.0, 0.0)
    assert x == pytest.approx(R * motors[0].output_angle, rel=1e-12)
    assert x > 0.05 and motors[0].output_speed < 100.0 / 50       # it did roll and slow down


@pytest.mark.parametrize("chi", [1.0, 1.5])
def test_spot_turn_yaw_is_r_times_the_wheel_angle_difference_over_chi_track(chi):
    w = 3.0
    k, _wheels, body = kin_rover([-w, w, -w, w], chi=chi)
    t = 3.0
    k.run_until(round(t * FS))
    x, y, yaw = body.pose
    psi = R * (w * t - (-w * t)) / (chi * B)                         # r·(φR − φL)/(χ·track)
    assert psi > math.pi                                             # wrapped below
    assert yaw == pytest.approx(wrap_angle(psi), abs=1e-12) and -math.pi < yaw <= math.pi
    assert body.yaw_unwrapped == pytest.approx(psi, rel=1e-12)
    assert abs(x) < 1e-15 and abs(y) < 1e-15 and body.distance == 0.0
    assert body.velocity == pytest.approx((0.0, 2 * R * w / (chi * B)))


def test_arc_pose_follows_the_analytic_circle_at_steps_and_between_them():
    wl, wr = 2.0, 3.0
    k, _wheels, body = kin_rover([wl, wr, wl, wr])
    v, wz = R * (wl + wr) / 2, R * (wr - wl) / (1.5 * B)
    for t_ticks in (round(0.7 * FS), round(3.0 * FS) + 4321, round(12.0 * FS) + 1):
        k.run_until(t_ticks)
        t = t_ticks / FS
        xe, ye, pe = circle(v, wz, t)
        x, y, yaw = body.pose_at_now()
        assert x == pytest.approx(xe, abs=1e-9) and y == pytest.approx(ye, abs=1e-9)
        assert yaw == pytest.approx(wrap_angle(pe), abs=1e-12)
    # the last-step pose lags by the partial step only
    xs, ys, _ = body.pose
    assert math.hypot(x - xs, y - ys) == pytest.approx(v * (1 / FS), rel=1e-3)
    assert body.distance == pytest.approx(v * (body.steps * 1e-3), rel=1e-12)


def test_differential_robot_with_chi_1_is_the_ideal_differential_drive():
    wl, wr = 1.0, 5.0
    k, wheels, body = kin_rover([wl, wr], sides="LR", chi=1.0, mu_turn=0.0, track=0.3, mass=5.0)
    k.run_until(2 * FS)
    v, wz = R * (wl + wr) / 2, R * (wr - wl) / 0.3
    xe, ye, pe = circle(v, wz, 2.0)
    x, y, yaw = body.pose
    assert (x, y) == pytest.approx((xe, ye), abs=1e-9) and yaw == pytest.approx(wrap_angle(pe), abs=1e-12)
    # no turning resistance: only rolling resistance, against each wheel's rotation
    f_roll = 0.03 * 5.0 * G / 2
    for wh in wheels:
        assert wh.params.load_torque == pytest.approx(R * f_roll * math.tanh(R * wh.w / 0.01), rel=1e-12)


def test_mirrored_motors_are_mapped_by_direction_and_their_loads_flip_sign():
    k, wheels, body = kin_rover([2.0, -2.0, 2.0, -2.0], directions=[1, -1, 1, -1])
    k.run_until(FS)
    x, y, yaw = body.pose
    assert x == pytest.approx(R * 2.0, rel=1e-12) and (y, yaw) == (0.0, 0.0)
    assert wheels[0].params.load_torque > 0 and wheels[1].params.load_torque < 0
    assert wheels[1].params.load_torque == pytest.approx(-wheels[0].params.load_torque, rel=1e-15)


# ---- loads -----------------------------------------------------------------------------------------------

def test_turning_resistance_opposes_the_right_wheels_and_pushes_the_left_ones_for_positive_yaw():
    wl, wr = 1.0, 3.0                                               # left arc: ω_z > 0
    k, wheels, body = kin_rover([wl, wr, wl, wr], crr=0.0)
    k.run_until(5 * MS)
    wz = R * (wr - wl) / (1.5 * B)
    m_r = 0.5 * M * G * L_WB / 4                                    # Wong: μ·W·l/4, l = wheelbase
    assert body.turn_moment == pytest.approx(m_r, rel=1e-12) and 27 < m_r < 28
    f = 2 * m_r / (4 * B)                                           # moment balance at ±track/2
    tau = R * f * math.tanh(wz / 0.05)
    for wh, side in zip(wheels, "LRLR", strict=True):
        expected = tau if side == "R" else -tau
        assert wh.params.load_torque == pytest.approx(expected, rel=1e-12)
    assert wheels[1].params.load_torque > 0 > wheels[0].params.load_torque
    # the wheel forces at ±track/2 balance M_r
    forces = [wh.params.load_torque / R for wh in wheels]
    assert (B / 2) * (sum(forces[1::2]) - sum(forces[0::2])) == pytest.approx(m_r * math.tanh(wz / 0.05))
    # mirror: a right turn (ω_z < 0) flips every sign
    k, wheels, body = kin_rover([wr, wl, wr, wl], crr=0.0)
    k.run_until(5 * MS)
    assert wheels[0].params.load_torque == pytest.approx(tau) and wheels[1].params.load_torque == pytest.approx(-tau)


def test_rolling_resistance_is_crr_m_g_over_n_per_wheel_against_the_rotation_and_fades_at_rest():
    k, wheels, _ = kin_rover([2.0, 2.0, -2.0, -2.0], sides="LLRR", mu_turn=0.0)
    k.run_until(2 * MS)
    f_roll = 0.03 * M * G / 4                                       # 3.7 N per wheel: 0.72 N·m at the wheel
    assert R * f_roll == pytest.approx(0.717, abs=1e-3)
    assert R * f_roll / (P.gear_ratio * P.efficiency) == pytest.approx(0.018, abs=1e-3)   # docs/plants.md §1.4 "≈20 mN·m"
    for wh in wheels:
        assert wh.params.load_torque == pytest.approx(math.copysign(R * f_roll, wh.w) * math.tanh(R * 2.0 / 0.01))
    k, wheels, _body = kin_rover([0.0] * 4)
    k.run_until(2 * MS)
    assert all(wh.params.load_torque == 0.0 for wh in wheels) and all(not wh.loads for wh in wheels)


def test_inertia_split_sets_each_motor_load_inertia_and_the_implied_yaw_inertia_is_reported():
    _, wheels, body = kin_rover([0.0] * 4)
    j_w = (M / 4) * R ** 2 + 0.5 * 2.0 * R ** 2
    assert j_w == pytest.approx(motor_preset(PRESET)["load_inertia"], rel=1e-3)   # docs/plants.md §1.4 value
    assert all(wh.params.load_inertia == pytest.approx(j_w, rel=1e-12) for wh in wheels)
    assert body.yaw_inertia_implied == pytest.approx(M * (1.5 * B / 2) ** 2) == pytest.approx(8.51, abs=0.01)
    assert body.yaw_inertia == pytest.approx(M * (L_WB ** 2 + B ** 2) / 12) == pytest.approx(2.10, abs=0.01)
    assert body.yaw_inertia_ratio == pytest.approx(4.05, abs=0.01)
    _k, wheels, body = kin_rover([0.0] * 2, sides="LR", mass=10.0, wheel_mass=0.5, yaw_inertia=0.3)
    assert wheels[0].params.load_inertia == pytest.approx(5.0 * R ** 2 + 0.25 * R ** 2)
    assert body.yaw_inertia == 0.3


def test_bad_body_configurations_are_config_errors():
    k = Kernel(TimeBase([FS]))
    ws = [Wheel(k, 0.0) for _ in range(4)]
    with pytest.raises(ConfigError, match="side per motor"):
        RoverBody(k, motors=ws, sides="LRL")
    with pytest.raises(ConfigError, match="both sides"):
        RoverBody(k, motors=ws, sides="LLLL")
    with pytest.raises(ConfigError, match="chi"):
        RoverBody(k, motors=ws, sides="LRLR", chi=0.8)
    with pytest.raises(ConfigError, match="too long"):
        RoverBody(k, motors=ws, sides="LRLR", step="20ms")
    with pytest.raises(ConfigError, match="directions"):
        RoverBody(k, motors=ws, sides="LRLR", directions=[1, 1, 1, 2])
    with pytest.raises(ConfigError, match="listed twice"):
        RoverBody(k, motors=[ws[0], ws[1], ws[0], ws[3]], sides="LRLR")
    with pytest.raises(ConfigError, match="not a wheel motor"):
        RoverBody(k, motors=[*ws[:3], Net("oops")], sides="LRLR")


# ---- real motors -----------------------------------------------------------------------------------------

def drive_rig(n=4, sides="LRLR"):
    k = Kernel(TimeBase([FS]))
    s = SimpleNamespace(k=k, motors=[], bridges=[], rpwm=[], lpwm=[])
    for j in range(n):
        m = DcMotor(k, f"m{j}", preset=PRESET)
        rp, lp = Net(f"RPWM{j}"), Net(f"LPWM{j}")
        s.bridges.append(Bts7960Bridge(k, m, rp, lp, name=f"ibt{j}"))
        s.motors.append(m)
        s.rpwm.append(rp)
        s.lpwm.append(lp)
    s.body = RoverBody(k, motors=s.motors, sides=sides)
    return s


def test_spot_turn_with_real_motors_the_motor_current_carries_the_turning_and_rolling_loads():
    """Left bridges in reverse, right bridges forward at full duty: a symmetric spot turn. At the
    steady state every motor's torque balances friction plus the body's output-shaft load, reflected
    through the gearbox (the motor drives the load: τ/(N·η))."""
    s = drive_rig()
    for j, side in enumerate("LRLR"):
        (s.lpwm if side == "L" else s.rpwm)[j].set("mcu", 1)
    s.k.run_until(round(0.6 * FS))
    wz = s.body.velocity[1]
    x, y, _yaw = s.body.pose_at_now()
    assert wz > 0 and abs(x) < 1e-9 and abs(y) < 1e-9
    phi = [m.output_angle for m in s.motors]
    assert s.body.yaw_unwrapped == pytest.approx(R * (phi[1] - phi[0]) / (1.5 * B), rel=1e-6)
    m_r = 0.5 * M * G * L_WB / 4
    for m, side in zip(s.motors, "LRLR", strict=True):
        w_out = m.output_speed
        sgn = 1.0 if side == "R" else -1.0
        tau_out = R * (0.03 * M * G / 4 * math.tanh(R * w_out / 0.01)
                       + sgn * 2 * m_r / (4 * B) * math.tanh(wz / 0.05))
        assert abs(tau_out) > 5.5                                   # ≈ r·(3.7 + 25.1 N)
        tl = math.copysign(P.tau_c, w_out) + tau_out / (P.gear_ratio * P.efficiency)
        assert m.current == pytest.approx((tl + P.b * m.speed) / P.K, rel=1e-4)
        # and the electrical side: 12 V across R + both R_ON at that speed
        v = 12.0 if side == "R" else -12.0
        assert m.current == pytest.approx((v - P.K * m.speed) / (P.R + BR.R_HS + BR.R_LS), rel=1e-4)


def test_in_a_left_arc_the_left_wheels_are_pushed_and_regenerate_the_right_ones_are_held_back():
    """All four bridges at full forward duty, the left ones on an 8 V supply (set_supply), the
    right ones on 12 V: a steady left arc (ω_z > 0). The turning resistance (25 N per wheel) exceeds
    the rolling resistance (3.7 N), so the left wheels are pushed forward by the body: the load
    back-drives their gearboxes (τ_out·η/N at the motor) and their current reverses."""
    s = drive_rig()
    for j, side in enumerate("LRLR"):
        s.rpwm[j].set("mcu", 1)
        if side == "L":
            s.bridges[j].set_supply(8.0)
    s.k.run_until(round(0.6 * FS))
    wz = s.body.velocity[1]
    assert wz > 0.2
    loads = s.body.wheel_loads
    assert loads[1] > 0 > loads[0] and loads[3] > 0 > loads[2]      # right opposed, left pushed
    m_r = 0.5 * M * G * L_WB / 4
    r_loop = P.R + BR.R_HS + BR.R_LS
    for m, side in zip(s.motors, "LRLR", strict=True):
        w_out = m.output_speed
        sgn = 1.0 if side == "R" else -1.0
        tau_out = R * (0.03 * M * G / 4 * math.tanh(R * w_out / 0.01)
                       + sgn * 2 * m_r / (4 * B) * math.tanh(wz / 0.05))
        if side == "R":
            tl = tau_out / (P.gear_ratio * P.efficiency)            # the motor drives the load
        else:
            assert tau_out < 0
            tl = tau_out * P.efficiency / P.gear_ratio              # the load back-drives the motor
        assert m.current == pytest.approx((P.tau_c + P.b * m.speed + tl) / P.K, rel=1e-4)
        v = 12.0 if side == "R" else 8.0
        assert m.current == pytest.approx((v - P.K * m.speed) / r_loop, rel=1e-4)
        assert (m.current < 0) == (side == "L")                      # left motors regenerate


# ---- E-stop ----------------------------------------------------------------------------------------------

def test_estop_cuts_the_enable_line_and_pulls_sense_low_release_restores():
    k = Kernel(TimeBase([FS]))
    en_in, en_out, sense = Net("GPIO_EN"), Net("ENABLE", pull=0), Net("ESTOP_SENSE", pull=1)
    es = EStop(k, enable_in=en_in, enable_out=en_out, sense=sense)
    assert (en_out.level, sense.level, es.pressed) == (0, 1, False)
    en_in.set("mcu", 1)
    assert en_out.level == 1                                        # NC contact closed: follows
    es.press()
    assert (en_out.level, sense.level, es.pressed) == (0, 0, True)
    en_in.set("mcu", 0)
    en_in.set("mcu", 1)                                             # firmware keeps enabling
    assert en_out.level == 0
    es.press()                                                      # latched: a second push is a no-op
    assert es.presses == 1
    es.release()
    assert (en_out.level, sense.level, es.pressed) == (1, 1, False)
    en_in.set("mcu", 0)
    assert en_out.level == 0


def test_estop_is_a_hardware_cut_the_bridge_coasts_and_the_current_dies_with_enable_still_high():
    k = Kernel(TimeBase([FS]))
    m = DcMotor(k, "m", preset=PRESET)
    rp, lp = Net("RPWM"), Net("LPWM")
    en_in, en_out, sense = Net("GPIO_EN"), Net("ENABLE", pull=0), Net("SENSE", pull=1)
    br = Bts7960Bridge(k, m, rp, lp, r_en=en_out, l_en=en_out)
    estop = EStop(k, enable_in=en_in, enable_out=en_out, sense=sense)
    en_in.set("mcu", 1)
    rp.set("mcu", 1)
    k.run_until(round(0.3 * FS))
    assert br.legs == ("H", "L") and m.current > 0.5 and m.output_speed > 0.5
    estop.press()
    assert br.legs == ("Z", "Z") and en_in.level == 1 and sense.level == 0
    k.run_until(k.now + MS)
    assert m.current == 0.0 and m.mode.startswith("dcm")            # fast decay, then blocked
    estop.release()
    assert br.legs == ("H", "L")


def test_the_hold_check_uses_the_dampers_least_time_constants_with_the_gearbox_efficiency():
    """Rolling resistance and the turning moment oppose the motion: the motors drive them, so they
    reach the motor divided by η, which shortens the smooth signs' time constants by η (the check
    had used them without it, 20 % less conservative than stated): η·v_ε/(crr·g) and
    η·χ·track²·ω_ε/(mu_turn·g·wheelbase)."""
    _, _, body = kin_rover([0.0] * 4)
    eta = P.efficiency
    assert body.hold_time_constants[0] == pytest.approx(eta * body.speed_eps / (body.crr * G), rel=1e-12)
    assert body.hold_time_constants[1] == pytest.approx(
        eta * body.chi * B ** 2 * body.yaw_rate_eps / (body.mu_turn * G * L_WB), rel=1e-12)
    assert body.hold_time_constants[0] == pytest.approx(0.0272, abs=2e-4)       # docs/plants.md: 27 ms
