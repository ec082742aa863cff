"""Register-access log: every firmware access to a peripheral register, as JSON lines.

One line per access::

    {"t_s": 0.005, "cycle": 1080000, "mcu": "nucleo-f746", "addr": "0x40000424", "reg": "TIM3.CNT",
     "op": "read", "value": "0x0000007b"}
    {"t_s": 0.0, "cycle": 0, "mcu": "nucleo-f746", "addr": "0x40010000", "reg": "TIM1.CR1",
     "op": "write", "value": "0x00000081", "changed": {"CEN": [0, 1]}}

``t_s`` is the simulated time in seconds, ``cycle`` the core clock cycles of that MCU
(``kernel.now // core period``: each board of a system counts its own), ``mcu`` the member name
(the board name for a single board; ``rcm``, ``mcm1`` ... in a system), ``addr`` the register's
bus address (base of the peripheral + register offset; on the ATmega328P the data-space
address, four hex digits), ``reg`` ``PERIPH.REG``. For a read, ``value`` is the whole register as
read; for a write, the data written (in its byte lanes), and ``changed`` lists the fields whose
value changed, ``{FIELD: [old, new]}``, new being what the register holds after the write (a
register without fields is one field named after the register; write-only fields, which read 0,
show the value written: ``{"UG": [0, 1]}``).

A compiled image (``--firmware app.elf``) adds ``fn``, the function (from the ELF's symbol
table) whose instruction made the access: ``"fn": "pwm_tim1_set_duty"``.

Only accesses through the bus are logged (the firmware, or a test calling ``mcu.read32`` ...):
they reach :attr:`Peripheral.access_log`. The hardware side of a model (``set_bits`` /
``clear_bits``: a timer setting UIF, a port latching a pin) does not. Without a log attached,
``access_log`` stays None on every peripheral and the bus pays one ``is not None`` test per access.

Known gaps, in the models rather than here: the NVIC's ISER/ICER/ISPR/ICPR/IABR registers are
handled outside ``Peripheral.write_register``/``bus_read`` and are not logged (its IPR registers
are); a byte or half-word access is logged at its register's address.

Start-up: a firmware whose ``main()`` runs while the simulation is built (the ControlMotor
firmware initialises its timers in the constructor) makes its first accesses before a log can be
attached to the built simulation. :func:`capture_startup` records them while the simulation is
built; ``RegisterLog(sim, ..., startup=capture)`` writes them first (at t = 0). :func:`load_logged`
does both.
"""

from __future__ import annotations

import contextlib
import fnmatch
import json

from .errors import ConfigError
from .outputs import open_output
from .registers import Peripheral


class StartupCapture:
    """Accesses recorded while peripherals are being built (see :func:`capture_startup`)."""

    def __init__(self):
        self.records: list[tuple] = []     # (kind, periph, reg, value, old, after)
        self.peripherals: list[Peripheral] = []
        self.active = False

    def _hook(self, kind, periph, reg, value, old):
        self.records.append((kind, periph, reg, value, old, periph.value.get(reg.name)))


@contextlib.contextmanager
def capture_startup():
    """Record the register accesses of every peripheral created inside the ``with`` block, from
    its creation on (the accesses a firmware makes while it is constructed)::

        with capture_startup() as startup:
            sim = mcusim.load("nucleo-f746")
        log = RegisterLog(sim, "regs.jsonl", startup=startup)

    Peripherals built in the block keep recording until a :class:`RegisterLog` takes them over
    (or until :meth:`RegisterLog.close`); call ``release(startup)`` to stop without a log.
    Not thread-safe: it wraps ``Peripheral.__init__`` for the duration of the block.
    """
    cap = StartupCapture()
    original = Peripheral.__init__

    def init(self, *args, **kwargs):
        original(self, *args, **kwargs)
        self.access_log = cap._hook
        cap.peripherals.append(self)

    Peripheral.__init__ = init
    cap.active = True
    try:
        yield cap
    finally:
        Peripheral.__init__ = original


def release(cap: StartupCapture) -> None:
    """Stop the recording of a capture that no log took over."""
    for p in cap.peripherals:
        if p.access_log == cap._hook:
            p.access_log = None
    cap.active = False


def _matcher(filter):
    """``match(member, periph, reg)`` deciding one register for ``filter``, or None for no filter."""
    if filter is None:
        return None
    if not isinstance(filter, (str, list, tuple, set, frozenset)):
        raise ConfigError(f"register log filter {filter!r:.60}: give names as text (\"TIM1,TIM2.CCR1\") "
                          "or a list of them")
    if isinstance(filter, str):
        filter = filter.replace(";", ",").split(",")
    pats = [str(x).strip().upper() for x in filter if str(x).strip()]

    def one(pat, member, periph, reg):
        full = f"{periph}.{reg}"
        if any(c in pat for c in "*?["):
            return any(fnmatch.fnmatchcase(x, pat) for x in (periph, member, full, f"{member}.{periph}",
                                                               f"{member}.{full}"))
        if "." not in pat:
            return pat in (periph, member)
        return full.startswith(pat) or f"{member}.{full}".startswith(pat)

    def match(member, periph, reg):
        m, p, r = member.upper(), periph.upper(), reg.upper()
        return any(one(pat, m, p, r) for pat in pats)
    return match


def _hooks(match, member: str, p) -> bool:
    """Whether some register of peripheral ``p`` of ``member`` matches: only those peripherals
    carry a hook. (Decided from the names of its registers, not the peripheral's name alone: a
    glob's ``?`` or ``*`` also matches the dot, and "mcm1.TIMER1" once hooked every peripheral
    of mcm1, whose ports then counted as watched and kept its encoder edges from being served.)"""
    return any(match(member, p.name, r) for r in p.register_names())


def _check_filter(sim, filter) -> None:
    """Every filter pattern must match a register (a typo would log nothing)."""
    if filter is None:
        return
    pats = filter.replace(";", ",").split(",") if isinstance(filter, str) else list(filter)
    if not any(str(x).strip() for x in pats):
        raise ConfigError("register log filter is empty: name peripherals or registers (TIM3, TIM3.CCR1, "
                          "GPIO*), or leave the filter out to log every access")
    periphs = [(m, p) for m, member in sim.members.items() for p in _bus_peripherals(member["mcu"])]
    for pat in (str(x).strip() for x in pats):
        if not pat:
            continue
        match = _matcher([pat])
        if any(_hooks(match, m, p) for m, p in periphs):
            continue
        parts = pat.upper().split(".")
        if len(sim.members) > 1 and len(parts) >= 2 and parts[0] in {m.upper() for m in sim.members}:
            member, parts = parts[0], parts[1:]     # MEMBER.PERIPH[.REG]: that board's peripherals
            names = {p.name.upper() for m, p in periphs if m.upper() == member}
            if not any(c in parts[0] for c in "*?[") and parts[0] not in names:
                raise ConfigError(f"register log filter {pat!r}: {member.lower()} has no peripheral "
                                  f"{parts[0]}; its peripherals: {', '.join(sorted(names))}")
            periphs_named = [p for m, p in periphs if m.upper() == member]
        else:
            periphs_named = [p for _, p in periphs]
        if len(parts) >= 2 and not any(c in parts[-1] for c in "*?["):   # PERIPH.REG: the register exists?
            regs = {r.upper() for p in periphs_named if p.name.upper() == parts[-2] for r in p.register_names()}
            if regs and not any(r.startswith(parts[-1]) for r in regs):     # (a prefix is allowed)
                raise ConfigError(f"register log filter {pat!r}: {parts[-2]} has no register {parts[-1]}; "
                                  f"registers: {', '.join(sorted(regs))}")
        known = sorted({p.name for _, p in periphs})
        raise ConfigError(f"register log filter {pat!r} matches no peripheral; peripherals: "
                          f"{', '.join(known)}" + (f"; boards: {', '.join(sim.members)}"
                                                   if len(sim.members) > 1 else ""))


def _addresses(bus) -> tuple[dict, dict]:
    """({id(periph): base} of peripherals mapped as a block, {(id(periph), offset): address} of
    registers mapped one by one (AVR data space))."""
    bases = {id(p): base for base, _size, p in getattr(bus, "_entries", ())}
    singles = {}
    for addr, (p, off) in getattr(bus, "_single", {}).items():
        key = (id(p), off)
        if key not in singles or addr < singles[key]:
            singles[key] = addr
    return bases, singles


def _bus_peripherals(mcu) -> list:
    seen, out = set(), []
    for p in list(mcu.periph.values()) + [e[2] for e in getattr(mcu.bus, "_entries", ())] + \
            [p for p, _ in getattr(mcu.bus, "_single", {}).values()]:
        if isinstance(p, Peripheral) and id(p) not in seen:
            seen.add(id(p))
            out.append(p)
    return out


class RegisterLog:
    """Log register accesses of every MCU of ``sim`` to ``path_or_file`` as JSON lines.

    ``filter``: None (everything) or a list (or comma-separated string) of peripheral names
    (``"TIM3"``), ``PERIPH.REG`` prefixes (``"TIM3.CCR"`` matches CCR1..CCR4; ``"TIM3.CCR1"``),
    glob patterns (``"GPIO*"``), or, in a system, member names (``"mcm1"``) and member-qualified
    names (``"mcm1.TWI"``); case-insensitive. ``startup``: a :func:`capture_startup` capture
    whose records are written first.
    """

    def __init__(self, sim, path_or_file, filter=None, startup: StartupCapture | None = None):
        self.sim = sim
        self.kernel = sim.kernel
        self.base_hz = sim.timebase.base_hz
        self.lines = 0
        self._match = _matcher(filter)
        _check_filter(sim, filter)
        if hasattr(path_or_file, "write"):
            self._file, self._own, self.path = path_or_file, False, None
        else:
            self.path, self._file = open_output(path_or_file, "register log")
            self._own = True
        self._closed = False
        self._hooked: list[Peripheral] = []
        self._info: dict[int, tuple] = {}   # id(periph) -> (member, period, base, singles, hex digits, cache)
        for mname, member in sim.members.items():
            mcu = member["mcu"]
            bases, singles = _addresses(mcu.bus)
            period = mcu.core_clock.period
            caller = getattr(mcu.cpu, "caller", None)      # a compiled image's core: PC -> function
            for p in _bus_peripherals(mcu):
                digits = 4 if getattr(p, "BUS_WIDTH", 4) == 1 else 8
                info = (mname, period, bases.get(id(p)), singles, digits, {}, caller)
                self._info[id(p)] = info
                if self._match is not None and not _hooks(self._match, mname, p):
                    continue
                p.access_log = self._make_hook(p, info)
                self._hooked.append(p)
        if startup is not None:
            for kind, p, reg, value, old, after in startup.records:
                info = self._info.get(id(p))
                if info is not None and self._wanted(info, p, reg):
                    self._emit(0, info, kind, p, reg, value, old, after)
            startup.active = False
            for p in startup.peripherals:           # not taken over (filtered out): stop recording
                if p.access_log == startup._hook:
                    p.access_log = None
        self._file.flush()

    # --- matching -----------------------------------------------------------------------------------
    def _wanted(self, info, p, reg) -> bool:
        if self._match is None:
            return True
        cache = info[5]
        ok = cache.get(reg.name)
        if ok is None:
            ok = cache[reg.name] = self._match(info[0], p.name, reg.name)
        return ok

    # --- recording ----------------------------------------------------------------------------------
    def _make_hook(self, p, info):
        kernel = self.kernel
        if self._match is None:
            def hook(kind, periph, reg, value, old):
                self._emit(kernel.now, info, kind, periph, reg, value, old, periph.value.get(reg.name))
        else:
            def hook(kind, periph, reg, value, old):
                if self._wanted(info, periph, reg):
                    self._emit(kernel.now, info, kind, periph, reg, value, old, periph.value.get(reg.name))
        hook._reglog = self
        return hook

    def _emit(self, now, info, kind, p, reg, value, old, after) -> None:
        mname, period, base, singles, digits, _cache, caller = info
        if base is not None:
            addr = base + reg.offset
        else:
            addr = singles.get((id(p), reg.offset))
        width = max(1, (getattr(reg, "width", 32) + 3) // 4)
        rec = {"t_s": now / self.base_hz, "cycle": now // period, "mcu": mname,
               "addr": None if addr is None else f"0x{addr:0{digits}x}",
               "reg": f"{p.name}.{reg.name}", "op": kind, "value": f"0x{value:0{width}x}"}
        if kind == "write":
            rec["changed"] = _changed(reg, value, old, after)
        fn = caller() if caller is not None else None
        if fn is not None:
            rec["fn"] = fn
        self._file.write(json.dumps(rec, separators=(",", ":")) + "\n")
        self.lines += 1

    # --- the trace protocol of Simulation._traces ---------------------------------------------------
    def flush(self, now: int) -> None:
        if not self._closed:
            self._file.flush()

    def close(self, now: int | None = None) -> None:
        if self._closed:
            return
        self._closed = True
        for p in self._hooked:
            if getattr(p.access_log, "_reglog", None) is self:   # not replaced by another log
                p.access_log = None
        self._hooked.clear()
        if self._own:
            self._file.close()
        else:
            self._file.flush()


def _changed(reg, data, old, after) -> dict:
    """{field: [old, new]} of the fields a write changed (``after`` None: a register the model
    does not store, e.g. an LPC GPIO pin register: the whole value as written)."""
    if after is None:
        return {reg.name: [old, data]} if old != data else {}
    w_mask = reg._masks.get("w", 0) if hasattr(reg, "_masks") else 0
    new = (after & ~w_mask) | (data & w_mask)
    out = {}
    for f in reg.fields:
        o, n = f.get(old), f.get(new)
        if o != n:
            out[f.name] = [o, n]
    return out


def load_logged(board: str, path_or_file, filter=None, **load_kwargs):
    """``mcusim.load(board, **load_kwargs)`` with a :class:`RegisterLog` from reset (start-up
    accesses included); the log is closed with the simulation. Returns ``(sim, log)``."""
    from .sim import load
    with capture_startup() as startup:
        try:
            sim = load(board, **load_kwargs)
        except BaseException:
            release(startup)
            raise
    log = RegisterLog(sim, path_or_file, filter=filter, startup=startup)
    sim._traces.append(log)
    return sim, log
