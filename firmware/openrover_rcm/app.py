"""``rover_control``: the OpenRover robot controller (NuttX on the EDU-CIAA's LPC4337).

Tasks (NuttX tasks on a 1 kHz system tick; priorities as numbers, higher = more urgent):

* ``motor_control`` (priority 100, every ``control_period_ms``):
  - at boot, identifies every motor module on I2C0 (WHO_AM_I, ``boot_retries`` attempts each),
    enables the PID of each, and raises the motor-enable line **only if every module answered**;
    otherwise the line stays low for good and the fault ``modules_missing`` names the absent ones
    (there is no hot-plug: a module that appears later is not taken);
  - each period: reads the E-stop input; computes the body command (zero while the E-stop is
    pressed, after its release until a *new* command arrives, when commands have stopped arriving
    for ``cmd_timeout_ms`` (the communication watchdog), and when the battery is critical);
    ramps the body set point towards it at ``max_accel``/``max_yaw_accel`` (a step from rest
    would drive every BTS7960 into its current limit, which the modules report as a driver
    fault: the E-stop is the exception, its zero takes effect at once); inverse kinematics of
    the layout, the wheel-speed limit, and one SETPOINT write per module;
    reads every module's 16-bit POSITION, unwraps it and integrates the odometry.
* ``battery_monitor`` (priority 50, every ``battery_period_ms``): one ADC0 conversion of CH1
  (battery through the divider ``r_top``/``r_bottom``), a moving average over
  ``battery_samples``, and the state machine NORMAL → LOW (< ``low_v``; back to NORMAL only
  above ``low_v + hysteresis_v``) → CRITICAL (< ``critical_v``). CRITICAL stops the rover and is
  latched until reset: the reading is taken under load, so the voltage recovers by the sag
  (0.2–0.8 V at 10–40 A on two batteries) as soon as the motors stop, which would otherwise
  start and stop the rover in a loop near empty.
* ``mavlink`` (priority 45): the MAVLink link on USART3 (``mavlink_baud``, 57600 8N1), see
  :mod:`.mavlink_task`: telemetry, STATUSTEXT events, velocity commands into the command mailbox
  (so the watchdog covers them), arming, parameters (the modules' PID gains over I2C, the battery
  thresholds) and the ground station's heartbeat failsafe (``gcs_timeout_ms``).
* ``status`` (priority 40, every 50 ms): the buzzer pattern of the battery state (LOW: one 100 ms
  beep every 5 s; CRITICAL: 200 ms on / 200 ms off; a missing module: three 100 ms beeps every
  2 s), LED1 heartbeat, LED2 fault, LED3 motors enabled.

Commands. The host's velocity command (``cmd_vel.linear`` m/s, ``cmd_vel.angular`` rad/s,
``cmd_vel.lateral`` m/s for holonomic layouts) arrives in a mailbox (:meth:`cmd_vel_rx`), the seam
where the MAVLink task on USART3 delivers its commands; the host side of :meth:`publish` (a
companion wired to the mailbox, not gated by MAVLink arming) streams the last command at ``cmd_rate_hz`` (as mavros streams setpoints at 10–50 Hz), and
``cmd_vel.stream=false`` stops the stream (what the watchdog is for). Each publish is a *new*
command (a new id); the stream repeats the same id, which keeps the watchdog fed but does not
clear an E-stop latch.

The paper gives the structure, not the figures; every constant below is ours (``firmware.<name>``).
"""

from __future__ import annotations

import math

from mcusim.fw.nuttx.lpc43_i2c import lpc43_i2c_init
from mcusim.fw.nuttx.lpc43_serial import Lpc43SerialDev
from mcusim.fw.openrover_mcm import protocol as P
from mcusim.fw.openrover_rcm.board import CiaaBoard
from mcusim.fw.openrover_rcm.kinematics import make_layout, saturate
from mcusim.fw.openrover_rcm.mavlink_task import SEV_CRITICAL, SEV_ERROR, SEV_NOTICE, SEV_WARNING, MavlinkLink
from mcusim.fw.openrover_rcm.odometry import Odometry, Unwrap16

from mcusim.errors import ConfigError
from mcusim.kernel import PRIO_INPUT
from mcusim.params import Param, firmware_params
from mcusim.recent import RecentLog

_ADDR = Param(0x08, min=0x08, max=0x77, doc="7-bit I2C address")
DEFAULTS = {
    "layout": Param("skid_steer", choices=("differential", "skid_steer", "omni", "mecanum"),
                    doc="wheel layout of the kinematics and the odometry"),
    "wheel_radius": Param(0.195, above=0, max=10.0, unit="m", doc="ElementAll: 0.39 m wheels"),
    "track_width": Param(0.55, above=0, max=100.0, unit="m", doc="distance between the left and right wheels"),
    "chi": Param(1.5, min=1.0, max=10.0, doc="ICR expansion factor (skid steer; 1: no skid)"),
    "wheel_distance": Param(0.25, above=0, max=100.0, unit="m", doc="omni: centre to wheel"),
    "angles_deg": Param((90.0, 210.0, 330.0), length=3, items=Param(0.0, min=-360.0, max=360.0, unit="°"),
                        doc="omni: wheel angles"),
    "lx": Param(0.2, above=0, max=100.0, unit="m", doc="mecanum: half wheelbase"),
    "ly": Param(0.2, above=0, max=100.0, unit="m", doc="mecanum: half track"),
    "modules": Param((0x08, 0x09, 0x0A, 0x0B), length=range(2, 9), items=_ADDR,
                     doc="I2C addresses of the motor modules in the layout's wheel order (FL, FR, RL, RR)"),
    "counts_per_motor_rev": Param(2048, min=4, max=1_000_000, unit="counts", doc="encoder counts per motor turn"),
    "gear_ratio": Param(50.0, above=0, max=10_000.0, doc="motor turns per wheel turn"),
    "max_wheel_speed": Param(4.0, above=0, max=1000.0, unit="rad/s",
                             doc="wheel speed limit (no-load ≈ 4.8 rad/s at 12 V)"),
    "max_accel": Param(0.5, above=0, max=100.0, unit="m/s²", doc="ramp of the body velocity set point"),
    "max_yaw_accel": Param(1.0, above=0, max=1000.0, unit="rad/s²", doc="ramp of the yaw-rate set point"),
    # the LPC4337 I2C0 runs up to 1 MHz (Fast-mode Plus); below 10 kHz SCLH/SCLL overflow 16 bits
    "i2c_frequency": Param(100_000, min=10_000, max=1_000_000, unit="Hz", doc="I2C0 SCL frequency"),
    # the USART's 16-bit divisor reaches 300 baud from 204 MHz; 3 Mbaud is the fastest standard rate
    "console_baud": Param(115200, min=300, max=3_000_000, unit="baud", doc="syslog on USART2"),
    "mavlink_baud": Param(57600, min=300, max=3_000_000, unit="baud", doc="MAVLink on USART3 (UART_232)"),
    "gcs_timeout_ms": Param(3000, min=100, max=3_600_000, unit="ms",
                            doc="MAVLink: no ground-station heartbeat for this long disarms and stops"),
    "manual_max_linear": Param(0.5, above=0, max=10.0, unit="m/s", doc="MANUAL_CONTROL x = 1000"),
    "manual_max_yaw": Param(1.0, above=0, max=20.0, unit="rad/s", doc="MANUAL_CONTROL r = 1000"),
    # SysTick's 24-bit reload: at least 13 Hz at 204 MHz; NuttX runs 100 Hz to 10 kHz ticks
    "tick_hz": Param(1000, min=100, max=10_000, unit="Hz", doc="system tick (CONFIG_USEC_PER_TICK)"),
    "control_period_ms": Param(20, min=1, max=10_000, unit="ms", doc="control task period"),
    "cmd_timeout_ms": Param(500, min=1, max=3_600_000, unit="ms", doc="command watchdog"),
    "boot_retries": Param(3, min=1, max=100, doc="module probes at boot"),
    "boot_delay_ms": Param(100, min=0, max=60_000, unit="ms",
                           doc="the modules' bootloader + setup() before the first probe"),
    "battery_period_ms": Param(100, min=1, max=60_000, unit="ms", doc="battery task period"),
    "battery_samples": Param(8, min=1, max=1000, doc="moving average of battery readings"),
    "r_top": Param(33_000.0, above=0, max=1e9, unit="Ω", doc="battery divider, upper resistor"),
    "r_bottom": Param(6_800.0, above=0, max=1e9, unit="Ω", doc="battery divider, lower resistor"),
    "vref": Param(3.3, min=2.7, max=3.6, unit="V", doc="ADC reference (LPC4337 VDDA range)"),
    "battery_channel": Param(1, min=0, max=7, doc="ADC0 channel of the battery divider"),
    # sAPI's adcInit at 200 kS/s: 204 MHz / 93 = 2.19 MHz; CLKDIV below 45 runs the ADC above its
    # 4.5 MHz maximum (a warning, an error with --strict)
    "adc_clkdiv": Param(92, min=0, max=255, doc="ADC0 CR.CLKDIV: the ADC clock is PCLK / (CLKDIV + 1)"),
    "low_v": Param(11.9, above=0, max=100.0, unit="V", doc="battery LOW threshold"),
    "critical_v": Param(11.5, above=0, max=100.0, unit="V", doc="battery CRITICAL threshold (below low_v)"),
    "hysteresis_v": Param(0.2, min=0, max=10.0, unit="V", doc="battery state hysteresis"),
    "cmd_rate_hz": Param(20.0, above=0, max=1000.0, unit="Hz", doc="rate of the host's command stream"),
    "cycles_boot": Param(204_000, min=0, max=2_040_000_000, unit="cycles",
                         doc="1 ms from reset to rover_control's first line"),
    "cycles_control": Param(6000, min=0, max=10_000_000, unit="cycles", doc="cost of one control step"),
    "cycles_battery": Param(1500, min=0, max=10_000_000, unit="cycles", doc="cost of one battery step"),
    "cycles_status": Param(300, min=0, max=10_000_000, unit="cycles", doc="cost of one status step"),
    "cycles_systick": Param(120, min=0, max=100_000, unit="cycles", doc="cost of the SysTick handler"),
    "cycles_mavlink_wake": Param(400, min=0, max=10_000_000, unit="cycles", doc="MAVLink task: one pass"),
    "cycles_mavlink_rx_byte": Param(60, min=0, max=100_000, unit="cycles",
                                    doc="MAVLink task: mavlink_parse_char per received byte"),
    "cycles_mavlink_handle": Param(1500, min=0, max=10_000_000, unit="cycles",
                                   doc="MAVLink task: one received message handled"),
    "cycles_mavlink_tx": Param(1200, min=0, max=10_000_000, unit="cycles",
                               doc="MAVLink task: one message packed (fields, CRC) and queued"),
}
LAYOUT_GEOMETRY = {"differential": ("wheel_radius", "track_width"),
                   "skid_steer": ("wheel_radius", "track_width", "chi"),
                   "omni": ("wheel_radius", "wheel_distance", "angles_deg"),
                   "mecanum": ("wheel_radius", "lx", "ly")}
NORMAL, LOW, CRITICAL = "normal", "low", "critical"
BUZZER_PATTERNS = {   # (on ms, off ms) steps, repeated
    LOW: ((100, 4900),),
    CRITICAL: ((200, 200),),
    "modules_missing": ((100, 100), (100, 100), (100, 1500)),
}
HOST_INPUTS = {
    "cmd_vel.linear": "forward speed, m/s",
    "cmd_vel.angular": "yaw rate, rad/s (counter-clockwise positive)",
    "cmd_vel.lateral": "sideways speed, m/s (omni and mecanum layouts)",
    "cmd_vel.stream": "true/false: the host keeps re-sending the command at cmd_rate_hz",
}
# their checked values: speeds beyond what the rover can do are saturated by the controller, but a
# command above 10 m/s or 20 rad/s is taken for a typo
INPUTS = {
    "cmd_vel.linear": Param(0.0, min=-10.0, max=10.0, unit="m/s", doc=HOST_INPUTS["cmd_vel.linear"]),
    "cmd_vel.angular": Param(0.0, min=-20.0, max=20.0, unit="rad/s", doc=HOST_INPUTS["cmd_vel.angular"]),
    "cmd_vel.lateral": Param(0.0, min=-10.0, max=10.0, unit="m/s", doc=HOST_INPUTS["cmd_vel.lateral"]),
    "cmd_vel.stream": Param(True, doc=HOST_INPUTS["cmd_vel.stream"]),
}


class RoverControl:
    PARAMS = DEFAULTS            # declared parameters (firmware.<name>), checked by mcusim.params
    CORE = "cortex-m"            # the cores it runs on (a profile's [core] kind starts with it)
    MAVLINK_UART = "USART3"      # the UART of the MAVLink task (mcusim run --mavlink connects it)
    HOST_INPUTS = HOST_INPUTS    # inputs a host can give (--set <name>=...)
    INPUTS = INPUTS              # and their checked values (mcusim boards --kinds)
    SUMMARY_TOP = ("odometry",)

    def __init__(self, mcu, **params):
        if isinstance(params.get("layout"), str):          # skid-steer and skid_steer alike
            params = {**params, "layout": params["layout"].replace("-", "_")}
        self.p = p = firmware_params(DEFAULTS, params)
        kind = p["layout"]
        if not p["critical_v"] < p["low_v"]:
            raise ConfigError(f"firmware.critical_v = {p['critical_v']:g} must be below firmware.low_v = "
                              f"{p['low_v']:g}")
        try:
            self.layout = make_layout(kind, **{k: p[k] for k in LAYOUT_GEOMETRY[kind]})
        except ValueError as exc:
            raise ConfigError(f"firmware: {exc}") from None
        self.modules = [int(a) for a in p["modules"]]
        if len(self.modules) != self.layout.wheels:
            raise ConfigError(f"firmware.modules: {len(self.modules)} addresses for a {kind} layout "
                              f"of {self.layout.wheels} wheels")
        twice = next((a for i, a in enumerate(self.modules) if a in self.modules[:i]), None)
        if twice is not None:   # one module would answer for two wheels, the other never driven
            raise ConfigError(f"firmware.modules: address {twice:#04x} is given twice; each wheel's module "
                              "has its own")
        self.mcu, self.cpu, self.rtos = mcu, mcu.cpu, mcu.rtos
        adc = mcu.periph.get("ADC0")
        wired = getattr(adc, "inputs", None)
        if wired is not None and p["battery_channel"] not in wired:
            # the chip has eight channels; a board brings out some (the EDU-CIAA: ADC0_0 to _3), and
            # converting one nothing is wired to is refused by the ADC model when it starts
            raise ConfigError(f"firmware.battery_channel = {p['battery_channel']}: ADC0 channel "
                              f"{p['battery_channel']} is not wired on this board (wired: "
                              f"{', '.join(str(c) for c in sorted(wired))})")
        self.rtos.tick_hz = p["tick_hz"]
        self.board = CiaaBoard(mcu, adc_clkdiv=p["adc_clkdiv"])
        self.counts_per_wheel_rev = p["counts_per_motor_rev"] * p["gear_ratio"]
        # state
        self.found: list[int] = []
        self.missing: list[int] = []
        self.motors_enabled = False
        self.faults: set[str] = set()
        self.module_status = [0] * len(self.modules)
        self.estop_pressed = False
        self.estop_latched = False
        self._estop_cmd_id = None
        self.watchdog_tripped = False
        self._modules_held = False
        self.cmd = (0.0, 0.0, 0.0)
        self.cmd_id = 0
        self.cmd_tick = None
        self.body_target = (0.0, 0.0, 0.0)
        self.wheel_setpoints = [0] * len(self.modules)     # counts/s sent to the modules
        self.wheel_speeds = [0.0] * len(self.modules)      # rad/s of each wheel, from POSITION
        self.unwrap = [Unwrap16() for _ in self.modules]
        self.odometry = Odometry(self.layout, self.counts_per_wheel_rev)
        self.i2c_errors = 0
        self.battery_v = None
        self.battery_state = NORMAL
        self.battery_log: list[tuple[int, str]] = []        # (tick, state) transitions
        self._samples: list[float] = []
        self.buzzer_on = False
        self.buzzer_log = RecentLog()    # (kernel tick, level) changes, the recent ones (mcusim.recent)
        self._host = {"linear": 0.0, "angular": 0.0, "lateral": 0.0, "stream": True, "id": 0}
        self._stream_ev = None
        self.i2c = None
        self.link = None
        self.rtos.create_task("motor_control", self.motor_control, priority=100)
        self.rtos.create_task("battery_monitor", self.battery_monitor, priority=50)
        self.rtos.create_task("mavlink", self.mavlink_task, priority=45)
        self.rtos.create_task("status", self.status_task, priority=40)

    def csv_columns(self, motors: list[str], member: str) -> list[tuple[str, object]]:
        """(column, getter) of the variables a CSV trace samples (mcusim.csvtrace): the odometry
        pose, the battery voltage it measures and the command it follows."""
        return [("odometry.x_m", lambda: self.odometry.pose[0]),
                ("odometry.y_m", lambda: self.odometry.pose[1]),
                ("odometry.yaw_rad", lambda: self.odometry.pose[2]),
                ("battery.measured_v", lambda: self.battery_v),
                ("cmd_vel.linear_m_s", lambda: self.cmd[0]),
                ("cmd_vel.angular_rad_s", lambda: self.cmd[2])]

    # --- start-up (nx_start → board init → rover_control main) -------------------------------
    def _ms(self, ms: int) -> int:
        return max(1, round(ms * self.p["tick_hz"] / 1000))

    def board_init(self) -> None:
        b = self.board
        self.cpu.vector(-1, self.rtos.systick_handler, cost=self.p["cycles_systick"])
        b.systick_init(int(self.cpu.clock.hz), self.p["tick_hz"])
        b.gpio_config_output("MOTOR_EN", 0)
        b.gpio_config_output("BUZZER", 0)
        for led in ("LED1", "LED2", "LED3"):
            b.gpio_config_output(led, 0)
        b.gpio_config_input("ESTOP")
        b.adc_init()
        self.i2c = lpc43_i2c_init(self.mcu, frequency=self.p["i2c_frequency"])
        self.console = Lpc43SerialDev(self.mcu, 0x400C1000, 26, self.p["console_baud"], int(self.cpu.clock.hz))
        self.console.up_setup()
        self.mavlink_dev = Lpc43SerialDev(self.mcu, 0x400C2000, 27, self.p["mavlink_baud"], int(self.cpu.clock.hz),
                                          txbufsize=1024)
        self.mavlink_dev.up_setup()
        self.link = MavlinkLink(self, self.mavlink_dev)
        self.syslog(f"layout {self.layout.kind}, {len(self.modules)} motor modules on I2C0")

    def syslog(self, msg: str) -> None:
        """syslog() to the console: ``rover_control: <msg>`` and CR LF."""
        self.console.write(f"rover_control: {msg}\r\n".encode())

    def notify(self, severity: int, msg: str, console: bool = True) -> None:
        """An event: a syslog line and a MAVLink STATUSTEXT."""
        if console:
            self.syslog(msg)
        if self.link is not None:
            self.link.event(severity, msg)

    # --- motor-control module -------------------------------------------------------------------
    async def identify_modules(self) -> None:
        for addr in self.modules:
            for _ in range(self.p["boot_retries"]):
                ret, data = await self.i2c.write_read(addr, bytes([P.BY_NAME["WHO_AM_I"].addr]), 1)
                if ret == 0 and data and data[0] == P.WHO_AM_I_VALUE:
                    self.found.append(addr)
                    break
                await self.rtos.delay(self._ms(10))
            else:
                self.missing.append(addr)
        if self.missing:
            self.faults.add("modules_missing")
            self.notify(SEV_ERROR, "motors disabled: no answer from " + " ".join(f"{a:#04x}" for a in self.missing))
            return
        for addr in self.modules:     # PID on, faults cleared, set point 0
            await self._write_reg(addr, "SETPOINT", 0)
            await self._write_reg(addr, "CONTROL", P.CTL_PID_ENABLE | P.CTL_CLEAR_FAULTS)
        self.board.gpio_write("MOTOR_EN", 1)
        self.motors_enabled = True
        self.syslog("motors enabled: " + " ".join(f"{a:#04x}" for a in self.found))

    async def _write_reg(self, addr: int, name: str, value) -> int:
        reg = P.BY_NAME[name]
        ret = await self.i2c.write(addr, bytes([reg.addr]) + P.encode(name, value))
        if ret != 0:
            self.i2c_errors += 1
        return ret

    async def _read_reg(self, addr: int, name: str):
        reg = P.BY_NAME[name]
        ret, data = await self.i2c.write_read(addr, bytes([reg.addr]), reg.size)
        if ret != 0 or len(data) != reg.size:
            self.i2c_errors += 1
            return None
        return P.decode(name, data)

    async def hold_modules(self, hold: bool) -> None:
        """While the E-stop latch is set the modules' PIDs are off (CONTROL = 0: output 0, PID_v1
        in MANUAL), so that their integrators do not wind up against wheels that coast with the
        bridges cut; when the latch clears they are re-enabled with their faults cleared."""
        if hold == self._modules_held:
            return
        control = 0 if hold else P.CTL_PID_ENABLE | P.CTL_CLEAR_FAULTS
        for addr in self.modules:
            await self._write_reg(addr, "CONTROL", control)
        self._modules_held = hold

    def command_target(self) -> tuple:
        """The body velocity to drive now, after the E-stop, watchdog and battery rules."""
        now = self.rtos.tick_count
        pressed = self.board.gpio_read("ESTOP") == 0
        if pressed != self.estop_pressed:
            self.notify(SEV_CRITICAL if pressed else SEV_NOTICE, "E-STOP pressed" if pressed else "E-STOP released")
            if pressed and self.link is not None:
                self.link.disarm()
        self.estop_pressed = pressed
        if self.estop_pressed:
            self.estop_latched, self._estop_cmd_id = True, self.cmd_id
        elif self.estop_latched and self.cmd_id != self._estop_cmd_id:
            self.estop_latched = False            # a new command after the release
        fresh = self.cmd_tick is not None and now - self.cmd_tick <= self._ms(self.p["cmd_timeout_ms"])
        tripped = self.cmd_tick is not None and not fresh
        if tripped and not self.watchdog_tripped:
            self.notify(SEV_WARNING, f"watchdog: no command for {self.p['cmd_timeout_ms']} ms, stopping")
        self.watchdog_tripped = tripped
        if self.estop_latched or not fresh or self.battery_state == CRITICAL or not self.motors_enabled:
            return (0.0, 0.0, 0.0)
        return self.cmd

    def ramp(self, current, target) -> tuple:
        """Move the body set point towards ``target`` by at most one period's acceleration."""
        if self.estop_latched:
            return (0.0, 0.0, 0.0)
        dt = self.p["control_period_ms"] / 1000
        limits = (self.p["max_accel"] * dt, self.p["max_accel"] * dt, self.p["max_yaw_accel"] * dt)
        return tuple(c + max(-lim, min(lim, t - c)) for c, t, lim in zip(current, target, limits))

    def wheel_counts(self, target) -> list[int]:
        vx, vy, wz = target
        wheels = self.layout.inverse(vx, vy if self.layout.holonomic else 0.0, wz)
        wheels = saturate(wheels, self.p["max_wheel_speed"])
        k = self.p["gear_ratio"] * self.p["counts_per_motor_rev"] / (2 * math.pi)
        return [round(w * k) for w in wheels]

    async def motor_control(self):
        await self.cpu.cycles(self.p["cycles_boot"])     # reset handler, clocks, nx_start until the app
        self.board_init()
        await self.cpu.cycles(2000)
        await self.rtos.delay(self._ms(self.p["boot_delay_ms"]))
        await self.identify_modules()
        period = self._ms(self.p["control_period_ms"])
        wake = self.rtos.tick_count
        n = 0
        while True:
            wake += period
            await self.rtos.delay_until(wake)
            self.body_target = self.ramp(self.body_target, self.command_target())
            await self.cpu.cycles(self.p["cycles_control"])
            if not self.motors_enabled:
                continue
            await self.hold_modules(self.estop_latched)
            setpoints = self.wheel_counts(self.body_target)
            for i, addr in enumerate(self.modules):
                if await self._write_reg(addr, "SETPOINT", setpoints[i]) == 0:
                    self.wheel_setpoints[i] = setpoints[i]
            counts, before = [], [u.count for u in self.unwrap]
            for i, addr in enumerate(self.modules):
                raw = await self._read_reg(addr, "POSITION")
                counts.append(self.unwrap[i].update(raw) if raw is not None else self.unwrap[i].count)
            k = 2 * math.pi / self.counts_per_wheel_rev / (self.p["control_period_ms"] / 1000)
            self.wheel_speeds = [(c - b) * k for c, b in zip(counts, before)]
            self.odometry.update(counts)
            n += 1
            if n % 10 == 0:       # module status every 10 periods
                for i, addr in enumerate(self.modules):
                    st = await self._read_reg(addr, "STATUS")
                    if st is not None:
                        self.module_status[i] = st
                        if st & (P.ST_STALL | P.ST_OVERCURRENT):
                            if f"module_{addr:#04x}_fault" not in self.faults:
                                what = "stall" if st & P.ST_STALL else "driver fault"
                                self.notify(SEV_ERROR, f"module {addr:#04x}: {what}", console=False)
                            self.faults.add(f"module_{addr:#04x}_fault")

    # --- battery monitor ---------------------------------------------------------------------------
    def battery_volts(self, code: int) -> float:
        p = self.p
        return code * p["vref"] / 1024 * (p["r_top"] + p["r_bottom"]) / p["r_bottom"]

    def battery_update(self, v: float) -> str:
        p, s = self.p, self.battery_state
        if s == NORMAL and v < p["low_v"]:
            s = LOW
        if s in (NORMAL, LOW) and v < p["critical_v"]:
            s = CRITICAL       # latched: the voltage recovers once the motors stop, the charge does not
        if s == LOW and v > p["low_v"] + p["hysteresis_v"]:
            s = NORMAL
        if s != self.battery_state:
            self.battery_state = s
            self.battery_log.append((self.mcu.kernel.now, s))
            self.notify(SEV_CRITICAL if s == CRITICAL else SEV_WARNING if s == LOW else SEV_NOTICE,
                        f"battery {s.upper()} {v:.2f} V")
        return s

    async def battery_monitor(self):
        await self.rtos.delay(1)          # after board_init (motor_control runs first)
        period = self._ms(self.p["battery_period_ms"])
        wake = self.rtos.tick_count
        while True:
            code = await self.board.adc_read(self.rtos, self.p["battery_channel"])
            self._samples = (self._samples + [self.battery_volts(code)])[-self.p["battery_samples"]:]
            self.battery_v = sum(self._samples) / len(self._samples)
            self.battery_update(self.battery_v)
            await self.cpu.cycles(self.p["cycles_battery"])
            wake += period
            await self.rtos.delay_until(wake)

    # --- MAVLink -------------------------------------------------------------------------------------
    async def mavlink_task(self):
        await self.rtos.delay(1)          # after board_init (motor_control runs first)
        await self.link.run()

    # --- buzzer and LEDs ------------------------------------------------------------------------
    def _pattern(self):
        if self.battery_state in (LOW, CRITICAL):
            return BUZZER_PATTERNS[self.battery_state]
        if "modules_missing" in self.faults:
            return BUZZER_PATTERNS["modules_missing"]
        return None

    def _buzz(self, on: bool) -> None:
        if on != self.buzzer_on:
            self.buzzer_on = on
            self.board.gpio_write("BUZZER", on)
            self.buzzer_log.append((self.mcu.kernel.now, int(on)))

    async def status_task(self):
        await self.rtos.delay(1)
        step = self._ms(50)
        wake, t_ms, beat = self.rtos.tick_count, 0, 0
        current, phase_end, idx, on = None, 0, 0, False
        while True:
            pattern = self._pattern()
            if pattern is not current:
                current, idx, phase_end, on = pattern, 0, t_ms, False
            if current is None:
                self._buzz(False)
            elif t_ms >= phase_end:
                on_ms, off_ms = current[idx % len(current)]
                on = not on
                if on:
                    phase_end = t_ms + on_ms
                else:
                    phase_end, idx = t_ms + off_ms, idx + 1
                self._buzz(on)
            beat += 1
            self.board.gpio_write("LED1", (beat // 10) % 2)
            self.board.gpio_write("LED2", bool(self.faults) or self.battery_state != NORMAL)
            self.board.gpio_write("LED3", self.motors_enabled)
            await self.cpu.cycles(self.p["cycles_status"])
            wake += step
            t_ms += 50
            await self.rtos.delay_until(wake)

    # --- command mailbox (the seam of the future MAVLink link) ----------------------------------
    def cmd_vel_rx(self, vx: float, vy: float, wz: float, cmd_id: int) -> None:
        self.cmd = (float(vx), float(vy), float(wz))
        self.cmd_id = cmd_id
        self.cmd_tick = self.rtos.tick_count

    def cmd_vel_clear(self, cmd_id: int) -> None:
        """Empty the mailbox: stop, with no command for the watchdog to watch (a disarm)."""
        self.cmd, self.cmd_id, self.cmd_tick = (0.0, 0.0, 0.0), cmd_id, None

    # --- host side (not firmware) ------------------------------------------------------------------
    def check_input(self, name: str, value):
        """``value`` for host input ``name`` converted to its type, or ConfigError."""
        if name not in HOST_INPUTS:
            raise ConfigError(f"no input {name!r}; the controller takes: " +
                              "; ".join(f"{k} ({v})" for k, v in HOST_INPUTS.items()))
        v = INPUTS[name].check(value, name)
        if name == "cmd_vel.lateral" and v and not self.layout.holonomic:
            art = "an" if self.layout.kind[:1] in "aeiou" else "a"
            raise ConfigError(f"{name}: {art} {self.layout.kind} rover cannot move sideways")
        return v

    def publish(self, name: str, value) -> None:
        v = self.check_input(name, value)
        key, h = name.removeprefix("cmd_vel."), self._host
        h[key] = v
        if key != "stream":
            h["id"] += 1
        if self._stream_ev is not None:
            self._stream_ev.cancel()
            self._stream_ev = None
        self._send()

    def _send(self) -> None:
        h = self._host
        if not h["stream"]:
            return
        self.cmd_vel_rx(h["linear"], h["lateral"], h["angular"], h["id"])
        kernel = self.mcu.kernel
        period = kernel.timebase.ticks(1 / self.p["cmd_rate_hz"], rounding=True)
        self._stream_ev = kernel.after(period, self._send, prio=PRIO_INPUT)

    def topic(self, name: str):
        values = {"odometry": dict(zip(("x", "y", "yaw"), self.odometry.pose)),
                  "battery_v": self.battery_v, "battery_state": self.battery_state,
                  "motors_enabled": self.motors_enabled, "estop": self.estop_pressed,
                  "watchdog": self.watchdog_tripped, "wheel_setpoints": list(self.wheel_setpoints)}
        if name not in values:
            raise ConfigError(f"no output {name!r}; the controller reports {', '.join(values)}")
        return values[name]

    def summary(self) -> dict:
        x, y, yaw = self.odometry.pose
        return {"odometry": {"x": x, "y": y, "yaw": yaw},
                "layout": self.layout.kind,
                "modules_found": [f"{a:#04x}" for a in self.found],
                "modules_missing": [f"{a:#04x}" for a in self.missing],
                "motors_enabled": self.motors_enabled,
                "battery_measured_v": self.battery_v, "battery_state": self.battery_state,
                "estop_latched": self.estop_latched, "watchdog_tripped": self.watchdog_tripped,
                "faults": sorted(self.faults), "i2c_errors": self.i2c_errors,
                # (the link is made at the first step, board_init: before it, its summary as made)
                "mavlink": self.link.summary() if self.link is not None else dict(MavlinkLink.BEFORE)}
