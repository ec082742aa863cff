"""Checking what a user gives a firmware: its parameters (``firmware.kp=0.03``) and its inputs
(``/motor1/set_pos=1.57``, ``velocity=10``), converted to the type they must have, or one clear
:class:`~mcusim.errors.ConfigError`."""

from __future__ import annotations

import math

from .errors import ConfigError

_TRUE, _FALSE = ("true", "1", "yes", "on"), ("false", "0", "no", "off")


def coerce(value, kind, what: str):
    """``value`` as ``kind`` (bool, int, float, str, tuple, list), or ConfigError naming ``what``."""
    if kind is bool:
        if isinstance(value, bool):
            return value
        text = str(value).strip().lower()
        if text in _TRUE:
            return True
        if text in _FALSE:
            return False
        raise ConfigError(f"{what} = {value!r}: expected true or false")
    if kind in (int, float):
        if isinstance(value, bool) or (kind is int and isinstance(value, float) and not value.is_integer()):
            raise ConfigError(f"{what} = {value!r}: expected {'an integer' if kind is int else 'a number'}")
        try:
            out = kind(value) if not isinstance(value, str) else kind(float(value) if kind is int else value)
        except (TypeError, ValueError):
            raise ConfigError(f"{what} = {value!r}: expected {'an integer' if kind is int else 'a number'}") from None
        if kind is float and not math.isfinite(out):
            raise ConfigError(f"{what} = {value!r}: expected a finite number")
        return out
    if kind in (tuple, list):
        if not isinstance(value, (tuple, list)):
            raise ConfigError(f"{what} = {value!r}: expected a list")
        return kind(value)
    return str(value)


def firmware_params(defaults: dict, params: dict) -> dict:
    """The firmware's parameters: ``defaults`` overridden by ``params``, each converted to the type
    of its default; an unknown name or a wrong type raises ConfigError."""
    unknown = set(params) - set(defaults)
    if unknown:
        raise ConfigError(f"unknown firmware parameter(s): {', '.join(sorted(unknown))} "
                          f"(known: {', '.join(sorted(defaults))})")
    out = dict(defaults)
    for name, value in params.items():
        default = defaults[name]
        kind = float if isinstance(default, float) else type(default)
        if isinstance(default, int) and not isinstance(default, bool) and isinstance(value, float):
            kind = float if not value.is_integer() else int
        out[name] = coerce(value, kind, f"firmware.{name}")
    return out
