"""Checks of a board profile's wiring and declarations made while it is built (mcusim.board):
each mistake is one ConfigError at the profile's line (``_located``), found before the run.

* pins: a pin a peripheral names belongs to a declared port (``check_pins_have_ports``); a
  peripheral output takes a pin no part drives (``part_driving``);
* constructors: a key without default is named as the key (``missing_args``);
* interrupts: every vector or NVIC line a peripheral is given, or takes by default, exists on the
  core (``check_irq_numbers``);
* the AVR I/O space the registers of the ATmega328P's peripherals live in (``AVR_IO``).
"""

from __future__ import annotations

import inspect
import re

from . import kinds
from .errors import ConfigError

#: the ATmega328P's I/O registers in data space: 64 I/O and 160 extended I/O (datasheet, memory map)
AVR_IO = (0x20, 0xFF)


def located(profile, where: str, msg: str, table=None, index=None, *key) -> ConfigError:
    """``msg`` at the profile's line of ``key`` in ``table`` when the profile knows its lines."""
    if hasattr(profile, "err"):
        return profile.err(msg, table, index, *key)
    return ConfigError(f"{where}: {msg}")


def check_memory_clear_of_peripherals(profile, where, bus) -> None:
    """No [[memory]] region (at its base or an alias) lies over a peripheral's registers: a
    compiled image's accesses there would reach one or the other. Checked whether or not the run
    loads an image, so a board file is accepted or refused alike."""
    entries = bus.ranges()
    for i, spec in enumerate(profile.get("memory", [])):
        size = spec.get("size")
        for key, b in [("base", spec.get("base"))] + [("aliases", a) for a in spec.get("aliases", [])]:
            if not isinstance(b, int) or not isinstance(size, int):
                continue
            for lo, n, periph in entries:
                if b < lo + n and lo < b + size:
                    raise located(profile, where, f"[[memory]] {spec.get('name')}: {b:#010x}-{b + size - 1:#010x} "
                                  f"overlaps peripheral {periph.name} at {lo:#010x}-{lo + n - 1:#010x}",
                                  "memory", i, key)


def check_pins_have_ports(profile, where, mcu) -> None:
    """Every pin a peripheral named (an external interrupt's ``pins``) is a pin of a declared port:
    a peripheral creates the pins it names, so a misspelt one (``PD9``) would be a pin of its own
    that nothing drives, and the interrupt would never fire."""
    owned, families = set(), set()
    for p in mcu.periph.values():
        for item in getattr(p, "pins", None) or ():
            for n in (item if isinstance(item, list) else [item]):
                owned.add(id(n))
                families.add(_pin_family(n.name))
    for name, net in mcu.pins.items():
        # a pin of its own that a peripheral made (a plugin's "BUZZ") is not a port's mistyped pin
        if id(net) in owned or _pin_family(name) not in families:
            continue
        for index, spec in enumerate(profile.get("peripheral", [])):
            for key, value in spec.items():
                if value == name or (isinstance(value, list) and name in value):
                    raise located(profile, where, f"peripheral {spec.get('name')}: {key} = {value!r}: no "
                                   f"port has a pin {name} (ports: {', '.join(_port_names(mcu)) or 'none'})",
                                   "peripheral", index, key)
        raise ConfigError(f"{where}: pin {name} belongs to no port")


def _port_names(mcu):
    return [n for n, p in mcu.periph.items() if getattr(p, "pins", None)]


def _pin_family(name: str) -> str:
    """The naming family of a port pin: its leading letters less the port letter ("PD9" -> "P",
    "GPIO3_3" -> "GPI"), the same for every pin of a port scheme."""
    letters = re.match(r"[A-Za-z]*", name).group()
    return letters[:-1] if len(letters) > 1 else letters


def part_driving(profile, pin_name: str):
    """The part terminal ("encoder.A") that [pins] wires to ``pin_name`` if the part drives it
    (its kind's OUTPUTS), else None."""
    target = profile.get("pins", {}).get(pin_name)
    if not isinstance(target, str):
        return None
    part, _, term = target.partition(".")
    spec = next((q for q in profile.get("part", []) if q.get("name") == part), None)
    if spec is None:
        return None
    try:
        kind = kinds.lookup("part", spec.get("kind"), "")
    except ConfigError:
        return None
    return target if kind.outputs and term.upper() in kind.outputs else None


def missing_args(cls, positional: int, given: set) -> str | None:
    """The first parameter without a default that the constructor of ``cls`` would miss (after
    the ``positional`` arguments passed by position), else None: named as the profile key, not as
    Python's "missing 1 required positional argument"."""
    params = list(inspect.signature(cls.__init__).parameters.values())[1 + positional:]
    for prm in params:
        if (prm.default is inspect.Parameter.empty and prm.name not in given
                and prm.kind in (prm.POSITIONAL_OR_KEYWORD, prm.KEYWORD_ONLY)):
            return prm.name
    return None


def check_irq_numbers(spec: dict, limit: int, what: str, where: str, kind=None) -> None:
    """Interrupt numbers a peripheral is given, or takes by default, must exist on the core (NVIC
    lines, AVR vectors)."""
    for key in ("irq", "irqs", "vector", "vectors"):
        given = key in spec
        v = spec.get(key) if given else getattr(kind, "params", {}).get(key)
        v = getattr(v, "default", v)
        values = v.values() if isinstance(v, dict) else v if isinstance(v, (list, tuple)) else [v]
        for n in values:
            if isinstance(n, int) and not 0 <= n < limit:
                raise ConfigError(f"{where}: peripheral {spec['name']}: {key} {n}{'' if given else ' (its default)'} "
                                  f"is not one of the core's {limit} {what}")


__all__ = ["AVR_IO", "check_irq_numbers", "check_pins_have_ports", "located", "missing_args", "part_driving"]
