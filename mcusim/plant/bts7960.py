"""IBT-2 motor driver board: two Infineon BTS7960 half bridges (docs/plants.md §2.1, §2.3).

Wiring: half bridge R (pins RPWM = IN, R_EN = INH, R_IS) drives M+, half bridge L (LPWM, L_EN,
L_IS) drives M−. The motor current i flows M+ -> motor -> M− (i > 0 for RPWM=1, LPWM=0).

Per half bridge (INH, IN -> leg): INH=0 -> Z (both switches off: body diodes); INH=1, IN=1 -> H
(high side on); INH=1, IN=0 -> L (low side on). So with both EN high: 10 forward drive, 01
reverse drive, 00 brake low, 11 brake high; both EN low: coast (fast decay, then discontinuous
conduction). ``r_en``/``l_en`` may be ``None``: INH tied high (the usual OpenRover/Arduino wiring).

Leg model as :mod:`mcusim.plant.l6206` (§2.1; current j out of the leg): H: v = Vs − R_HS·j;
L: v = −R_LS·j; Z: v = −(V_D + r_D·j) for j > 0 (low-side diode), Vs + V_D − r_D·j for j < 0
(high-side diode). The bridge hands ``(V⁺, V⁻, R_br, has_diode)`` to the motor.

Current limitation (datasheet §4.3.7–4.3.9; docs/plants.md §2.3 / §5.2 item 7): each switch senses
its own *forward* current — high side: current out of the leg, j > I_CLH; low side: current into
the leg, −j > I_CLL (reverse conduction is not detected [I]). On detection the half bridge is in
current-limitation fault for ``t_CLS`` (rounded to the nearest base tick): the detecting switch is
turned off and, by default (``cl_action="other"``), the *other* switch of that half bridge is
turned on, ignoring IN [S/I: the datasheet's current-limitation text as remembered, and the truth
table of the sibling NovalithIC BTM7752G: "short circuit in HS detected -> HS OFF, LS ON"; the
datasheet figures only say "the switch is shut off for t_CLS"]. ``cl_action="off"`` turns both switches
off instead (leg Z). INH low still turns the half bridge off during the fault. After t_CLS the
half bridge follows IN again; if the current is still above the limit it trips again at once.
With an inductive load this is the switched-mode current limit of §2.3. The detection is a guard
on the motor's exact segment (located to the first base tick with |i| above the limit); a state
change of IN/INH or a re-enable checks the limit at the same tick.

IS outputs (``is_r``, ``is_l``: :class:`~mcusim.signals.AnalogNet` with ``.source(t_ticks)``):
I_IS = max(j, 0)/k_ILIS + I_ISH while that half bridge's high side is on (forward current only),
capped at I_IS(lim); I_ISL otherwise; I_IS(lim) during a current-limitation fault. V_IS =
min(I_IS·R_IS, Vcc). The current comes from ``motor.state_at(t)`` (the exact closed form at tick
t), the switch state from a short history of this bridge's state changes, so an ADC that samples
IS at a tick inside the PWM period sees the chopped waveform exactly. At a tick where the state
changed, the state after the change is used.

Overtemperature: there is no thermal model, so the shutdown is an injected fault
(``overtemperature(side)``, e.g. from a scenario): the half bridge turns both switches off (leg Z)
and its IS pin shows the fault current I_IS(lim) until the latch is reset by an INH low pulse or by
``clear_overtemperature(side)`` (cooled down) [§2.3: thermal shutdown latched, reset via INH].

Supply coupling (battery, docs/plants.md §4, §5.1 "Battery coupling"): ``params.Vs`` is the bus voltage
B+ − B−. Alone the bridge treats it as an ideal source; a :class:`mcusim.plant.battery.LeadAcidBank`
connected to it calls :meth:`Bts7960Bridge.set_supply` once per battery step (the held bus voltage,
piecewise constant) and reads :meth:`Bts7960Bridge.supply_charge`, the charge drawn from B+ since
the last call. The supply current is ``I_s = i·[leg M+ on Vs] − i·[leg M− on Vs]`` (i: motor
current M+ -> M−), a leg being on Vs when it is H (the high-side FET conducts both ways) or Z with
its high-side body diode conducting (current out of the leg negative). So forward drive draws i,
brake low/high draw nothing, coast returns −|i| (fast decay), and reverse drive draws −i.

The charge is integrated *exactly*, not by quadrature: within one motor segment (constant leg
states, supply, conduction sign) I_s = c·i with c ∈ {−1, 0, 1} constant and v_m = V − R_br·i, so
the motor's KVL integrated over the segment gives ``∫i dt = (V·Δt − L·Δi − K·Δθ)/(R + R_br)``
from the closed-form state at both ends (i ≡ 0 in discontinuous conduction). The bridge is a guard
provider of its motor, whose segment rebuild (at every bridge state change, supply change, guard
event and re-check) calls :meth:`plant_guards`; that call closes the running segment's account.
The end state is taken from the ended segment's closed form, not from the motor's next start
state, which a guard may have projected (i := 0 at a current-zero event): through the L·Δi term
such a projection would count as a spurious charge of τe·|di/dt|·1 tick (≈ 7e-6 A·s at 16 MHz).
What remains is that a segment ending at a current-zero event is integrated to the located tick,
up to one base tick past the true zero: an error below ½·|di/dt|·(1 tick)² ≈ 1e-10 A·s per event.
A test pins the total against a 0.5 µs trapezoid integration of the exact current over 25 ms of
20 kHz PWM with drive, brake, coast and DCM (agreement 4e-8 of the charge throughput; the
trapezoid rule on the PWM segment ends alone, ≤ 40 µs, would be off by ≈ 6e-5). Cost: one
closed-form evaluation and ~10 flops per motor segment that moves charge (≈ 1 µs; drive and coast
phases, not brake phases).

Not modelled: dead time and switching delays/slew rate (R_SR), the junction temperature itself
(T_jSD is not computed: see above), under/over-voltage lock-out, the temperature and
supply dependence of R_ON and of the current-limit levels, the k_ILIS spread (a parameter, typ.
8500), IS settling time, any RC filter on the board's IS lines, supply ripple within a battery
step (see :mod:`mcusim.plant.battery`).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, replace

from mcusim.plant.hbridge import MosfetBridge

from ..errors import ConfigError, McusimError
from ..kernel import PRIO_PLANT
from ..signals import AnalogNet, Net
from .bts7960_steady import SteadyDrive
from .dcmotor import _check_overrides


@dataclass(frozen=True)
class Bts7960Params:
    Vs: float = 12.0          # supply, V (ideal source)                           [given]
    R_HS: float = 7e-3        # high-side R_ON, Ω (25 °C typ; max 9, 150 °C 10/12.5) [V]
    R_LS: float = 9e-3        # low-side R_ON, Ω (25 °C typ; max 12, 150 °C 14/18)   [V]
    V_D: float = 0.8          # reverse-diode forward voltage, V (25 °C typ, 9 A)  [V]
    r_D: float = 0.0          # diode slope, Ω (not in the datasheet)              [I]
    I_CLH: float = 60.0       # high-side current-limit detection, A (44/60/80)    [V]
    I_CLL: float = 43.0       # low-side current-limit detection, A (34/43/61)     [V]
    t_CLS: float = 115e-6     # current-limit shut-off time, s (70/115/210 µs)     [V]
    k_ILIS: float = 8500.0    # current sense ratio I_L/I_IS (typ; spread 3000–14000) [V]
    R_IS: float = 1000.0      # IS resistor on the IBT-2, Ω: UNVERIFIED (assumed)  [S]
    I_IS_lim: float = 4.5e-3  # max analog sense current = fault current, A (4/4.5/7 mA) [V]
    I_ISL: float = 0.0        # IS leakage with IN or INH = 0, A (datasheet: ≤ 1 µA) [V max]
    I_ISH: float = 0.0        # IS offset with the high side on at I_L = 0, A (≤ 200 µA) [V max]
    Vcc: float = 5.0          # logic supply: IS voltage clamp, V                  [S: IBT-2 VCC 5 V]

    def __post_init__(self):
        for name in ("I_CLH", "I_CLL", "t_CLS", "k_ILIS", "R_IS", "Vcc"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"bts7960 parameter {name} = {getattr(self, name)} must be positive")
        for name in ("Vs", "R_HS", "R_LS", "V_D", "r_D", "I_IS_lim", "I_ISL", "I_ISH"):
            if not getattr(self, name) >= 0:
                raise ConfigError(f"bts7960 parameter {name} = {getattr(self, name)} must not be negative")

    @classmethod
    def from_mapping(cls, mapping: dict, base: Bts7960Params | None = None) -> Bts7960Params:
        return replace(base or cls(), **_check_overrides(cls, dict(mapping), "bts7960"))


_SIDES = ("R", "L")
_HISTORY = 32      # state changes remembered for IS evaluation at past ticks


class _Half:
    """One BTS7960: IN, INH nets, and the current-limitation state."""

    __slots__ = ("en", "fault", "inp", "overtemp", "release_ev", "tripped", "trips")

    def __init__(self, inp: Net, en: Net | None):
        self.inp, self.en = inp, en
        self.fault = False
        self.overtemp = False    # latched thermal shutdown (injected)
        self.tripped = None      # "H" or "L": the switch that detected the over-current
        self.trips = 0
        self.release_ev = None


class Bts7960Bridge(SteadyDrive, MosfetBridge):
    """``Bts7960Bridge(kernel, motor, rpwm, lpwm, r_en=None, l_en=None, name="ibt2", *, params=None,
    is_r=None, is_l=None, cl_action="other", **overrides)``.

    ``rpwm``, ``lpwm`` (IN), ``r_en``, ``l_en`` (INH; ``None`` = tied high): :class:`Net` inputs.
    ``overrides`` are :class:`Bts7960Params` names (``Vs, R_HS, R_LS, V_D, r_D, I_CLH, I_CLL, t_CLS,
    k_ILIS, R_IS, I_IS_lim, I_ISL, I_ISH, Vcc``). ``is_r``/``is_l``: optional
    :class:`AnalogNet` s to drive (created as ``<name>.R_IS`` / ``<name>.L_IS`` otherwise).

    Attributes: ``legs`` (("H"|"L"|"Z", "H"|"L"|"Z") for (M+, M−) now), ``fault`` (either half
    bridge in current limitation), ``fault_r``/``fault_l``, ``cl_trips`` (total trips),
    ``cl_trips_r``/``cl_trips_l``, ``trip_log`` ((tick, side, "H"|"L") of the latest 256 trips),
    ``cls_ticks`` (t_CLS in base ticks), ``is_r``/``is_l``
    (AnalogNets), ``params``; ``is_voltage(side, tick=None)`` with side "R"/"L".
    Supply: ``set_supply(volts)`` (the bus voltage from now), ``supply_charge()`` (A·s drawn from
    B+ since the previous call, negative when returned), ``charge_total`` (A·s since construction).
    """

    def __init__(self, kernel, motor, rpwm: Net, lpwm: Net, r_en: Net | None = None,
                 l_en: Net | None = None, name: str = "ibt2", *, params: Bts7960Params | dict | None = None,
                 is_r: AnalogNet | None = None, is_l: AnalogNet | None = None, cl_action: str = "other",
                 **overrides):
        self.kernel, self.motor, self.name = kernel, motor, name
        if isinstance(params, dict):
            params = Bts7960Params.from_mapping(params)
        self.params = Bts7960Params.from_mapping(overrides, base=params)
        if cl_action not in ("other", "off"):
            raise ConfigError(f"{name}: cl_action = {cl_action!r} must be 'other' or 'off'")
        self.cl_action = cl_action
        self.rpwm, self.lpwm, self.r_en, self.l_en = rpwm, lpwm, r_en, l_en
        self._half = {"R": _Half(rpwm, r_en), "L": _Half(lpwm, l_en)}
        self.cls_ticks = max(1, round(self.params.t_CLS * kernel.timebase.base_hz))
        self.is_r = is_r if is_r is not None else AnalogNet(f"{name}.R_IS")
        self.is_l = is_l if is_l is not None else AnalogNet(f"{name}.L_IS")
        self.is_r.source = lambda t=None: self.is_voltage("R", t)
        self.is_l.source = lambda t=None: self.is_voltage("L", t)
        self._legs_seen = None
        self._drive_cache = {}
        self._supply_cache = {}      # (legs, conduction sign) -> (c, V, R_br): I_s = c·i, v_m = V − R_br·i
        self._seg = None             # supply account of the running motor segment (see _account)
        self._q = 0.0                # charge drawn from the supply since the last supply_charge(), A·s
        self.charge_total = 0.0      # charge drawn since construction, up to the last account, A·s
        self._inv_hz = 1.0 / kernel.timebase.base_hz
        self._hist = deque(maxlen=_HISTORY)
        self.trip_log = deque(maxlen=256)   # (tick, side, switch) of the latest trips
        self._cacc = None            # fast engine: supply account of a chunk of whole periods
        self._periodic = False       # fast engine: the motor follows drive_schedule()
        self._sched = None           # fast engine: (anchor, period, ((offset, legs), ...))
        self._shape = None           # fast engine: the input shape that schedule was made from
        self._pieces_cache = {}      # fast engine: input shape -> (anchor mod period, period, pieces) or None
        self._edge_ev = None         # fast engine: edges of waveforms the schedule does not cover
        self._record()
        for net in (rpwm, lpwm, r_en, l_en):
            if net is not None:
                # fast engine: waveforms are handled here (drive_schedule), not edge by edge
                net.listen(self._on_pin, waves=bool(getattr(kernel, "fast", False)))
        motor.add_guard_provider(self)
        motor.attach_driver(self)

    # ---- state ---------------------------------------------------------------------------------
    def _leg_of(self, side: str) -> str:
        h = self._half[side]
        if (h.en is not None and not h.en.level) or h.overtemp:
            return "Z"
        if h.fault:
            if self.cl_action == "off":
                return "Z"
            return "L" if h.tripped == "H" else "H"
        return "H" if h.inp.level else "L"

    @property
    def legs(self):
        return (self._leg_of("R"), self._leg_of("L"))

    @property
    def fault_r(self) -> bool:
        return self._half["R"].fault

    @property
    def fault_l(self) -> bool:
        return self._half["L"].fault

    @property
    def fault(self) -> bool:
        return self._half["R"].fault or self._half["L"].fault

    @property
    def cl_trips_r(self) -> int:
        return self._half["R"].trips

    @property
    def cl_trips_l(self) -> int:
        return self._half["L"].trips

    @property
    def cl_trips(self) -> int:
        return self._half["R"].trips + self._half["L"].trips

    def _snapshot(self):
        r, l_ = self._half["R"], self._half["L"]
        return (self._leg_of("R"), self._leg_of("L"), r.fault or r.overtemp, l_.fault or l_.overtemp)

    def _record(self, snap=None):
        snap = self._snapshot() if snap is None else snap
        now = self.kernel.now
        hist = self._hist
        if hist and hist[-1][0] == now:
            hist[-1] = (now, snap)
        elif not hist or hist[-1][1] != snap:
            hist.append((now, snap))


    def set_params(self, **overrides) -> None:
        new = Bts7960Params.from_mapping(overrides, base=self.params)

        def do():
            self.params = new
            self._drive_cache = {}
            self._supply_cache = {}
            self.cls_ticks = max(1, round(new.t_CLS * self.kernel.timebase.base_hz))
        self.motor._change(do)

    # ---- supply coupling (battery) --------------------------------------------------------------
    def set_supply(self, volts: float) -> None:
        """The bus voltage B+ − B− from now on (V). The motor's segment is rebuilt (its account
        closed at the old voltage first); nothing happens when the value is unchanged."""
        v = float(volts)
        if v == self.params.Vs:
            return
        if not (math.isfinite(v) and v >= 0.0):
            raise ConfigError(f"{self.name}: supply voltage {volts!r} must be a finite number >= 0")
        new = replace(self.params, Vs=v)

        def do():
            self.params = new
            self._drive_cache = {}
            self._supply_cache = {}
        self.motor._change(do)

    def supply_charge(self) -> float:
        """Charge drawn from the supply (A·s; negative when the bridge returned more than it drew)
        since the previous call, exact to the closed form of the motor; resets the count."""
        seg = self._seg
        now = self.kernel.now
        if self._cacc is not None:
            acc = self._cacc
            self._close_chunk(now)
            self._cacc = (now,) + acc[1:]
        elif seg is not None and seg[3] and now > seg[0]:
            m = self.motor
            if seg[0] >= m._t0:
                i1, _, th1 = m.state_at(now)
                ts, tr = m._t0, m._traj
            else:
                # the motor was re-based at now (a state jump, a new input) and its rebuild, which
                # closes this account, waits for the end of the tick (fast engine): the account
                # ends where the segment it was opened for ends, by that segment's closed form
                prev = m._prev
                if m._t0 != now or prev is None or prev[0] > seg[0]:
                    raise McusimError(f"{self.name}: supply accounting lost a motor segment")
                i1, _, th1 = m._at(prev[1], now - prev[0])
                ts, tr = prev
            self._close(seg, now, i1, self._turned(tr, ts, seg[0], now))
            self._seg = (now, i1, th1) + seg[3:]
        q, self._q = self._q, 0.0
        return q

    def _turned(self, tr, ts, a, b):
        """The angle the motor turns from tick ``a`` to tick ``b`` on trajectory ``tr`` (started
        at tick ``ts``), from the angles turned since its start: the difference of two absolute
        angles would lose the angle's rounding at its scale (an ulp of 1e6 rad is 1e-10 rad; the
        engines' accounts then parted by 2e-9 of the current on a rover whose wheels had turned
        that far)."""
        if tr.kind == "chunk":
            return tr.dtheta(b - ts) - tr.dtheta(a - ts)
        inv = self._inv_hz
        return tr.dtheta((b - ts) * inv) - tr.dtheta((a - ts) * inv)

    def _close(self, seg, t1, i1, dth):
        """Add the charge of account ``seg`` from its start to tick ``t1`` (current i1 there, the
        shaft turned by ``dth`` in between)."""
        t0, i0, _, c, v, rt, ind, k = seg
        if c:
            q = c * (v * (t1 - t0) * self._inv_hz - ind * (i1 - i0) - k * dth) / rt
            self._q += q
            self.charge_total += q

    def _account(self):
        """At a motor segment start (called from plant_guards): close the account of the segment
        that just ended at now, open one for the new segment."""
        self._close_segment()
        m = self.motor
        now = self.kernel.now
        if m._driver is not self:
            self._seg = (now, 0.0, 0.0, 0, 0.0, 1.0, 0.0, 0.0)
            return
        es = m._es
        # fast engine: a piece of a periodic drive was built from the schedule, not drive_state()
        legs = self.legs if self._periodic else self._legs_seen
        c, v, rbr = self._supply_coeffs(legs, es)
        p = m.params
        x0 = m._x0
        self._seg = (now, x0[0], x0[2], c, v, p.R + rbr, p.L, p.K)

    def _close_segment(self):
        """Close the account of the motor segment (or chunk of periods) that just ended at now."""
        m = self.motor
        now = self.kernel.now
        seg = self._seg
        if self._cacc is not None:
            self._close_chunk(now)
            self._cacc = None
        elif seg is not None and seg[3] and now > seg[0]:      # only segments that move charge
            prev = m._prev
            if prev is None or prev[0] > seg[0]:
                raise McusimError(f"{self.name}: supply accounting lost a motor segment")
            # the end state from the ended segment's closed form (not m._x0, which a guard may have
            # projected, e.g. i := 0 at a current-zero event)
            i1 = prev[1].eval((now - prev[0]) * self._inv_hz)[0]
            self._close(seg, now, i1, self._turned(prev[1], prev[0], seg[0], now))
        self._seg = None

    def _supply_coeffs(self, legs, es):
        """(c, V, R_br) of leg states ``legs`` in conduction domain ``es``: I_s = c·i, v_m = V − R_br·i."""
        key = (legs, es)
        ent = self._supply_cache.get(key)
        if ent is None:
            a, b = legs
            if es == 0:
                c = 0                                 # discontinuous conduction: i ≡ 0
            elif es is None:                         # no Z leg: H is on Vs whatever the sign of i
                c = (a == "H") - (b == "H")
            elif es > 0:                              # i > 0: out of A, into B (B's high-side diode)
                c = (a == "H") - (b != "L")
            else:                                     # i < 0: A's high-side diode, out of B
                c = (a != "L") - (b == "H")
            d = self.drive_for(legs)
            ent = self._supply_cache[key] = (c, d[1] if es is not None and es < 0 else d[0], d[2])
        return ent

    # ---- IS outputs ------------------------------------------------------------------------------
    def is_current(self, side: str, tick: int | None = None) -> float:
        """Current out of the IS pin of half bridge ``side`` ("R"/"L") at ``tick`` (default now), A."""
        t = self.kernel.now if tick is None else int(tick)
        snap = None
        for t_c, s in reversed(self._hist):
            if t_c <= t:
                snap = s
                break
        if snap is None:
            raise ValueError(f"{self.name}: IS at tick {t} is older than the remembered state changes")
        if snap[0] == "w":          # fast engine: the inputs were steady waveforms from then on
            legs = self._legs_from(snap[1], t)
            snap = (legs[0], legs[1], False, False)
        p = self.params
        k = 0 if side == "R" else 1
        if snap[2 + k]:
            return p.I_IS_lim
        if snap[k] != "H":
            return p.I_ISL
        i = self.motor.state_at(t)[0]
        j = i if k == 0 else -i          # current out of this leg; forward for the high side if > 0
        return min(max(0.0, j) / p.k_ILIS + p.I_ISH, p.I_IS_lim)

    def is_voltage(self, side: str, tick: int | None = None) -> float:
        """IS voltage across R_IS (clamped at Vcc) of half bridge ``side`` at ``tick``, V."""
        return min(self.is_current(side, tick) * self.params.R_IS, self.params.Vcc)

    # ---- current limitation: motor guard interface ----------------------------------------------
    def _limit_guard(self, side):
        """Guard (ci, c0) with h = ci·i + c0 (< 0: over the limit) for the switch now on, or None."""
        h = self._half[side]
        if h.fault:
            return None
        leg = self._leg_of(side)
        p = self.params
        sgn = 1.0 if side == "R" else -1.0      # j = sgn·i
        if leg == "H":                           # trip when j > I_CLH: h = I_CLH − j
            return (-sgn, p.I_CLH, leg)
        if leg == "L":                           # trip when −j > I_CLL: h = I_CLL + j
            return (sgn, p.I_CLL, leg)
        return None

    def plant_guards(self):
        self._account()        # called once per motor segment: the supply-charge account
        out = []
        for side in _SIDES:
            g = self._limit_guard(side)
            if g is not None:
                out.append((g[0], 0.0, 0.0, g[1], True, self, (side, g[2])))
        return out

    def on_guard(self, tag):
        side, leg = tag
        if self._half[side].fault or self._leg_of(side) != leg:
            return
        self._trip(side, leg)
        self._record()
        self.motor.input_changed()

    def _trip(self, side, leg):
        h = self._half[side]
        h.fault = True
        h.tripped = leg
        h.trips += 1
        self.trip_log.append((self.kernel.now, side, leg))
        h.release_ev = self.kernel.after(self.cls_ticks, self._release, side, prio=PRIO_PLANT)

    def _check_now(self):
        """Trip at once any switch that is on and already over its limit (after a state change)."""
        i = self.motor.current
        for side in _SIDES:
            g = self._limit_guard(side)
            if g is not None and g[0] * i + g[1] < 0.0:
                self._trip(side, g[2])

    def _release(self, side):
        h = self._half[side]
        h.release_ev = None
        h.fault = False
        h.tripped = None
        self._check_now()
        self._record()
        self.motor.input_changed()

    # ---- overtemperature (injected; no thermal model) -------------------------------------------
    @property
    def overtemp(self) -> bool:
        return self._half["R"].overtemp or self._half["L"].overtemp

    def overtemperature(self, side: str = "both") -> None:
        """Latch the thermal shutdown of half bridge "R", "L" or both, now."""
        self._set_overtemp(side, True)

    def clear_overtemperature(self, side: str = "both") -> None:
        """Reset the latch (the chip has cooled down and been re-armed)."""
        self._set_overtemp(side, False)

    def _set_overtemp(self, side, value):
        sides = _SIDES if side == "both" else (side,)
        if any(s not in _SIDES for s in sides):
            raise ConfigError(f"{self.name}: side must be 'R', 'L' or 'both', not {side!r}")

        def do():
            for s in sides:
                self._half[s].overtemp = value
            self._record()
        self.motor._change(do)

    def _reset_overtemp(self, h) -> None:
        """An INH low pulse on half ``h``: its thermal latch is reset (§2.3)."""
        self.motor._change(lambda: (setattr(h, "overtemp", False), self._record()))

    def _on_pin(self, net):
        for h in self._half.values():  # an INH low pulse resets the thermal latch
            if h.overtemp and h.en is net and not net.level:
                self._reset_overtemp(h)
        if self.kernel.fast and (self._periodic or self._waves()):
            if self._schedule_stands():
                return
            if self._edge_ev is not None:
                self._edge_ev.cancel()
                self._edge_ev = None
            self._legs_seen = None
            self.motor.edge_tick = self.kernel.now      # an input edge: the limits are checked
            self.motor.input_changed()      # the motor asks drive_schedule()
            return
        if self.legs != self._legs_seen:
            self._check_now()
            self._record()
            self.motor.input_changed()

    def __repr__(self):
        f = "".join(f" CL-{s}" for s in _SIDES if self._half[s].fault)
        return f"Bts7960Bridge({self.name}: {''.join(self.legs)}{f})"
