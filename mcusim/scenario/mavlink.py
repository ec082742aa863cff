"""MAVLink in scenario files: the ``mavlink`` action of ``[[at]]`` (send a message) and
``[[expect]]`` tables with ``mavlink = "<MESSAGE>"`` (a message received by a time).

A scenario that uses either gets one ground station (:class:`mcusim.mavlink.MavlinkClient`, system
255, component 190, a GCS HEARTBEAT every simulated second) on the firmware's MAVLink UART.
Message and field names are pymavlink's (``common`` dialect): ``COMMAND_LONG``,
``target_system``... Omitted fields are 0 (empty for strings and arrays).

Expectation: passes if a message of that type, received after ``after`` (default: from the start)
and by ``time`` (default: the end of the run), has every field in ``fields`` equal to the value
given; a ``float`` field is compared with the value rounded to float32 (what the wire carries), or
within ``tol`` when given; an array given with fewer elements than the field has is compared on
those first elements. A failure says how many messages of the type came and what the last one held.
"""

from __future__ import annotations

import math
import struct
from fractions import Fraction

from .check import _fmt_time
from .expect import PRIO_CHECK, ExpectResult

MAVLINK_EXPECT_KEYS = ("name", "time", "mavlink", "fields", "after", "tol")
INT_TYPES = ("int8_t", "uint8_t", "int16_t", "uint16_t", "int32_t", "uint32_t", "int64_t", "uint64_t")


def _dialect():
    from ..mavlink import _dialect
    return _dialect()


def message_class(sc, name, line, where):
    ml = _dialect()
    cls = ml.mavlink_map.get(getattr(ml, f"MAVLINK_MSG_ID_{name}", -1)) if isinstance(name, str) else None
    if cls is None:
        raise sc._err(line, f"{where}: {name!r} is not a MAVLink message of the common dialect "
                      "(e.g. COMMAND_LONG, SET_POSITION_TARGET_LOCAL_NED, PARAM_SET, HEARTBEAT)")
    return cls


def _type(cls, field) -> tuple:
    """(C type, array length or 0) of a field (``array_lengths`` is in wire order)."""
    n = dict(zip(cls.ordered_fieldnames, cls.array_lengths))[field]
    return cls.fieldtypes[cls.fieldnames.index(field)], n


def _field_value(sc, cls, field, value, line, where):
    """``value`` checked against the field's type (an int in range, a number, a string)."""
    kind, n = _type(cls, field)
    if kind == "char":
        if not isinstance(value, str) or len(value.encode()) > n:
            raise sc._err(line, f"{where}: {field} = {value!r}: expected a string of at most {n} bytes")
        return value.encode()
    if n:
        if not isinstance(value, list) or len(value) > n or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
            raise sc._err(line, f"{where}: {field} = {value!r}: expected a list of at most {n} numbers")
        return list(value) + [0] * (n - len(value))
    if kind in INT_TYPES:
        bits, signed = int("".join(c for c in kind if c.isdigit())), not kind.startswith("u")
        lo, hi = (-(1 << bits - 1), (1 << bits - 1) - 1) if signed else (0, (1 << bits) - 1)
        if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
            raise sc._err(line, f"{where}: {field} = {value!r}: expected a whole number from {lo} to {hi} ({kind})")
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise sc._err(line, f"{where}: {field} = {value!r}: expected a number ({kind})")
    return float(value)


def _fields(sc, cls, spec: dict, line_of, where) -> dict:
    out = {}
    for field, value in spec.items():
        if field not in cls.fieldnames:
            raise sc._err(line_of(field), f"{where}: {cls.msgname} has no field {field!r} (fields: "
                          f"{', '.join(cls.fieldnames)})")
        out[field] = _field_value(sc, cls, field, value, line_of(field), where)
    return out


def build_message(cls, fields: dict):
    args = []
    for name in cls.fieldnames:
        kind, n = _type(cls, name)
        default = b"" if kind == "char" else [0] * n if n else 0
        args.append(fields.get(name, default))
    return cls(*args)


def client_for(sc, sim):
    """The scenario's ground station on ``sim`` (made on first use)."""
    if getattr(sc, "_gcs", None) is None or sc._gcs.sim is not sim:
        from ..mavlink import MavlinkClient, mavlink_port
        uart, member = mavlink_port(sim)
        sc._gcs = MavlinkClient(sim, uart, member=member)
    return sc._gcs


# --- the action ---------------------------------------------------------------------------------------
class SendMavlink:
    """``mavlink = { message = "COMMAND_LONG", target_system = 1, command = 400, param1 = 1 }``."""

    def parse(self, sc, i, name, spec):
        where, line = f"[[at]] #{i + 1}: mavlink", sc._line("at", i, name)
        if not isinstance(spec, dict) or "message" not in spec:
            raise sc._err(line, f"{where}: expected a table {{ message = \"COMMAND_LONG\", <field> = value, ... }}")
        cls = message_class(sc, spec["message"], sc._line("at", i, name, "message"), where)
        rest = {k: v for k, v in spec.items() if k != "message"}
        fields = _fields(sc, cls, rest, lambda f: sc._line("at", i, name, f), where)
        build_message(cls, fields)
        return {"message": spec["message"], "fields": fields}

    def prepare(self, sc, sim, spec, line, where):
        from ..errors import ConfigError
        try:
            gcs = client_for(sc, sim)
        except ConfigError as exc:
            raise sc._err(line, f"{where}: {exc}") from None
        cls = message_class(sc, spec["message"], line, where)
        msg = build_message(cls, spec["fields"])
        try:
            msg.pack(gcs.mav)
        except (struct.error, TypeError, ValueError) as exc:
            raise sc._err(line, f"{where}: {spec['message']} does not pack: {exc}") from None

        def fn():
            gcs.mav.send(msg)
            sc._done(f"mavlink {spec['message']} " + " ".join(f"{k}={v!r}" for k, v in spec["fields"].items()))
        return fn


# --- the expectation ----------------------------------------------------------------------------------
class MavlinkExpect:
    """A parsed ``[[expect]]`` with ``mavlink = "<MESSAGE>"``."""

    def __init__(self, sc, i: int, e: dict):
        where = f"[[expect]] #{i + 1}"
        sc._unknown("expect", i, e, MAVLINK_EXPECT_KEYS)
        self.index, self.line = i, sc._line("expect", i)
        self.cls = message_class(sc, e["mavlink"], sc._line("expect", i, "mavlink"), where)
        self.time = sc._value("expect", i, ("time",), e["time"], "duration") if "time" in e else None
        if self.time is not None and self.time > sc._horizon:
            raise sc._err(sc._line("expect", i, "time"), f"{where}: time {_fmt_time(self.time)} is after the "
                          f"end of the run (duration {_fmt_time(sc._horizon)}); leave time out for the end")
        self.after = sc._value("expect", i, ("after",), e["after"], "duration") if "after" in e else Fraction(0)
        if self.after > (sc._horizon if self.time is None else self.time):
            raise sc._err(sc._line("expect", i, "after"), f"{where}: after {_fmt_time(self.after)} is later than "
                          + (f"time {_fmt_time(self.time)}" if self.time is not None else
                             f"the end of the run (duration {_fmt_time(sc._horizon)})"))
        spec = e.get("fields", {})
        if not isinstance(spec, dict):
            raise sc._err(sc._line("expect", i, "fields"), f"{where}: fields = {{ <field> = value, ... }}")
        self.fields = _fields(sc, self.cls, spec, lambda f: sc._line("expect", i, "fields", f), where)
        for field, value in spec.items():       # an array given in part: only that prefix is compared
            if isinstance(value, list):
                self.fields[field] = self.fields[field][:len(value)]
        self.tol = sc._value("expect", i, ("tol",), e["tol"], "number") if "tol" in e else None
        if self.tol is not None and self.tol < 0:
            raise sc._err(sc._line("expect", i, "tol"), f"{where}: tol must not be negative")
        shown = ", ".join(f"{k}={v.decode() if isinstance(v, bytes) else v!r}" for k, v in spec.items())
        self.expected = f"{self.cls.msgname}" + (f" with {shown}" if shown else "")
        when = f"by {_fmt_time(self.time)}" if self.time is not None else "by the end"
        self.name = (sc._value("expect", i, ("name",), e["name"], "str") if "name" in e
                     else f"MAVLink {self.cls.msgname} {when}")
        self.result = None

    def _matches(self, m) -> bool:
        for field, want in self.fields.items():
            got = getattr(m, field)
            kind = self.cls.fieldtypes[self.cls.fieldnames.index(field)]
            if isinstance(want, bytes):
                want = want.decode()
            if isinstance(want, list):
                if len(got) < len(want) or not all(self._equal(kind, g, w) for g, w in zip(got, want)):
                    return False
            elif not self._equal(kind, got, want):
                return False
        return True

    def _equal(self, kind, got, want) -> bool:
        if kind not in ("float", "double"):
            return got == want
        if self.tol is not None:
            return abs(got - want) <= self.tol
        return (got == (want if kind == "double" else struct.unpack("<f", struct.pack("<f", want))[0])
                or (math.isnan(got) and math.isnan(want)))

    def _shown(self, m) -> str:
        """The expected fields as ``m`` has them."""
        return ", ".join(f"{f}={getattr(m, f)!r}" for f in self.fields) or str(m)

    def plan(self, sc, sim, end: int) -> tuple:
        where = f"[[expect]] #{self.index + 1}"
        from ..errors import ConfigError
        try:
            gcs = client_for(sc, sim)
        except ConfigError as exc:
            raise sc._err(self.line, f"{where}: {exc}") from None
        tb = sim.timebase
        tick = end if self.time is None else sc._ticks(tb, self.time, sc._line("expect", self.index, "time"),
                                                         f"{where}: time")
        after = tb.ticks(self.after, rounding=True)
        # the messages of this type from `after` on, as they arrive (the client's log keeps the
        # recent ones only): how many, the last one, the tick of the first that matches
        seen = {"n": 0, "last": None, "hit": None}
        name = self.cls.msgname

        def watch(t, m):
            if t >= after and m.get_type() == name:
                seen["n"] += 1
                seen["last"] = m
                if seen["hit"] is None and self._matches(m):
                    seen["hit"] = t
        gcs.watchers.append(watch)

        def check():
            gcs.watchers.remove(watch)
            hit = seen["hit"]
            if hit is not None:
                got = f"received at {hit / tb.base_hz:.6f} s"
            elif seen["n"]:
                got = f"{seen['n']} received, none matched; last: {self._shown(seen['last'])}"
            else:
                got = "not received"
            self.result = ExpectResult(self.name, sim.time_s, self.expected, got, hit is not None, self.line)
        return tick, PRIO_CHECK, check
