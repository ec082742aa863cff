"""The whole ElementAll rover: the EDU-CIAA running rover_control, four Pro Mini modules on one
I2C bus, the skid-steer body, the SLA bank and the E-stop, on one event queue.

These runs are the expensive ones of the suite (about 0.06-0.1 simulated seconds per wall
second), so each checks several things and drives slowly where speed does not matter."""

import math

import pytest

import mcusim

R = 0.195
CPR_WHEEL = 2048 * 50
CTRL = 0.020                     # rover_control period


def rover(**over):
    return mcusim.load("elementall", overrides=over)


def enable_net(sim):
    return sim.part("estop").enable_out


def test_boot_identifies_the_four_modules_over_i2c_and_then_enables_the_motor_line():
    sim = rover(**{"cmd_vel.linear": 0.0})
    en = sim.members["rcm"]["mcu"].pin("GPIO3_3")
    rises = []
    en.listen(lambda n: rises.append(sim.time_s) if n.level else None)
    sim.run(seconds="0.3s")
    fw = sim.firmware
    assert fw.found == [0x08, 0x09, 0x0A, 0x0B] and fw.missing == [] and fw.faults == set()
    assert len(rises) == 1 and 0.1 < rises[0] < 0.2   # after the 100 ms boot delay and the probes
    assert enable_net(sim).level == 1                  # through the released E-stop to every INH
    for i in range(1, 5):
        assert sim.members[f"mcm{i}"]["firmware"].status & 0x01      # PID enabled over I2C
    # every module saw its WHO_AM_I read: the bus carried the five MCUs on one time base
    assert sim.timebase.base_hz == 816_000_000


def test_boot_with_one_module_missing_never_enables_the_motors_and_reports_which():
    sim = rover(**{"mcm3.present": False, "cmd_vel.linear": 0.3})
    en = sim.members["rcm"]["mcu"].pin("GPIO3_3")
    rises = []
    en.listen(lambda n: rises.append(sim.time_s) if n.level else None)
    sim.run(seconds="0.6s")
    s = sim.summary()
    assert s["firmware"]["modules_missing"] == ["0x0a"]
    assert s["firmware"]["modules_found"] == ["0x08", "0x09", "0x0b"]
    assert "modules_missing" in s["firmware"]["faults"] and s["firmware"]["motors_enabled"] is False
    assert not rises and enable_net(sim).level == 0
    for name, m in s["motors"].items():
        assert m["angle_rad"] == 0.0, name          # no wheel moved
    assert sim.members["mcm3"]["firmware"] is None  # the absent module has no firmware running


@pytest.mark.heavy
def test_estop_cuts_the_drive_in_hardware_and_the_setpoints_stay_zero_until_a_new_command():
    sim = rover(**{"cmd_vel.linear": 0.15})
    fw = sim.firmware
    sim.run(seconds="0.8s")
    assert all(sp > 0 for sp in fw.wheel_setpoints)
    estop = sim.part("estop")
    estop.press()
    assert enable_net(sim).level == 0                       # hardware cut at once
    bridges = [sim.part(f"mcm{i}.ibt2") for i in range(1, 5)]
    assert all(b.legs == ("Z", "Z") for b in bridges)        # INH low: both half bridges off
    sim.run(seconds=CTRL * 2)
    assert fw.estop_pressed and fw.estop_latched and fw.wheel_setpoints == [0, 0, 0, 0]
    modules = [sim.members[f"mcm{i}"]["firmware"] for i in range(1, 5)]
    # the modules' PIDs are off while latched: no integrator winds up against coasting wheels
    assert all(not m.status & 0x01 and m.duty == 0 for m in modules)
    sim.run(seconds="0.4s")                                   # the rover coasts to a stop
    estop.release()
    x_release = sim.summary()["pose"]["x"]
    sim.run(seconds="0.3s")                                   # the host keeps streaming the old command
    assert enable_net(sim).level == 1 and not fw.estop_pressed
    assert fw.estop_latched and fw.wheel_setpoints == [0, 0, 0, 0]
    assert abs(sim.summary()["pose"]["x"] - x_release) < 1e-4   # nothing moves after the release
    assert all(not m.status & 0x06 for m in modules)          # no stall, no driver fault
    sim.publish("cmd_vel.linear", 0.1)                        # a new command releases the latch
    sim.run(seconds="0.3s")
    assert not fw.estop_latched and all(sp > 0 for sp in fw.wheel_setpoints)
    assert all(m.status & 0x01 for m in modules) and fw.faults == set()
    assert sim.summary()["pose"]["x"] - x_release > 0.005     # and the rover drives again


@pytest.mark.heavy
def test_watchdog_zeroes_the_setpoints_when_commands_stop_arriving():
    sim = rover(**{"cmd_vel.linear": 0.1})
    fw = sim.firmware
    sim.run(seconds="0.5s")
    assert all(sp > 0 for sp in fw.wheel_setpoints) and not fw.watchdog_tripped
    sim.publish("cmd_vel.stream", False)                      # the host goes silent
    t_last = fw.cmd_tick / fw.p["tick_hz"]
    sim.run(seconds="0.45s")
    assert not fw.watchdog_tripped                             # within cmd_timeout_ms
    sim.run(seconds="0.2s")
    assert fw.watchdog_tripped
    # the body set point then ramps down at max_accel: 0.1 m/s in 0.2 s, then zero set points
    sim.run(seconds="0.25s")
    assert fw.wheel_setpoints == [0, 0, 0, 0] and fw.body_target == (0.0, 0.0, 0.0)
    assert 0.5 < sim.time_s - t_last


def _lag_bound(speed):
    """Odometry is sampled once per control period and reads the four POSITION registers one
    after the other over I2C (about 2.3 ms at 100 kHz): at the end of a run it lags the true pose
    by at most one period plus the read time, i.e. speed x 22.3 ms; encoder quantisation adds
    2*pi*r/102400 = 12 um per wheel."""
    return speed * (CTRL + 0.0023) + 2 * math.pi * R / CPR_WHEEL


@pytest.mark.heavy
def test_odometry_after_a_straight_run_and_after_a_turn_in_place_is_within_the_sampling_bound():
    # straight: 0.3 m/s for 2 s (ramped at 0.5 m/s^2)
    sim = rover(**{"cmd_vel.linear": 0.3})
    sim.run(seconds="2s")
    s = sim.summary()
    odo, pose = s["odometry"], s["pose"]
    assert pose["x"] > 0.35 and abs(pose["yaw"]) < 0.02
    assert abs(odo["x"] - pose["x"]) <= _lag_bound(0.3)
    assert abs(odo["y"] - pose["y"]) <= _lag_bound(0.3)
    assert abs(odo["yaw"] - pose["yaw"]) <= _lag_bound(0.3) * 2 / (1.5 * 0.55) + 1e-3
    assert s["firmware"]["faults"] == [] and s["battery_min_v"] < 12.7   # the bank sagged while accelerating


@pytest.mark.heavy
def test_odometry_of_a_turn_in_place_matches_the_icr_model_and_shows_the_uncalibrated_error():
    sim = rover(**{"cmd_vel.angular": 0.5})
    sim.run(seconds="1.6s")
    s = sim.summary()
    odo, pose = s["odometry"], s["pose"]
    assert pose["yaw"] > 0.4 and math.hypot(pose["x"], pose["y"]) < 0.01
    # the firmware's chi equals the body's: the yaw estimate lags only by the sampling bound
    assert abs(odo["yaw"] - pose["yaw"]) <= 0.5 * (CTRL + 0.0023) + 2 * (2 * math.pi / CPR_WHEEL) * R / 0.825
    # with the geometric track (chi = 1, an uncalibrated skid-steer) the same wheel counts give
    # chi = 1.5 times the true yaw (Mandow 2007): odometry with that layout, fed the final counts
    from mcusim.fw.openrover_rcm.kinematics import make_layout
    from mcusim.fw.openrover_rcm.odometry import Odometry
    naive = Odometry(make_layout("skid_steer", wheel_radius=R, track_width=0.55, chi=1.0), CPR_WHEEL)
    naive.update([u.count for u in sim.firmware.unwrap])
    assert naive.yaw == pytest.approx(1.5 * odo["yaw"], rel=1e-9)
    assert abs(naive.yaw - 1.5 * pose["yaw"]) <= 1.5 * (0.5 * (CTRL + 0.0023) + 1e-3)


def test_a_two_wheel_differential_rover_declared_the_same_way_drives_an_arc():
    sim = mcusim.load("rover-diff", overrides={"cmd_vel.linear": 0.2, "cmd_vel.angular": 0.4})
    sim.run(seconds="1s")
    s = sim.summary()
    assert s["firmware"]["layout"] == "differential" and s["firmware"]["modules_found"] == ["0x08", "0x09"]
    assert s["pose"]["yaw"] > 0.05 and s["pose"]["x"] > 0.05
    # chi = 1 on both sides: the odometry lags the true pose only by the sampling bound
    assert abs(s["odometry"]["yaw"] - s["pose"]["yaw"]) <= 0.4 * (CTRL + 0.0012) + 1e-3
    assert abs(s["odometry"]["x"] - s["pose"]["x"]) <= _lag_bound(0.2)


@pytest.mark.parametrize("engine", ["fast", "reference"])
def test_every_register_access_of_each_mcu_falls_on_its_own_clock_edge(tmp_path, engine):
    """docs/design.md: every clock edge falls on a whole tick, and a CPU acts on its own edges. The
    I2C bus, clocked by the 204 MHz controller, raised the modules' TWI requests between their
    16 MHz edges; the handler, and the loop it preempted, then ran off the module's grid for good
    (715 of 6,533 accesses of a 200 ms run). A request now waits for the core's next edge."""
    import json
    log = tmp_path / "r.jsonl"
    sim = mcusim.load("elementall", engine=engine)
    sim.trace_registers(log)
    sim.run(seconds="0.13s")           # past the controller's module probes (TWI requests from 0.1 s)
    sim.close()
    period = {name: m["mcu"].cpu.clock.period for name, m in sim.members.items()}
    hz = sim.kernel.timebase.base_hz
    seen = set()
    for line in log.read_text().splitlines():
        rec = json.loads(line)
        tick = round(rec["t_s"] * hz)
        assert tick % period[rec["mcu"]] == 0, line
        seen.add((rec["mcu"], rec["reg"].split(".")[0]))
    assert ("mcm1", "TWI") in seen and ("rcm", "I2C0") in seen


def test_a_boards_own_inputs_outputs_and_pins_are_reached_by_its_name_from_python():
    """pytest.md: in a system ``sim.publish("mcm2.velocity", 5)``, ``sim.topic(...)`` and
    ``sim.pin("mcm1.PB1")``, as --set and scenarios name them (they had said 'no input')."""
    sim = mcusim.load("elementall")
    try:
        sim.publish("mcm2.velocity", 5)
        sim.run(seconds="0.02s")
        assert sim.topic("mcm2.velocity") == sim.members["mcm2"]["firmware"].topic("velocity")
        assert sim.members["mcm2"]["firmware"].setpoint != 0       # the module took the set point
        assert sim.pin("mcm1.PB1") is sim.members["mcm1"]["mcu"].pin("PB1")
        with pytest.raises(mcusim.ConfigError, match="^mcm2: no input 'nope'"):
            sim.publish("mcm2.nope", 1)
    finally:
        sim.close()


def test_the_main_boards_own_name_works_as_a_prefix_as_in_scenarios():
    sim = mcusim.load("elementall")
    try:
        sim.publish("rcm.cmd_vel.linear", 0.25)     # the controller's own input, named with its board
        sim.run(seconds="0.01s")
        assert sim.firmware.cmd[0] == 0.25
        assert sim.topic("rcm.battery_state") == sim.topic("battery_state")
    finally:
        sim.discard()
