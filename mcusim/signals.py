"""Digital nets (pins) with edge listeners, and analog nets.

A :class:`Net` is driven by at most one level at a time. Drivers are named (``"GPIOE"``,
``"encoder1"``); an external stimulus (``drive()``) overrides every driver until ``release()``.
Listeners are called synchronously, at the current kernel time, when the resolved level changes.
"""

from __future__ import annotations

import math
from fractions import Fraction

from .errors import McusimError


def _level(level, what: str) -> int:
    """A digital level given from Python: 0 or 1 (False, True), else one clear error."""
    if level in (0, 1):         # 0, 1, False, True, 0.0, 1.0 (a level read back from a CSV)
        return int(level)
    raise McusimError(f"{what}({level!r}): a digital level is 0 or 1")

class _Carrier:
    """Listeners and steady waveforms, shared by :class:`Net` and :class:`Port`.

    A listener registered with ``listen(fn)`` needs every edge: while a waveform
    (:class:`mcusim.engine.waveform.Waveform`) is present, the carrier *expands* it into one kernel
    event per edge for such listeners. ``listen(fn, waves=True)`` registers a listener that handles
    waveforms itself: it is called on every level change while no waveform is present, and once
    whenever the waveform starts, changes or ends (read ``.wave``). ``waves`` may also be a callable:
    the listener handles waveforms itself only while it returns true (its owner calls
    :meth:`refresh` when that may have changed).

    A level need not be periodic: a *descriptor* computed on demand (an encoder output derived from
    the shaft angle, :class:`mcusim.plant.encoder.ShaftCode`) has ``level_at`` but no edges to
    expand. Its driver publishes it only where every listener takes it: ``listen(fn, waves=...,
    sinks=f)`` declares that ``f(descriptor)`` names the models that would read it, as a list of
    (model, key), or None when one of them needs edges (:meth:`Net.wave_sinks`). A listener
    without ``sinks`` never takes one; if it arrives while a descriptor is present, the
    descriptor's ``release()`` turns it back into levels.
    """

    __slots__ = ()

    def _init_listeners(self):
        self._listeners = []    # need every edge
        self._wlisteners = []   # (fn, predicate or None): handle waveforms themselves
        self._exp_ev = None     # next edge event of the expander

    def listen(self, fn, waves=False, sinks=None) -> None:
        if waves is False:
            self._listeners.append(fn)
        else:
            self._wlisteners.append((fn, None if waves is True else waves, sinks))
        w = self.wave
        if w is not None and hasattr(w, "release") and self.wave_sinks(w) is None:
            w.release()     # a listener that cannot read the descriptor: levels from now on
        self.refresh()

    def wave_sinks(self, desc):
        """The models that would read the descriptor ``desc`` on this carrier, as (model, key)
        pairs, or None if a listener needs edges or cannot read it (class docstring)."""
        if self._listeners or getattr(self, "_forced", None) is not None or len(getattr(self, "_drivers", ())) > 1:
            return None
        out = []
        for _fn, _pred, sinks in self._wlisteners:
            got = None if sinks is None else sinks(desc)
            if got is None:
                return None
            out.extend(got)
        return out

    def _edge_listeners(self):
        out = list(self._listeners)
        for fn, pred, _ in self._wlisteners:
            if pred is not None and not pred():
                out.append(fn)
        return out

    def _notify(self, level_changed: bool, wave_changed: bool) -> None:
        """Call the listeners after a change of the resolved level and/or of the waveform. While a
        waveform is present, a level change is an expanded edge: only edge listeners hear it."""
        if level_changed:
            for fn in self._listeners:
                fn(self)
        if self._wlisteners:
            expanded = self.wave is not None and not wave_changed
            for fn, pred, _ in self._wlisteners:
                if pred is None or pred():
                    if wave_changed or (level_changed and not expanded):
                        fn(self)
                elif level_changed:
                    fn(self)

    # --- the expander: edges as events for the listeners that need them --------------------------
    def _wave_sources(self):
        raise NotImplementedError

    def refresh(self) -> None:
        """(Re)start or stop the expander after a change of waveforms or listeners."""
        if self._exp_ev is not None:
            self._exp_ev.cancel()
            self._exp_ev = None
        else:
            self._catch_up()    # no expander kept the stored level: bring it to now
        waves = self._wave_sources()
        if not waves:
            return
        if self.wave is not None and not self._edge_listeners():
            return      # everyone reads the descriptor
        for w in waves:
            if hasattr(w, "release"):   # a level descriptor has no edges to expand (a drive, a
                w.release()             # second driver, a listener that needs edges): levels
                return
        kernel = waves[0].kernel
        ts = [t for w, t in ((w, w.next_edge(kernel.now)[0]) for w in waves) if w.end is None or t < w.end]
        if not ts:
            return      # the owner publishes again before the next edge
        from .kernel import PRIO_HW
        self._exp_ev = kernel.at(min(ts), self._expand, prio=PRIO_HW)

    def _expand(self) -> None:
        self._exp_ev = None
        self._resolve(expanding=True)
        if self._exp_ev is None:
            self.refresh()


class Net(_Carrier):
    __slots__ = ("_drivers", "_exp_ev", "_forced", "_listeners", "_lvl", "_wlisteners", "name", "pull",
                 "wave")

    def __init__(self, name: str, level: int = 0, pull: int | None = None):
        self.name = name
        self.pull = pull  # level when nothing drives the net (None: keeps its last level)
        self._lvl = level if pull is None else pull
        self._drivers: dict = {}   # driver -> 0/1, or a Waveform
        self._forced: int | None = None
        self.wave = None           # the net's level is this waveform (one driver gives it)
        self._init_listeners()

    @property
    def level(self) -> int:
        w = self.wave
        return self._lvl if w is None else w.level_at(w.kernel.now)

    def set(self, driver: str, level: int | None) -> None:
        """Driver ``driver`` drives ``level`` (0/1), or releases the net with ``None``."""
        if level is None:
            self._drivers.pop(driver, None)
        else:
            self._drivers[driver] = 1 if level else 0
        self._resolve()

    def settle(self, driver: str, level: int) -> None:
        """Driver ``driver``, the net's only one, drives ``level``; every listener has already had
        the changes up to it, served in closed form (the fast engine's served edges,
        :mod:`mcusim.engine.served`), so none is called."""
        self._drivers[driver] = self._lvl = 1 if level else 0

    def set_wave(self, driver: str, wave) -> None:
        """Driver ``driver`` drives a steady waveform from now on (until its next set/set_wave)."""
        self._drivers[driver] = wave
        self._resolve()
        if self.wave is None and len(self._drivers) > 1:
            # several drivers: the expander that checks them for contention follows the new
            # descriptor (one planned from the old one would expand an edge past its end)
            self.refresh()

    def set_pull(self, level: int | None) -> None:
        """Change the level the net takes when nothing drives it (a board pull-up or pull-down)."""
        self.pull = level
        self._resolve()

    def drive(self, level: int) -> None:
        """External stimulus: force the level (0 or 1), taking the net away from every driver."""
        self._forced = _level(level, "drive")
        self._resolve()

    def release(self) -> None:
        self._forced = None
        self._resolve()

    @property
    def forced(self) -> bool:
        return self._forced is not None

    def _wave_sources(self):
        return [v for v in self._drivers.values() if type(v) is not int]

    def _catch_up(self) -> None:
        w = self.wave
        if w is not None:
            self._lvl = w.settled_level(w.kernel.now)

    def _resolve(self, expanding: bool = False) -> None:
        if self.wave is not None and self._exp_ev is None and not expanding:
            self._catch_up()                # no expander kept it: the level now, not a stale one
        wave = None
        if self._forced is not None:
            new = self._forced
        elif self._drivers:
            drivers = self._drivers
            if len(drivers) == 1:
                v = next(iter(drivers.values()))
                if type(v) is int:
                    new = v
                else:
                    wave, new = v, v.level
            else:
                levels = {v if type(v) is int else v.level for v in drivers.values()}
                if len(levels) > 1:
                    raise McusimError(f"contention on net {self.name}: drivers {sorted(drivers)} disagree")
                new = levels.pop()
        elif self.pull is not None:
            new = self.pull
        else:
            new = self._lvl
        old_wave = self.wave
        changed = new != self._lvl
        self._lvl = new
        if wave is None and old_wave is None:
            if changed:
                self._notify(True, False)
            if self._exp_ev is None and len(self._drivers) > 1:
                self.refresh()      # several drivers, one of them a waveform: expand for contention
            return
        self.wave = wave
        if wave is not old_wave:
            self.refresh()
            self._notify(changed, True)
        elif changed:   # an expanded edge (or a stale level caught up: then no edge listener exists)
            self._notify(True, False)

    def __repr__(self):
        return f"Net({self.name}={self.level})"


def pack_levels(nets) -> int:
    """The levels of ``nets`` as an integer, bit n the level of ``nets[n]`` (a port's PIN
    register; :attr:`Net.level` inlined: the encoder ISRs read PIND tens of thousands of times a
    simulated second)."""
    v, bit = 0, 1
    for net in nets:
        w = net.wave
        if (net._lvl if w is None else w.level_at(w.kernel.now)):
            v |= bit
        bit <<= 1
    return v


def exact_voltage(v) -> Fraction:
    """A voltage as an exact Fraction (a float through its shortest decimal form), so that an ADC's
    ``floor(V * 1024 / Vref)`` decides code boundaries exactly (2.5 V at 5 V is 512)."""
    if isinstance(v, (int, Fraction)):
        return Fraction(v)
    v = float(v)
    got = _EXACT.get(v)
    if got is None:
        if not math.isfinite(v):
            raise McusimError(f"ADC input voltage {v} is not a finite number")
        got = _decimal(repr(v))
        if len(_EXACT) >= 256:
            _EXACT.clear()
        _EXACT[v] = got
    return got


# recent conversions (a reference voltage is converted at every sample); -0.0 keys as 0.0, the
# same value
_EXACT: dict[float, Fraction] = {}


def _decimal(text: str) -> Fraction:
    """``Fraction(text)`` for a float's repr ("-1.25e-07", "12.5", "3e+20"), without the regular
    expression Fraction's string parser runs (a few times faster; an ADC converts every sample)."""
    mant, _, exp = text.partition("e")
    e = int(exp) if exp else 0
    whole, _, frac = mant.partition(".")
    n = int(whole + frac)               # int() takes the sign
    e -= len(frac)
    return Fraction(n * 10 ** e) if e >= 0 else Fraction(n, 10 ** -e)


class AnalogNet:
    """A voltage. Either set directly, or computed on demand by a source callable ``source(t)``.
    ``floating``: neither has happened (no part's output is wired to it and nothing set it), so
    the 0 V it reads stands for a pin left open."""

    def __init__(self, name: str, volts: float | None = None):
        self.name, self._volts, self.source = name, 0.0 if volts is None else volts, None
        self._set = volts is not None

    def set(self, volts: float) -> None:
        self._volts, self.source, self._set = float(volts), None, True

    @property
    def floating(self) -> bool:
        return self.source is None and not self._set

    def voltage(self, t: int | None = None) -> float:
        return self.source(t) if self.source is not None else self._volts


class Port(_Carrier):
    """A peripheral's output towards the pin mux: 0, 1, or ``None`` (not driving), or a steady
    waveform (:meth:`set_wave`, fast engine).

    Listeners ``fn(port)`` are called whenever the value changes, including to or from ``None``
    (see :class:`_Carrier` for listeners that handle waveforms themselves).
    """

    __slots__ = ("_exp_ev", "_listeners", "_val", "_wlisteners", "name", "wave")

    def __init__(self, name: str):
        self.name, self._val, self.wave = name, None, None
        self._init_listeners()

    @property
    def value(self):
        w = self.wave
        return self._val if w is None else w.level_at(w.kernel.now)

    def set(self, value: int | None) -> None:
        if value is not None:
            value = 1 if value else 0
        if self.wave is not None:
            if self._exp_ev is None:
                self._catch_up()
            self.wave = None
            self.refresh()
            changed = value != self._val
            self._val = value
            self._notify(changed, True)
        elif value != self._val:
            self._val = value
            self._notify(True, False)

    def set_wave(self, wave) -> None:
        """From now on the output is ``wave`` (its level now must be the port's value now)."""
        if wave is self.wave:
            return
        if self.wave is not None and self._exp_ev is None:
            self._catch_up()
        changed = wave.level != self._val
        self._val = wave.level
        self.wave = wave
        self.refresh()
        self._notify(changed, True)

    def _wave_sources(self):
        return [self.wave] if self.wave is not None else []

    def _catch_up(self) -> None:
        w = self.wave
        if w is not None:
            self._val = w.settled_level(w.kernel.now)

    def _resolve(self, expanding: bool = True) -> None:  # an expander edge: the value follows the waveform
        v = self.wave.level
        if v != self._val:
            self._val = v
            self._notify(True, False)

    def __repr__(self):
        return f"Port({self.name}={self.value})"
