"""Checking what a user gives: firmware parameters (``firmware.kp=0.03``), firmware inputs
(``/motor1/set_pos=1.57``, ``velocity=10``) and plant-part parameters (``motor1.R=2.5``), each
converted to the type it must have and checked against its declared range or choices, or one
clear :class:`~mcusim.errors.ConfigError`.

A value is declared with :class:`Param`::

    DEFAULTS = {
        "pid_period_ms": Param(5, min=1, max=1000, unit="ms", doc="period of the PID tasks"),
        "variant": Param("correct", choices=("correct", "thesis")),
        "kp": Param(400.0, min=0, max=1e6, unit="%/rad"),
    }

The type is the default's (``bool``, ``int``, ``float``, ``str``, ``tuple``/``list``); numbers must
be finite; ``min``/``max`` are inclusive unless ``above``/``below`` (exclusive) are used instead;
``items`` checks every element of a list. A plain value in such a table (``"kp": 400.0``) is
checked for its type only.
"""

from __future__ import annotations

import math
import struct
import sys

from .errors import ConfigError

_TRUE, _FALSE = ("true", "1", "yes", "on"), ("false", "0", "no", "off")

#: the largest finite float: an integer beyond it (TOML and ``--set`` read 400 nines as one) is no
#: number a model can compute with
FLOAT_MAX = sys.float_info.max
TOO_LARGE = "too large (beyond ±1.8e308, the largest number)"


def shortest_f32(value: float) -> float:
    """The shortest decimal that is the same float32 as ``value`` (itself a float32 widened), as
    C's printf("%g") round trip gives it: 1.57f reads as 1.57, not 1.5700000524520874. A host reads
    a firmware's float messages so (an image's f32 topics, the ControlMotor port's)."""
    if not math.isfinite(value):
        return value
    raw = struct.pack("<f", value)
    for digits in range(1, 10):
        d = float(f"{value:.{digits}g}")
        try:
            if struct.pack("<f", d) == raw:
                return d
        except OverflowError:               # rounded past the largest float32
            continue
    return value


def fmt_number(x) -> str:
    """A number as a user wrote it: ``5``, ``0.25``, ``1e+06`` (no ``Fraction(...)``)."""
    if isinstance(x, bool):
        return str(x).lower()
    if isinstance(x, int):
        if abs(x) < 10**12:
            return str(x)
        if abs(x) <= sys.float_info.max:
            return f"{x:.6g}"
        if x.bit_length() > 14000:  # (str() refuses more than 4300 digits): its size alone
            return f"{'-' if x < 0 else ''}an integer of about {int(x.bit_length() * 0.30103)} digits"
        digits = str(abs(x))        # beyond a float: the leading digits and the power of ten
        return f"{'-' if x < 0 else ''}{digits[0]}.{digits[1:6]}e+{len(digits) - 1}"
    try:
        f = float(x)
    except (TypeError, ValueError, OverflowError):
        return repr(x)
    return f"{f:g}"


def _show(value) -> str:
    """A value in a message, short: a 300-digit number or a long string is cut."""
    text = repr(value) if isinstance(value, str) else (fmt_number(value) if isinstance(value, (int, float))
                                                       else repr(value))
    return text if len(text) <= 60 else text[:57] + "..."


def coerce(value, kind, what: str):
    """``value`` as ``kind`` (bool, int, float, str, tuple, list), or ConfigError naming ``what``.
    Numbers must be finite; a float with a whole value is accepted as an int."""
    if kind is bool:
        if isinstance(value, bool):
            return value
        text = str(value).strip().lower()
        if text in _TRUE:
            return True
        if text in _FALSE:
            return False
        # (a float shown as written: 0.0 is no switch position, while the whole number 0 is)
        shown = repr(value) if isinstance(value, float) else _show(value)
        raise ConfigError(f"{what} = {shown}: expected true or false")
    if kind in (int, float):
        want = "an integer" if kind is int else "a number"
        if isinstance(value, bool):
            raise ConfigError(f"{what} = {_show(value)}: expected {want}")
        try:
            out = float(value) if isinstance(value, str) else value
            if not isinstance(out, (int, float)):
                raise TypeError
        except (TypeError, ValueError):
            raise ConfigError(f"{what} = {_show(value)}: expected {want}") from None
        if isinstance(out, float) and not math.isfinite(out):
            raise ConfigError(f"{what} = {_show(value)}: expected a finite number")
        if isinstance(out, int) and not -FLOAT_MAX <= out <= FLOAT_MAX:
            raise ConfigError(f"{what} = {_show(value)}: {TOO_LARGE}")
        if kind is int:
            if isinstance(out, float) and not out.is_integer():
                raise ConfigError(f"{what} = {_show(value)}: expected {want}")
            return int(out)
        return float(out)
    if kind in (tuple, list):
        if not isinstance(value, (tuple, list)):
            raise ConfigError(f"{what} = {_show(value)}: expected a list")
        return kind(value)
    if not isinstance(value, str):
        raise ConfigError(f"{what} = {_show(value)}: expected a string")
    return value


def _hertz(text: str, what: str, kind):
    """A frequency written with its unit (``"400kHz"``) for a parameter in hertz: a number of
    hertz (a whole one for an integer parameter), or ConfigError naming ``what``."""
    from .errors import TimeError
    from .time import parse_frequency
    try:
        hz = parse_frequency(text)
    except TimeError as exc:
        raise ConfigError(f"{what}: {exc}") from None
    if kind is int:
        if hz.denominator != 1:
            raise ConfigError(f"{what} = {_show(text)}: expected a whole number of hertz")
        return int(hz)
    try:
        return float(hz)
    except OverflowError:
        raise ConfigError(f"{what} = {_show(text)}: {TOO_LARGE}") from None




class Param:
    """A declared value: default, type, range or choices, unit and a line of documentation."""

    def __init__(self, default, *, min=None, max=None, above=None, below=None, choices=None,
                 items: Param | None = None, length=None, unit: str = "", doc: str = "", kind=None,
                 unique: str | None = None, required: bool = False):
        self.default = default
        self.required = required   # a kind's parameter the profile must give (no default fits)
        self.kind = kind or (float if isinstance(default, float) else type(default))
        self.min, self.max, self.above, self.below = min, max, above, below
        self.choices = tuple(choices) if choices is not None else None
        self.items, self.length, self.unit, self.doc = items, length, unit, doc
        # ``unique="i2c"``: no two boards of a system may take the same value (a bus address)
        self.unique = unique

    def range_text(self) -> str:
        """``from 1 to 1000 ms``, ``above 0 Ω``, ``one of correct, thesis`` (empty if unbounded)."""
        u = f" {self.unit}" if self.unit else ""
        lo = (f"{fmt_number(self.min)}", False) if self.min is not None else \
            (f"{fmt_number(self.above)}", True) if self.above is not None else None
        hi = (f"{fmt_number(self.max)}", False) if self.max is not None else \
            (f"{fmt_number(self.below)}", True) if self.below is not None else None
        if self.choices is not None:
            return "one of " + ", ".join(str(c) for c in self.choices)
        if lo and hi:
            if not lo[1] and not hi[1]:
                return f"from {lo[0]} to {hi[0]}{u}"
            return f"{'above' if lo[1] else 'at least'} {lo[0]} and {'below' if hi[1] else 'at most'} {hi[0]}{u}"
        if lo:
            return f"{'above' if lo[1] else 'at least'} {lo[0]}{u}"
        if hi:
            return f"{'below' if hi[1] else 'at most'} {hi[0]}{u}"
        return ""

    def check(self, value, what: str):
        """``value`` converted and checked, or ConfigError ``<what> = <value>: must be ...``."""
        if self.kind is str and isinstance(value, bool) and self.choices is not None:
            # ``--set ibt2.cl_action=off`` reads off as false: the one choice spelled as such a word
            words = _TRUE if value else _FALSE
            hits = [c for c in self.choices if isinstance(c, str) and c.lower() in words]
            if len(hits) == 1:
                value = hits[0]
        given = value
        if self.unit == "Hz" and isinstance(value, str) and value.strip().lower().endswith("hz"):
            value = _hertz(value, what, self.kind)
        out = coerce(value, self.kind, what)
        if self.choices is not None:
            if out not in self.choices:
                raise ConfigError(f"{what} = {_show(value)}: expected {self.range_text()}")
            return out
        if isinstance(out, (tuple, list)):
            if self.length is not None and len(out) not in (
                    self.length if isinstance(self.length, (tuple, range)) else (self.length,)):
                n = self.length
                want = (f"{n.start} to {n.stop - 1}" if isinstance(n, range) else
                        " or ".join(map(str, n)) if isinstance(n, tuple) else str(n))
                raise ConfigError(f"{what} = {_show(value)}: expected a list of {want} values")
            if self.items is not None:
                out = type(out)(self.items.check(v, f"{what}[{i}]") for i, v in enumerate(out))
            return out
        if isinstance(out, (int, float)) and not isinstance(out, bool):
            bad = ((self.min is not None and out < self.min) or (self.max is not None and out > self.max)
                   or (self.above is not None and out <= self.above)
                   or (self.below is not None and out >= self.below))
            if bad:
                raise ConfigError(f"{what} = {_show(given)}: must be {self.range_text()}")
        return out

    def check_file(self, value, what: str):
        """:meth:`check` for a value written in a profile (TOML has types of its own): a number, a
        true/false or a list written as text (``counts_per_rev = "48"``) is refused, not read as
        one; a ``--set`` value arrives as text and goes to :meth:`check`."""
        if isinstance(value, str) and self.kind in (int, float, bool, tuple, list) and not (
                self.unit == "Hz" and value.strip().lower().endswith("hz")):
            want = {int: "an integer", float: "a number", bool: "true or false"}.get(self.kind, "a list")
            raise ConfigError(f"{what} = {_show(value)}: expected {want}, not text (write it without quotes)")
        if isinstance(value, (tuple, list)) and self.items is not None and self.kind in (tuple, list):
            for i, v in enumerate(value):
                self.items.check_file(v, f"{what}[{i}]")
        return self.check(value, what)

    def describe(self) -> str:
        """One line for documentation and ``mcusim keys``: type, default, range, doc."""
        kind = {bool: "true/false", int: "integer", float: "number", str: "text", tuple: "list",
                list: "list"}.get(self.kind, self.kind.__name__)
        rng = self.range_text()
        default = (fmt_number(self.default) if isinstance(self.default, (int, float)) else
                   "none" if self.default in ("", None) else ", ".join(map(fmt_number, self.default))
                   if isinstance(self.default, (tuple, list)) else self.default)
        parts = [kind, "required" if self.required else f"default {default}"] + ([rng] if rng else [])
        return ", ".join(parts) + (f": {self.doc}" if self.doc else "")


def declared(spec) -> Param:
    """A :class:`Param` for a table entry (a Param, or a plain default: type check only)."""
    return spec if isinstance(spec, Param) else Param(spec)


def check_params(declarations: dict, params: dict, prefix: str) -> dict:
    """``params`` checked against ``declarations`` (name -> Param or plain default): unknown
    names and bad values raise ConfigError ``<prefix>.<name> ...``. Returns the converted values
    of the given names only."""
    unknown = set(params) - set(declarations)
    if unknown:
        raise ConfigError(f"unknown parameter{'s' if len(unknown) > 1 else ''} "
                          f"{', '.join(f'{prefix}.{n}' for n in sorted(unknown))} "
                          f"(known: {', '.join(sorted(declarations))})")
    return {name: declared(declarations[name]).check(value, f"{prefix}.{name}") for name, value in params.items()}


def firmware_params(defaults: dict, params: dict) -> dict:
    """The firmware's parameters: ``defaults`` (name -> :class:`Param` or plain default) overridden
    by ``params``, each converted and checked; an unknown name or a bad value raises ConfigError."""
    unknown = sorted(set(params) - set(defaults))
    if len(unknown) == 1:       # named first, as the key was written: a message located at its line
        raise ConfigError(f"firmware.{unknown[0]}: unknown firmware parameter (known: {', '.join(sorted(defaults))})")
    if unknown:
        raise ConfigError(f"unknown firmware parameters {', '.join(f'firmware.{k}' for k in unknown)} "
                          f"(known: {', '.join(sorted(defaults))})")
    out = {name: declared(spec).default for name, spec in defaults.items()}
    out.update(check_params(defaults, params, "firmware"))
    return out


# --- durations a user writes -------------------------------------------------------------------

def fmt_duration(t) -> str:
    """Exact seconds (a Fraction) for a message: ``2ms``, ``1.5us``, ``1e+400s``."""
    from decimal import Decimal
    from fractions import Fraction
    t = Fraction(t)
    if t == 0:
        return "0s"
    if abs(t) < Fraction(1, 10**15):     # below a thousandth of a ps: in seconds (1e-300s, not 1e-288ps)
        return f"{Decimal(t.numerator) / Decimal(t.denominator):.6g}s"
    for unit, scale in (("s", 1), ("ms", 10**3), ("us", 10**6), ("ns", 10**9), ("ps", 10**12)):
        if abs(t) >= Fraction(1, scale) or unit == "ps":
            v = t * scale
            try:
                return f"{float(v):.12g}{unit}"
            except OverflowError:
                return f"{Decimal(v.numerator) / Decimal(v.denominator):.6g}{unit}"
    return f"{t}s"   # not reached


def a_or_an(word: str) -> str:
    """``word`` with its indefinite article, as it is read: "an estop", "an 8-bit", "a uart"."""
    first = str(word)[:1].lower()
    return f"{'an' if first in 'aeio8' or str(word)[:2] in ('11', '18') else 'a'} {word}"


def fmt_duration_exact(t) -> str:
    """:func:`fmt_duration`, with as many digits as it takes to tell ``t`` from its twelve-digit
    rounding (``1.0000000000000000000000001ms``, which a message about ticks must not show as
    ``1ms``); up to 40 digits."""
    from decimal import Context, Decimal
    from fractions import Fraction
    t = Fraction(t)
    shown = fmt_duration(t)
    unit = shown.lstrip("+-0123456789.e").removeprefix("+") or "s"
    scale = {"s": 1, "ms": 10**3, "us": 10**6, "ns": 10**9, "ps": 10**12}.get(unit)
    if scale is None or Fraction(shown[:-len(unit)]) / scale == t:
        return shown
    v = t * scale
    digits = Context(prec=40).divide(Decimal(v.numerator), Decimal(v.denominator))
    return f"{digits.normalize():f}{unit}"


def user_duration(value, what: str, *, positive: bool = True, maximum=None, max_hint: str = ""):
    """A duration as a user gives it (``"500ms"``, ``"2s"``; a unit is required) -> exact seconds
    (Fraction). Finite, positive (or not negative), at most ``maximum`` seconds if given;
    otherwise ConfigError ``<what> ...``. A Fraction (already exact) is taken as seconds."""
    from fractions import Fraction

    from .errors import TimeError
    from .time import parse_duration
    if isinstance(value, Fraction):
        seconds = value
    elif isinstance(value, bool) or not isinstance(value, str):
        raise ConfigError(f"{what} = {_show(value)}: expected a duration with a unit, such as \"500ms\" or \"2s\"")
    else:
        text = value.strip()
        if text and text[-1].isdigit() or text.endswith("."):
            try:
                zero = float(text) == 0.0
            except ValueError:
                zero = False
            hint = "such as 500ms or 2s" if zero and positive else f"such as {text}s or {text}ms"
            raise ConfigError(f"{what} {_show(value)}: a duration needs a unit (s, ms, us, ns, ps or min), "
                              + hint)
        try:
            seconds = parse_duration(text)
        except TimeError as exc:
            raise ConfigError(f"{what}: {exc}") from None
    if seconds < 0 or (positive and seconds == 0):
        shown = value.strip() if isinstance(value, str) else fmt_duration(seconds)   # as the user wrote it
        raise ConfigError(f"{what} {shown}: must be {'positive' if positive else 'at least 0s'}")
    if maximum is not None and seconds > maximum:
        raise ConfigError(f"{what} {fmt_duration(seconds)}: longer than the limit of {fmt_duration(maximum)}"
                          + (f" ({max_hint})" if max_hint else ""))
    return seconds


class DurationParam(Param):
    """A declared duration (``step = "1ms"``): a string with a unit, ``min``/``max`` in seconds."""

    def __init__(self, default: str, *, min=None, max=None, doc: str = ""):
        super().__init__(default, min=min, max=max, doc=doc, kind=str)

    def range_text(self) -> str:
        lo = fmt_duration(self.min) if self.min is not None else None
        hi = fmt_duration(self.max) if self.max is not None else None
        return f"from {lo} to {hi}" if lo and hi else f"at least {lo}" if lo else f"at most {hi}" if hi else ""

    def check(self, value, what: str):
        from fractions import Fraction
        seconds = user_duration(value, what)
        if (self.min is not None and seconds < Fraction(self.min)) or (self.max is not None and seconds > Fraction(self.max)):
            raise ConfigError(f"{what} = {_show(value)}: must be {self.range_text()}")
        return seconds

    def describe(self) -> str:
        return f"duration, default {self.default}, {self.range_text()}" + (f": {self.doc}" if self.doc else "")
