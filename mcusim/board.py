"""Board profiles: read a TOML profile, apply ``--set`` overrides, build the system.

The kernel knows no vendor: peripheral and firmware classes are named in the profile as
``"module:Class"`` and imported here by name; plant parts by ``kind``.
"""

from __future__ import annotations

import importlib
import importlib.resources
import tomllib
from fractions import Fraction
from pathlib import Path

from .errors import ConfigError
from .firmware import Cpu, Rtos
from .irq import AvrInterrupts, Nvic, Scb
from .kernel import Kernel
from .mcu import Mcu
from .registers import Bus
from .time import TimeBase, parse_frequency

PART_KINDS = {
    "dcmotor": "mcusim.plant.dcmotor:DcMotor",
    "l6206": "mcusim.plant.l6206:L6206Bridge",
    "bts7960": "mcusim.plant.bts7960:Bts7960Bridge",
    "encoder": "mcusim.plant.encoder:QuadratureEncoder",
    "battery": "mcusim.plant.parts:BatteryPart",
    "divider": "mcusim.plant.parts:DividerPart",
    "rover-body": "mcusim.plant.parts:RoverBodyPart",
    "estop": "mcusim.plant.parts:EStopPart",
}
# digital terminals wired through [pins]: (required, optional)
PART_TERMINALS = {"l6206": (("IN1", "IN2", "EN"), ()), "bts7960": (("RPWM", "LPWM"), ("R_EN", "L_EN")),
                  "encoder": (("A", "B"), ()), "dcmotor": ((), ()), "battery": ((), ()), "divider": ((), ()),
                  "rover-body": ((), ()), "estop": (("ENABLE_IN",), ("ENABLE_OUT", "SENSE"))}
# part parameters that name other parts (resolved to the part objects): one name or a list
PART_REFS = {"motor": "motor", "source": "source", "loads": "loads", "motors": "motors"}


def board_names() -> list[str]:
    files = importlib.resources.files("boards")
    return sorted(p.name[:-5] for p in files.iterdir() if p.name.endswith(".toml"))


def read_profile(board: str) -> tuple[dict, str]:
    """The parsed profile of a board name (``nucleo-f746``) or a path to a .toml file."""
    path = Path(board)
    if path.suffix == ".toml" and path.exists():
        text, where = path.read_text(), str(path)
    else:
        res = importlib.resources.files("boards") / f"{board}.toml"
        if not res.is_file():
            raise ConfigError(f"unknown board {board!r}; known boards: {', '.join(board_names())}")
        text, where = res.read_text(), f"boards/{board}.toml"
    try:
        return tomllib.loads(text), where
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{where}: {exc}") from None


def _import(spec: str, where: str):
    try:
        module, _, name = spec.partition(":")
        return getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError, ValueError) as exc:
        raise ConfigError(f"{where}: cannot load {spec!r}: {exc}") from None


def parse_value(text: str):
    """A ``--set`` value: true/false, an int, a float, else the string itself."""
    low = text.strip().lower()
    if low in ("true", "on", "yes"):
        return True
    if low in ("false", "off", "no"):
        return False
    for conv in (int, float):
        try:
            return conv(text)
        except ValueError:
            pass
    return text


def _firmware_inputs(profile: dict) -> set:
    """The names in the firmware module's ``HOST_INPUTS`` (inputs a host can give it)."""
    spec = profile.get("firmware", {}).get("class", "")
    try:
        module = importlib.import_module(spec.partition(":")[0]) if spec else None
    except ImportError:
        return set()
    return set(getattr(module, "HOST_INPUTS", {}))


def split_overrides(profile: dict, overrides: dict) -> tuple[dict, dict, list]:
    """Sort ``--set`` keys into part parameters, firmware parameters and topic messages."""
    parts = {p["name"]: {} for p in profile.get("part", [])}
    firmware, topics = {}, []
    for key, value in overrides.items():
        if key.startswith("/") or "." not in key:  # a topic or a firmware input (velocity=10)
            topics.append((key, value))
            continue
        if key in _firmware_inputs(profile):       # a dotted firmware input (cmd_vel.linear)
            topics.append((key, value))
            continue
        head, dot, name = key.partition(".")
        if not dot or not name:
            raise ConfigError(f"--set {key}: expected a topic (/motor1/set_pos) or part.parameter (motor1.J)")
        if head == "firmware":
            firmware[name] = value
        elif head in parts:
            parts[head][name] = value
        else:
            inputs = sorted(_firmware_inputs(profile))
            raise ConfigError(f"--set {key}: no part {head!r}; parts: {', '.join(parts)}, firmware"
                              + (f"; firmware inputs: {', '.join(inputs)}" if inputs else ""))
    return parts, firmware, topics


def board_clocks(profile: dict) -> list:
    """The clock frequencies a board needs in the time base (its [clocks] ``base`` list)."""
    clocks = profile.get("clocks", {})
    if "sysclk" not in clocks:
        return []
    return [parse_frequency(f) for f in clocks.get("base", [clocks["sysclk"]])]


def _resolve_peripheral_refs(spec, mcu, kernel, buses, where):
    """Peripheral parameters that name shared objects: ``inputs = {0 = "A0"}`` (analog nets of the
    MCU) and ``bus = "i2c0"`` (a bus shared by every MCU of the system)."""
    from .i2c import I2cBus
    from .signals import AnalogNet
    out = {}
    if "inputs" in spec:
        nets = {}
        for ch, net_name in spec["inputs"].items():
            net = mcu.analog.setdefault(net_name, AnalogNet(net_name))
            nets[int(ch)] = net
        out["inputs"] = nets
    if "bus" in spec:
        name = spec["bus"]
        if name not in buses:
            buses[name] = I2cBus(kernel, name)
        out["bus"] = buses[name]
    return out


def build_parts(kernel, specs: list, part_overrides: dict, wiring: dict, where: str,
                lookup=None) -> dict:
    """Instantiate plant parts in declaration order. ``wiring[part][TERMINAL]`` is the Net of each
    digital terminal; parameters in :data:`PART_REFS` name other parts, resolved among the parts
    built so far or by ``lookup(name)`` (a system's parts of its boards: ``"mcm1.motor"``)."""
    parts: dict = {}

    def ref(name, who):
        if name in parts:
            return parts[name]
        found = lookup(name) if lookup is not None else None
        if found is None:
            raise ConfigError(f"{where}: part {who}: no part {name!r} declared before it")
        return found

    for spec in specs:
        name, kind = spec["name"], spec.get("kind")
        if kind not in PART_KINDS:
            raise ConfigError(f"{where}: part {name}: unknown kind {kind!r} (kinds: {', '.join(PART_KINDS)})")
        cls = _import(PART_KINDS[kind], f"{where}: part {name}")
        params = {k: v for k, v in spec.items() if k not in ("name", "kind") and k not in PART_REFS}
        params.update(part_overrides.get(name, {}))
        args = {}
        for key in PART_REFS:
            if key in spec:
                v = spec[key]
                args[key] = [ref(x, name) for x in v] if isinstance(v, list) else ref(v, name)
        required, optional = PART_TERMINALS[kind]
        unknown = set(wiring.get(name, {})) - set(required + optional)
        if unknown:
            raise ConfigError(f"{where}: part {name} ({kind}) has no terminal {', '.join(sorted(unknown))}; "
                              f"terminals: {', '.join(required + optional) or 'none'}")
        for term in required + optional:
            net = wiring.get(name, {}).get(term)
            if net is None:
                if term in optional:
                    continue
                raise ConfigError(f"{where}: part {name}: terminal {term} is not wired in [pins]")
            args[term.lower()] = net
        try:
            parts[name] = cls(kernel, name=name, **args, **params)
        except TypeError as exc:
            raise ConfigError(f"{where}: part {name}: {exc}") from None
    for part in wiring:
        if part not in parts:
            raise ConfigError(f"{where}: [pins] names part {part!r}, which is not declared")
    return parts


def build(profile: dict, where: str, part_overrides: dict, with_firmware: bool, firmware_params: dict,
          buses: dict | None = None, kernel: Kernel | None = None, external: dict | None = None,
          engine: str = "reference"):
    """Instantiate kernel, MCU, peripherals, plant and (optionally) firmware. Returns a namespace dict.

    A system (:mod:`mcusim.system`) builds several boards on one ``kernel`` (whose time base must
    contain every board's clocks), shares I2C ``buses`` by name, and hands in ``external`` nets
    for part terminals the board leaves open (``{"ibt2": {"R_EN": net}}``: the rover's
    motor-enable line)."""
    try:
        board = profile["board"]
        clocks = profile["clocks"]
        core = profile["core"]
    except KeyError as exc:
        raise ConfigError(f"{where}: missing table [{exc.args[0]}]") from None
    sysclk = parse_frequency(clocks["sysclk"])
    if kernel is None:
        kernel = Kernel(TimeBase(board_clocks(profile)), engine)
    timebase = kernel.timebase
    buses = {} if buses is None else buses
    bus = Bus(f"{board['name']}.bus")
    mcu = Mcu(board["mcu"], kernel, bus, timebase.clock("SYSCLK", sysclk))
    mcu.clocks["SYSCLK"] = mcu.core_clock

    avr = core.get("kind", "").startswith("avr")
    if avr:
        irq = AvrInterrupts(num_vectors=core.get("vectors", 26))
    else:
        irq = Nvic(num_irqs=core.get("nvic_irqs", 98), prio_bits=core.get("nvic_prio_bits", 4))
        bus.attach(0xE000E100, irq)
        bus.attach(0xE000ED00, Scb(irq))
    mcu.nvic = mcu.irq = irq
    for spec in profile.get("peripheral", []):
        cls = _import(spec["class"], f"{where}: peripheral {spec.get('name')}")
        kwargs = {k: v for k, v in spec.items() if k not in ("name", "class", "base", "clock", "outputs")}
        kwargs.update(_resolve_peripheral_refs(spec, mcu, kernel, buses, where))
        if spec["class"].endswith(":Rcc"):
            kwargs["sysclk_hz"] = sysclk
        if "clock" in spec:
            if spec["clock"] not in mcu.clocks:
                raise ConfigError(f"{where}: peripheral {spec['name']}: no clock {spec['clock']!r} "
                                  f"(clocks: {', '.join(mcu.clocks)})")
            kwargs["clock"] = mcu.clocks[spec["clock"]]
        try:
            p = cls(spec["name"], mcu, **kwargs)
        except TypeError as exc:
            raise ConfigError(f"{where}: peripheral {spec['name']}: {exc}") from None
        mcu.periph[spec["name"]] = p
        if p.BUS_WIDTH == 1:
            bus.attach_registers(spec.get("base", 0), p)  # AVR: registers scattered in data space
        else:
            bus.attach(spec["base"], p)
        if "clock" in spec:
            mcu.clock_users.setdefault(spec["clock"], []).append(p)
    # [pull]: board-level pull resistors on pins (an active-low button's pull-up)
    for pin_name, level in profile.get("pull", {}).items():
        if level not in (0, 1):
            raise ConfigError(f"{where}: [pull] {pin_name} = {level!r}: expected 0 or 1")
        mcu.pin(pin_name).set_pull(level)
    # peripheral outputs that take over a port pin (AVR: OC1A on PB1 while DDRB1 = 1)
    for spec in profile.get("peripheral", []):
        for out, pin_name in spec.get("outputs", {}).items():
            net = mcu.pin(pin_name)
            owner = next((q for q in mcu.periph.values() if net in getattr(q, "pins", ())
                          and hasattr(q, "connect_override")), None)
            if owner is None:
                raise ConfigError(f"{where}: peripheral {spec['name']}: no port owns pin {pin_name}")
            owner.connect_override(owner.pins.index(net), mcu.periph[spec["name"]].oc[out])

    if not avr:
        from periph.cortexm.systick import SysTick  # the Cortex-M core's own timer
        hclk = mcu.clocks.get("HCLK", mcu.core_clock)
        ref = timebase.clock("SysTick_ref", hclk.hz / 8) if core.get("systick_ref") == "HCLK/8" else hclk
        systick = SysTick("SysTick", mcu, mcu.core_clock, ref)
        mcu.periph["SysTick"] = systick
        bus.attach(0xE000E010, systick)
    mcu.cpu = Cpu(kernel, mcu.core_clock, irq, entry_latency=core.get("entry_latency", 12))
    mcu.rtos = Rtos(mcu.cpu)

    # plant parts and wiring
    wiring: dict[str, dict[str, object]] = {}
    for pin, target in profile.get("pins", {}).items():
        part, _, terminal = target.partition(".")
        wiring.setdefault(part, {})[terminal.upper()] = mcu.pin(pin)
    for part, terms in (external or {}).items():
        wiring.setdefault(part, {}).update({t.upper(): net for t, net in terms.items()})
    parts = build_parts(kernel, profile.get("part", []), part_overrides, wiring, where)
    # [analog]: an MCU analog input follows a part's analog output (IBT-2 R_IS -> A0)
    for net_name, target in profile.get("analog", {}).items():
        part_name, _, terminal = target.partition(".")
        src = getattr(parts.get(part_name), terminal.lower(), None)
        if src is None and not terminal:
            src = parts.get(part_name)
        if src is None or not hasattr(src, "voltage"):
            raise ConfigError(f"{where}: [analog] {net_name} = {target!r}: no such analog output")
        if net_name not in mcu.analog:
            raise ConfigError(f"{where}: [analog] {net_name}: no peripheral reads this analog input")
        mcu.analog[net_name].source = src.voltage

    firmware = None
    if with_firmware:
        fw = profile.get("firmware")
        if fw is None:
            raise ConfigError(f"{where}: the board has no [firmware]")
        cls = _import(fw["class"], f"{where}: firmware")
        params = {k: v for k, v in fw.items() if k != "class"}
        params.update(firmware_params)
        firmware = mcu.cpu.run_code(lambda: cls(mcu, **params))
    elif firmware_params:
        raise ConfigError(f"firmware parameters {', '.join(firmware_params)} given, but the firmware is off")
    return {"timebase": timebase, "kernel": kernel, "mcu": mcu, "parts": parts, "firmware": firmware,
            "board": board, "profile": profile, "sysclk": Fraction(sysclk), "buses": buses}
