"""Checked reading: the values of a scenario file and the names it gives in a built simulation
(parts, boards, topics, whole ticks). Every mistake is one :class:`~mcusim.errors.ConfigError`
``<file>:<line>: <problem>``; :class:`Checker` is the base of :class:`~.model.Scenario` and the
parsers and preparers of ``actions`` and ``expect`` call its methods on the scenario."""

from __future__ import annotations

import math
import sys

from ..errors import ConfigError, McusimError, TimeError
from ..params import _show, a_or_an, fmt_duration, user_duration

# part kinds a key may name: the methods a part of that kind has
PART_KINDS = {
    "motor": ("apply_load_torque", "set_state", "set_params"),
    "encoder": ("glitch", "drop_edges"),
    "battery": ("set_soc", "connect"),
    "estop": ("press", "release"),
    "bts7960": ("overtemperature", "clear_overtemperature"),
}


def _fmt_time(t) -> str:
    """``Fraction(1, 500)`` -> ``"2ms"``; None (the end of the run) -> ``"end"``."""
    if t is None:
        return "end"
    return fmt_duration(t)


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


class Checker:
    """File:line errors and checked values; needs ``path`` and ``_lines`` (a ``_Lines``)."""

    path: str

    # --- errors -------------------------------------------------------------------------------
    def _err(self, line: int, msg: str) -> ConfigError:
        return ConfigError(f"{self.path}:{line}: {msg}")

    def _line(self, table=None, index=None, *key) -> int:
        return self._lines.line(table, index, key)

    @staticmethod
    def _where(table, index) -> str:
        return f"[[{table}]] #{index + 1}" if index is not None else f"[{table}]"

    def _unknown(self, table, index, d: dict, known, what="key", key=()):
        for k in d:
            if k not in known:
                raise self._err(self._line(table, index, *key, k),
                                f"{self._where(table, index)}: unknown {what} {k!r} (known: {', '.join(known)})")

    # --- values of the file -------------------------------------------------------------------
    def _value(self, table, index, key: tuple, value, typ: str):
        """``value`` checked as ``typ`` (str, number, int, bool, duration); durations as Fractions."""
        where = f"{self._where(table, index)}: {'.'.join(key)}"
        line = self._line(table, index, *key)
        if typ == "duration":
            try:
                return user_duration(value, where, positive=False)
            except ConfigError as exc:
                raise self._err(line, str(exc)) from None
        ok = {"str": lambda v: isinstance(v, str) and v != "", "number": _is_number,
              "int": lambda v: isinstance(v, int) and not isinstance(v, bool),
              "bool": lambda v: isinstance(v, bool)}[typ]
        if not ok(value):
            want = {"str": "a non-empty string", "number": "a number", "int": "a whole number",
                    "bool": "true or false"}[typ]
            shown = str(value).lower() if isinstance(value, bool) else _show(value)   # as TOML writes it
            raise self._err(line, f"{where} = {shown}: expected {want}")
        return value

    def _fields(self, table, index, key: tuple, spec, fields: dict) -> dict:
        where = f"{self._where(table, index)}: {'.'.join(key)}"
        if not isinstance(spec, dict):
            raise self._err(self._line(table, index, *key),
                            f"{where} = {spec!r}: expected a table {{ {', '.join(fields)} }}")
        self._unknown(table, index, spec, tuple(fields), key=key)
        out = {}
        for name, (typ, required) in fields.items():
            if name in spec:
                out[name] = self._value(table, index, key + (name,), spec[name], typ)
            elif required:
                raise self._err(self._line(table, index, *key), f"{where}: missing {name} = ...")
        return out

    # --- names in the simulation ----------------------------------------------------------------
    def _ticks(self, tb, t, line, what) -> int:
        try:
            return tb.ticks(t)
        except TimeError:
            raise self._err(line, f"{what} = {_fmt_time(t)} is not a whole number of base ticks "
                            f"(1/{tb.base_hz} s)") from None

    def _part(self, sim, name, kind, line, where):
        part = sim.parts.get(name)
        if part is None:
            raise self._err(line, f"{where}: no part {name!r} on {sim.board_name} "
                            f"(parts: {', '.join(sim.parts)})")
        if not all(hasattr(part, m) for m in PART_KINDS[kind]):
            fit = [n for n, p in sim.parts.items() if all(hasattr(p, m) for m in PART_KINDS[kind])]
            raise self._err(line, f"{where}: part {name!r} is not {a_or_an(kind)} "
                            f"({kind} parts: {', '.join(fit) or 'none'})")
        return part

    def _firmware_for(self, sim, topic, line, where):
        """(firmware, name) for a topic, as :meth:`mcusim.sim.Simulation.firmware_for` resolves it
        (``"mcm2.velocity"``: a member board's); a mistake at the scenario's line."""
        try:
            return sim.firmware_for(topic)
        except ConfigError as exc:
            raise self._err(line, f"{where}: {exc}") from None

    def _check_input(self, fw, name, line, where, value=None, members=()):
        """``members``: in a system whose main firmware ``fw`` is, the other boards, whose inputs
        are given as ``<board>.<input>``."""
        topics = getattr(fw, "topics", None)
        if isinstance(topics, dict):
            inputs = [n for n, t in topics.items() if getattr(t, "direction", "sub") == "sub"]
        else:
            inputs = getattr(sys.modules.get(type(fw).__module__), "HOST_INPUTS", None)
        if inputs is not None and name not in inputs:
            more = (f"; a board's own input as <board>.<input>, boards: {', '.join(members)}"
                    if members else "")
            raise self._err(line, f"{where}: the firmware takes no input {name!r} (inputs: "
                            f"{', '.join(inputs)}{more})")
        if value is not None and hasattr(fw, "check_input"):
            try:
                fw.check_input(name, value)
            except McusimError as exc:
                raise self._err(line, f"{where}: {exc}") from None

    def _check_output(self, fw, name, line, where):
        try:
            fw.topic(name)
        except McusimError as exc:
            raise self._err(line, f"{where}: {exc}") from None
