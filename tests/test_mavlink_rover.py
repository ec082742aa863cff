"""rover_control's MAVLink link on USART3, driven by pymavlink as the ground station (its own
generated packing, parsing and CRC: mcusim.mavlink.MavlinkClient) in simulated time.

The EDU-CIAA alone (no motor modules) is the cheap rig for the link itself; the ElementAll rover is
used where the modules or the body must answer (arming, gains over I2C, driving)."""

import itertools
import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import mcusim
from mcusim.mavlink import MavlinkClient
from mcusim.plant.battery import ConstantLoad
from mcusim.testing import wait_until

MAV_TYPE_GROUND_ROVER, MAV_AUTOPILOT_GENERIC = 10, 0          # MAVLink common.xml enums
MAV_STATE_STANDBY, MAV_STATE_ACTIVE, MAV_STATE_CRITICAL, MAV_STATE_EMERGENCY = 3, 4, 5, 6
ARMED = 128
ACCEPTED, TEMPORARILY_REJECTED, DENIED, UNSUPPORTED, FAILED = 0, 1, 2, 3, 4   # MAV_RESULT
ARM_DISARM = 400
BODY_NED, VEL_YAWRATE_MASK = 8, 0x05C7                        # what mavros setpoint_velocity sends


def bench(**over):
    sim = mcusim.load("ciaa-edu", overrides=over)
    return sim, MavlinkClient(sim, "USART3")


def rover(**over):
    sim = mcusim.load("elementall", overrides=over)
    return sim, MavlinkClient(sim, "USART3", member="rcm")


def arm(gcs, value=1, component=0):
    gcs.mav.command_long_send(1, component, ARM_DISARM, 0, value, 0, 0, 0, 0, 0, 0)
    return gcs.recv_match("COMMAND_ACK", timeout="0.1s")


def test_heartbeat_is_a_generic_ground_rover_at_1hz_from_system_1_component_1():
    sim, gcs = bench()
    sim.run(seconds="2.6s")
    beats = [(t, m) for t, m in gcs.log if m.get_type() == "HEARTBEAT"]
    assert len(beats) == 3
    for _, m in beats:
        assert (m.type, m.autopilot, m.mavlink_version) == (MAV_TYPE_GROUND_ROVER, MAV_AUTOPILOT_GENERIC, 3)
        assert (m.get_srcSystem(), m.get_srcComponent()) == (1, 1)
        assert m.get_header().mlen and m.get_msgbuf()[0] == 0xFD          # MAVLink 2 on the wire
    ticks = [t for t, _ in beats]
    hz = sim.timebase.base_hz
    for a, b in itertools.pairwise(ticks):    # queued 1000 system ticks apart, behind < 50 ms of telemetry
        assert abs((b - a) / hz - 1.0) < 0.05
    # no modules on the bench: the controller says CRITICAL (modules missing) and reports why
    assert beats[-1][1].system_status == MAV_STATE_CRITICAL and not beats[-1][1].base_mode & ARMED
    text = gcs.messages("STATUSTEXT")[0]
    assert text.text.startswith("motors disabled: no answer from 0x08")


def test_arm_is_acknowledged_for_target_component_0_and_failed_without_motor_modules():
    sim, gcs = bench()
    sim.run(seconds="0.3s")
    ack = arm(gcs, 1, component=0)               # pymavlink's target_component after wait_heartbeat
    assert (ack.command, ack.result) == (ARM_DISARM, FAILED)     # valid, cannot be carried out
    assert (ack.target_system, ack.target_component) == (255, 190)
    assert arm(gcs, 0, component=1).result == ACCEPTED    # disarming is always accepted
    assert arm(gcs, 0.5).result == DENIED                  # param1 other than 0/1 is invalid
    gcs.mav.command_long_send(1, 1, 176, 0, 1, 0, 0, 0, 0, 0, 0)   # DO_SET_MODE: answered anyway
    assert gcs.recv_match("COMMAND_ACK", timeout="0.1s").result == UNSUPPORTED
    gcs.mav.command_long_send(2, 1, ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)   # another system's
    sim.run(seconds="0.1s")
    assert not [m for m in gcs.messages("COMMAND_ACK")[4:]]


def test_mission_request_list_is_answered_with_count_0_for_every_mission_type():
    sim, gcs = bench()
    sim.run(seconds="0.05s")
    for kind in (0, 1, 2):                      # mission, fence, rally
        gcs.mav.mission_request_list_send(1, 1, kind)
        m = gcs.recv_match("MISSION_COUNT", timeout="0.1s")
        assert (m.count, m.mission_type, m.target_system, m.target_component) == (0, kind, 255, 190)


def test_param_list_is_indexed_and_counted_and_param_set_of_a_threshold_changes_the_monitor():
    sim, gcs = bench()
    sim.run(seconds="0.3s")
    gcs.mav.param_request_list_send(1, 0)
    got = [gcs.recv_match("PARAM_VALUE", timeout="0.2s") for _ in range(6)]
    assert [m.param_index for m in got] == list(range(6)) and {m.param_count for m in got} == {6}
    values = {m.param_id: m.param_value for m in got}
    assert all(math.isnan(values[k]) for k in ("WHL_KP", "WHL_KI", "WHL_KD"))   # no module to ask
    assert values["BATT_LOW_V"] == pytest.approx(11.9) and values["BATT_CRIT_V"] == pytest.approx(11.5)
    # critical must stay below low: refused, and the echo says the value did not change
    gcs.mav.param_set_send(1, 0, b"BATT_CRIT_V", 12.5, 9)
    assert gcs.recv_match("PARAM_VALUE", timeout="0.1s").param_value == pytest.approx(11.5)
    gcs.mav.param_set_send(1, 0, b"BATT_LOW_V", 13.0, 9)       # above the 12.74 V a full bank reads
    echo = gcs.recv_match("PARAM_VALUE", timeout="0.1s")
    assert (echo.param_id, echo.param_index, echo.param_value) == ("BATT_LOW_V", 3, 13.0)
    sim.run(seconds="0.2s")
    assert sim.firmware.battery_state == "low"
    gcs.mav.param_request_read_send(1, 1, b"", 3)
    assert gcs.recv_match("PARAM_VALUE", timeout="0.1s").param_value == 13.0


def test_battery_low_and_critical_are_statustext_battery_status_and_heartbeat_state():
    sim, gcs = bench(**{"battery.soc": 0.3 / 1.1})          # 11.95 V at rest
    load = ConstantLoad(sim.kernel, 0.0)
    sim.part("battery").connect(load)
    sim.run(seconds="0.3s")
    load.set(10.0)                                            # 11.75 V under load: LOW
    low = gcs.recv_match("STATUSTEXT", condition=lambda m: "LOW" in m.text, timeout="1.5s")
    assert low.severity == 4 and low.text.startswith("battery LOW 11.")       # MAV_SEVERITY_WARNING
    assert gcs.recv_match("BATTERY_STATUS", timeout="1.1s").charge_state == 2   # MAV_BATTERY_CHARGE_STATE_LOW
    load.set(30.0)                                            # 11.35 V: CRITICAL
    crit = gcs.recv_match("STATUSTEXT", condition=lambda m: "CRITICAL" in m.text, timeout="1.5s")
    assert crit.severity == 2
    b = gcs.recv_match("BATTERY_STATUS", timeout="1.1s")
    assert b.charge_state == 3 and b.voltages[0] == round(sim.firmware.battery_v * 1000)
    s = gcs.recv_match("SYS_STATUS", timeout="1.1s")
    assert not s.onboard_control_sensors_health & 0x02000000 and s.onboard_control_sensors_present & 0x02000000
    assert gcs.recv_match("HEARTBEAT", timeout="1.1s").system_status == MAV_STATE_CRITICAL


def test_estop_is_a_statustext_and_an_emergency_heartbeat_and_refuses_arming():
    sim, gcs = bench()
    sim.run(seconds="0.2s")
    sim.part("estop").press()
    t = gcs.recv_match("STATUSTEXT", condition=lambda m: "E-STOP" in m.text, timeout="0.1s")
    assert (t.text, t.severity) == ("E-STOP pressed", 2)
    assert arm(gcs).result == TEMPORARILY_REJECTED
    assert gcs.recv_match("HEARTBEAT", timeout="1.1s").system_status == MAV_STATE_EMERGENCY
    sim.part("estop").release()
    t = gcs.recv_match("STATUSTEXT", condition=lambda m: "E-STOP" in m.text, timeout="0.1s")
    assert (t.text, t.severity) == ("E-STOP released", 5)


def test_set_message_interval_and_request_message():
    sim, gcs = bench()
    sim.run(seconds="0.05s")
    gcs.mav.command_long_send(1, 0, 511, 0, 0, 200_000, 0, 0, 0, 0, 0)   # HEARTBEAT every 200 ms
    assert gcs.recv_match("COMMAND_ACK", timeout="0.1s").result == ACCEPTED
    t0 = sim.now
    sim.run(seconds="1.05s")
    beats = [t / sim.timebase.base_hz for t, m in gcs.log if m.get_type() == "HEARTBEAT" and t > t0]
    assert len(beats) == 6                       # one at once, then every 200 ms
    # queued every 200 system ticks; each waits behind at most the telemetry already in the buffer
    assert all(abs(b - a - 0.2) < 0.05 for a, b in itertools.pairwise(beats))
    gcs.mav.command_long_send(1, 0, 511, 0, 32, -1, 0, 0, 0, 0, 0)      # LOCAL_POSITION_NED off
    gcs.recv_match("COMMAND_ACK", timeout="0.1s")
    t0 = sim.now
    sim.run(seconds="0.5s")
    assert not [t for t, m in gcs.log if m.get_type() == "LOCAL_POSITION_NED" and t > t0]
    gcs.mav.command_long_send(1, 0, 512, 0, 148, 0, 0, 0, 0, 0, 0)      # REQUEST_MESSAGE AUTOPILOT_VERSION
    assert gcs.recv_match("COMMAND_ACK", timeout="0.1s").result == ACCEPTED
    v = gcs.recv_match("AUTOPILOT_VERSION", timeout="0.1s")
    assert v.capabilities & 8192 and v.capabilities & 128
    gcs.mav.command_long_send(1, 0, 512, 0, 9999, 0, 0, 0, 0, 0, 0)
    assert gcs.recv_match("COMMAND_ACK", timeout="0.1s").result == DENIED


def test_a_module_driver_fault_is_an_error_statustext_and_a_critical_heartbeat():
    sim, gcs = rover()
    sim.run(seconds="0.3s")
    sim.part("mcm2.ibt2").overtemperature("both")       # BTS7960 thermal shutdown: IS shows the fault
    t = gcs.recv_match("STATUSTEXT", condition=lambda m: m.text.startswith("module"), timeout="0.25s")
    assert (t.text, t.severity) == ("module 0x09: driver fault", 3)      # MAV_SEVERITY_ERROR
    assert "module_0x09_fault" in sim.firmware.faults
    hb = gcs.recv_match("HEARTBEAT", timeout="1s")
    assert hb.system_status == MAV_STATE_CRITICAL


def test_param_set_of_a_wheel_gain_reaches_the_kp_register_of_every_module_and_is_echoed():
    sim, gcs = rover()
    sim.run(seconds="0.25s")
    gcs.mav.param_request_read_send(1, 0, b"WHL_KP", -1)
    before = gcs.recv_match("PARAM_VALUE", timeout="0.1s")
    modules = [sim.members[f"mcm{i}"]["firmware"] for i in range(1, 5)]
    assert before.param_value == pytest.approx(modules[0].pid.get_kp(), rel=1e-7)
    gcs.mav.param_set_send(1, 0, b"WHL_KP", 0.03125, 9)
    echo = gcs.recv_match("PARAM_VALUE", timeout="0.1s")
    assert (echo.param_id, echo.param_value, echo.param_index, echo.param_count) == ("WHL_KP", 0.03125, 0, 6)
    from mcusim.fw.openrover_mcm import protocol as P
    for m in modules:                          # the KP register each module serves over I2C
        img = m.register_image()
        assert P.decode("KP", img[P.BY_NAME["KP"].addr:]) == 0.03125
    for bad in (-1.0, 3.4e38, math.nan):            # outside the modules' 0..1e4: refused, echoed unchanged
        gcs.mav.param_set_send(1, 0, b"WHL_KI", bad, 9)
        assert gcs.recv_match("PARAM_VALUE", timeout="0.1s").param_value == pytest.approx(before_ki(modules))


def before_ki(modules):
    return modules[0].pid.get_ki()


@pytest.mark.heavy
def test_armed_body_velocity_setpoints_drive_the_rover_with_odometry_reported_then_the_watchdog_stops_it():
    sim, gcs = rover()
    fw = sim.firmware
    sim.run(seconds="0.25s")
    # disarmed: a setpoint is ignored
    gcs.mav.set_position_target_local_ned_send(0, 1, 0, BODY_NED, VEL_YAWRATE_MASK, 0, 0, 0, 0.3, 0, 0, 0, 0, 0, 0, 0)
    sim.run(seconds="0.05s")
    assert fw.cmd_tick is None
    assert arm(gcs).result == ACCEPTED
    gcs.mav.command_long_send(1, 0, 512, 0, 0, 0, 0, 0, 0, 0, 0)       # REQUEST_MESSAGE HEARTBEAT
    gcs.flush()
    hb = gcs.recv_match("HEARTBEAT", timeout="0.1s")
    assert hb.base_mode & ARMED and hb.system_status == MAV_STATE_ACTIVE
    for _ in range(8):                         # 20 Hz for 0.4 s: 0.3 m/s forward, 0.2 rad/s to the left
        gcs.mav.set_position_target_local_ned_send(0, 1, 0, BODY_NED, VEL_YAWRATE_MASK,
                                                   0, 0, 0, 0.3, 0, 0, 0, 0, 0, 0, -0.2)
        sim.run(seconds="0.05s")
    assert all(sp != 0 for sp in fw.wheel_setpoints)
    gcs.flush()
    pos = gcs.recv_match("LOCAL_POSITION_NED", timeout="0.15s")
    x, y, _yaw = fw.odometry.pose
    assert pos.x > 0.005 and pos.vx > 0.05
    assert pos.x == pytest.approx(x, abs=0.01) and pos.y == pytest.approx(-y, abs=0.01)   # NED: y right
    att = gcs.recv_match("ATTITUDE", timeout="0.15s")
    assert att.yaw < 0 and att.yawspeed < 0                 # turning left is a negative NED yaw
    vel = gcs.recv_match("NAMED_VALUE_FLOAT", condition=lambda m: m.name == "W1_VEL", timeout="0.25s")
    cmd = gcs.recv_match("NAMED_VALUE_FLOAT", condition=lambda m: m.name == "W1_CMD", timeout="0.05s")
    assert vel.value > 0 and cmd.value > 0
    # the GCS stopped sending after its last setpoint: the watchdog (500 ms) zeroes the command at
    # the first 20 ms control period past it
    t_cmd = fw.cmd_tick
    wait_until(sim, lambda: fw.watchdog_tripped, timeout="0.6s", poll="1ms")
    assert 500 < fw.rtos.tick_count - t_cmd <= 521         # (the poll instant is up to a tick late)
    w = gcs.recv_match("STATUSTEXT", condition=lambda m: m.text.startswith("watchdog"), timeout="0.1s")
    assert w.severity == 4 and fw.command_target() == (0.0, 0.0, 0.0)


def test_losing_the_gcs_heartbeat_disarms_and_stops_the_rover():
    sim = mcusim.load("elementall", overrides={"rcm.firmware.gcs_timeout_ms": 100})
    gcs = MavlinkClient(sim, "USART3", member="rcm", heartbeat_hz=20)
    fw = sim.firmware
    sim.run(seconds="0.25s")
    assert arm(gcs).result == ACCEPTED
    gcs.mav.manual_control_send(1, 600, 0, 0, 0, 0)          # joystick: 0.6 of manual_max_linear
    sim.run(seconds="0.02s")
    assert fw.cmd == (pytest.approx(0.3), 0.0, 0.0) and fw.link.armed
    gcs.stop_heartbeat()
    for _ in range(6):                            # the setpoints keep coming, the heartbeat does not
        gcs.mav.manual_control_send(1, 600, 0, 0, 0, 0)
        sim.run(seconds="0.03s")
    lost = gcs.recv_match("STATUSTEXT", condition=lambda m: "GCS" in m.text, timeout="0.1s")
    assert lost.text.startswith("GCS heartbeat lost") and not fw.link.armed
    assert fw.cmd == (0.0, 0.0, 0.0) and fw.command_target() == (0.0, 0.0, 0.0)


def _command(gcs, n):
    """A COMMAND_LONG (unsupported command 31000 + n): one ACK each."""
    return gcs.mav.command_long_encode(1, 1, 31000 + n, 0, n, 0, 0, 0, 0, 0, 0).pack(gcs.mav)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.sampled_from(["garbage", "truncated", "bitflip", "none"]),
                          st.binary(min_size=1, max_size=40), st.integers(0, 10_000)), min_size=1, max_size=6))
def test_garbage_truncated_frames_and_bit_flips_are_counted_and_lose_no_valid_frame(noise):
    sim, gcs = bench()
    sim.run(seconds="0.01s")
    stream, sent, corrupted = b"", 0, 0
    for i, (kind, junk, pos) in enumerate(noise):
        frame = _command(gcs, i)
        if kind == "garbage":
            stream += junk
        elif kind == "truncated":
            stream += frame[: 1 + pos % (len(frame) - 1)]
        elif kind == "bitflip":
            bit = pos % (8 * len(frame))
            stream += frame[: bit // 8] + bytes([frame[bit // 8] ^ (1 << bit % 8)]) + frame[bit // 8 + 1:]
        corrupted += kind != "none"
        stream += _command(gcs, 100 + i)                      # a valid frame after each
        sent += 1
    gcs.endpoint.feed(stream)
    sim.run(seconds=len(stream) * 10 / 57600 + 0.02)
    link = sim.firmware.link
    if not corrupted:
        assert link.rx_errors == 0 and link.rx_frames == sent
    # a broken header can claim up to 280 bytes: the frames behind it are found once they have come
    gcs.endpoint.feed(bytes(280))
    sim.run(seconds=280 * 10 / 57600 + 0.02)
    acks = [m.command for m in gcs.messages("COMMAND_ACK")]
    assert sorted(c for c in acks if c >= 31100) == [31100 + i for i in range(sent)]
    assert link.rx_errors > 0                      # the padding itself is garbage
    gcs.mav.command_long_send(1, 1, 30999, 0, 0, 0, 0, 0, 0, 0, 0)   # still answering
    assert gcs.recv_match("COMMAND_ACK", condition=lambda m: m.command == 30999, timeout="0.1s")
