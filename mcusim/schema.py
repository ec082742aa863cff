"""Reading and checking board and system profiles before anything is built.

:func:`read_profile_text` reads a profile as UTF-8 TOML; :func:`check_profile` checks every table,
key and value against the schema of ``docs/boards.md`` and the kinds of :mod:`mcusim.kinds`.
Every mistake is one :class:`~mcusim.errors.ConfigError` ``<file>:<line>: <problem>`` (the line
of the offending key, or of its table's header).
"""

from __future__ import annotations

import math
import re
import tomllib

from .errors import ConfigError, TimeError
from .kinds import CORES, lookup
from .params import FLOAT_MAX, TOO_LARGE, Param, _show
from .scenario.source import _Lines
from .time import parse_frequency

BOARD_TABLES = ("board", "clocks", "core", "memory", "peripheral", "pull", "pins", "analog", "part", "firmware",
                "run", "bench")
SYSTEM_TABLES = ("system", "member", "links", "pins", "analog", "part", "run", "bench")
_NAME_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_-]*\Z")
_CORE = {
    "kind": Param("cortex-m4", choices=CORES, doc="the CPU core"),
    "clock": Param("SYSCLK", choices=("SYSCLK",), doc="the core clock"),
    "entry_latency": Param(12, min=0, max=1000, unit="cycles", doc="from pending to the first handler instruction"),
    "nvic_irqs": Param(98, min=1, max=496, doc="Cortex-M: external interrupt lines"),
    "nvic_prio_bits": Param(4, min=2, max=8, doc="Cortex-M: implemented priority bits"),
    "systick_ref": Param("HCLK", choices=("HCLK", "HCLK/8"), doc="Cortex-M: SysTick reference clock"),
    "vectors": Param(26, min=2, max=64, doc="AVR: interrupt vectors"),
    "cycles_per_instruction": Param(1, min=1, max=100, unit="cycles",
                                    doc="Cortex-M running an ELF: core cycles each instruction takes"),
    "boot_address": Param(0, min=0, max=0xFFFFFF80, doc="Cortex-M running an ELF: the vector table at reset "
                                                        "(initial SP, reset vector; VTOR's reset value)"),
}
MEMORY_KINDS = ("flash", "ram")
MAX_CLOCK_HZ = 10**10


class Profile(dict):
    """A parsed profile: the TOML tables, plus ``where`` (its file) and ``lines`` (key lines)."""

    where: str = "profile"
    lines: _Lines | None = None

    def line(self, table=None, index=None, *key) -> int | None:
        return self.lines.line(table, index, key) if self.lines is not None else None

    def err(self, msg: str, table=None, index=None, *key) -> ConfigError:
        line = self.line(table, index, *key)
        return ConfigError(f"{self.where}:{line}: {msg}" if line else f"{self.where}: {msg}")


def parse_toml(text: str, where: str) -> dict:
    """TOML text (a profile or a scenario), else one ConfigError naming the file and line. A
    byte-order mark (which Windows editors put at the start of a UTF-8 file) is skipped."""
    text = text.removeprefix("\ufeff")
    try:
        data = tomllib.loads(text)
    except RecursionError:
        raise ConfigError(f"{where}: invalid TOML: nested too deeply") from None
    except tomllib.TOMLDecodeError as exc:
        msg = str(exc)
        m = re.search(r"\s*\(at line (\d+), column (\d+)\)", msg)
        if m:
            raise ConfigError(f"{where}:{m.group(1)}: invalid TOML: {msg[:m.start()]} (column {m.group(2)})") from None
        line = text.count("\n") + 1 if "end of document" in msg else 1
        raise ConfigError(f"{where}:{line}: invalid TOML: {msg}") from None
    except ValueError:          # Python reads no integer of more than 4300 digits from text
        raise ConfigError(_at_line(text, where, r"\d{4300}") + ": a number of more than 4300 digits") from None
    huge = _huge_int(data)
    if huge is not None:
        key, value = huge
        raise ConfigError(f"{_at_line(text, where, re.escape(str(abs(value))[:20]))}: {key} = {_show(value)}: "
                          f"{TOO_LARGE}")
    return data


def _at_line(text: str, where: str, pattern: str) -> str:
    """``where:line`` of the first line of ``text`` matching ``pattern`` (``_`` digit separators
    dropped), or ``where`` alone."""
    line = next((n for n, row in enumerate(text.splitlines(), 1) if re.search(pattern, row.replace("_", ""))),
                None)
    return f"{where}:{line}" if line else where


def _huge_int(data, key=""):
    """(key path, value) of the first integer in parsed TOML ``data`` beyond the float range, or
    None: TOML reads 400 nines as one integer, which no model computes with (it would overflow
    where it meets a float, far from the file)."""
    items = data.items() if isinstance(data, dict) else enumerate(data) if isinstance(data, list) else ()
    for k, v in items:
        path = f"{key}.{k}" if isinstance(k, str) and key else f"{key}[{k}]" if not isinstance(k, str) else k
        if isinstance(v, int) and not isinstance(v, bool) and not -FLOAT_MAX <= v <= FLOAT_MAX:
            return path, v
        got = _huge_int(v, path)
        if got is not None:
            return got
    return None


def read_profile_text(data: bytes, where: str) -> Profile:
    """Parse a profile's bytes: UTF-8 TOML, else ConfigError naming the file (and line)."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise ConfigError(f"{where}:{line}: not a UTF-8 text file (byte {data[exc.start]:#04x} at offset "
                          f"{exc.start}); a profile is TOML text") from None
    prof = Profile(parse_toml(text, where))
    prof.where, prof.lines = where, _Lines(text)
    return prof


def _frequency(prof, value, what, *path):
    # frequencies take units, as durations do: a bare number ("216", 216) is refused, not read as Hz
    if isinstance(value, bool) or not isinstance(value, str) or not value.strip().lower().endswith("hz"):
        raise prof.err(f"{what} = {_show(value)}: a frequency with a unit, such as \"216MHz\" "
                       "(a bare number is refused)", *path)
    try:
        hz = parse_frequency(value)
    except TimeError as exc:
        raise prof.err(f"{what}: {exc}", *path) from None
    if hz.denominator != 1 or not 1 <= hz <= MAX_CLOCK_HZ:
        raise prof.err(f"{what} = {_show(value)}: must be a whole number of hertz from 1 Hz to 10 GHz", *path)
    return hz


def _table(prof, value, what, *path) -> dict:
    if not isinstance(value, dict):
        raise prof.err(f"{what} must be a table", *path)
    return value


def _array(prof, name) -> list:
    arr = prof.get(name, [])
    if not isinstance(arr, list) or not all(isinstance(x, dict) for x in arr):
        raise prof.err(f"{name} must be an array of tables: [[{name}]]", name)
    return arr


def _name(prof, value, what, *path) -> str:
    if not isinstance(value, str) or not _NAME_RE.match(value):
        raise prof.err(f"{what} = {_show(value)}: expected a name of letters, digits, _ and - "
                       f"(starting with a letter)", *path)
    return value


def _string(prof, value, what, *path) -> str:
    if not isinstance(value, str) or not value:
        raise prof.err(f"{what} = {_show(value)}: expected a non-empty string", *path)
    return value


def _scalar_table(prof, value, what, *path, lists=False) -> None:
    """A table of --set style values: numbers, true/false, strings (and lists of them)."""
    _table(prof, value, what, *path)
    for k, v in value.items():
        ok = isinstance(v, (bool, int, float, str)) or (
            lists and isinstance(v, list) and all(isinstance(x, (bool, int, float, str)) for x in v))
        if not ok:
            raise prof.err(f"{what}: {k} = {_show(v)}: expected a number, true/false or a string"
                           + (" (or a list of them)" if lists else ""), *path, k)
        if isinstance(v, float) and not math.isfinite(v):
            raise prof.err(f"{what}: {k} = {_show(v)}: expected a finite number", *path, k)


def _known(prof, d: dict, known, where: str, table=None, index=None, *key) -> None:
    for k in d:
        if k not in known:
            raise prof.err(f"{where}: unknown key {k!r} (known: {', '.join(known)})", table, index, *key, k)


def _class_key(prof, spec, where, table, index) -> None:
    if "class" in spec:
        raise prof.err(f"{where}: class = {_show(spec['class'])}: a profile names a kind (kind = \"...\"), "
                       "never a Python class to import; see docs/boards.md", table, index, "class")


def check_params(prof, kind, spec: dict, skip, where, table, index) -> dict:
    """The kind's parameters given in ``spec`` (minus ``skip`` keys), checked: {name: value}."""
    out = {}
    for k, v in spec.items():
        if k in skip:
            continue
        if k not in kind.params:
            if kind.open_params:
                out[k] = v
                continue
            raise prof.err(f"{where}: unknown parameter {k!r} of kind {kind.name} "
                           f"(known: {', '.join(sorted(kind.params)) or 'none'})", table, index, k)
        try:
            out[k] = kind.params[k].check_file(v, k)
        except ConfigError as exc:
            raise prof.err(f"{where}: {exc}", table, index, k) from None
    for k, p in kind.params.items():
        if getattr(p, "required", False) and k not in spec:
            raise prof.err(f"{where}: {kind.name} needs {k} = ... ({p.doc})", table, index)
    return out


def _check_board_tables(prof: Profile) -> None:
    board = _table(prof, prof.get("board"), "[board]", "board") if "board" in prof else None
    if board is None:
        raise prof.err("missing table [board] (name, mcu, description)")
    _known(prof, board, ("name", "description", "mcu"), "[board]", "board")
    for key in ("name", "mcu"):
        if key not in board:
            raise prof.err(f"[board]: missing {key} = \"...\"", "board")
    _name(prof, board["name"], "[board] name", "board", None, "name")
    _string(prof, board["mcu"], "[board] mcu", "board", None, "mcu")
    if "description" in board and not isinstance(board["description"], str):
        raise prof.err("[board] description must be a string", "board", None, "description")

    if "clocks" not in prof:
        raise prof.err("missing table [clocks] (sysclk = \"...\")")
    clocks = _table(prof, prof["clocks"], "[clocks]", "clocks")
    _known(prof, clocks, ("sysclk", "base"), "[clocks]", "clocks")
    if "sysclk" not in clocks:
        raise prof.err("[clocks]: missing sysclk = \"...\" (the core clock, e.g. \"216MHz\")", "clocks")
    sysclk = _frequency(prof, clocks["sysclk"], "[clocks] sysclk", "clocks", None, "sysclk")
    base = clocks.get("base", [clocks["sysclk"]])
    if not isinstance(base, list) or not base:
        raise prof.err("[clocks] base must be a list of frequencies", "clocks", None, "base")
    freqs = [_frequency(prof, f, "[clocks] base", "clocks", None, "base") for f in base]
    if math.lcm(*map(int, freqs)) % int(sysclk):
        raise prof.err(f"[clocks]: sysclk {clocks['sysclk']} does not divide the base frequency", "clocks")

    if "core" not in prof:
        raise prof.err("missing table [core] (kind = \"cortex-m4\", \"cortex-m7\" or \"avr\")")
    core = _table(prof, prof["core"], "[core]", "core")
    _known(prof, core, tuple(_CORE), "[core]", "core")
    if "kind" not in core:
        raise prof.err("[core]: missing kind = \"...\" (" + ", ".join(CORES) + ")", "core")
    for k, v in core.items():
        try:
            _CORE[k].check_file(v, f"[core] {k}")
        except ConfigError as exc:
            raise prof.err(str(exc), "core", None, k) from None


def _check_memory(prof: Profile) -> None:
    """[[memory]]: name, base, size (4 KiB multiples: the core maps pages), kind, aliases."""
    spans, names = [], set()
    for i, spec in enumerate(_array(prof, "memory")):
        where = f"[[memory]] #{i + 1}"
        _known(prof, spec, ("name", "base", "size", "kind", "aliases"), where, "memory", i)
        for key in ("name", "base", "size", "kind"):
            if key not in spec:
                raise prof.err(f"{where}: missing {key} = ...", "memory", i)
        name = _name(prof, spec["name"], f"{where} name", "memory", i, "name")
        if name in names:
            raise prof.err(f"{where}: name {name!r} is taken by another [[memory]] table", "memory", i, "name")
        names.add(name)
        where = f"[[memory]] {name}"
        if spec["kind"] not in MEMORY_KINDS:
            raise prof.err(f"{where}: kind = {_show(spec['kind'])}: expected one of {', '.join(MEMORY_KINDS)}",
                           "memory", i, "kind")
        size = spec["size"]
        if isinstance(size, bool) or not isinstance(size, int) or size <= 0 or size % 0x1000:
            raise prof.err(f"{where}: size = {_show(size)}: expected a positive multiple of 0x1000 bytes",
                           "memory", i, "size")
        aliases = spec.get("aliases", [])
        if not isinstance(aliases, list):
            raise prof.err(f"{where}: aliases must be a list of addresses", "memory", i, "aliases")
        for key, b in [("base", spec["base"])] + [("aliases", a) for a in aliases]:
            if isinstance(b, bool) or not isinstance(b, int) or b % 0x1000 or not 0 <= b <= 0x100000000 - size:
                shown = f"{b:#x}" if isinstance(b, int) and not isinstance(b, bool) else _show(b)
                raise prof.err(f"{where}: {key} {shown}: expected a 0x1000-aligned address with the region "
                               "below 4 GiB", "memory", i, key)
            for other, lo, hi in spans:
                if b < hi and lo < b + size:
                    raise prof.err(f"{where}: {b:#010x}-{b + size - 1:#010x} overlaps {other}", "memory", i, key)
            spans.append((name, b, b + size))


def _named_kinds(prof: Profile, table: str):
    """(index, spec, where, kind) of each entry of ``[[table]]``: a unique name and a known kind."""
    names = set()
    for i, spec in enumerate(_array(prof, table)):
        where = f"[[{table}]] #{i + 1}"
        _class_key(prof, spec, where, table, i)
        if "name" not in spec:
            raise prof.err(f"{where}: missing name = \"...\"", table, i)
        name = _name(prof, spec["name"], f"{where} name", table, i, "name")
        where = f"[[{table}]] {name}"
        if name in names:
            raise prof.err(f"{where}: a second {table} of that name", table, i, "name")
        names.add(name)
        if "kind" not in spec:
            raise prof.err(f"{where}: missing kind = \"...\"", table, i)
        try:
            kind = lookup(table, spec["kind"], where)
        except ConfigError as exc:
            raise prof.err(str(exc), table, i, "kind") from None
        yield i, spec, where, kind


def _check_peripherals(prof: Profile) -> None:
    for i, spec, where, kind in _named_kinds(prof, "peripheral"):
        for need in kind.needs:
            if need not in spec:
                raise prof.err(f"{where}: kind {kind.name} needs {need} = ...", "peripheral", i)
        if "base" in spec:
            b = spec["base"]
            if isinstance(b, bool) or not isinstance(b, int) or not 0 <= b <= 0xFFFFFFFF:
                raise prof.err(f"{where}: base = {_show(b)}: expected an address from 0 to 0xFFFFFFFF",
                               "peripheral", i, "base")
        if "clock" in spec:
            _string(prof, spec["clock"], f"{where} clock", "peripheral", i, "clock")
        if "outputs" in spec:
            _table(prof, spec["outputs"], f"{where} outputs", "peripheral", i, "outputs")
            for out, pin in spec["outputs"].items():
                _string(prof, pin, f"{where} outputs.{out}", "peripheral", i, "outputs", out)
        params = check_params(prof, kind, spec, ("name", "kind", "base", "clock", "outputs"), where, "peripheral", i)
        _check_interrupts(prof, params, where, i)


def _check_interrupts(prof: Profile, params: dict, where: str, i: int) -> None:
    """Interrupt numbers given to a peripheral must exist on the core (NVIC lines, AVR vectors)."""
    core = prof.get("core", {})
    avr = core.get("kind") == "avr"
    limit, what = (core.get("vectors", 26), "vectors") if avr else (core.get("nvic_irqs", 98), "NVIC lines")
    for key in ("irq", "irqs", "vector", "vectors"):
        v = params.get(key)
        values = v.values() if isinstance(v, dict) else v if isinstance(v, (list, tuple)) else [v]
        for n in values:
            if isinstance(n, int) and not isinstance(n, bool) and not 0 <= n < limit:
                raise prof.err(f"{where}: {key}: interrupt {n} is not one of the core's {limit} {what}",
                               "peripheral", i, key)


def _check_wiring(prof: Profile, system: bool) -> None:
    for table in ("pins", "analog", "pull"):
        if table not in prof:
            continue
        t = _table(prof, prof[table], f"[{table}]", table)
        for k, v in t.items():
            if table == "pull":
                if isinstance(v, bool) or v not in (0, 1):
                    raise prof.err(f"[pull] {k} = {_show(v)}: expected 0 or 1", table, None, k)
                continue
            _string(prof, v, f"[{table}] {k}", table, None, k)
            if system and "." not in k:
                raise prof.err(f"[{table}] {k!r}: expected <member>.<name>", table, None, k)
            if table == "pins" and "." not in v:
                raise prof.err(f"[pins] {k} = {v!r}: expected \"<part>.<TERMINAL>\"", table, None, k)


def _check_parts(prof: Profile) -> None:
    for i, spec, where, kind in _named_kinds(prof, "part"):
        for ref in kind.refs:
            if ref in spec:
                v = spec[ref]
                if not (isinstance(v, str) and v) and not (
                        isinstance(v, list) and v and all(isinstance(x, str) and x for x in v)):
                    raise prof.err(f"{where}: {ref} = {_show(v)}: expected a part name or a list of them",
                                   "part", i, ref)
        check_params(prof, kind, spec, ("name", "kind") + kind.refs, where, "part", i)


def _check_firmware(prof: Profile) -> None:
    if "firmware" not in prof:
        return
    fw = _table(prof, prof["firmware"], "[firmware]", "firmware")
    _class_key(prof, fw, "[firmware]", "firmware", None)
    if "kind" not in fw:
        raise prof.err("[firmware]: missing kind = \"...\"", "firmware")
    try:
        kind = lookup("firmware", fw["kind"], "[firmware]")
    except ConfigError as exc:
        raise prof.err(str(exc), "firmware", None, "kind") from None
    kind.load()
    params = firmware_declarations(kind)
    for k, v in fw.items():
        if k == "kind":
            continue
        if params is not None and k not in params:
            raise prof.err(f"[firmware]: unknown parameter {k!r} of {kind.name} (known: {', '.join(sorted(params))})",
                           "firmware", None, k)
        if params is not None:
            try:
                (params[k] if isinstance(params[k], Param) else Param(params[k])).check_file(v, f"firmware.{k}")
            except ConfigError as exc:
                raise prof.err(str(exc), "firmware", None, k) from None


def firmware_declarations(kind):
    """A firmware kind's declared parameters (its class's ``PARAMS``), or None if it has none."""
    return getattr(kind.load(), "PARAMS", None)


def _check_run_tables(prof: Profile) -> None:
    for table in ("run", "bench"):
        if table in prof:
            t = _table(prof, prof[table], f"[{table}]", table)
            _known(prof, t, ("set",), f"[{table}]", table)
            if "set" in t:
                _scalar_table(prof, t["set"], f"[{table}.set]", table, None, "set")


def _check_system(prof: Profile) -> None:
    system = _table(prof, prof["system"], "[system]", "system")
    _known(prof, system, ("name", "description", "main"), "[system]", "system")
    if "name" not in system:
        raise prof.err("[system]: missing name = \"...\"", "system")
    _name(prof, system["name"], "[system] name", "system", None, "name")
    if "main" in system:
        _name(prof, system["main"], "[system] main", "system", None, "main")
    if "description" in system and not isinstance(system["description"], str):
        raise prof.err("[system] description must be a string", "system", None, "description")
    members = _array(prof, "member")
    if not members:
        raise prof.err("a system needs at least one [[member]] (name, board)")
    names = set()
    for i, m in enumerate(members):
        where = f"[[member]] #{i + 1}"
        _known(prof, m, ("name", "board", "plant", "set"), where, "member", i)
        for key in ("name", "board"):
            if key not in m:
                raise prof.err(f"{where}: missing {key} = \"...\"", "member", i)
        name = _name(prof, m["name"], f"{where} name", "member", i, "name")
        if name in names:
            raise prof.err(f"[[member]] {name}: a second member of that name", "member", i, "name")
        names.add(name)
        _string(prof, m["board"], f"[[member]] {name} board", "member", i, "board")
        if "plant" in m and not isinstance(m["plant"], bool):
            raise prof.err(f"[[member]] {name}: plant = {_show(m['plant'])}: expected true or false",
                           "member", i, "plant")
        if "set" in m:
            _scalar_table(prof, m["set"], f"[[member]] {name} set", "member", i, "set", lists=True)
    if "links" in prof:
        links = _table(prof, prof["links"], "[links]", "links")
        for k, v in links.items():
            targets = [v] if isinstance(v, str) else v
            if not isinstance(targets, list) or not targets or not all(isinstance(t, str) and t for t in targets):
                raise prof.err(f"[links] {k} = {_show(v)}: expected \"member.part.TERMINAL\" or a list of them",
                               "links", None, k)


def check_profile(prof: Profile) -> None:
    """Check a parsed profile (board or system) against the schema; ConfigError file:line."""
    system = "system" in prof
    allowed = SYSTEM_TABLES if system else BOARD_TABLES
    for k in prof:
        if k not in allowed:
            hint = ("; a scenario file? run it with --scenario FILE and a board"
                    if k in ("scenario", "at", "expect") else "")
            raise prof.err(f"unknown table or key {k!r} in a {'system' if system else 'board'} profile "
                           f"(known: {', '.join(allowed)}){hint}", None, None, k)
    if system:
        _check_system(prof)
    else:
        _check_board_tables(prof)
        _check_memory(prof)
        _check_peripherals(prof)
        _check_firmware(prof)
    _check_wiring(prof, system)
    _check_parts(prof)
    _check_run_tables(prof)
