"""rover_control on the EDU-CIAA alone (bench set-up: battery, divider, E-stop, no modules):
boot without modules, the battery monitor's thresholds, hysteresis and buzzer patterns under sag."""

import itertools

import pytest

import mcusim
from mcusim.errors import ConfigError
from mcusim.plant.battery import ConstantLoad

R_SERIES = 0.020 / 2 + 0.010      # two SLA in parallel (R0 = 20 mΩ each) + 10 mΩ wiring


def bench(soc=1.0, **over):
    sim = mcusim.load("ciaa-edu", overrides={"battery.soc": soc, **over})
    load = ConstantLoad(sim.kernel, 0.0)
    sim.part("battery").connect(load)
    buzzer = []
    sim.pin("GPIO3_4").listen(lambda n: buzzer.append((sim.time_s, n.level)))
    return sim, load, buzzer


def test_board_alone_finds_no_module_and_keeps_the_motor_line_low():
    sim, _, _ = bench()
    en = sim.pin("GPIO3_3")
    rises = []
    en.listen(lambda n: rises.append(sim.time_s) if n.level else None)
    sim.run(seconds="0.5s")
    s = sim.summary()
    assert s["firmware"]["modules_missing"] == ["0x08", "0x09", "0x0a", "0x0b"]
    assert "modules_missing" in s["firmware"]["faults"]
    assert not rises and en.level == 0 and sim.firmware.motors_enabled is False
    # every WHO_AM_I probe was NACKed on the bus (SLA+W not acknowledged, 0x20): 3 per module
    codes = [code for _, code in sim.mcu.periph["I2C0"].status_log]
    assert codes.count(0x20) == 3 * 4 and 0x18 not in codes


def test_battery_reading_is_the_divider_code_scaled_back():
    """12.75 V (full, rested) -> 2.1755 V at CH1 -> code floor(2.1755*1024/3.3) = 675 -> 12.737 V."""
    sim, _, _ = bench(soc=1.0)
    sim.run(seconds="1s")
    code = int(12.75 * 6800 / 39800 * 1024 / 3.3)
    assert code == 675
    assert sim.firmware.battery_v == pytest.approx(code * 3.3 / 1024 * 39800 / 6800, abs=1e-12)
    assert sim.firmware.battery_state == "normal"


def test_battery_alarms_at_the_thresholds_under_sag_with_hysteresis_and_distinct_buzzer_patterns():
    # OCV = 11.65 + 1.10*soc = 11.95 V: above low_v = 11.9 at rest, below low_v + hysteresis = 12.1
    soc = 0.3 / 1.1
    sim, load, buzzer = bench(soc=soc)
    fw = sim.firmware
    sim.run(seconds="1s")
    assert fw.battery_state == "normal"
    # 10 A: sag 0.2 V -> 11.75 V, between critical (11.5) and low (11.9)
    load.set(10.0)
    t_low = sim.time_s
    assert 11.5 < 11.95 - R_SERIES * 10.0 < 11.9
    sim.run(seconds="1.2s")
    assert fw.battery_state == "low"
    (t_alarm, state), = fw.battery_log
    t_alarm /= sim.timebase.base_hz
    # the moving average of 8 samples at 100 ms crosses the threshold within the window
    assert state == "low" and t_low < t_alarm <= t_low + 0.9
    # LOW: one 100 ms beep every 5 s (before it, the missing modules' three-beep pattern played)
    sim.run(seconds="5.5s")
    on = [t for t, lv in buzzer if lv and t >= t_alarm]
    off = [t for t, lv in buzzer if not lv and t > t_alarm]
    assert len(on) >= 2 and off[0] - on[0] == pytest.approx(0.100, abs=1e-6)
    assert on[1] - on[0] == pytest.approx(5.0, abs=1e-6)
    # load off: 11.95 V is above low_v but below low_v + hysteresis (12.1 V): still LOW
    load.set(0.0)
    sim.run(seconds="1s")
    assert fw.battery_state == "low" and len(fw.battery_log) == 1
    # 30 A: sag 0.6 V -> 11.35 V < critical: CRITICAL, 200 ms on / 200 ms off
    load.set(30.0)
    assert 11.95 - R_SERIES * 30.0 < 11.5
    sim.run(seconds="1.5s")
    assert fw.battery_state == "critical"
    buzzer.clear()
    sim.run(seconds="1s")
    on = [t for t, lv in buzzer if lv]
    assert [round(b - a, 6) for a, b in itertools.pairwise(on)] == [0.4] * (len(on) - 1) and len(on) >= 2
    # load off: the voltage recovers to 11.95 V, but CRITICAL is latched (the charge did not come back)
    load.set(0.0)
    sim.run(seconds="2s")
    assert fw.battery_state == "critical"
    assert [s for _, s in fw.battery_log] == ["low", "critical"]


def test_missing_modules_beep_three_times_every_2s_and_a_full_battery_stays_normal():
    sim, _, buzzer = bench(soc=1.0)
    sim.run(seconds="2.5s")
    assert sim.firmware.battery_state == "normal"
    on = [t for t, lv in buzzer if lv]
    steps = [round(b - a, 6) for a, b in itertools.pairwise(on)]
    assert steps[:3] == [0.2, 0.2, 1.6]          # (100 on, 100 off) x2, 100 on, 1500 off
    assert sim.part("battery").min_voltage == pytest.approx(12.75)


def test_unknown_controller_input_is_a_clear_error():
    with pytest.raises(ConfigError, match="cmd_vel.linear"):
        mcusim.load("ciaa-edu", overrides={"cmd_vel.forward": 0.5})


def test_lateral_command_is_refused_for_a_skid_steer_rover():
    with pytest.raises(ConfigError, match="cannot move sideways"):
        mcusim.load("ciaa-edu", overrides={"cmd_vel.lateral": 0.2})


def test_console_lines_leave_usart2_at_115200_baud_back_to_back():
    """syslog goes out through the THRE-interrupt driver: 8N1 frames of exactly 10 bits at the
    LPCOpen divisor (DL 83, DIVADDVAL 5, MULVAL 15: 53120/3 PCLK cycles per frame), back to back."""
    from fractions import Fraction
    sim = mcusim.load("ciaa-edu")
    ep = sim.connect_serial("USART2", "buffer")
    sim.run(seconds="0.5s")
    text = bytes(ep.sent).decode()
    assert text.splitlines()[:2] == ["rover_control: layout skid_steer, 4 motor modules on I2C0",
                                     "rover_control: motors disabled: no answer from 0x08 0x09 0x0a 0x0b"]
    log = sim.mcu.periph["USART2"].tx_log
    frame = Fraction(10 * 16 * 83 * (15 + 5), 15)
    assert frame == Fraction(53120, 3)
    first_line = len(text.splitlines()[0]) + 2
    t0 = log[0][0] - 17707                     # the first frame ends ceil(frame) after it starts
    for n, (tick, _) in enumerate(log[:first_line], start=1):
        assert tick == t0 + -(-n * frame // 1)   # exact, never drifting (ceil of n frames)


def test_console_reaches_a_pty_that_pyserial_reads():
    serial = pytest.importorskip("serial")
    sim = mcusim.load("ciaa-edu")
    ep = sim.connect_serial("USART2", "pty")
    try:
        port = serial.Serial(ep.path, 115200, timeout=1)
        sim.run(seconds="0.3s")
        line = port.readline()
        assert line == b"rover_control: layout skid_steer, 4 motor modules on I2C0\r\n"
        port.close()
    finally:
        sim.close()


def test_connect_serial_to_a_missing_uart_names_the_uarts():
    sim = mcusim.load("ciaa-edu")
    with pytest.raises(ConfigError, match="USART2, USART3"):
        sim.connect_serial("UART1")
    sim.discard()


def test_a_misspelled_part_terminal_is_refused_not_left_unwired(tmp_path):
    """A terminal nobody declares (estop.SENS) would leave the E-stop sense unwired: refuse it."""
    import importlib.resources
    text = (importlib.resources.files("mcusim.boards") / "ciaa-edu.toml").read_text()
    bad = tmp_path / "typo.toml"
    bad.write_text(text.replace('"estop.SENSE"', '"estop.SENS"'))
    with pytest.raises(ConfigError, match=r"part estop \(estop\) has no terminal SENS; terminals: ENABLE_IN"):
        mcusim.load(str(bad))


def test_adc_clock_above_4_5_mhz_is_a_summary_warning_and_an_error_when_strict():
    from mcusim.errors import McusimError
    cr = 1 << 21 | 1 << 1 | 1 << 24          # PDN, SEL = CH1, START now; CLKDIV = 0: 204 MHz ADC clock
    sim = mcusim.load("ciaa-edu", firmware=False)
    with pytest.warns(UserWarning, match="4.5 MHz"):
        sim.mcu.write32(0x400E3000, cr)
    sim.run(seconds="1us")
    assert any("4.5 MHz" in w for w in sim.summary()["warnings"])
    strict = mcusim.load("ciaa-edu", firmware=False, strict=True)
    with pytest.raises(McusimError, match="4.5 MHz"):
        strict.mcu.write32(0x400E3000, cr)


def test_the_nuttx_serial_driver_interrupts_at_eight_received_bytes_or_a_character_timeout():
    """lpc43_serial.c up_setup: FCR = RXTRIGGER_8 | TXRST | RXRST | FIFOEN, so the receive
    interrupt comes when the FIFO holds 8 bytes, or after the character time-out (UM10503: no
    character for 3.5 to 4.5 character times) with fewer. The port had set trigger level 1: one
    interrupt per byte. Seen through the driver's receive notifications (``rxavail``, the upper
    half's recvsem post), one per interrupt that moved bytes."""
    sim = mcusim.load("ciaa-edu")
    sim.run(seconds="20ms")                      # booted: the MAVLink port (USART3) is set up
    usart, dev = sim.mcu.periph["USART3"], sim.firmware.mavlink_dev
    n0 = dev.rxavail.count
    frame = 10 / sim.firmware.p["mavlink_baud"]  # 8N1: ten bits a character
    usart.receive(bytes(3))
    sim.run(seconds=3 * frame + 2 * frame)       # three frames in, under four character times later
    assert dev.rxavail.count == n0
    sim.run(seconds=3 * frame)                   # the time-out: one interrupt for the three bytes
    assert dev.rxavail.count == n0 + 1
    usart.receive(bytes(8))
    sim.run(seconds=7 * frame + frame / 2)
    assert dev.rxavail.count == n0 + 1
    sim.run(seconds=frame)                       # the eighth byte in: the trigger level
    assert dev.rxavail.count == n0 + 2
