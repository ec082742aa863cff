"""The OpenRover motor-controller module sketch (Arduino Pro Mini, ATmega328P at 16 MHz).

Hardware: IBT-2 (two BTS7960 half-bridges) with RPWM on D9 and LPWM on D10 driven by TimerOne at
20 kHz; R_EN/L_EN tied high; the current-sense outputs R_IS on A0 and L_IS on A1; the motor's AMT10
encoder (512 PPR, 2048 counts per motor turn) on D2/D3 read by the PJRC Encoder library; I2C slave
on A4/A5 (Wire) with the register map of :mod:`mcusim.fw.openrover_mcm.protocol`.

loop(): every SAMPLE_MS (PID_v1's sample time) the velocity in counts/s is measured from the
encoder, PID_v1 computes a duty in [-1024, 1024] (TimerOne units), the sign picks RPWM or LPWM;
both IS pins are read and the current of the driving half-bridge is converted to mA; charge is
integrated; a stall (|duty| above STALL_DUTY while the speed stays below STALL_SPEED for STALL_MS)
stops the motor and raises the STALL fault, and an IS reading at the BTS7960's fault level
(current limit or overtemperature) stops it and raises the driver fault; both are cleared over I2C.

The paper gives the structure, not the figures; the constants below are ours (overridable as
``firmware.<name>``). A pass that finds nothing to do has read only ``millis()``, so instead of
simulating the passes after it one by one the loop waits until Timer0's overflow ISR moves
``millis()`` (encoder and TWI interrupts preempt the wait as they preempted those passes).
"""

from __future__ import annotations

import struct

from mcusim.fw.arduino.core import A0, A1, ArduinoCore
from mcusim.fw.arduino.encoder import Encoder
from mcusim.fw.arduino.pid_v1 import AUTOMATIC, DIRECT, MANUAL, PID
from mcusim.fw.arduino.timerone import TimerOne
from mcusim.fw.arduino.wire import TwoWire
from mcusim.fw.openrover_mcm import protocol as P

from mcusim.errors import ConfigError
from mcusim.kernel import PRIO_INPUT
from mcusim.params import Param, firmware_params

DEFAULTS = {
    # 7-bit addresses 0x08..0x77: 0x00-0x07 and 0x78-0x7F are reserved by the I2C specification
    "i2c_address": Param(P.DEFAULT_ADDRESS, min=0x08, max=0x77, unique="i2c",
                         doc="the module's 7-bit I2C slave address"),
    "sample_ms": Param(10, min=1, max=10_000, unit="ms", doc="PID_v1 sample time and velocity window"),
    # PID_v1's SetTunings ignores negative gains; duty units (1/1024) per count/s
    "kp": Param(0.02, min=0, max=1e4, doc="PID_v1 Kp, duty (1/1024) per count/s"),
    "ki": Param(0.2, min=0, max=1e4, doc="PID_v1 Ki, per second"),
    "kd": Param(0.0, min=0, max=1e4, doc="PID_v1 Kd, seconds"),
    "stall_duty": Param(300, min=0, max=1024, doc="a stall: |duty| (of 1024) above this ..."),
    "stall_speed": Param(200, min=0, max=10_000_000, unit="counts/s", doc="... with |velocity| below this ..."),
    "stall_ms": Param(500, min=1, max=3_600_000, unit="ms", doc="... for this long"),
    "r_is": Param(1000.0, above=0, max=1e7, unit="Ω", doc="IBT-2 current-sense resistor (I = V_IS / R_IS · k_ILIS)"),
    "k_ilis": Param(8500.0, above=0, max=1e6, doc="BTS7960 current-sense ratio"),
    "is_fault_counts": Param(900, min=1, max=1024, unit="ADC counts",
                             doc="IS reading taken as a driver fault (4.5 mA · 1 kΩ ≈ 920 counts)"),
    "avcc": Param(5.0, min=1.8, max=5.5, unit="V", doc="ADC reference (ATmega328P AVCC range)"),
    "wire_variant": Param("fixed", choices=("fixed", "core"),
                          doc="core: the Wire slave bug that makes it deaf after a NACKed byte"),
    "cycles_loop_work": Param(3000, min=0, max=10_000_000, unit="cycles",
                              doc="declared: soft-float PID_v1 + bookkeeping per sample"),
    "cycles_loop_idle": Param(40, min=1, max=1_000_000, unit="cycles",
                              doc="declared: one pass of loop() with nothing to do"),
}
RPWM_PIN, LPWM_PIN, ENC_A_PIN, ENC_B_PIN = 9, 10, 2, 3
COUNTS_PER_MOTOR_TURN, GEAR_RATIO = 2048, 50

# Inputs a host can give the module (``--set velocity=10``): each becomes an I2C write from a
# host master on the module's bus, as the robot controller would send it.
HOST_INPUTS = {
    "velocity": "wheel velocity set point, rpm (SETPOINT = rpm·50·2048/60 counts/s)",
    "pid_enable": "CONTROL bit 0 (false stops the motor)",
    "clear_faults": "CONTROL = PID_ENABLE | CLEAR_FAULTS",
}


# the checked values of those inputs: the set point travels as int32 counts/s; ±1000 rpm at the
# wheel (20 times what the 100 W motor reaches) keeps typos out without limiting a test
INPUTS = {
    "velocity": Param(0.0, min=-1000.0, max=1000.0, unit="rpm", doc=HOST_INPUTS["velocity"]),
    "pid_enable": Param(True, doc=HOST_INPUTS["pid_enable"]),
    "clear_faults": Param(True, doc=HOST_INPUTS["clear_faults"]),
}


def rpm_to_counts(rpm: float) -> int:
    return round(rpm * GEAR_RATIO * COUNTS_PER_MOTOR_TURN / 60)


def counts_per_second(delta: int, dt_ms: int) -> int:
    """``delta * 1000 / dt_ms`` in the sketch's long arithmetic: C's division truncates towards
    zero (Python's ``//`` floors: a reverse speed had come out one count/s lower whenever the
    division was not exact, 3 samples in 125)."""
    n = delta * 1000
    return -(-n // dt_ms) if n < 0 else n // dt_ms


def counts_to_rpm(counts_s: float) -> float:
    return counts_s * 60 / (GEAR_RATIO * COUNTS_PER_MOTOR_TURN)


class OpenRoverMcm:
    PARAMS = DEFAULTS            # declared parameters (firmware.<name>), checked by mcusim.params
    CORE = "avr"                 # the cores it runs on (a profile's [core] kind starts with it)
    HOST_INPUTS = HOST_INPUTS    # inputs a host can give (--set <name>=...)
    INPUTS = INPUTS              # and their checked values (mcusim boards --kinds)

    def __init__(self, mcu, adc=None, **params):
        self.p = firmware_params(DEFAULTS, params)
        self.mcu, self.cpu, self.rtos = mcu, mcu.cpu, mcu.rtos
        adc = adc if adc is not None else mcu.periph.get("ADC")
        self.core = ArduinoCore(mcu, adc=adc)
        # globals, constructed before init() as C++ globals are
        self.encoder = Encoder(self.core, ENC_A_PIN, ENC_B_PIN)
        for n in (0, 1):  # the library's measured ISR length (reference sheet §3)
            self.core.set_isr_cycles(n, Encoder.ISR_CYCLES)
        self.timer1 = TimerOne(mcu.bus, self.core)
        self.wire = TwoWire(self.core, variant=self.p["wire_variant"])
        self.pid = PID(self.p["kp"], self.p["ki"], self.p["kd"], direction=DIRECT, millis=self.core.millis)
        self.velocity = 0            # counts/s
        self.setpoint = 0            # counts/s
        self.duty = 0
        self.current_ma = 0
        self.charge_mas = 0.0        # mA·s
        self.status = 0
        self.error = P.ERR_NONE
        self.pointer = 0
        self._stall_since = None
        # simulation: a pass of loop() after which millis() is still short of the sample time only
        # reads it (loop()'s first lines), so the fast engine may serve it (mcusim.engine.ticks)
        self._idle_pass = self.core.idle_pass(
            self.p["cycles_loop_idle"], lambda ms: (ms - self._last_ms) & 0xFFFFFFFF < self.p["sample_ms"])
        self.rtos.create_task("arduino", self.main, priority=1)

    def csv_columns(self, motors: list[str], member: str) -> list[tuple[str, object]]:
        """(column, getter) of the variables a CSV trace samples (mcusim.csvtrace): the wheel's
        set point and measured speed, the duty and the current the sketch measures."""
        prefix = motors[0] if motors else f"{member}.motor"
        return [(f"{prefix}.setpoint_rpm", lambda: counts_to_rpm(self.setpoint)),
                (f"{prefix}.velocity_rpm", lambda: counts_to_rpm(self.velocity)),
                (f"{prefix}.duty_pct", lambda: self.duty * 100 / 1024),
                (f"{prefix}.fw_current_a", lambda: self.current_ma / 1000)]

    # --- main() of the Arduino core: init(); setup(); for (;;) loop(); ---------------------------
    async def main(self):
        # the C++ global constructors run before main(): the Encoder's, with its 2 ms wait for
        # the pull-ups (a Python constructor cannot wait: its cycles are paid here, before init())
        await self.core.pay_debt()
        self.core.init()
        self.setup()
        await self.core.pay_debt()
        while True:
            polled = self.core.millis_changed.count
            worked = await self.loop()
            await self.cpu.cycles(self.p["cycles_loop_work"] if worked else self.p["cycles_loop_idle"])
            await self.core.pay_debt()
            if not worked:
                # an idle pass reads only millis(): the passes after it find nothing to do until
                # Timer0's overflow ISR moves it (their cycles are this wait), so wait for that;
                # an overflow during this pass means the very next pass sees it
                await self.rtos.wait_signal(self.core.millis_changed, since=polled, idle=self._idle_pass)

    def setup(self) -> None:
        self.timer1.initialize(50)                 # 50 µs: 20 kHz
        self.timer1.pwm(RPWM_PIN, 0)
        self.timer1.pwm(LPWM_PIN, 0)
        self.wire.begin(self.p["i2c_address"])
        self.wire.on_receive(self.receive_event)
        self.wire.on_request(self.request_event)
        self.pid.set_output_limits(-1024, 1024)
        self.pid.set_sample_time(self.p["sample_ms"])
        self.pid.setpoint = 0.0
        self.pid.set_mode(AUTOMATIC)
        self.status |= P.ST_PID_ENABLED
        self._last_ms = self.core.millis()
        self._last_count = self.encoder.read()

    async def loop(self) -> bool:
        now = self.core.millis()
        dt = (now - self._last_ms) & 0xFFFFFFFF
        if dt < self.p["sample_ms"]:
            return False
        count = self.encoder.read()
        self.velocity = counts_per_second(count - self._last_count, dt)
        self._last_count, self._last_ms = count, now
        self.pid.input = float(self.velocity)
        self.pid.setpoint = float(self.setpoint)
        if self.pid.compute():
            self.set_duty(int(self.pid.output))
        await self.measure_current(dt)
        self.check_stall(dt)
        return True

    def set_duty(self, duty: int) -> None:
        self.duty = duty
        if duty >= 0:
            self.timer1.set_pwm_duty(LPWM_PIN, 0)
            self.timer1.set_pwm_duty(RPWM_PIN, duty)
        else:
            self.timer1.set_pwm_duty(RPWM_PIN, 0)
            self.timer1.set_pwm_duty(LPWM_PIN, -duty)

    async def measure_current(self, dt_ms: int) -> None:
        r = await self.core.analog_read(A0)
        l_ = await self.core.analog_read(A1)
        if max(r, l_) >= self.p["is_fault_counts"]:  # a BTS7960 reports a fault on its IS pin
            self.stop_motor()
            self.status |= P.ST_OVERCURRENT
        volts = (r if self.duty >= 0 else l_) * self.p["avcc"] / 1024
        ma = volts / self.p["r_is"] * self.p["k_ilis"] * 1000
        self.current_ma = int(ma) if self.duty >= 0 else -int(ma)
        self.charge_mas += abs(ma) * dt_ms / 1000

    def check_stall(self, dt_ms: int) -> None:
        if abs(self.duty) > self.p["stall_duty"] and abs(self.velocity) < self.p["stall_speed"]:
            if self._stall_since is None:
                self._stall_since = 0
            self._stall_since += dt_ms
            if self._stall_since >= self.p["stall_ms"]:
                self.stop_motor()
                self.status |= P.ST_STALL
        else:
            self._stall_since = None
        self.status = (self.status | P.ST_MOVING) if self.velocity else (self.status & ~P.ST_MOVING)

    def stop_motor(self) -> None:
        self.pid.set_mode(MANUAL)
        self.pid.output = 0.0
        self.set_duty(0)
        self.status &= ~P.ST_PID_ENABLED

    # --- host side (not firmware): commands as I2C transactions on the module's bus ---------------
    def _host(self):
        if getattr(self, "_host_master", None) is None:
            from mcusim.i2c import I2cMaster
            twi = self.mcu.periph["TWI"]
            self._host_master = I2cMaster(self.mcu.kernel, twi.bus, scl_hz=100_000)
        return self._host_master

    def check_input(self, name: str, value):
        """``value`` for host input ``name`` converted to its type, or ConfigError."""
        if name not in INPUTS:
            raise ConfigError(f"no input {name!r}; the module takes: " +
                              "; ".join(f"{k} ({v})" for k, v in HOST_INPUTS.items()))
        return INPUTS[name].check(value, name)

    def publish(self, name: str, value) -> None:
        """A host input as an I2C write on the module's bus, from 5 ms after reset on: a host
        starts talking once the module has booted (its TWI listens from about 2.1 ms, after the
        Encoder constructor's 2 ms wait and init(); a write before that is not acknowledged)."""
        value = self.check_input(name, value)
        addr, reg = self.p["i2c_address"], P.BY_NAME
        if name == "velocity":
            data = bytes([reg["SETPOINT"].addr]) + P.encode("SETPOINT", rpm_to_counts(value))
        elif name == "pid_enable":
            data = bytes([reg["CONTROL"].addr, P.CTL_PID_ENABLE if value else 0])
        else:
            data = bytes([reg["CONTROL"].addr, P.CTL_PID_ENABLE | P.CTL_CLEAR_FAULTS])
        kernel = self.mcu.kernel
        start = max(kernel.now, kernel.timebase.ticks("5ms"))
        kernel.at(start, lambda: self._host().write(addr, data), prio=PRIO_INPUT)

    def topic(self, name: str):
        values = {"velocity": counts_to_rpm(self.velocity), "current": self.current_ma / 1000,
                  "status": self.status, "charge": self.charge_mas / 1000}
        if name not in values:
            raise ConfigError(f"no output {name!r}; the module reports {', '.join(values)}")
        return values[name]

    def summary(self) -> dict:
        return {"velocity_setpoint_rpm": counts_to_rpm(self.setpoint),
                "velocity_measured_rpm": counts_to_rpm(self.velocity),
                "current_a": self.current_ma / 1000, "charge_c": self.charge_mas / 1000,
                "faults": [n for n, bit in (("stall", P.ST_STALL), ("driver", P.ST_OVERCURRENT),
                                            ("request_error", P.ST_ERROR)) if self.status & bit]}

    # --- I2C (called from the TWI ISR, as Wire's callbacks are) -------------------------------------
    def receive_event(self, n: int) -> None:
        data = bytes(self.wire.read() for _ in range(n))
        if not data:
            return
        reg_addr, payload = data[0], data[1:]
        self.pointer = reg_addr
        if not payload:
            if reg_addr >= P.MAP_SIZE:
                self._fail(P.ERR_UNKNOWN_REGISTER)
            return
        reg = P.BY_ADDR.get(reg_addr)
        if reg is None:
            self._fail(P.ERR_UNKNOWN_REGISTER)
        elif not reg.writable:
            self._fail(P.ERR_READ_ONLY)
        elif len(payload) < reg.size:
            self._fail(P.ERR_SHORT_WRITE)
        else:
            self.write_register(reg.name, struct.unpack("<" + reg.fmt, payload[: reg.size])[0])

    def _fail(self, code: int) -> None:
        self.error = code
        self.status |= P.ST_ERROR

    def write_register(self, name: str, value) -> None:
        if name == "SETPOINT":
            self.setpoint = value
        elif name == "CONTROL":
            if value & P.CTL_CLEAR_FAULTS:
                self.status &= ~(P.ST_STALL | P.ST_OVERCURRENT | P.ST_ERROR)
                self.error = P.ERR_NONE
                self._stall_since = None
            if value & P.CTL_PID_ENABLE and not self.status & P.ST_STALL:
                self.pid.set_mode(AUTOMATIC)
                self.status |= P.ST_PID_ENABLED
            elif not value & P.CTL_PID_ENABLE:
                self.stop_motor()
        elif name in ("KP", "KI", "KD"):
            kp, ki, kd = self.pid.get_kp(), self.pid.get_ki(), self.pid.get_kd()
            kp, ki, kd = (value if name == "KP" else kp), (value if name == "KI" else ki), (value if name == "KD" else kd)
            self.pid.set_tunings(kp, ki, kd)

    def register_image(self) -> bytearray:
        img = bytearray(P.MAP_SIZE)
        values = {
            "WHO_AM_I": (P.WHO_AM_I_VALUE,), "VERSION": P.FW_VERSION, "STATUS": (self.status,),
            "CONTROL": (1 if self.status & P.ST_PID_ENABLED else 0,), "SETPOINT": (self.setpoint,),
            "POSITION": (self.encoder.read() & 0xFFFF,), "CURRENT": (max(-32768, min(32767, self.current_ma)),),
            "CHARGE": (min(int(self.charge_mas), 0xFFFFFFFF),), "KP": (float(self.pid.get_kp()),),
            "KI": (float(self.pid.get_ki()),), "KD": (float(self.pid.get_kd()),),
            "VELOCITY": (self.velocity,), "ERROR": (self.error,),
        }
        for reg in P.REGISTERS:
            img[reg.addr: reg.addr + reg.size] = struct.pack("<" + reg.fmt, *values[reg.name])
        return img

    def request_event(self) -> None:
        if self.pointer >= P.MAP_SIZE:
            self._fail(P.ERR_UNKNOWN_REGISTER)
            self.wire.write(b"\xff")
            return
        img = self.register_image()
        self.wire.write(bytes(img[self.pointer: self.pointer + 32]))
