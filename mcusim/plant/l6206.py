"""One full bridge of an ST L6206, as on the X-NUCLEO-IHM04A1 (docs/plants.md §2.1–2.2).

Truth table (EN, IN1, IN2 -> OUT1, OUT2): EN=0 -> Z Z (all off: fast decay through the body
diodes, then discontinuous conduction); EN=1: 10 -> H L (drive +), 01 -> L H (drive −),
00 -> L L (brake low), 11 -> H H (brake high).

Leg model (current j out of the leg): H: v = Vs − R_HS·j; L: v = −R_LS·j; Z: v = −(V_D + r_D·j)
for j > 0 (low-side diode), v = Vs + V_D − r_D·j for j < 0 (high-side diode). With i flowing
OUT1 -> motor -> OUT2 the motor voltage is affine in i within each sign domain; the bridge hands
``(V⁺, V⁻, R_br, has_diode)`` to the motor (see :class:`mcusim.plant.dcmotor.DcMotor`).

Over-current detection: when |i| > ``I_ocd`` (5.6 A on the board) while a high-side switch is on
(the L6206 senses the high-side DMOS current; [I] with only the low sides on — brake low — there
is no detection), the bridge turns all switches off and the ``ocd`` net goes to 1. The EN line
is released and recharges through R_EN·C_EN from ``V_pullup``; the bridge re-enables when it
crosses ``V_th``: ``t_release = R_EN·C_EN·ln(V_pullup/(V_pullup − V_th))`` (0.4415 ms for
100 kΩ, 5.6 nF, 3.3 V, 1.8 V), rounded to the nearest base tick. If EN is low at that time the
bridge simply stays off per the truth table. With ``drive_en=True`` the bridge also pulls the EN
net low (open drain, driver ``<name>.ocd``) while tripped, so the MCU's FLAG/EN input sees the
falling edge; leave it False when the MCU drives EN push-pull (that would be contention).

Not modelled: dead time (1 µs typ.; its duty loss of ~t_d/T_PWM is left out), switching delays
and rise times, temperature dependence of R_DS(on), supply ripple (Vs is an ideal source), the
thermal shutdown.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from mcusim.plant.hbridge import MosfetBridge, input_shape, leg_pieces

from ..errors import ConfigError
from ..kernel import PRIO_PLANT
from ..signals import Net
from .dcmotor import _check_overrides


@dataclass(frozen=True)
class L6206Params:
    Vs: float = 12.0          # supply, V (ideal source)
    R_HS: float = 0.34        # high-side R_DS(on), Ω
    R_LS: float = 0.28        # low-side R_DS(on), Ω
    V_D: float = 0.75         # body diode offset, V
    r_D: float = 0.14         # body diode slope, Ω
    I_ocd: float = 5.6        # over-current threshold, A
    R_EN: float = 100e3       # EN recharge resistor, Ω
    C_EN: float = 5.6e-9      # EN capacitor, F
    V_pullup: float = 3.3     # EN pull-up supply, V
    V_th: float = 1.8         # EN turn-on threshold, V

    def __post_init__(self):
        for name in ("R_EN", "C_EN", "V_pullup", "I_ocd"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"l6206 parameter {name} = {getattr(self, name)} must be positive")
        for name in ("Vs", "R_HS", "R_LS", "V_D", "r_D"):
            if not getattr(self, name) >= 0:
                raise ConfigError(f"l6206 parameter {name} = {getattr(self, name)} must not be negative")
        if not 0 < self.V_th < self.V_pullup:
            raise ConfigError(f"l6206 parameter V_th = {self.V_th} must be between 0 and V_pullup = {self.V_pullup}")

    @classmethod
    def from_mapping(cls, mapping: dict, base: L6206Params | None = None) -> L6206Params:
        return replace(base or cls(), **_check_overrides(cls, dict(mapping), "l6206"))

    @property
    def t_release(self) -> float:
        """Seconds from an OCD trip until EN recharges past V_th."""
        return self.R_EN * self.C_EN * math.log(self.V_pullup / (self.V_pullup - self.V_th))


_TRUTH = {(0, 0): ("L", "L"), (1, 0): ("H", "L"), (0, 1): ("L", "H"), (1, 1): ("H", "H")}


class L6206Bridge(MosfetBridge):
    """``L6206Bridge(kernel, motor, in1, in2, en, name="bridgeA", ocd=None, drive_en=False, **params)``.

    ``in1``, ``in2``, ``en``: :class:`~mcusim.signals.Net` inputs (listened to). ``params`` are
    :class:`L6206Params` names (``Vs, R_HS, R_LS, V_D, r_D, I_ocd, R_EN, C_EN, V_pullup, V_th``).
    Attributes: ``legs`` (("H"|"L"|"Z", ...) now), ``ocd_active``, ``ocd`` (Net, 1 while
    tripped, named ``<name>.ocd``), ``ocd_trips`` (count), ``release_ticks``, ``params``.
    """

    def __init__(self, kernel, motor, in1: Net, in2: Net, en: Net, name: str = "bridgeA", *,
                 params: L6206Params | dict | None = None, ocd: Net | None = None,
                 drive_en: bool = False, **overrides):
        self.kernel, self.motor, self.name = kernel, motor, name
        if isinstance(params, dict):
            params = L6206Params.from_mapping(params)
        self.params = L6206Params.from_mapping(overrides, base=params)
        self.in1, self.in2, self.en = in1, in2, en
        self.ocd = ocd if ocd is not None else Net(f"{name}.ocd")
        self.ocd.set(name, 0)
        self.drive_en = bool(drive_en)
        self.ocd_active = False
        self.ocd_trips = 0
        self.release_ticks = max(1, round(self.params.t_release * kernel.timebase.base_hz))
        self._release_ev = None
        self._legs_seen = None
        self._drive_cache = {}
        self._periodic = False      # fast engine: the motor follows drive_schedule()
        self._edge_ev = None        # fast engine: edges of waveforms that do not share a period
        for net in (in1, in2, en):
            net.listen(self._on_pin, waves=True)
        motor.add_guard_provider(self)
        motor.attach_driver(self)

    # ---- state ---------------------------------------------------------------------------------
    @property
    def legs(self):
        if self.ocd_active or not self.en.level:
            return ("Z", "Z")
        return _TRUTH[(1 if self.in1.level else 0, 1 if self.in2.level else 0)]

    def _legs_at(self, t):
        lv = [n.wave.level_at(t) if n.wave is not None else n.level for n in (self.in1, self.in2, self.en)]
        if self.ocd_active or not lv[2]:
            return ("Z", "Z")
        return _TRUTH[(lv[0], lv[1])]

    def drive_schedule(self):
        """Fast engine: ``(anchor, period, pieces)`` when the inputs are steady waveforms of one
        period (pieces: ``(offset, drive_state, guards)`` from ``anchor``), else None (the drive is
        constant, or edges come one by one)."""
        waves = [n.wave for n in (self.in1, self.in2, self.en) if n.wave is not None]
        if not waves or self.ocd_active:
            self._periodic = False
            return None
        found = leg_pieces(waves, self._legs_at)
        if found is None:
            self._periodic = False
            return None
        anchor, P, pieces = found
        self._periodic = True
        self._shape = self._input_shape()
        I = self.params.I_ocd
        ocd = ((-1.0, 0.0, 0.0, I, True, self, "ocd"), (1.0, 0.0, 0.0, I, True, self, "ocd"))
        return (anchor, P, tuple((o, self.drive_for(lg), ocd if "H" in lg else ()) for o, lg in pieces))


    def set_params(self, **overrides) -> None:
        new = L6206Params.from_mapping(overrides, base=self.params)

        def do():
            self.params = new
            self._drive_cache = {}
            self.release_ticks = max(1, round(new.t_release * self.kernel.timebase.base_hz))
        self.motor._change(do)

    # ---- motor interface -------------------------------------------------------------------------
    def plant_guards(self):
        if self.ocd_active or "H" not in self.legs:
            return ()
        I = self.params.I_ocd
        return ((-1.0, 0.0, 0.0, I, True, self, "ocd"), (1.0, 0.0, 0.0, I, True, self, "ocd"))

    def on_guard(self, tag):
        if self.ocd_active:
            return
        self.ocd_active = True
        self.ocd_trips += 1
        self.ocd.set(self.name, 1)
        if self.drive_en:
            self.en.set(self.name + ".ocd", 0)
        self._release_ev = self.kernel.after(self.release_ticks, self._release, prio=PRIO_PLANT)
        self.motor.input_changed()

    def _release(self):
        self._release_ev = None
        self.ocd_active = False
        self.ocd.set(self.name, 0)
        if self.drive_en:
            self.en.set(self.name + ".ocd", None)
        self.motor.input_changed()
        if self.kernel.fast:
            self._restart_edges()

    def _restart_edges(self):
        """Fast engine: input waveforms of different periods reach the motor edge by edge."""
        if self._edge_ev is not None:
            self._edge_ev.cancel()
            self._edge_ev = None
        if not self._periodic and not self.ocd_active and any(
                n.wave is not None for n in (self.in1, self.in2, self.en)):
            self._next_edge()

    def _input_shape(self):
        return input_shape((self.in1, self.in2, self.en))

    def _on_pin(self, net):
        if self._periodic and not self.ocd_active and self._input_shape() == self._shape:
            # a waveform republished with the same shape (the timer learned it ends at the next
            # update event, where a preload waits): the schedule the motor follows is unchanged
            return
        if self.kernel.fast and (self._periodic or self._edge_ev is not None or any(
                n.wave is not None for n in (self.in1, self.in2, self.en))):
            # once the event that moved the pin returns, with every pin it moved: a timer update
            # that reverses the motor republishes both inputs (52 of the nucleo-f746's 283
            # update events in its first second), and the motor's plan for the first alone is
            # thrown away at the second
            if not self.kernel.end_of_event(self._pins_changed):
                self._pins_changed()
            return
        if self.legs != self._legs_seen:
            self.motor.input_changed()

    def _pins_changed(self):
        """Fast engine: the inputs moved; the motor asks drive_schedule()."""
        self._legs_seen = None
        self.motor.input_changed()
        self._restart_edges()

    def _next_edge(self):
        now = self.kernel.now
        t = min(n.wave.next_edge(now)[0] for n in (self.in1, self.in2, self.en) if n.wave is not None)
        self._edge_ev = self.kernel.at(t, self._on_edge)

    def _on_edge(self):
        self._edge_ev = None
        if self.legs != self._legs_seen:
            self.motor.input_changed()
        self._next_edge()

    def __repr__(self):
        return f"L6206Bridge({self.name}: {''.join(self.legs)}{' OCD' if self.ocd_active else ''})"
