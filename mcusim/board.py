"""Board profiles: read a TOML profile, apply ``--set`` overrides, build the system.

A profile is data: it names peripheral models, plant parts and firmware by *kind*, looked up in
the registry of :mod:`mcusim.kinds` (the project's own kinds and those registered by an entry
point), never a Python object to import. The whole format is in ``docs/boards.md``;
:mod:`mcusim.schema` checks a profile before anything is built.
"""

from __future__ import annotations

import importlib.resources
from fractions import Fraction
from pathlib import Path

from . import kinds
from .board_checks import (
    AVR_IO,
    check_irq_numbers,
    check_memory_clear_of_peripherals,
    check_pins_have_ports,
    missing_args,
    part_driving,
)
from .board_checks import located as _located
from .errors import ConfigError, McusimError, read_input
from .firmware import Cpu, Rtos
from .irq import AvrInterrupts, Nvic, Scb
from .kernel import Kernel
from .mcu import Mcu
from .params import _show
from .registers import Bus
from .schema import check_params, check_profile, read_profile_text
from .time import TimeBase, parse_frequency

# the errors a model's constructor raises for a value it cannot take: reported as one line naming
# the peripheral, part or firmware (the schema catches the common mistakes first, with their line)
BUILD_ERRORS = (TypeError, ValueError, ArithmeticError, LookupError, AttributeError)


def board_names() -> list[str]:
    files = importlib.resources.files("mcusim.boards")
    return sorted(p.name[:-5] for p in files.iterdir() if p.name.endswith(".toml"))


def shipped_text(board: str) -> str:
    """The text of a shipped profile (``mcusim boards --show``)."""
    if board not in board_names():
        raise ConfigError(f"unknown board {_show(str(board))}; known boards: {', '.join(board_names())}")
    return (importlib.resources.files("mcusim.boards") / f"{board}.toml").read_text(encoding="utf-8")


def read_profile(board: str) -> tuple[dict, str]:
    """The parsed and checked profile of a board name (``nucleo-f746``) or a path to a .toml
    file. Any mistake raises ConfigError ``<file>:<line>: <problem>``."""
    if not isinstance(board, (str, Path)):
        raise ConfigError(f"board = {board!r:.60}: expected a board name or the path of a .toml file; "
                          f"known boards: {', '.join(board_names())}")
    if not str(board).strip():
        raise ConfigError(f"no board given; known boards: {', '.join(board_names())}")
    path = Path(board)
    if path.suffix == ".toml" or path.exists() or "/" in str(board):
        try:
            data, where = read_input(path, "board profile", 4 << 20), str(path)
        except OSError as exc:
            raise ConfigError(f"cannot read board profile {str(board)!r}: {exc.strerror or exc}") from None
    else:
        res = importlib.resources.files("mcusim.boards") / f"{board}.toml"
        if not res.is_file():
            raise ConfigError(f"unknown board {_show(str(board))}; known boards: {', '.join(board_names())}")
        data, where = res.read_bytes(), f"boards/{board}.toml"
    profile = read_profile_text(data, where)
    check_profile(profile)
    return profile, where


def profile_file(board: str) -> Path | None:
    """The file a board name or path reads (a shipped profile's too, where it is a file), or None."""
    path = Path(board)
    if path.suffix == ".toml" or path.exists() or "/" in str(board):
        return path
    res = importlib.resources.files("mcusim.boards") / f"{board}.toml"
    return Path(str(res)) if res.is_file() and Path(str(res)).is_file() else None


def profile_files(board: str) -> list:
    """The files reading the profile ``board`` involves: its own and, for a system, its members'
    (what no output of a run may overwrite)."""
    own = profile_file(board)
    if own is None:
        return []
    files = [own]
    profile, _ = read_profile(board)
    if "system" in profile:
        for m in profile.get("member", []):
            if isinstance(m, dict) and isinstance(m.get("board"), str):
                files += [f for f in [profile_file(m["board"])] if f is not None]
    return files


def parse_value(text: str):
    """A ``--set`` value: true/false, an int (also 0x.., 0b..), a float, a list (``8,9`` or ``[8,9]``),
    else the string itself; in quotes (``"off"``, ``'12'``) always the string inside them."""
    stripped = text.strip()
    if len(stripped) >= 2 and stripped[0] == stripped[-1] and stripped[0] in "\"'":
        return stripped[1:-1]
    low = stripped.lower()
    if low in ("true", "on", "yes"):
        return True
    if low in ("false", "off", "no"):
        return False
    if "," in text or (low.startswith("[") and low.endswith("]")):   # a list: 8,9 or [8, 9]
        inner = stripped[1:-1] if low.startswith("[") and low.endswith("]") else stripped
        if not inner.strip():
            return []
        items = inner.split(",")
        if not all(t.strip() for t in items):
            raise ConfigError(f"{text!r}: an empty item in a list (two commas in a row, or a comma "
                              "at an end); write the items as 8,9,10")
        return [parse_value(t) for t in items]
    if low.startswith(("0x", "-0x", "0b", "0o")):
        try:
            return int(low, 0)
        except ValueError:
            pass
    for conv in (int, float):
        try:
            return conv(text)
        except ValueError:
            pass
    return text


def _firmware_inputs(profile: dict) -> set:
    """The names in the firmware's ``HOST_INPUTS`` (inputs a host can give it)."""
    fw = profile.get("firmware")
    if not isinstance(fw, dict) or "kind" not in fw:
        return set()
    cls = kinds.lookup("firmware", fw["kind"], "[firmware]").load()
    return set(getattr(cls, "HOST_INPUTS", {}))


def is_input_key(profile: dict, key: str) -> bool:
    """Whether a ``--set`` key is a message or input for a firmware (``/motor1/set_pos``,
    ``velocity``, ``cmd_vel.linear``, ``mcm1.velocity``), not a parameter (``motor1.R``,
    ``firmware.kp``, ``mcm3.present``)."""
    head, dot, rest = key.partition(".")
    if "system" in profile:
        members = {m.get("name"): m for m in profile.get("member", [])}
        if dot and head in members:
            if rest == "present":
                return False
            try:
                return is_input_key(read_profile(members[head]["board"])[0], rest)
            except ConfigError:
                return False
        parts = {p.get("name") for p in profile.get("part", [])}
        return not (dot and (head == "firmware" or head in parts))
    if key.startswith("/") or not dot:
        return True
    return key in _firmware_inputs(profile)


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
    freqs = clocks.get("base", [clocks["sysclk"]])
    for f in [clocks["sysclk"], *(freqs if isinstance(freqs, list) else [freqs])]:
        if not isinstance(f, str):      # frequencies take units, as everywhere (a bare number is refused)
            raise ConfigError(f"[clocks] {f!r}: a frequency with a unit, such as \"216MHz\"")
    return [parse_frequency(f) for f in freqs]


def _resolve_peripheral_refs(spec, mcu, kernel, buses, where, kind=None):
    """Peripheral parameters that name shared objects: ``inputs = {0 = "A0"}`` (analog nets of the
    MCU) and ``bus = "i2c0"`` (a bus shared by every MCU of the system; the kind's default bus
    where the profile names none)."""
    from .i2c import I2cBus
    from .signals import AnalogNet
    out = {}
    if "inputs" in spec:
        nets = {}
        for ch, net_name in spec["inputs"].items():
            net = mcu.analog.setdefault(net_name, AnalogNet(net_name))
            nets[int(ch)] = net
        out["inputs"] = nets
    default = getattr(kind.params.get("bus"), "default", None) if kind is not None else None
    if "bus" in spec or isinstance(default, str):
        name = spec.get("bus", default)
        if name not in buses:
            buses[name] = I2cBus(kernel, name)
        out["bus"] = buses[name]
    return out


def _part_params(kind, spec: dict, overrides: dict, name: str, where: str) -> dict:
    """A part's parameters: the profile's (checked when it was read) and the ``--set`` ones."""
    class _Where:          # check_params wants a profile to blame; here the message is enough
        @staticmethod
        def err(msg, *path):
            return ConfigError(msg)
    params = check_params(_Where, kind, spec, ("name", "kind") + kind.refs, f"{where}: part {name}", None, None)
    for key, value in overrides.items():
        if key in kind.refs:
            raise ConfigError(f"--set {name}.{key}: names other parts; it is set in the profile only")
        if key not in kind.params and not kind.open_params:
            raise ConfigError(f"--set {name}.{key}: {name} ({kind.name}) has no parameter {key!r} "
                              + (f"(known: {', '.join(sorted(kind.params))})" if kind.params else "(it takes none)"))
        params[key] = kind.params[key].check(value, f"{name}.{key}") if key in kind.params else value
    kind.check_rules(params, f"{where}: part {name}" if not overrides else f"part {name}")
    return params


class _PartError(ConfigError):
    """A mistake in one part's declaration or wiring: (message, part, its key, terminal, file),
    so that :func:`build` can name the profile's line."""

    def __str__(self):
        return f"{self.args[4]}: {self.args[0]}"


def located_part_error(profile, where: str, exc: _PartError) -> ConfigError:
    """``exc`` (from :func:`build_parts`) at the profile's line: the ``[pins]`` entry that wires
    its terminal, else its part's key (or table)."""
    msg, name, key, term, _ = exc.args
    pin = next((p for p, target in profile.get("pins", {}).items() if term is not None
                and target.partition(".")[0] == name and target.partition(".")[2].upper() == term), None)
    if pin is not None:
        return _located(profile, where, msg, "pins", None, pin)
    index = next((i for i, sp in enumerate(profile.get("part", [])) if sp.get("name") == name), None)
    return _located(profile, where, msg, "part", index, *((key,) if key else ()))


def build_parts(kernel, specs: list, part_overrides: dict, wiring: dict, where: str,
                lookup=None) -> dict:
    """Instantiate plant parts in declaration order. ``wiring[part][TERMINAL]`` is the Net of each
    digital terminal; parameters in the kind's ``refs`` name other parts, resolved among the parts
    built so far or by ``lookup(name)`` (a system's parts of its boards: ``"mcm1.motor"``)."""
    parts: dict = {}
    declared = {s.get("name") for s in specs}
    for part, terms in wiring.items():   # a misspelt part in [pins] first: else it shows as an unwired terminal
        if part not in declared:
            raise _PartError(f"[pins] names part {part!r}, which is not declared "
                             f"(parts: {', '.join(sorted(str(d) for d in declared if d))})", part, None,
                             next(iter(terms), None), where)

    order = [s.get("name") for s in specs]

    def wrong_kind(kind_name, obj, allowed) -> bool:
        """A built-in kind that is none of ``allowed`` (a bridge named as a motor). A part of a
        kind registered elsewhere (a plugin's motor) is left to the part that takes it."""
        if not allowed:
            return False
        builtin = kinds.builtin_part_kinds()
        if obj is not None:
            ok = tuple(builtin[k] for k in allowed if k in builtin)
            return isinstance(obj, tuple(builtin.values())) and not isinstance(obj, ok)
        return kind_name in builtin and kind_name not in allowed

    def ref(name, who, key, allowed=()):
        found = parts[name] if name in parts else lookup(name) if lookup is not None else None
        if found is None:
            later = name in order and order.index(name) > order.index(who)
            if later and wrong_kind(specs[order.index(name)].get("kind"), None, allowed):
                raise _PartError(f"part {who}: {key} = {name!r} is not a {' or '.join(allowed)} part",
                                 who, key, None, where)
            raise _PartError(f"part {who}: {key} = {name!r} is declared after it; parts are built in "
                             f"order, so declare {name} first" if later else
                             f"part {who}: no part {name!r} declared before it", who, key, None, where)
        if wrong_kind(None, found, allowed):
            raise _PartError(f"part {who}: {key} = {name!r} is not a {' or '.join(allowed)} part",
                             who, key, None, where)
        return found

    for spec in specs:
        name = spec["name"]
        kind = kinds.lookup("part", spec.get("kind"), f"{where}: part {name}")
        cls = kind.load()
        params = _part_params(kind, spec, part_overrides.get(name, {}), name, where)
        args = {}
        for key in kind.refs:
            if key in spec:
                v = spec[key]
                allowed = kind.ref_kinds.get(key, ())
                if isinstance(v, list):
                    twice = next((x for i, x in enumerate(v) if x in v[:i]), None)
                    if twice is not None:       # (a body's wheel, a battery's load: each counts once)
                        raise _PartError(f"part {name}: {key} lists {twice!r} twice", name, key, None, where)
                args[key] = ([ref(x, name, key, allowed) for x in v] if isinstance(v, list)
                             else ref(v, name, key, allowed))
        required, optional = kind.terminals
        unknown = set(wiring.get(name, {})) - set(required + optional)
        if unknown:
            raise _PartError(f"part {name} ({kind.name}) has no terminal {', '.join(sorted(unknown))}; "
                             f"terminals: {', '.join(required + optional) or 'none'}", name, None,
                             min(unknown), where)
        for term in required + optional:
            net = wiring.get(name, {}).get(term)
            if net is None:
                if term in optional:
                    continue
                raise _PartError(f"part {name}: terminal {term} is not wired in [pins]", name, None, None, where)
            args[term.lower()] = net
        missing = missing_args(cls, 1, {"name", *args, *params})
        if missing:
            raise _PartError(f"part {name} ({kind.name}): missing {missing} = ... (its constructor has no "
                             "default)",
                             name, None, None, where)
        try:
            parts[name] = cls(kernel, name=name, **args, **params)
        except _PartError:
            raise
        except ConfigError as exc:      # about this part's declaration, unless --set changed it
            if part_overrides.get(name) or str(exc).startswith(where):
                raise
            raise _PartError(f"part {name} ({kind.name}): {exc}", name, None, None, where) from None
        except McusimError:
            raise
        except BUILD_ERRORS as exc:
            raise ConfigError(f"{where}: part {name} ({kind.name}): {exc}") from None
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
    for key in ("sysclk",):          # frequencies take units, as everywhere (a bare number is refused)
        if not isinstance(clocks.get(key), str):
            raise ConfigError(f"{where}: [clocks] {key} = {clocks.get(key)!r}: a frequency with a unit, "
                              "such as \"216MHz\"")
    sysclk = parse_frequency(clocks["sysclk"])
    if kernel is None:
        kernel = Kernel(TimeBase(board_clocks(profile)), engine)
    timebase = kernel.timebase
    buses = {} if buses is None else buses
    bus = Bus(f"{board['name']}.bus")
    mcu = Mcu(board["mcu"], kernel, bus, timebase.clock("SYSCLK", sysclk))
    mcu.clocks["SYSCLK"] = mcu.core_clock

    avr = core.get("kind", "").startswith("avr")
    elf = with_firmware if isinstance(with_firmware, (str, Path)) else None
    if elf is not None:
        from .elf.image import resolve_firmware
        from .elf.setup import attach_memories, check_elf_board
        elf = resolve_firmware(elf)
        image, memories = check_elf_board(profile, where, elf)
    if avr:
        irq = AvrInterrupts(num_vectors=core.get("vectors", 26))
    else:
        irq = Nvic(num_irqs=core.get("nvic_irqs", 98), prio_bits=core.get("nvic_prio_bits", 4))
        bus.attach(0xE000E100, irq)
        if elf is None:
            bus.attach(0xE000ED00, Scb(irq))
    mcu.nvic = mcu.irq = irq
    limit, what = (core.get("vectors", 26), "vectors") if avr else (core.get("nvic_irqs", 98), "NVIC lines")
    for index, spec in enumerate(profile.get("peripheral", [])):
        pwhere = f"{where}: peripheral {spec.get('name')}"
        kind = kinds.lookup("peripheral", spec.get("kind"), pwhere)
        cls = kind.load()
        check_irq_numbers(spec, limit, what, where, kind)
        kwargs = _part_params(kind, {k: v for k, v in spec.items() if k not in ("base", "clock", "outputs")},
                              {}, spec["name"], where)
        kwargs.update(_resolve_peripheral_refs(spec, mcu, kernel, buses, where, kind))
        if kind.name == "stm32-rcc":
            kwargs["sysclk_hz"] = sysclk
        if "clock" in spec:
            if spec["clock"] not in mcu.clocks:
                raise _located(profile, where, f"peripheral {spec['name']}: no clock {spec['clock']!r} "
                               f"(clocks: {', '.join(mcu.clocks)})", "peripheral", index, "clock")
            kwargs["clock"] = mcu.clocks[spec["clock"]]
        missing = missing_args(cls, 2, set(kwargs))
        if missing:
            raise _located(profile, where, f"peripheral {spec['name']} ({kind.name}): missing {missing} = ... "
                           "(its constructor has no default)", "peripheral", index)
        try:
            p = cls(spec["name"], mcu, **kwargs)
            mcu.periph[spec["name"]] = p
            if p.BUS_WIDTH == 1:
                base = spec.get("base", 0)
                bad = [r for r in p.REGISTERS if not AVR_IO[0] <= base + r.offset <= AVR_IO[1]]
                if avr and bad:
                    raise ConfigError(f"base = {base:#x} puts {bad[0].name} at {base + bad[0].offset:#x}, outside "
                                      f"the I/O space ({AVR_IO[0]:#x}-{AVR_IO[1]:#x}) where the firmware reaches "
                                      "its registers")
                bus.attach_registers(base, p)  # AVR: registers scattered in data space
            else:
                bus.attach(spec["base"], p)
        except ConfigError as exc:      # about this peripheral's declaration: at its table
            if str(exc).startswith(where):
                raise
            raise _located(profile, where, f"peripheral {spec['name']} ({kind.name}): {exc}", "peripheral",
                           index) from None
        except McusimError:
            raise
        except BUILD_ERRORS as exc:
            raise _located(profile, where, f"peripheral {spec['name']} ({kind.name}): {exc}", "peripheral",
                           index) from None
        vecs = getattr(p, "vectors", None)     # as built: a model's own defaults too (Timer0's 14-16)
        check_irq_numbers({"name": spec["name"], "vector": list(vecs.values()) if isinstance(vecs, dict)
                            else vecs}, limit, what, where)
        if "clock" in spec:
            mcu.clock_users.setdefault(spec["clock"], []).append(p)
    if avr:     # the chip's other I/O registers: an access names them (periph/avr/unmodelled.py)
        from mcusim.periph.avr.unmodelled import STORAGE, UNITS, AvrUnmodelled
        free = {a for _, a, *_ in UNITS + STORAGE if bus.peripheral_at(a) is None}
        bus.attach_registers(0, AvrUnmodelled("ATmega328P", free, mcu))
    check_pins_have_ports(profile, where, mcu)
    check_memory_clear_of_peripherals(profile, where, bus)
    if elf is not None:         # (after the peripherals: a region over one is named at its own line)
        attach_memories(bus, memories)
    # [pull]: board-level pull resistors on pins (an active-low button's pull-up)
    for pin_name, level in profile.get("pull", {}).items():
        if level not in (0, 1):
            raise ConfigError(f"{where}: [pull] {pin_name} = {level!r}: expected 0 or 1")
        try:
            net = mcu.pin(pin_name)
        except ConfigError as exc:
            raise _located(profile, where, f"[pull] {exc}", "pull", None, pin_name) from None
        net.set_pull(level)
    # peripheral outputs that take over a port pin (AVR: OC1A on PB1 while DDRB1 = 1), one per pin
    taken: dict = {}
    for index, spec in enumerate(profile.get("peripheral", [])):
        for out, pin_name in spec.get("outputs", {}).items():
            if pin_name in taken:
                raise _located(profile, where, f"peripheral {spec['name']}: outputs.{out} = {pin_name!r}: "
                               f"{taken[pin_name]} already drives that pin (one output per pin)",
                               "peripheral", index, "outputs", out)
            taken[pin_name] = f"{spec['name']} output {out}"
            driver = part_driving(profile, pin_name)
            if driver is not None:
                raise _located(profile, where, f"peripheral {spec['name']}: outputs.{out} = {pin_name!r}: "
                               f"[pins] has {driver} drive that pin (one output per pin)",
                               "peripheral", index, "outputs", out)
            try:
                net = mcu.pin(pin_name)
            except ConfigError as exc:
                raise _located(profile, where, f"peripheral {spec['name']}: outputs.{out}: {exc}", "peripheral",
                               index, "outputs", out) from None
            owner = next((q for q in mcu.periph.values() if net in getattr(q, "pins", ())
                          and hasattr(q, "connect_override")), None)
            if owner is None:
                raise _located(profile, where, f"peripheral {spec['name']}: no port owns pin {pin_name}",
                               "peripheral", index, "outputs", out)
            oc = getattr(mcu.periph[spec["name"]], "oc", {})
            if out not in oc:
                raise _located(profile, where, f"peripheral {spec['name']}: no output {out!r} "
                               f"(outputs: {', '.join(oc) or 'none'})", "peripheral", index, "outputs", out)
            owner.connect_override(owner.pins.index(net), oc[out])

    if not avr:
        from mcusim.periph.cortexm.systick import SysTick  # the Cortex-M core's own timer
        hclk = mcu.clocks.get("HCLK", mcu.core_clock)
        ref = timebase.clock("SysTick_ref", hclk.hz / 8) if core.get("systick_ref") == "HCLK/8" else hclk
        systick = SysTick("SysTick", mcu, mcu.core_clock, ref)
        mcu.periph["SysTick"] = systick
        bus.attach(0xE000E010, systick)
    if elf is not None:
        from .elf.setup import build_core
        mcu.cpu = build_core(profile, mcu, image, memories)
    else:
        mcu.cpu = Cpu(kernel, mcu.core_clock, irq, entry_latency=core.get("entry_latency", 12))
        mcu.rtos = Rtos(mcu.cpu)

    # plant parts and wiring
    wiring: dict[str, dict[str, object]] = {}
    for pin, target in profile.get("pins", {}).items():
        part, _, terminal = target.partition(".")
        try:
            net = mcu.pin(pin)
        except ConfigError as exc:
            raise _located(profile, where, f"[pins] {exc}", "pins", None, pin) from None
        wiring.setdefault(part, {})[terminal.upper()] = net
    for part, terms in (external or {}).items():
        wiring.setdefault(part, {}).update({t.upper(): net for t, net in terms.items()})
    try:
        parts = build_parts(kernel, profile.get("part", []), part_overrides, wiring, where)
    except _PartError as exc:
        raise located_part_error(profile, where, exc) from None
    # [analog]: an MCU analog input follows a part's analog output (IBT-2 R_IS -> A0)
    for net_name, target in profile.get("analog", {}).items():
        part_name, _, terminal = target.partition(".")
        src = getattr(parts.get(part_name), terminal.lower(), None)
        if src is None and not terminal:
            src = parts.get(part_name)
        if src is None or not hasattr(src, "voltage"):
            raise _located(profile, where, f"[analog] {net_name} = {target!r}: no such analog output",
                           "analog", None, net_name)
        if net_name not in mcu.analog:
            raise _located(profile, where, f"[analog] {net_name}: no peripheral reads this analog input",
                           "analog", None, net_name)
        mcu.analog[net_name].source = src.voltage

    firmware = None
    if elf is not None:
        from .elf.firmware import ElfFirmware
        if firmware_params:
            raise ConfigError(f"firmware parameters {', '.join(firmware_params)} given, but the firmware is "
                              f"the ELF {elf}: its parameters are compiled in")
        firmware = ElfFirmware(mcu.cpu, elf)
    elif with_firmware:
        fw = profile.get("firmware")
        if fw is None:
            raise ConfigError(f"{where}: the board has no [firmware]")
        kind = kinds.lookup("firmware", fw.get("kind"), f"{where}: [firmware]")
        cls = kind.load()
        family = getattr(cls, "CORE", None)
        if family is not None and not core.get("kind", "").startswith(
                family if isinstance(family, str) else tuple(family)):
            raise _located(profile, where, f"[firmware] kind = {kind.name!r} runs on a core of the {family} "
                           f"family; this board's [core] is {core.get('kind')!r}", "firmware", None, "kind")
        params = {k: v for k, v in fw.items() if k != "kind"}
        params.update(firmware_params)
        try:
            firmware = mcu.cpu.run_code(lambda: cls(mcu, **params))
        except BaseException as exc:
            for task in mcu.rtos.tasks:        # tasks it created will never run: end them quietly
                task.close()
            if isinstance(exc, KeyError) and exc.args and isinstance(exc.args[0], str):
                raise ConfigError(f"{where}: firmware {kind.name} needs {exc.args[0]!r}, which the profile "
                                  f"does not declare (peripherals: {', '.join(mcu.periph)})") from None
            if isinstance(exc, BUILD_ERRORS):
                raise ConfigError(f"{where}: firmware {kind.name}: {exc}") from None
            raise
        missing = [m for m in ("publish", "topic") if not callable(getattr(firmware, m, None))]
        if missing:
            for task in mcu.rtos.tasks:
                task.close()
            raise ConfigError(f"{where}: firmware kind {kind.name!r} ({kind.origin}) is not a firmware: "
                              f"it has no {' or '.join(missing)}()")
    elif firmware_params:
        raise ConfigError(f"firmware parameters {', '.join(firmware_params)} given, but the firmware is off")
    return {"timebase": timebase, "kernel": kernel, "mcu": mcu, "parts": parts, "firmware": firmware,
            "board": board, "profile": profile, "sysclk": Fraction(sysclk), "buses": buses}
