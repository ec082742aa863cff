"""The registry of what a board profile may name: peripheral models, plant parts, firmware and cores.

A profile is data. It names a *kind* (``kind = "stm32-tim"``), never a Python object to import:
a profile from an untrusted source cannot make mcusim run code it does not already have. The
kinds are the project's own (the tables below) and those an installed package registers
explicitly through an entry point (groups ``mcusim.peripherals``, ``mcusim.parts``,
``mcusim.firmware``; see ``docs/boards.md``)::

    [project.entry-points."mcusim.parts"]
    my-motor = "my_package.plant:MyMotor"

Each kind declares the parameters a profile (or ``--set``) may give it, as
:class:`~mcusim.params.Param` (type, range or choices, unit): a registered class does so with a
``PARAMS`` mapping (and, for a part, ``TERMINALS = (required, optional)`` and ``REFS``, the
parameters that name other parts; for a peripheral, ``NEEDS``, a subset of ``("base", "clock")``).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field

from .errors import ConfigError
from .params import DurationParam, Param

GROUPS = {"peripheral": "mcusim.peripherals", "part": "mcusim.parts", "firmware": "mcusim.firmware"}


@dataclass
class Kind:
    """One registered kind: what it builds (``target``, a class or a built-in ``module:attr``), the
    parameters it takes, and for parts its terminals and references, for peripherals what it needs."""

    group: str
    name: str
    target: object
    params: dict = field(default_factory=dict)
    doc: str = ""
    terminals: tuple = ((), ())          # parts: (required, optional) digital terminals
    outputs: tuple | None = None         # parts: the terminals it drives (None: not declared)
    refs: tuple = ()                     # parts: parameters naming other parts
    ref_kinds: dict = field(default_factory=dict)   # parts: ref -> the part kinds it may name
    needs: tuple = ()                    # peripherals: "base", "clock"
    origin: str = "mcusim"
    open_params: bool = False            # a registered class without PARAMS: names not checked
    rules: tuple = ()                    # checks across parameters: rule(values) -> message or None
    _cls: object = None

    def check_rules(self, given: dict, who: str) -> None:
        """Checks across parameters, on the given values over the declared defaults."""
        values = {k: p.default for k, p in self.params.items()}
        values.update(given)
        values["_given"] = tuple(given)
        for rule in self.rules:
            msg = rule(values)
            if msg:
                raise ConfigError(f"{who}: {msg}")

    def load(self):
        """The class this kind builds (imported on first use)."""
        if self._cls is None:
            target = self.target
            if isinstance(target, str):        # a built-in: one of mcusim's own modules
                module, _, attr = target.partition(":")
                target = getattr(importlib.import_module(module), attr)
            self._cls = target
        return self._cls


def _num(default, **kw):
    return Param(float(default), **kw)


# --- peripherals ------------------------------------------------------------------------------------
_IRQ = Param(0, min=0, max=495, doc="interrupt number (NVIC IRQ or AVR vector)")
_VEC = Param(0, min=1, max=63, doc="AVR interrupt vector")


def _irq(default: int, what: str) -> Param:
    """An interrupt number a peripheral defaults to when the profile gives none (the class's own
    default: the chip's line for that peripheral)."""
    return Param(default, min=0, max=495, doc=f"NVIC interrupt line ({what})")


def _vec(default: int, what: str) -> Param:
    return Param(default, min=1, max=63, doc=f"AVR interrupt vector ({what})")


class _Table(Param):
    """A table of named integers (``irqs = { update = 25, cc = 27 }``) or of analog-net names
    (``inputs = { 0 = "A0" }``)."""

    def __init__(self, keys, item: Param, *, doc="", any_int_keys: range | None = None):
        super().__init__({}, kind=dict, doc=doc)
        self.keys, self.item, self.any_int_keys = tuple(keys), item, any_int_keys

    def range_text(self) -> str:
        if self.any_int_keys is not None:
            r = self.any_int_keys
            return f"keys {r.start} to {r.stop - 1}"
        return "keys " + ", ".join(self.keys)

    def check(self, value, what):
        if not isinstance(value, dict):
            raise ConfigError(f"{what} = {value!r}: expected a table {{ {', '.join(self.keys) or '0 = ...'} }}"[:200])
        out = {}
        for k, v in value.items():
            if self.any_int_keys is not None:
                try:
                    ik = int(k)
                except (TypeError, ValueError):
                    ik = None
                if ik is None or ik not in self.any_int_keys:
                    raise ConfigError(f"{what}: key {k!r}: expected a channel number from "
                                      f"{self.any_int_keys.start} to {self.any_int_keys.stop - 1}")
                out[ik] = self.item.check(v, f"{what}.{k}")
            else:
                if k not in self.keys:
                    raise ConfigError(f"{what}: unknown key {k!r} (known: {', '.join(self.keys)})")
                out[k] = self.item.check(v, f"{what}.{k}")
        return out

    def check_file(self, value, what):
        if isinstance(value, dict):
            for k, v in value.items():
                self.item.check_file(v, f"{what}.{k}")
        return self.check(value, what)

    def describe(self) -> str:
        return f"table, {self.range_text()}" + (f": {self.doc}" if self.doc else "")


_NET = Param("A0", doc="analog net name")
_PORT = Param("A", choices=tuple("ABCDEFGHIJK"), doc="port letter")
_BUSNAME = Param("i2c0", doc="I2C bus name (boards of a system share buses by name)")
_BASE_CLOCK = Param("", doc="the CGU base clock feeding it (BASE_APB3_CLK for ADC0/1, BASE_APB1_CLK for "
                    "I2C0, BASE_UARTn_CLK for USARTn): checked to give `clock` each time it runs; "
                    "empty: not checked")


def _P(**params):
    return params


PERIPHERALS = {k.name: k for k in (
    Kind("peripheral", "stm32-rcc", "mcusim.periph.stm32.rcc:Rcc", {},
         "STM32F7 reset and clock control: CR/PLLCFGR as the board's clock set-up leaves them (the PLL "
         "may be reprogrammed only to `sysclk`), the APB prescalers and TIMPRE (the timers' kernel clocks "
         "follow at once; HPRE other than /1 is refused), the clock enable registers (stored, not gating)",
         needs=("base",)),
    Kind("peripheral", "stm32-flash", "mcusim.periph.stm32.sysctl:Flash", {},
         "STM32F7 flash interface: ACR (wait states, ART), as start-up code writes it", needs=("base",)),
    Kind("peripheral", "stm32-pwr", "mcusim.periph.stm32.sysctl:Pwr", {},
         "STM32F7 power controller: CR1/CSR1 (regulator scale, over-drive and their ready flags)", needs=("base",)),
    Kind("peripheral", "stm32-dbgmcu", "mcusim.periph.stm32.sysctl:DbgMcu", {},
         "STM32F7 debug MCU registers: IDCODE (device and revision), CR and the APB freeze bits, stored",
         needs=("base",)),
    Kind("peripheral", "stm32-devid", "mcusim.periph.stm32.sysctl:DeviceId", _P(
        uid=Param((0x0020001F, 0x3236510E, 0x33363138), length=3, items=Param(0, min=0, max=0xFFFFFFFF),
                  doc="the 96-bit unique ID, UID0-UID2"),
        flash_kb=Param(1024, min=1, max=0xFFFF, doc="flash size in Kbytes")),
         "STM32F7 device electronic signature: unique ID and flash size (read only)", needs=("base",)),
    Kind("peripheral", "stm32-tim", "mcusim.periph.stm32.tim:Tim", _P(
        irqs=_Table(("brk", "update", "trg_com", "cc"), _IRQ, doc="NVIC lines of the timer's events"),
        counter_bits=Param(16, choices=(16, 32), doc="counter width"),
        advanced=Param(False, doc="TIM1/TIM8: RCR and BDTR.MOE (no complementary outputs, dead time or break)"),
        arr_reset=Param(0, min=0, max=0xFFFFFFFF, doc="ARR after reset")),
        "STM32 general-purpose and advanced timer", needs=("base", "clock")),
    Kind("peripheral", "stm32-gpio", "mcusim.periph.stm32.gpio:Gpio", _P(port=_PORT),
         "STM32 GPIO port (16 pins P<port>0..15)", needs=("base",)),
    Kind("peripheral", "lpc43xx-adc", "mcusim.periph.lpc43xx.adc:Adc", _P(
        irq=_irq(17, "ADC0"), inputs=_Table((), _NET, any_int_keys=range(8), doc="analog net of each channel"),
        vref=_num(3.3, min=2.7, max=3.6, unit="V", doc="VDDA"),
        strict=Param(False, doc="specification limits are errors"), base_clock=_BASE_CLOCK),
        "LPC4337 10-bit ADC", needs=("base", "clock")),
    Kind("peripheral", "lpc43xx-i2c", "mcusim.periph.lpc43xx.i2c:I2c", _P(irq=_irq(18, "I2C0"), bus=_BUSNAME,
                                                                           base_clock=_BASE_CLOCK),
         "LPC4337 I2C master", needs=("base", "clock")),
    Kind("peripheral", "lpc43xx-gpio", "mcusim.periph.lpc43xx.gpio:Gpio", _P(
        ports=Param(8, min=1, max=8), pins_per_port=Param(32, min=1, max=32)),
        "LPC4337 GPIO port block (pins GPIO<port>_<n>)", needs=("base",)),
    Kind("peripheral", "lpc43xx-usart", "mcusim.periph.lpc43xx.uart:Usart", _P(irq=Param(
        0, min=0, max=495, required=True, doc="NVIC interrupt line: 24 USART0, 25 UART1, 26 USART2, 27 USART3"),
        base_clock=_BASE_CLOCK), "LPC4337 USART", needs=("base", "clock")),
    Kind("peripheral", "lpc43xx-cgu", "mcusim.periph.lpc43xx.cgu:Cgu", _P(
        xtal_hz=Param(12_000_000, min=1_000_000, max=25_000_000, unit="Hz", doc="crystal on XTAL1/XTAL2")),
        "LPC43xx clock generation unit: crystal, PLL0USB/PLL0AUDIO, PLL1 and LOCK, dividers, base "
        "clocks; BASE_M4_CLK and PLL1 held to the board's core clock", needs=("base",)),
    Kind("peripheral", "lpc43xx-ccu1", "mcusim.periph.lpc43xx.cgu:Ccu1", {},
         "LPC43xx clock control unit 1: branch clock CFG/STAT (STAT follows CFG), PM, BASE_STAT; not gating",
         needs=("base",)),
    Kind("peripheral", "lpc43xx-ccu2", "mcusim.periph.lpc43xx.cgu:Ccu2", {},
         "LPC43xx clock control unit 2 (UART, SSP, SDIO, audio branch clocks), as CCU1", needs=("base",)),
    Kind("peripheral", "lpc43xx-scu", "mcusim.periph.lpc43xx.scu:Scu", {},
         "LPC43xx system control unit: pin configuration registers, stored (pin functions not modelled)",
         needs=("base",)),
    Kind("peripheral", "lpc43xx-creg", "mcusim.periph.lpc43xx.scu:Creg", {},
         "LPC43xx configuration registers: CHIPID, M4MEMMAP held to the board's boot shadow, the rest stored",
         needs=("base",)),
    Kind("peripheral", "lpc43xx-rgu", "mcusim.periph.lpc43xx.rgu:Rgu", {},
         "LPC43xx reset generation unit: a peripheral reset completes at once; resets the GPIO, ADC, SCU "
         "and CREG models, refuses the others it cannot do", needs=("base",)),
    Kind("peripheral", "avr-cpu", "mcusim.periph.avr.cpu:AvrCpuRegs", {},
         "ATmega328P SREG (its I flag is the global interrupt enable)"),
    Kind("peripheral", "avr-port", "mcusim.periph.avr.port:AvrPort", _P(
        port=Param("B", choices=("B", "C", "D")), pins=Param(8, min=1, max=8, doc="pins bonded out")),
        "ATmega328P I/O port (PINx, DDRx, PORTx)", needs=("base",)),
    Kind("peripheral", "avr-extint", "mcusim.periph.avr.extint:ExtInt", _P(
        pins=Param(("PD2", "PD3"), length=2, items=Param("PD2"), doc="INT0, INT1 pins"),
        vectors=Param((1, 2), length=2, items=_VEC)),
        "ATmega328P external interrupts INT0/INT1", needs=("clock",)),
    Kind("peripheral", "avr-timer0", "mcusim.periph.avr.timer0:Timer0", _P(
        vectors=_Table(("compa", "compb", "ovf"), _VEC)), "ATmega328P Timer/Counter0", needs=("clock",)),
    Kind("peripheral", "avr-timer1", "mcusim.periph.avr.timer1:Timer1", _P(
        vectors=_Table(("capt", "compa", "compb", "ovf"), _VEC),
        icp=Param("PB0", doc="the input capture pin ICP1 (empty: none)")), "ATmega328P Timer/Counter1",
        needs=("clock",)),
    Kind("peripheral", "avr-adc", "mcusim.periph.avr.adc:Adc", _P(
        inputs=_Table((), _NET, any_int_keys=range(8), doc="analog net of each channel"),
        avcc=_num(5.0, min=1.8, max=5.5, unit="V"), vector=_vec(21, "ADC conversion complete"),
        # none by default, as the model's (the Pro Mini's AREF pin carries only a capacitor): with
        # a voltage on it the datasheet forbids the internal references (ADMUX.REFS = 01, 11)
        aref=Param(None, kind=float, above=0, max=5.5, unit="V",
                   doc="external reference voltage on AREF (none: REFS = 00 is refused; with one, REFS = 01 and 11 are)")),
        "ATmega328P 10-bit ADC", needs=("clock",)),
    Kind("peripheral", "avr-twi", "mcusim.periph.avr.twi:Twi", _P(bus=_BUSNAME, vector=_vec(24, "TWI")),
         "ATmega328P TWI (I2C slave)", needs=("clock",)),
)}

# --- plant parts ------------------------------------------------------------------------------------
_OHM = {"unit": "Ω"}


def _motor_params():
    from .plant.presets import MOTOR_PRESETS
    return _P(
        preset=Param("", choices=tuple(sorted(MOTOR_PRESETS)), doc="named parameter set"),
        R=_num(2.18, min=1e-3, max=1e3, **_OHM, doc="armature resistance"),
        L=_num(1.5e-3, min=1e-6, max=1.0, unit="H", doc="armature inductance"),
        K=_num(0.011, min=1e-4, max=10.0, unit="V·s/rad", doc="back-EMF and torque constant"),
        J=_num(5e-6, min=1e-9, max=10.0, unit="kg·m²", doc="rotor inertia (motor shaft)"),
        tau_c=_num(1.54e-3, min=0, max=100.0, unit="N·m", doc="Coulomb friction (motor shaft)"),
        b=_num(6.3e-7, min=0, max=10.0, unit="N·m·s/rad", doc="viscous friction (motor shaft)"),
        tau_s=_num(5e-3, min=0, max=100.0, unit="N·m", doc="stiction, at least tau_c (motor shaft)"),
        gear_ratio=_num(30.0, min=0.01, max=1e5, doc="motor turns per output turn"),
        efficiency=_num(0.78, above=0, max=1.0, doc="gearbox efficiency"),
        load_inertia=_num(0.0, min=0, max=1e4, unit="kg·m²", doc="on the output shaft"),
        load_torque=_num(0.0, min=-1e3, max=1e3, unit="N·m", doc="on the output shaft, against positive rotation"),
        current=_num(0.0, min=-1e3, max=1e3, unit="A", doc="initial current"),
        speed=_num(0.0, min=-1e4, max=1e4, unit="rad/s", doc="initial motor-shaft speed"),
        angle=_num(0.0, min=-1e6, max=1e6, unit="rad", doc="initial motor-shaft angle"),
        horizon=_num(50e-6, min=1e-6, max=1e-2, unit="s", doc="first step of the event search"),
        max_horizon=_num(5e-3, min=1e-6, max=1.0, unit="s", doc="longest step of the event search"),
    )


def _motor_rule(values: dict):
    """Stiction at least Coulomb friction, on the preset's values under the given ones."""
    from .plant.presets import motor_preset
    merged = dict(values)
    if values.get("preset"):
        base = motor_preset(values["preset"])
        merged = {**merged, **{k: v for k, v in base.items() if k not in values.get("_given", ())}}
    if merged["tau_s"] < merged["tau_c"]:
        return f"tau_s = {merged['tau_s']:g} N·m (stiction) must be at least tau_c = {merged['tau_c']:g} N·m"
    return None


_BRIDGE_COMMON = _P(
    Vs=_num(12.0, min=0, max=60.0, unit="V", doc="supply"),
    R_HS=_num(0.34, min=0, max=100.0, **_OHM, doc="high-side on resistance"),
    R_LS=_num(0.28, min=0, max=100.0, **_OHM, doc="low-side on resistance"),
    V_D=_num(0.75, min=0, max=5.0, unit="V", doc="diode forward voltage"),
    r_D=_num(0.14, min=0, max=100.0, **_OHM, doc="diode slope"),
)

PARTS = {k.name: k for k in (
    Kind("part", "dcmotor", "mcusim.plant.dcmotor:DcMotor", {}, "brushed DC motor with gearbox and load",
         rules=(lambda v: _motor_rule(v),)),
    Kind("part", "l6206", "mcusim.plant.l6206:L6206Bridge", {**_BRIDGE_COMMON, **_P(
        I_ocd=_num(5.6, above=0, max=100.0, unit="A", doc="over-current threshold"),
        R_EN=_num(100e3, above=0, max=1e9, **_OHM, doc="EN recharge resistor"),
        C_EN=_num(5.6e-9, above=0, max=1e-3, unit="F", doc="EN capacitor"),
        V_pullup=_num(3.3, above=0, max=5.5, unit="V", doc="EN pull-up supply"),
        V_th=_num(1.8, above=0, max=5.5, unit="V", doc="EN threshold, below V_pullup"),
        drive_en=Param(False, doc="the bridge drives EN low on over-current"))},
        "one full bridge of an ST L6206", terminals=(("IN1", "IN2", "EN"), ()), outputs=("EN",), refs=("motor",),
        ref_kinds={"motor": ("dcmotor",)},
        rules=(lambda v: None if v["V_th"] < v["V_pullup"] else
               f"V_th = {v['V_th']:g} V must be below V_pullup = {v['V_pullup']:g} V",)),
    Kind("part", "bts7960", "mcusim.plant.bts7960:Bts7960Bridge", {**_BRIDGE_COMMON, **_P(
        Vs=_num(12.0, min=0, max=40.0, unit="V", doc="supply"),
        R_HS=_num(7e-3, min=0, max=10.0, **_OHM), R_LS=_num(9e-3, min=0, max=10.0, **_OHM),
        V_D=_num(0.8, min=0, max=5.0, unit="V"), r_D=_num(0.0, min=0, max=10.0, **_OHM),
        I_CLH=_num(60.0, above=0, max=1000.0, unit="A", doc="high-side current limit"),
        I_CLL=_num(43.0, above=0, max=1000.0, unit="A", doc="low-side current limit"),
        t_CLS=_num(115e-6, above=0, max=1.0, unit="s", doc="current-limit shut-off time"),
        k_ILIS=_num(8500.0, above=0, max=1e6, doc="current-sense ratio"),
        R_IS=_num(1000.0, above=0, max=1e7, **_OHM, doc="IS resistor"),
        I_IS_lim=_num(4.5e-3, min=0, max=0.1, unit="A", doc="IS fault current"),
        I_ISL=_num(0.0, min=0, max=0.01, unit="A"), I_ISH=_num(0.0, min=0, max=0.01, unit="A"),
        Vcc=_num(5.0, above=0, max=5.5, unit="V", doc="logic supply (IS clamp)"),
        cl_action=Param("other", choices=("other", "off"), doc="current limit: switch to the other side or off"))},
        "IBT-2: two Infineon BTS7960 half bridges", terminals=(("RPWM", "LPWM"), ("R_EN", "L_EN")),
        outputs=(), refs=("motor",), ref_kinds={"motor": ("dcmotor",)}),
    Kind("part", "encoder", "mcusim.plant.encoder:QuadratureEncoder", _P(
        counts_per_rev=Param(64, min=1, max=100_000, unit="counts per motor turn",
                             doc="quadrature counts (4 per line of the disc)")),
        "quadrature encoder on the motor shaft", terminals=(("A", "B"), ()), outputs=("A", "B"), refs=("motor",),
        ref_kinds={"motor": ("dcmotor",)}),
    Kind("part", "battery", "mcusim.plant.parts:BatteryPart", _P(
        count=Param(2, min=1, max=8, doc="12 V batteries in parallel"),
        soc=_num(1.0, min=0, max=1.0, doc="state of charge"),
        capacity_ah=_num(9.0, above=0, max=1000.0, unit="Ah"),
        r0=_num(0.020, min=0, max=1.0, **_OHM), r1=_num(0.015, min=0, max=1.0, **_OHM),
        tau1=_num(60.0, above=0, max=1e5, unit="s"),
        ocv_empty=_num(11.65, above=0, max=100.0, unit="V"), ocv_full=_num(12.75, above=0, max=100.0, unit="V"),
        peukert_k=_num(1.15, min=1.0, max=2.0), wiring_r=_num(0.010, min=0, max=1.0, **_OHM),
        step=DurationParam("1ms", min=1e-6, max=1.0, doc="update step")),
        "bank of 12 V sealed lead-acid batteries", refs=("loads",), ref_kinds={"loads": ("bts7960",)},
        rules=(lambda v: None if v["ocv_full"] > v["ocv_empty"] else
               f"ocv_full = {v['ocv_full']:g} V must be above ocv_empty = {v['ocv_empty']:g} V",)),
    Kind("part", "divider", "mcusim.plant.parts:DividerPart", _P(
        r_top=_num(33e3, above=0, max=1e9, **_OHM), r_bottom=_num(6.8e3, above=0, max=1e9, **_OHM)),
        "resistor divider from a part's voltage", refs=("source",)),
    Kind("part", "rover-body", "mcusim.plant.parts:RoverBodyPart", _P(
        sides=Param(("L", "R"), length=range(2, 9), items=Param("L", choices=("L", "R"))),
        directions=Param((1, 1), length=range(2, 9), items=Param(1, choices=(1, -1))),
        wheel_diameter=_num(0.39, above=0, max=10.0, unit="m"), track=_num(0.55, above=0, max=100.0, unit="m"),
        wheelbase=_num(0.45, above=0, max=100.0, unit="m"), mass=_num(50.0, above=0, max=1e5, unit="kg"),
        wheel_mass=_num(2.0, min=0, max=1e4, unit="kg"), yaw_inertia=Param(
            None, kind=float, above=0, max=1e6, unit="kg·m²",
            doc="the rigid body's yaw inertia, a reference only: reported against the inertia the model's "
                "yaw dynamics have (the mass split over the wheels) as yaw_inertia_ratio, docs/plants.md "
                "§1.5; none: m·(wheelbase² + track²)/12"),
        chi=_num(1.5, min=1.0, max=10.0), mu_turn=_num(0.5, min=0, max=10.0), crr=_num(0.03, min=0, max=1.0),
        step=DurationParam("1ms", min=1e-6, max=1.0),
        yaw_rate_eps=_num(0.05, above=0, max=10.0, unit="rad/s"), speed_eps=_num(0.01, above=0, max=10.0, unit="m/s"),
        x=_num(0.0, min=-1e6, max=1e6, unit="m"), y=_num(0.0, min=-1e6, max=1e6, unit="m"),
        yaw=_num(0.0, min=-1e3, max=1e3, unit="rad")),
        "skid-steer or differential rover body on its wheel motors", refs=("motors",),
        ref_kinds={"motors": ("dcmotor",)}),
    Kind("part", "estop", "mcusim.plant.parts:EStopPart", {}, "E-stop button cutting the motor-enable line",
         terminals=(("ENABLE_IN",), ("ENABLE_OUT", "SENSE")), outputs=("ENABLE_OUT", "SENSE")),
)}

# --- firmware ---------------------------------------------------------------------------------------
FIRMWARE = {k.name: k for k in (
    Kind("firmware", "controlmotor", "mcusim.fw.controlmotor.app:ControlMotorFirmware", {},
         "the ControlMotorROS thesis firmware (STM32F746)"),
    Kind("firmware", "openrover-mcm", "mcusim.fw.openrover_mcm.sketch:OpenRoverMcm", {},
         "the OpenRover motor-controller module sketch (ATmega328P)"),
    Kind("firmware", "openrover-rcm", "mcusim.fw.openrover_rcm.app:RoverControl", {},
         "the OpenRover robot controller rover_control (LPC4337)"),
)}

CORES = ("cortex-m4", "cortex-m7", "avr")
_BUILTIN = {"peripheral": PERIPHERALS, "part": PARTS, "firmware": FIRMWARE}
_registered: dict = {}


def _entry_points(group: str) -> dict:
    """Kinds registered by installed packages (entry points), loaded on first use."""
    if group not in _registered:
        from importlib.metadata import entry_points
        found = {}
        for ep in entry_points(group=GROUPS[group]):
            if ep.name in _BUILTIN[group]:
                continue                      # the project's own kinds cannot be replaced
            found[ep.name] = Kind(group, ep.name, ep, origin=f"entry point {ep.value}")
        _registered[group] = found
    return _registered[group]


def builtin_part_kinds() -> dict:
    """mcusim's own part kinds: name -> class (for the kind checks of part references)."""
    return {name: kind.load() for name, kind in PARTS.items()}


def register(group: str, name: str, cls, **declared) -> Kind:
    """Register a kind from Python (tests, notebooks): the same as an entry point."""
    if group not in _BUILTIN:
        raise ConfigError(f"no group {group!r} (groups: {', '.join(_BUILTIN)})")
    if name in _BUILTIN[group]:
        raise ConfigError(f"{group} kind {name!r} is one of mcusim's own and cannot be replaced")
    kind = Kind(group, name, cls, origin="registered")
    _declare(kind, cls)
    kind.__dict__.update(declared)
    _entry_points(group)[name] = kind
    return kind


def _declare(kind: Kind, cls) -> None:
    """Take a registered class's declarations (PARAMS, TERMINALS, OUTPUTS, REFS, NEEDS)."""
    if not isinstance(cls, type):
        raise ConfigError(f"{kind.group} kind {kind.name!r} ({kind.origin}) is not a class")
    params = getattr(cls, "PARAMS", None)
    kind.open_params = params is None
    kind.params = dict(params or {})
    kind.terminals = tuple(tuple(t) for t in getattr(cls, "TERMINALS", ((), ())))
    kind.refs = tuple(getattr(cls, "REFS", ()))
    outputs = getattr(cls, "OUTPUTS", None)
    kind.outputs = None if outputs is None else tuple(outputs)
    kind.needs = tuple(getattr(cls, "NEEDS", ()))
    kind.doc = (cls.__doc__ or "").strip().split("\n")[0]
    kind._cls = cls


def lookup(group: str, name, where: str) -> Kind:
    """The kind ``name`` of ``group`` ("peripheral", "part", "firmware"), or ConfigError listing
    the known ones."""
    if not isinstance(name, str) or not name:
        raise ConfigError(f"{where}: kind = {name!r}: expected the name of a {group} kind "
                          f"({', '.join(known(group))})")
    kind = _BUILTIN[group].get(name)
    if kind is None:
        kind = _entry_points(group).get(name)
        if kind is None:
            raise ConfigError(f"{where}: unknown {group} kind {name!r} (kinds: {', '.join(known(group))})")
        if kind._cls is None:
            try:
                cls = kind.target.load()
            except Exception as exc:  # noqa: BLE001 (a broken plug-in, whatever it raises: one line naming it)
                raise ConfigError(f"{where}: {group} kind {name!r} ({kind.origin}) cannot be loaded: "
                                  f"{type(exc).__name__}: {exc}") from None
            _declare(kind, cls)
    elif name == "dcmotor" and not kind.params:
        kind.params = _motor_params()
    return kind


def known(group: str) -> list[str]:
    return list(_BUILTIN[group]) + sorted(_entry_points(group))


def all_kinds(group: str) -> list[Kind]:
    return [lookup(group, n, "mcusim") if n == "dcmotor" else (_BUILTIN[group].get(n) or _entry_points(group)[n])
            for n in known(group)]


def reference(group: str) -> str:
    """Markdown tables of every kind of ``group`` and its parameters (``docs/boards.md`` holds the
    project's own; ``mcusim boards --kinds`` prints them with the registered ones)."""
    from .params import Param
    out = []
    for kind in all_kinds(group):
        head = f"#### `{kind.name}`" + (f" ({kind.origin})" if kind.origin != "mcusim" else "")
        out += [head, "", (kind.doc[:1].upper() + kind.doc[1:] or "(undocumented)") + "."]
        extra = []
        if kind.needs:
            extra.append("needs " + " and ".join(f"`{n}`" for n in kind.needs))
        if group == "part":
            req, opt = kind.terminals
            if req or opt:
                extra.append("terminals " + ", ".join([f"`{t}`" for t in req] + [f"`{t}` (optional)" for t in opt]))
            if kind.refs:
                extra.append("names other parts with " + ", ".join(
                    f"`{r}`" + (f" ({' or '.join(kind.ref_kinds[r])})" if r in kind.ref_kinds else "")
                    for r in kind.refs))
        if extra:
            text = "; ".join(extra)
            out[-1] += " " + text[:1].upper() + text[1:] + "."
        params = kind.params
        if group == "firmware":
            params = getattr(kind.load(), "PARAMS", None) or {}
        if params:
            out += ["", "| key | type, default, range: meaning |", "|---|---|"]
            for name, p in params.items():
                p = p if isinstance(p, Param) else Param(p)
                out.append(f"| `{name}` | {p.describe().replace('|', '/')} |")
        elif kind.open_params:
            out += ["", "Its parameters are not declared (no `PARAMS`): they are passed unchecked."]
        inputs = getattr(kind.load(), "INPUTS", None) if group == "firmware" else None
        if inputs:      # what a host gives the firmware (--set NAME=VALUE), with the checked ranges
            out += ["", "Inputs a host gives it (`--set NAME=VALUE`):", "",
                    "| input | type, default, range: meaning |", "|---|---|"]
            for name, p in inputs.items():
                out.append(f"| `{name}` | {p.describe().replace('|', '/')} |")
        out.append("")
    return "\n".join(out)
