"""Rules of the MAVLink message definitions (pymavlink's generated ``common`` dialect: its enums and
field docs) and of the C library's parser that the rover's link must keep, each pinned by a test;
pymavlink is the ground station throughout."""

import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcusim.fw.openrover_rcm.mavlink_task import MavlinkLink
from pymavlink.dialects.v20 import common as ml

import mcusim
from mcusim.mavlink import MavlinkClient

ARM_DISARM = ml.MAV_CMD_COMPONENT_ARM_DISARM


def rover(heartbeat_hz=1, **over):
    sim = mcusim.load("elementall", overrides=over)
    return sim, MavlinkClient(sim, "USART3", member="rcm", heartbeat_hz=heartbeat_hz)


def armed_rover(heartbeat_hz=1, **over):
    sim, gcs = rover(heartbeat_hz, **over)
    sim.run(seconds="0.25s")
    gcs.mav.command_long_send(1, 0, ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
    assert gcs.recv_match("COMMAND_ACK", timeout="0.1s").result == ml.MAV_RESULT_ACCEPTED
    return sim, gcs


# --- every field of every handled message may carry any value the wire can carry ----------------------
HANDLED = sorted(getattr(ml, "MAVLINK_MSG_ID_" + n[3:].upper()) for n in dir(MavlinkLink) if n.startswith("on_"))
SPECIAL_FLOATS = [math.nan, math.inf, -math.inf, 3.4028235e38, -3.4028235e38, 1e-45, -0.0, 0.5, 1.0, 511.0, 30.0]
INT_RANGES = {"int8_t": (-128, 127), "uint8_t": (0, 255), "int16_t": (-32768, 32767), "uint16_t": (0, 65535),
              "int32_t": (-(1 << 31), (1 << 31) - 1), "uint32_t": (0, (1 << 32) - 1),
              "int64_t": (-(1 << 63), (1 << 63) - 1), "uint64_t": (0, (1 << 64) - 1)}


def _scalar(kind):
    if kind in ("float", "double"):
        return st.sampled_from(SPECIAL_FLOATS) | st.floats(width=32)
    lo, hi = INT_RANGES[kind]
    return st.sampled_from([lo, hi, 0, 1]) | st.integers(lo, hi)


@st.composite
def handled_message(draw):
    cls = ml.mavlink_map[draw(st.sampled_from(HANDLED))]
    lengths = dict(zip(cls.ordered_fieldnames, cls.array_lengths))
    args = []
    for name, kind in zip(cls.fieldnames, cls.fieldtypes):
        n = lengths[name]
        if kind == "char":
            args.append(draw(st.binary(max_size=n)))
        elif name == "command":        # the commands the task handles, and any other
            args.append(draw(st.sampled_from([400, 511, 512, 520]) | st.integers(0, 65535)))
        elif n:
            args.append(draw(st.lists(_scalar(kind), min_size=n, max_size=n)))
        else:
            args.append(draw(_scalar(kind)))
    return cls(*args)


@pytest.mark.heavy
@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(handled_message(), min_size=1, max_size=12))
def test_any_field_value_of_a_handled_message_leaves_the_controller_answering(msgs):
    """NaN, +-inf and extreme values are valid on the wire in float fields (MAV_CMD_SET_MESSAGE_INTERVAL
    param1 included): a command answers, it never stops the controller."""
    sim, gcs = armed_rover()
    for m in msgs:
        gcs.mav.send(m)
        sim.run(seconds="0.01s")
    gcs.mav.command_long_send(1, 1, 31999, 0, 0, 0, 0, 0, 0, 0, 0)
    ack = gcs.recv_match("COMMAND_ACK", condition=lambda a: a.command == 31999, timeout="0.2s")
    assert ack.result == ml.MAV_RESULT_UNSUPPORTED


@pytest.mark.parametrize("param1", [math.nan, math.inf, -math.inf, 30.5, 1e30])
@pytest.mark.parametrize("command", [ml.MAV_CMD_SET_MESSAGE_INTERVAL, ml.MAV_CMD_REQUEST_MESSAGE])
def test_a_message_id_param_that_is_not_a_whole_number_is_denied(command, param1):
    """param1 of SET_MESSAGE_INTERVAL / REQUEST_MESSAGE is a message id: anything else is an invalid
    parameter, MAV_RESULT_DENIED."""
    sim, gcs = rover()
    sim.run(seconds="0.05s")
    gcs.mav.command_long_send(1, 1, command, 0, param1, 100000, 0, 0, 0, 0, 0)
    assert gcs.recv_match("COMMAND_ACK", timeout="0.1s").result == ml.MAV_RESULT_DENIED


# --- one far end per UART ------------------------------------------------------------------------------
def test_a_second_connection_to_the_mavlink_uart_is_refused_naming_what_holds_it():
    from mcusim.errors import ConfigError
    sim, gcs = rover()
    with pytest.raises(ConfigError, match=r"USART3 of rcm is already connected to a MAVLink ground station"):
        MavlinkClient(sim, "USART3", member="rcm")
    sim.run(seconds="1.1s")                     # the first ground station still hears the rover
    assert gcs.messages("HEARTBEAT")


def test_cli_refuses_mavlink_with_a_scenario_that_talks_mavlink(capsys):
    from mcusim.cli import main
    assert main(["run", "elementall", "--mavlink", "udpout:127.0.0.1:14793", "--scenario", "mavlink_drive"]) == 2
    err = capsys.readouterr().err
    assert "sends or expects MAVLink" in err and "Traceback" not in err


# --- the parser ------------------------------------------------------------------------------------------
def test_a_valid_frame_of_an_id_outside_the_dialect_is_dropped_whole_and_holds_up_nothing():
    """mavlink_parse_char drops a frame whose id it does not know as a whole (its CRC_EXTRA is
    unknown): an ardupilotmega MEMINFO whose payload holds 0xFD and a large byte must not make the
    parser wait for a phantom frame, nor count as a link error."""
    from pymavlink.dialects.v20 import ardupilotmega as apm
    sim, gcs = rover()
    sim.run(seconds="0.05s")
    meminfo = apm.MAVLink_meminfo_message(0xFFFD, 0).pack(apm.MAVLink(None, 255, 190))
    assert meminfo[10:12] == b"\xfd\xff"       # the payload: a start byte and a length of 255
    assert ml.mavlink_map.get(apm.MAVLINK_MSG_ID_MEMINFO) is None
    link = sim.firmware.link
    gcs.endpoint.feed(meminfo)
    gcs.mav.command_long_send(1, 1, 31999, 0, 0, 0, 0, 0, 0, 0, 0)
    line_time = (len(meminfo) + 41) * 10 / 57600
    ack = gcs.recv_match("COMMAND_ACK", condition=lambda a: a.command == 31999, timeout=line_time + 0.02)
    assert ack and link.rx_errors == 0 and link.ignored == 1


def test_param_set_of_a_gain_one_module_did_not_take_is_not_echoed_as_taken():
    """The PARAM_VALUE echo of PARAM_SET is the acknowledgement (PARAM_SET's definition): with mcm3 off
    the bus the new gain is not held by every module, so the echo is NaN, not the value asked for,
    and a STATUSTEXT names the module."""
    sim, gcs = rover()
    sim.run(seconds="0.25s")
    assert sim.members["mcm3"]["firmware"].p["i2c_address"] == 0x0A
    mcm3 = next(p for p in sim.members["mcm3"]["mcu"].periph.values() if hasattr(p, "i2c_address"))
    mcm3.bus.detach(mcm3)
    gcs.mav.param_set_send(1, 0, b"WHL_KP", 0.03125, ml.MAV_PARAM_TYPE_REAL32)
    echo = gcs.recv_match("PARAM_VALUE", timeout="0.1s")
    assert echo.param_id == "WHL_KP" and math.isnan(echo.param_value)
    text = gcs.messages("STATUSTEXT")[-1]
    assert text.severity == ml.MAV_SEVERITY_WARNING and text.text == "WHL_KP not written to 0x0a"
    mcm3.bus.attach(mcm3)                            # back: the others hold 0.03125, mcm3 its old gain
    gcs.mav.param_request_read_send(1, 0, b"WHL_KP", -1)
    assert math.isnan(gcs.recv_match("PARAM_VALUE", timeout="0.1s").param_value)
    gcs.mav.param_set_send(1, 0, b"WHL_KP", 0.03125, ml.MAV_PARAM_TYPE_REAL32)
    assert gcs.recv_match("PARAM_VALUE", timeout="0.1s").param_value == 0.03125


# --- failsafes ------------------------------------------------------------------------------------------
def test_arming_while_the_ground_station_heartbeat_is_lost_is_temporarily_rejected_until_it_returns():
    """An ACCEPTED arm must hold; while the GCS heartbeat is lost the failsafe would undo it, so the
    answer is MAV_RESULT_TEMPORARILY_REJECTED, and a heartbeat that comes back allows arming."""
    sim = mcusim.load("elementall", overrides={"rcm.firmware.gcs_timeout_ms": 100})
    gcs = MavlinkClient(sim, "USART3", member="rcm", heartbeat_hz=20)
    sim.run(seconds="0.25s")
    gcs.stop_heartbeat()
    sim.run(seconds="0.2s")
    gcs.mav.command_long_send(1, 0, ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
    assert gcs.recv_match("COMMAND_ACK", timeout="0.1s").result == ml.MAV_RESULT_TEMPORARILY_REJECTED
    gcs.mav.heartbeat_send(ml.MAV_TYPE_GCS, ml.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    gcs.mav.command_long_send(1, 0, ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
    assert gcs.recv_match("COMMAND_ACK", timeout="0.1s").result == ml.MAV_RESULT_ACCEPTED
    sim.run(seconds="0.05s")
    assert sim.firmware.link.armed


def test_only_a_gcs_or_onboard_controller_heartbeat_keeps_the_link_alive():
    """MAV_TYPE_GCS (QGroundControl) and MAV_TYPE_ONBOARD_CONTROLLER (mavros) are what the rover
    watches; another vehicle's heartbeat on a shared UDP network does not keep it from stopping."""
    sim, gcs = armed_rover(20, **{"rcm.firmware.gcs_timeout_ms": 100})
    gcs.stop_heartbeat()
    for _ in range(10):                                  # a rover, system 2, at 20 Hz
        gcs.mav.srcSystem, gcs.mav.srcComponent = 2, 1
        gcs.mav.heartbeat_send(ml.MAV_TYPE_GROUND_ROVER, ml.MAV_AUTOPILOT_GENERIC, 0, 0, 0)
        gcs.mav.srcSystem, gcs.mav.srcComponent = 255, 190
        sim.run(seconds="0.05s")
    assert not sim.firmware.link.armed and sim.firmware.link.gcs_lost
    sim2, gcs2 = armed_rover(20, **{"rcm.firmware.gcs_timeout_ms": 100})
    gcs2.stop_heartbeat()
    for _ in range(10):                                  # mavros: 1.191, ONBOARD_CONTROLLER
        gcs2.mav.srcSystem, gcs2.mav.srcComponent = 1, 191
        gcs2.mav.heartbeat_send(ml.MAV_TYPE_ONBOARD_CONTROLLER, ml.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        sim2.run(seconds="0.05s")
    assert sim2.firmware.link.armed and not sim2.firmware.link.gcs_lost


def test_disarming_stops_the_rover_without_a_watchdog_warning():
    """A disarm is not a command that stopped coming: no 'watchdog' STATUSTEXT follows it."""
    sim, gcs = armed_rover()
    gcs.mav.set_position_target_local_ned_send(0, 1, 0, ml.MAV_FRAME_BODY_NED, 0x05C7,
                                               0, 0, 0, 0.3, 0, 0, 0, 0, 0, 0, 0)
    sim.run(seconds="0.05s")
    gcs.mav.command_long_send(1, 0, ARM_DISARM, 0, 0, 0, 0, 0, 0, 0, 0)
    assert gcs.recv_match("COMMAND_ACK", timeout="0.1s").result == ml.MAV_RESULT_ACCEPTED
    sim.run(seconds="0.7s")
    fw = sim.firmware
    assert fw.command_target() == (0.0, 0.0, 0.0) and not fw.watchdog_tripped
    assert not [m for m in gcs.messages("STATUSTEXT") if m.text.startswith("watchdog")]


# --- MAV_RESULT ----------------------------------------------------------------------------------------
def _result_meaning(code):
    return ml.enums["MAV_RESULT"][code].description


def test_arming_that_cannot_be_carried_out_is_failed_and_bad_param1_is_denied():
    """MAV_RESULT_FAILED: 'valid, but execution has failed ... attempting to arm when sensors are not
    calibrated'; MAV_RESULT_DENIED: 'one or more parameter values are invalid'."""
    assert "arm" in _result_meaning(ml.MAV_RESULT_FAILED) and "invalid" in _result_meaning(ml.MAV_RESULT_DENIED)
    sim = mcusim.load("ciaa-edu")                       # no motor modules: the motors are not enabled
    gcs = MavlinkClient(sim, "USART3")
    sim.run(seconds="0.3s")
    gcs.mav.command_long_send(1, 0, ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
    assert gcs.recv_match("COMMAND_ACK", timeout="0.1s").result == ml.MAV_RESULT_FAILED
    gcs.mav.command_long_send(1, 0, ARM_DISARM, 0, 2, 0, 0, 0, 0, 0, 0)
    assert gcs.recv_match("COMMAND_ACK", timeout="0.1s").result == ml.MAV_RESULT_DENIED


def test_arming_while_the_controller_boots_is_temporarily_rejected_as_waiting_clears_it():
    """MAV_RESULT_TEMPORARILY_REJECTED: 'the command is valid, but cannot be executed at this time
    ... retry later'. During the first ~0.11 s the controller identifies its modules (HEARTBEAT
    BOOT); an arm then had been FAILED, which a ground station takes as final, though the same
    command 0.2 s later is accepted."""
    assert "retry" in _result_meaning(ml.MAV_RESULT_TEMPORARILY_REJECTED).lower()
    sim, gcs = rover()
    sim.run(seconds="0.02s")
    assert gcs.recv_match("HEARTBEAT", timeout="0.01s").system_status == ml.MAV_STATE_BOOT
    gcs.mav.command_long_send(1, 0, ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
    assert gcs.recv_match("COMMAND_ACK", timeout="0.1s").result == ml.MAV_RESULT_TEMPORARILY_REJECTED
    sim.run(seconds="0.2s")
    gcs.mav.command_long_send(1, 0, ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
    assert gcs.recv_match("COMMAND_ACK", timeout="0.1s").result == ml.MAV_RESULT_ACCEPTED


@pytest.mark.parametrize("command", [ARM_DISARM, ml.MAV_CMD_SET_MESSAGE_INTERVAL, ml.MAV_CMD_REQUEST_MESSAGE,
                                     ml.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES])
def test_a_command_long_only_command_sent_as_command_int_says_so(command):
    """MAV_RESULT_COMMAND_LONG_ONLY: 'Command is only accepted when sent as a COMMAND_LONG'."""
    assert "COMMAND_LONG" in _result_meaning(ml.MAV_RESULT_COMMAND_LONG_ONLY)
    sim = mcusim.load("ciaa-edu")
    gcs = MavlinkClient(sim, "USART3")
    sim.run(seconds="0.05s")
    gcs.mav.command_int_send(1, 1, 0, command, 0, 0, 1, 0, 0, 0, 0, 0, 0)
    assert gcs.recv_match("COMMAND_ACK", timeout="0.1s").result == ml.MAV_RESULT_COMMAND_LONG_ONLY
    gcs.mav.command_int_send(1, 1, 0, ml.MAV_CMD_DO_SET_MODE, 0, 0, 1, 0, 0, 0, 0, 0, 0)
    assert gcs.recv_match("COMMAND_ACK", timeout="0.1s").result == ml.MAV_RESULT_UNSUPPORTED


# --- set points ----------------------------------------------------------------------------------------
IGNORE_ALL_BUT_VELOCITY_AND_YAW_RATE = (ml.POSITION_TARGET_TYPEMASK_X_IGNORE | ml.POSITION_TARGET_TYPEMASK_Y_IGNORE
                                        | ml.POSITION_TARGET_TYPEMASK_Z_IGNORE | ml.POSITION_TARGET_TYPEMASK_VZ_IGNORE
                                        | ml.POSITION_TARGET_TYPEMASK_AX_IGNORE | ml.POSITION_TARGET_TYPEMASK_AY_IGNORE
                                        | ml.POSITION_TARGET_TYPEMASK_AZ_IGNORE | ml.POSITION_TARGET_TYPEMASK_YAW_IGNORE)


@pytest.mark.parametrize("ignore, frame, expected", [
    (ml.POSITION_TARGET_TYPEMASK_VX_IGNORE | ml.POSITION_TARGET_TYPEMASK_VY_IGNORE, ml.MAV_FRAME_BODY_NED,
     (0.0, 0.0, 0.5)),                                               # 0x05FF: a yaw rate alone
    (ml.POSITION_TARGET_TYPEMASK_VY_IGNORE, ml.MAV_FRAME_BODY_NED, (0.2, 0.0, 0.5)),            # 0x05D7
    (ml.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE, ml.MAV_FRAME_LOCAL_OFFSET_NED, (0.2, 0.0, 0.0)),
])
def test_a_set_point_with_any_velocity_or_yaw_rate_in_use_is_obeyed_with_ignored_axes_zero(ignore, frame, expected):
    """type_mask bits mark fields to ignore (POSITION_TARGET_TYPEMASK): a set point that uses only
    some of vx, vy, yaw_rate is still a set point; MAV_FRAME_LOCAL_OFFSET_NED velocities are
    LOCAL_NED velocities (at heading 0, forward = north)."""
    mask = IGNORE_ALL_BUT_VELOCITY_AND_YAW_RATE | ignore
    sim, gcs = armed_rover()
    gcs.mav.set_position_target_local_ned_send(0, 1, 0, frame, mask, 0, 0, 0, 0.2, 9.0, 0, 0, 0, 0, 0, -0.5)
    sim.run(seconds="0.02s")
    fw = sim.firmware
    assert fw.cmd == pytest.approx(expected, abs=1e-3) and fw.cmd_tick is not None
    assert fw.link.ignored == 0


# --- the line's capacity -------------------------------------------------------------------------------
def test_a_message_interval_the_57600_baud_line_cannot_carry_is_denied():
    """57600 baud 8N1 carries 5760 bytes/s; ATTITUDE (28-byte payload, 40 bytes framed) at 1 kHz
    would need 40 kB/s: MAV_RESULT_DENIED ('value allowed by spec but not supported'), the
    interval unchanged; 20 Hz fits."""
    sim, gcs = rover()
    sim.run(seconds="0.05s")
    gcs.mav.command_long_send(1, 1, ml.MAV_CMD_SET_MESSAGE_INTERVAL, 0, ml.MAVLINK_MSG_ID_ATTITUDE, 1000, 0, 0, 0, 0, 0)
    assert gcs.recv_match("COMMAND_ACK", timeout="0.1s").result == ml.MAV_RESULT_DENIED
    assert sim.firmware.link.intervals[ml.MAVLINK_MSG_ID_ATTITUDE] == 100
    gcs.mav.command_long_send(1, 1, ml.MAV_CMD_SET_MESSAGE_INTERVAL, 0, ml.MAVLINK_MSG_ID_ATTITUDE, 50000, 0, 0, 0, 0, 0)
    assert gcs.recv_match("COMMAND_ACK", timeout="0.1s").result == ml.MAV_RESULT_ACCEPTED


def test_replies_and_heartbeats_are_never_skipped_for_telemetry_when_the_line_is_full():
    """Each PARAM_REQUEST_READ is answered by one PARAM_VALUE (the parameter protocol), however many
    come at once; replies outgrow requests (37 vs 32 bytes) so the transmit buffer fills: the
    streams give way, the heartbeat still goes out every second."""
    sim, gcs = rover()
    sim.run(seconds="0.05s")
    burst = b"".join(gcs.mav.param_request_read_encode(1, 1, b"", 3).pack(gcs.mav) for _ in range(150))
    gcs.endpoint.feed(burst)
    sim.run(seconds=len(burst) * 10 / 57600 + 0.6)
    assert len(gcs.messages("PARAM_VALUE")) == 150
    beats = [t for t, m in gcs.log if m.get_type() == "HEARTBEAT"]
    drain = 1024 * 10 / 57600                # at most a full 1 kB transmit buffer ahead of it
    assert len(beats) == 2 and (beats[1] - beats[0]) / sim.timebase.base_hz == pytest.approx(1.0, abs=drain)
    assert sim.firmware.link.tx_skipped > 0          # the telemetry was what gave way


# --- what the rover reports ----------------------------------------------------------------------------
def _heartbeat_now(sim, gcs):
    gcs.mav.command_long_send(1, 1, ml.MAV_CMD_REQUEST_MESSAGE, 0, ml.MAVLINK_MSG_ID_HEARTBEAT, 0, 0, 0, 0, 0, 0)
    gcs.flush()
    return gcs.recv_match("HEARTBEAT", timeout="0.1s")


def test_heartbeat_base_mode_names_the_command_source_in_use():
    """MAV_MODE_FLAG_GUIDED_ENABLED: driven by set points; MAV_MODE_FLAG_MANUAL_INPUT_ENABLED: by a
    joystick (MANUAL_CONTROL); neither while disarmed."""
    guided, manual = ml.MAV_MODE_FLAG_GUIDED_ENABLED, ml.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
    sim, gcs = armed_rover()
    gcs.mav.manual_control_send(1, 300, 0, 0, 0, 0)
    assert _heartbeat_now(sim, gcs).base_mode & (guided | manual) == manual
    gcs.mav.set_position_target_local_ned_send(0, 1, 0, ml.MAV_FRAME_BODY_NED, 0x05C7, 0, 0, 0, 0.2, 0, 0, 0, 0, 0, 0, 0)
    hb = _heartbeat_now(sim, gcs)
    assert hb.base_mode & (guided | manual) == guided and hb.base_mode & ml.MAV_MODE_FLAG_SAFETY_ARMED
    gcs.mav.command_long_send(1, 0, ARM_DISARM, 0, 0, 0, 0, 0, 0, 0, 0)
    assert _heartbeat_now(sim, gcs).base_mode & (guided | manual | ml.MAV_MODE_FLAG_SAFETY_ARMED) == 0


def test_the_first_sys_status_load_does_not_count_the_boot():
    """SYS_STATUS.load is the main loop's usage over the reporting interval: the first figure starts
    when the task does, so it is no higher than the steady figures after it."""
    sim = mcusim.load("ciaa-edu")
    gcs = MavlinkClient(sim, "USART3")
    sim.run(seconds="2.1s")
    loads = [m.load for m in gcs.messages("SYS_STATUS")]
    assert len(loads) == 3 and loads[0] <= max(loads[1:]) < 1000


def test_battery_status_bank_voltage_is_the_batterys_terminal_voltage_within_one_adc_step():
    """BATTERY_STATUS.voltages[0] (mV) is the bank when cells are not measured; the monitor reads it
    through the divider with the 10-bit ADC at VREFP = 3.3 V: one code is 3.3 / 1024 / ratio volts."""
    sim = mcusim.load("ciaa-edu")
    gcs = MavlinkClient(sim, "USART3")
    sim.run(seconds="1.05s")
    gcs.flush()
    status = gcs.recv_match("BATTERY_STATUS", timeout="1.0s")
    step = 3.3 / 1024 / sim.part("vbat_divider").ratio
    assert abs(status.voltages[0] / 1000 - sim.part("battery").voltage()) <= step + 0.0005
    assert status.voltages[1:] == [65535] * 9


def test_battery_status_before_the_first_reading_has_no_charge_state():
    """MAV_BATTERY_CHARGE_STATE_UNDEFINED (0): 'Low battery state is not provided'. The message the
    controller sends before its battery monitor's first reading has the voltage unknown
    (UINT16_MAX) and had claimed OK (1) all the same."""
    assert "not provided" in ml.enums["MAV_BATTERY_CHARGE_STATE"][0].description
    sim = mcusim.load("ciaa-edu")
    gcs = MavlinkClient(sim, "USART3")
    sim.run(seconds="0.01s")
    first = gcs.recv_match("BATTERY_STATUS", timeout="0.1s")
    assert (first.voltages[0], first.charge_state) == (65535, 0)
    sim.run(seconds="1.1s")
    later = gcs.messages("BATTERY_STATUS")[-1]
    assert later.voltages[0] != 65535 and later.charge_state == 1


def test_arming_with_a_module_fault_is_failed_as_the_heartbeat_says_critical():
    """A module's driver over temperature: HEARTBEAT CRITICAL, the motor health bit cleared, and
    an arm had been ACCEPTED all the same."""
    sim, gcs = rover()
    sim.run(seconds="0.25s")
    sim.part("mcm2.ibt2").overtemperature()
    sim.run(seconds="0.3s")
    assert sim.firmware.faults, sim.firmware.faults
    gcs.flush()
    assert gcs.recv_match("HEARTBEAT", timeout="1.1s").system_status == ml.MAV_STATE_CRITICAL
    gcs.mav.command_long_send(1, 0, ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
    assert gcs.recv_match("COMMAND_ACK", timeout="0.1s").result == ml.MAV_RESULT_FAILED


def test_manual_control_r_positive_turns_clockwise_and_x_positive_drives_forward():
    """MANUAL_CONTROL: x forward-back, r yaw with clockwise positive; the controller's yaw rate is
    counter-clockwise positive, so r = +500 of 1000 is half the manual yaw rate, negated."""
    sim, gcs = armed_rover()
    p = sim.firmware.p
    gcs.mav.manual_control_send(1, 400, 0, 0, 500, 0)
    sim.run(seconds="0.02s")
    assert sim.firmware.cmd == pytest.approx((0.4 * p["manual_max_linear"], 0.0, -0.5 * p["manual_max_yaw"]))


def test_a_body_frd_velocity_to_the_right_is_a_negative_lateral_command_on_a_mecanum_rover():
    """MAV_FRAME_BODY_FRD: x forward, y right, z down, so yaw_rate > 0 turns clockwise; the
    controller's body frame is x forward, y left, yaw counter-clockwise (REP 103)."""
    sim, gcs = armed_rover(**{"rcm.firmware.layout": "mecanum"})
    gcs.mav.set_position_target_local_ned_send(0, 1, 0, ml.MAV_FRAME_BODY_FRD, 0x05C7,
                                               0, 0, 0, 0.1, 0.2, 0, 0, 0, 0, 0, 0.3)
    sim.run(seconds="0.02s")
    assert sim.firmware.cmd == pytest.approx((0.1, -0.2, -0.3))


def test_a_local_ned_velocity_is_rotated_into_the_body_by_the_heading():
    """MAV_FRAME_LOCAL_NED: x north (the start's forward), y east (its right); the heading in NED is
    clockwise, the odometry's yaw counter-clockwise. A velocity along the heading is all forward,
    one 90 degrees clockwise of it (NED) is all to the right: a negative lateral command."""
    sim, gcs = armed_rover(**{"rcm.firmware.layout": "mecanum"})
    fw = sim.firmware
    for k in range(8):
        yaw = -math.pi + (k + 0.5) * math.pi / 4      # odometry heading, counter-clockwise
        fw.odometry.yaw = yaw                         # (the rover stands still: nothing updates it)
        psi = -yaw                                    # NED heading
        right = psi + math.pi / 2
        vn, ve = 0.2 * math.cos(psi) + 0.1 * math.cos(right), 0.2 * math.sin(psi) + 0.1 * math.sin(right)
        gcs.mav.set_position_target_local_ned_send(0, 1, 0, ml.MAV_FRAME_LOCAL_NED, 0x05C7,
                                                   0, 0, 0, vn, ve, 0, 0, 0, 0, 0, 0)
        sim.run(seconds="0.015s")                    # 65 bytes at 57600 baud: 11.3 ms
        assert fw.cmd == pytest.approx((0.2, -0.1, 0.0), abs=1e-5), yaw   # float32 on the wire
