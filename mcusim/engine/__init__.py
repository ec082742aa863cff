"""The two engines that run one model (see docs/engine.md).

* ``reference``: every edge is its own kernel event (a PWM output toggles its net twice per period,
  the plant rebuilds its segment at every toggle). Simple, slow, the truth.
* ``fast`` (the default): the same models skip work whose outcome is already determined. A timer whose
  registers do not change publishes a steady waveform (:mod:`.waveform`) instead of toggling its pins;
  a plant fed a steady waveform advances many PWM periods at once (:mod:`.periodmap`), screening its
  guards over whole chunks (:mod:`.screening`) and falling back to edge-by-edge work in the period
  where one may fire.

The engine is a property of the kernel (``kernel.fast``): every model asks it, nothing else is
switched.
"""

from __future__ import annotations

from ..errors import ConfigError

ENGINES = ("fast", "reference")
DEFAULT_ENGINE = "fast"


def check_engine(name) -> str:
    """The engine name, or a ConfigError that lists the choices."""
    if name not in ENGINES:
        raise ConfigError(f"unknown engine {name!r}: choose fast or reference")
    return name
