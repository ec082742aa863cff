"""A compiled image as the simulation's firmware: its topics are globals of the ELF.

The topic map is ``<elf stem>.topics.toml`` beside the ELF::

    [topics."/motor1/set_pos"]
    symbol = "motor1_set_pos"      # a global in the ELF's symbol table
    type = "f32"                   # bool, u8, i8, u16, i16, u32, i32, f32, f64
    direction = "sub"              # sub: the host writes it (--set, scenarios, sim.publish); pub: read
    count = "motor1_set_pos_count" # optional: a u32 the host increments after each write

A host write is a store into RAM at that instant. Writes made before the image's ``main`` runs
(``--set`` at t = 0) are held until ``main`` is entered, so that the startup code's copy of
``.data`` and zeroing of ``.bss`` does not erase them.
"""

from __future__ import annotations

import math
import struct
from pathlib import Path

from unicorn import UC_HOOK_CODE

from ..errors import ConfigError
from ..params import _show, shortest_f32
from ..schema import parse_toml

TYPES = {"bool": "<?", "u8": "<B", "i8": "<b", "u16": "<H", "i16": "<h", "u32": "<I", "i32": "<i",
         "f32": "<f", "f64": "<d"}


class ElfTopic:
    def __init__(self, name, address, type_, direction, count_addr):
        self.name, self.address, self.type, self.direction, self.count_addr = name, address, type_, direction, count_addr
        self.fmt = TYPES[type_]
        self.size = struct.calcsize(self.fmt)


def read_topic_map(elf_path: str, image) -> dict:
    path = Path(elf_path).with_suffix(".topics.toml")
    if not path.exists():
        return {}
    where = str(path)
    try:
        data = parse_toml(path.read_text(encoding="utf-8"), where)
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read topic map {where}: {exc}") from None
    if set(data) - {"topics"} or not isinstance(data.get("topics", {}), dict):
        raise ConfigError(f"{where}: expected only [topics.\"/name\"] tables")
    out = {}
    for name, spec in data.get("topics", {}).items():
        if not isinstance(spec, dict):
            raise ConfigError(f"{where}: topics.{name!r} must be a table")
        unknown = set(spec) - {"symbol", "type", "direction", "count"}
        if unknown:
            raise ConfigError(f"{where}: topic {name}: unknown key {min(unknown)!r} "
                              "(known: symbol, type, direction, count)")
        for key in ("symbol", "type", "direction"):
            if key not in spec:
                raise ConfigError(f"{where}: topic {name}: missing {key} = ...")
        for key, value in spec.items():
            if not isinstance(value, str):
                raise ConfigError(f"{where}: topic {name}: {key} = {value!r}: expected a string")
        if spec["type"] not in TYPES:
            raise ConfigError(f"{where}: topic {name}: type {spec['type']!r} is not one of {', '.join(TYPES)}")
        if spec["direction"] not in ("sub", "pub"):
            raise ConfigError(f"{where}: topic {name}: direction {spec['direction']!r}: expected sub or pub")
        sym = spec["symbol"]
        if not image.symbols:
            raise ConfigError(f"{where}: topic {name}: the ELF has no symbol table (stripped?), so its "
                              f"symbol {sym!r} cannot be found: give the unstripped image")
        if sym not in image.symbols:
            raise ConfigError(f"{where}: topic {name}: the ELF has no symbol {sym!r}")
        size = struct.calcsize(TYPES[spec["type"]])
        if image.sizes.get(sym) not in (0, size, None):
            raise ConfigError(f"{where}: topic {name}: {sym} is {image.sizes[sym]} bytes, not a {spec['type']}")
        count = None
        if "count" in spec:
            if spec["direction"] != "sub":
                raise ConfigError(f"{where}: topic {name}: count goes with direction = \"sub\" (the host "
                                  "increments it after each write; a pub topic is only read)")
            if spec["count"] not in image.symbols:
                raise ConfigError(f"{where}: topic {name}: the ELF has no symbol {spec['count']!r} (count)")
            if spec["count"] == sym:
                raise ConfigError(f"{where}: topic {name}: count = {sym!r} is the topic's own symbol; the count "
                                  "is a u32 of its own")
            if image.sizes.get(spec["count"]) not in (0, 4, None):
                raise ConfigError(f"{where}: topic {name}: count {spec['count']} is "
                                  f"{image.sizes[spec['count']]} bytes, not a u32")
            count = image.symbols[spec["count"]]
        out[name] = ElfTopic(name, image.symbols[sym], spec["type"], spec["direction"], count)
    _no_shared_storage(out, where)
    return out


def _no_shared_storage(topics: dict, where: str) -> None:
    """No storage the host writes (a sub topic's value, a count) shares bytes of RAM with another
    topic's: the write would change that one behind the firmware's back. Two pub topics reading
    one symbol (an alias) are fine."""
    spans = sorted((a, a + size, what, written) for t in topics.values()
                   for a, size, what, written in ((t.address, t.size, t.name, t.direction == "sub"),
                                                  (t.count_addr, 4, f"{t.name} (count)", True))
                   if a is not None)
    for i, (a0, e0, w0, h0) in enumerate(spans):
        for a1, _, w1, h1 in spans[i + 1:]:
            if a1 >= e0:
                break
            if h0 or h1:
                raise ConfigError(f"{where}: topics {w0} and {w1} share RAM at {a1:#010x}, and the host writes "
                                  "one of them; each needs a symbol of its own")


class ElfFirmware:
    """The firmware object of a simulation running an ELF (``sim.firmware``)."""

    def __init__(self, core, path):
        self.core, self.image, self.path = core, core.image, str(path)
        self.symbols = self.image.symbols
        self.topics = read_topic_map(path, self.image)
        for t in self.topics.values():        # the host stores into them: they must be RAM
            for what, address, size in ((t.name, t.address, t.size), (f"{t.name} (count)", t.count_addr, 4)):
                if address is not None and not core._covered(address, size):
                    raise ConfigError(f"{Path(path).with_suffix('.topics.toml')}: topic {what}: its symbol at "
                                      f"{address:#010x} ({size} bytes) is not in the board's RAM")
        self._held = []
        if "/motor1/set_pos" in self.topics:      # the summary's set point per motor, as the ports give it
            self.set_point = lambda n: self.topic(f"/motor{n}/set_pos")
        self.started = "main" not in self.symbols
        if not self.started:
            main = self.symbols["main"]
            self._hook = core.uc.hook_add(UC_HOOK_CODE, self._at_main, begin=main, end=main)

    def _at_main(self, uc, address, size, _):
        if self.started:
            return
        self.started = True
        for topic, value in self._held:
            self._store(topic, value)
        self._held.clear()

    # --- the host side -----------------------------------------------------------------------
    def check_input(self, name, value):
        t = self.topics.get(name)
        if t is None or t.direction != "sub":
            subs = [n for n, x in self.topics.items() if x.direction == "sub"]
            raise ConfigError(f"no subscribed topic {name!r}; the firmware subscribes to "
                              f"{', '.join(subs) or 'nothing (no topic map beside the ELF)'}")
        if t.type == "bool":
            if not isinstance(value, (bool, int)) or value not in (0, 1):
                raise ConfigError(f"{name} = {value!r}: expected true or false")
            return bool(value)
        if t.type.startswith("f"):
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ConfigError(f"{name} = {_show(value)}: expected a finite number")
            try:
                v = float(value)
            except OverflowError:       # an integer beyond any float
                v = math.inf
            if not math.isfinite(v):
                raise ConfigError(f"{name} = {_show(value)}: expected a finite number")
            try:
                struct.pack(t.fmt, v)
            except OverflowError:       # beyond float32 (rounding to its largest finite value is fine)
                raise ConfigError(f"{name} = {_show(value)}: out of range for {t.type} (largest magnitude "
                                  "3.4028235e+38)") from None
            return v
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{name} = {value!r}: expected an integer ({t.type})")
        bits = 8 * t.size
        lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if t.type[0] == "i" else (0, (1 << bits) - 1)
        if not lo <= value <= hi:
            raise ConfigError(f"{name} = {value}: out of range for {t.type} ({lo} to {hi})")
        return value

    def publish(self, name, value) -> None:
        topic = self.topics.get(name)
        value = self.check_input(name, value)
        if self.started:
            self._store(topic, value)
        else:
            self._held.append((topic, value))

    def _store(self, topic, value):
        self.core.write(topic.address, struct.pack(topic.fmt, value))
        if topic.count_addr is not None:
            n = struct.unpack("<I", self.core.read(topic.count_addr, 4))[0]
            self.core.write(topic.count_addr, struct.pack("<I", (n + 1) & 0xFFFFFFFF))

    def topic(self, name):
        t = self.topics.get(name)
        if t is None:
            raise ConfigError(f"no topic {name!r}; topics: {', '.join(self.topics) or 'none'}")
        raw = self.core.read(t.address, t.size)
        value = struct.unpack(t.fmt, raw)[0]
        return shortest_f32(value) if t.type == "f32" else value

    def summary(self) -> dict:
        core = self.core
        out = {"elf": Path(self.path).name, "instructions": core.instructions,
               "pc": core.where(), "state": core.state}
        for name, t in self.topics.items():
            if t.direction == "pub":
                out[name] = self.topic(name)
        return out
