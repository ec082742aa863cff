"""Lead-acid battery bank feeding the motor bridges, and the controller's battery divider
(docs/plants.md §4, §4.1, §5.1 "Battery coupling").

Model: ``count`` identical 12 V 9 Ah sealed lead-acid (VRLA/AGM) batteries in parallel, each a
first-order Thevenin equivalent circuit (§4; the classic ECM of PyBaMM's "Thevenin" model and the
``thevenin`` package)::

    dSOC/dt = −I / (3600·Q_eff·n)                      I > 0: discharge (A, bank current)
    dv1/dt  = −v1/τ1 + I/(n·C1) ,  τ1 = R1·C1          (the bank's RC pair is R1/n ‖ n·C1: same τ1)
    v_t     = OCV(SOC) − v1 − (R0/n + R_wiring)·I

with perfect current sharing between the n batteries (§4.1: "R0/n, n·Q"). Parameters (all per
battery; provenance marks as in docs/plants.md):

- OCV(SOC) = ocv_empty + (ocv_full − ocv_empty)·SOC = 11.65 + 1.10·SOC V: the linear fit of the
  recommended AGM/SLA table of §4.1 (11.65 / 11.95 / 12.20 / 12.45 / 12.75 V at 0…100 %) [I].
  SOC is clamped to [0, 1]: below empty the model does not hold (the real voltage collapses), above
  full the charge is not accepted (charge acceptance and gassing are not modelled) [I].
- R0 = 20 mΩ (§4.1: 15–25 mΩ class value for 7–9 Ah SLAs, at full charge) [I]; its rise towards
  empty (1.5–2×) and in the cold is not modelled.
- R1 = 15 mΩ, τ1 = 60 s (§4.1: 10–20 mΩ, 30–120 s) [I].
- Q = 9 Ah at the 20 h rate (I20 = Q/20 = 0.45 A per battery) [V: the part's rating, per §4.1].
- Peukert (§4.1: ``Q_eff = Q20·(I20/I)^(k−1)``, k = 1.1–1.25 for SLA [I]): applied to discharge
  above the 20 h rate only, with the *per-battery* current of the step: Q_eff = Q·(I20/(I/n))^(k−1)
  for I/n > I20, else Q (no capacity gain at lighter loads: the formula is an extrapolation there,
  and the rating already is the light-load capacity) [I]. Charge returned by the bridges
  (regeneration, fast decay) counts at full efficiency against Q (no Peukert, no charge losses)
  [I]. ``peukert_k = 1`` switches the correction off. k = 1.15 gives Q_eff ≈ 5.7 Ah per battery at
  10 A, about what SLA sheets show at the 1C rate.
- wiring_r = 10 mΩ: the bus wiring and connectors to the bridges, shared by all loads (§1.4:
  10–20 mΩ) [I].

Simulation: the bank is one kernel event every ``step`` (1 ms, ``PRIO_PLANT``). At each step it
asks every connected load (``bridge.supply_charge()``: A·s since the previous step, negative when
returned) for its charge, takes the average current I over the step, advances SOC and v1 *exactly
for a constant current I over the step* (SOC linearly, v1 by the exponential), computes the terminal
voltage v_t = OCV(SOC) − v1 − (R0/n + wiring)·I and hands it to every load with
``bridge.set_supply(v_t)``; the loads run on that held value until the next step.

Approximation (this is the one place where the exact-between-events rule of the architecture is
relaxed, as §5.1 suggests): the bus voltage is piecewise constant per step and is computed from
the average supply current of the *previous* step. Consequences:

- PWM-frequency supply ripple is not modelled. On the IBT-2 the bulk capacitors across B+/B−
  filter it [I]; the motors see the step-average bus voltage. The step should be a whole number of
  PWM periods (1 ms = 20 periods of the OpenRover module's 20 kHz TimerOne PWM) so the averaged
  current carries no aliased ripple; with a 490 Hz PWM a 1 ms step holds alternately on- and
  off-phase averages (an aliased ripple of at most (R0/n + wiring)·ΔI/2).
- The coupling is explicit, one step late. Steady states are exact (the held voltage then equals the
  instantaneous one; a test pins a motor's steady state on one battery to 1e-9). In transients the
  bus voltage lags by one step: the error is (R0/n + wiring)·ΔI, ΔI being the change of the bank
  current over one step. The gain of this delayed feedback is at most its DC value
  N_motors·(R0/n + wiring)/R_loop (R_loop ≈ 0.18 Ω: motor + both R_ON) for locked motors, less at
  speed (back-EMF): ≈ 0.11 per motor with the defaults, 0.45 for four motors on two batteries,
  0.68 for four locked motors on one battery. Below 1 the scheme is stable by the small-gain
  argument and the lag error decays geometrically within a few steps; the armature inductance
  (τe ≈ 1.7 ms with the loop resistance) also lets only ≈ 1/4 of a voltage change through to the
  next step's average current, so a DC gain somewhat above 1 still settles (four locked motors
  on one battery through 0.1 Ω of wiring, DC gain 2.7: ringing for ≈ 15 steps, then the exact
  value). Much higher gains do not: with 0.2 Ω of wiring (gain 5) the bus voltage keeps swinging
  (0.8-4.2 V at 60 ms against an exact 2.1 V). Such a bank cannot run those motors anyway; keep
  N_motors·(R0/n + wiring)/R_loop below ≈ 3 (a review measured these cases).
- The SOC/OCV and v1 changes within a step (µV) are ignored, and so is the voltage dependence of
  a load's current within the step.

Also here: :class:`ConstantLoad` (a constant-current sink on the bus: the controller electronics,
or a test load) and :class:`VoltageDivider` (an ideal unloaded divider of any source: the CIAA's
battery divider on its ADC input; the board part wrapping it is in :mod:`mcusim.plant.parts`).
"""

from __future__ import annotations

import math
from collections import deque

from ..errors import ConfigError, McusimError
from ..kernel import PRIO_PLANT
from ..signals import AnalogNet

__all__ = ["ConstantLoad", "LeadAcidBank", "VoltageDivider"]

_HISTORY = 64          # held terminal voltages remembered for voltage(t) at past ticks


def _num(name, value, who, *, positive=False, nonneg=False):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{who}: {name} = {value!r} is not a number") from None
    if not math.isfinite(v):
        raise ConfigError(f"{who}: {name} = {value!r} must be finite")
    if positive and not v > 0:
        raise ConfigError(f"{who}: {name} = {value!r} must be positive")
    if nonneg and not v >= 0:
        raise ConfigError(f"{who}: {name} = {value!r} must not be negative")
    return v


class LeadAcidBank:
    """``LeadAcidBank(kernel, name="battery", *, count=2, soc=1.0, capacity_ah=9.0, r0=0.020,
    r1=0.015, tau1=60.0, ocv_empty=11.65, ocv_full=12.75, peukert_k=1.15, wiring_r=0.010,
    step="1ms", loads=None)``: ``count`` (1..8) 12 V SLA batteries in parallel (see the module).

    ``connect(load)`` adds a load (a :class:`~mcusim.plant.bts7960.Bts7960Bridge`, a
    :class:`ConstantLoad`, anything with ``supply_charge()`` and ``set_supply(v)``); ``loads`` at
    construction connects each. Observers: ``voltage(t=None)`` (held terminal voltage; at a past
    tick, the value held then), ``net`` (an :class:`AnalogNet` following it), ``soc``, ``ocv``,
    ``v1`` (RC-pair voltage), ``current`` (last step's average bank current, A), ``min_voltage``
    (lowest terminal voltage so far), ``charge_ah`` (net charge drawn, Ah), ``steps``.
    ``set_soc(soc)`` sets the state of charge now (an injected sag, for scenarios).
    """

    READERS = ("voltage",)     # methods a scenario expectation may read as values

    def __init__(self, kernel, name: str = "battery", *, count=2, soc=1.0, capacity_ah=9.0,
                 r0=0.020, r1=0.015, tau1=60.0, ocv_empty=11.65, ocv_full=12.75, peukert_k=1.15,
                 wiring_r=0.010, step="1ms", loads=None):
        self.kernel, self.name = kernel, name
        who = f"battery {name}"
        if isinstance(count, bool) or not isinstance(count, (int, float)) or count != int(count) \
                or not 1 <= count <= 8:
            raise ConfigError(f"{who}: count = {count!r}: expected a whole number of 12 V batteries "
                              f"in parallel from 1 to 8")
        self.count = n = int(count)
        self.capacity_ah = _num("capacity_ah", capacity_ah, who, positive=True)
        self.r0 = _num("r0", r0, who, nonneg=True)
        self.r1 = _num("r1", r1, who, nonneg=True)
        self.tau1 = _num("tau1", tau1, who, positive=True)
        self.ocv_empty = _num("ocv_empty", ocv_empty, who, positive=True)
        self.ocv_full = _num("ocv_full", ocv_full, who, positive=True)
        if not self.ocv_full > self.ocv_empty:
            raise ConfigError(f"{who}: ocv_full = {ocv_full} must be above ocv_empty = {ocv_empty}")
        self.peukert_k = _num("peukert_k", peukert_k, who)
        if not 1.0 <= self.peukert_k <= 2.0:
            raise ConfigError(f"{who}: peukert_k = {peukert_k!r} must be in [1, 2] (1 = no correction)")
        self.wiring_r = _num("wiring_r", wiring_r, who, nonneg=True)
        s0 = _num("soc", soc, who)
        if not 0.0 <= s0 <= 1.0:
            raise ConfigError(f"{who}: soc = {soc!r} must be in [0, 1]")
        try:
            self.step_ticks = kernel.timebase.ticks(step)
        except McusimError as exc:   # a TimeError: re-label it with the part name
            raise ConfigError(f"{who}: step = {step!r}: {exc}") from None
        if self.step_ticks <= 0:
            raise ConfigError(f"{who}: step = {step!r} must be positive")
        self.step_s = self.step_ticks / kernel.timebase.base_hz
        # bank values
        self.r_series = self.r0 / n + self.wiring_r     # instant (ohmic) resistance, Ω
        self.r_rc = self.r1 / n                          # RC-pair resistance, Ω
        self.q_as = 3600.0 * self.capacity_ah * n        # rated bank capacity, A·s
        self._i20 = self.capacity_ah / 20.0              # 20 h rate per battery, A
        self._decay = math.exp(-self.step_s / self.tau1)
        self._soc = s0
        self.v1 = 0.0
        self.current = 0.0
        self.charge_as = 0.0                             # net charge drawn, A·s
        self.steps = 0
        self._loads = []
        self._v = self.ocv
        self.min_voltage = self._v
        self._hist = deque([(kernel.now, self._v)], maxlen=_HISTORY)
        self.net = AnalogNet(f"{name}.V")
        self.net.source = self.voltage
        for load in loads or ():
            self.connect(load)
        self._ev = kernel.after(self.step_ticks, self._step, prio=PRIO_PLANT)

    # ---- loads -------------------------------------------------------------------------------------
    def connect(self, load) -> None:
        """Put ``load`` on the bus from now: it gets the present terminal voltage, and the charge
        it counted before is discarded."""
        if not (hasattr(load, "supply_charge") and hasattr(load, "set_supply")):
            raise ConfigError(f"battery {self.name}: {getattr(load, 'name', load)!r} cannot be "
                              f"a load (needs supply_charge() and set_supply())")
        if any(x is load for x in self._loads):
            raise ConfigError(f"battery {self.name}: {getattr(load, 'name', load)!r} is already connected")
        load.supply_charge()
        load.set_supply(self._v)
        self._loads.append(load)

    @property
    def loads(self):
        return tuple(self._loads)

    # ---- the step ----------------------------------------------------------------------------------
    def q_eff_as(self, current: float) -> float:
        """Effective bank capacity (A·s) for a bank discharge current ``current`` (Peukert, see the
        module); the rated capacity for charge and for currents at or below the 20 h rate."""
        per = current / self.count
        if self.peukert_k == 1.0 or per <= self._i20:
            return self.q_as
        return self.q_as * (self._i20 / per) ** (self.peukert_k - 1.0)

    def _step(self):
        q = 0.0
        for load in self._loads:
            q += load.supply_charge()
        h = self.step_s
        i = q / h
        self.current = i
        self.charge_as += q
        soc = self._soc - q / self.q_eff_as(i)
        self._soc = min(1.0, max(0.0, soc))
        a = self._decay                                 # exact for constant I over the step
        self.v1 = self.v1 * a + self.r_rc * i * (1.0 - a)
        v = self.ocv - self.v1 - self.r_series * i
        v = max(v, 0.0)
        self.steps += 1
        self._hold(v)
        self._ev = self.kernel.after(self.step_ticks, self._step, prio=PRIO_PLANT)

    def _hold(self, v):
        now = self.kernel.now
        if v != self._v:
            self._v = v
            if self._hist[-1][0] == now:
                self._hist[-1] = (now, v)
            else:
                self._hist.append((now, v))
            for load in self._loads:
                load.set_supply(v)
        self.min_voltage = min(self.min_voltage, v)

    def set_soc(self, soc: float) -> None:
        """Injected change (scenario fault ``battery_sag``): the state of charge becomes ``soc``
        now; the terminal voltage follows at once (same law as a step, with the last current)."""
        s = _num("soc", soc, f"battery {self.name}")
        if not 0.0 <= s <= 1.0:
            raise ConfigError(f"battery {self.name}: soc = {soc!r} must be in [0, 1]")
        self._soc = s
        self._hold(max(self.ocv - self.v1 - self.r_series * self.current, 0.0))

    # ---- observers ---------------------------------------------------------------------------------
    def voltage(self, t: int | None = None) -> float:
        """Terminal voltage (V) held now, or at tick ``t`` (at a step tick: the value after the
        step). Usable as an :class:`AnalogNet` source."""
        if t is None or t >= self._hist[-1][0]:
            return self._v
        for t_c, v in reversed(self._hist):
            if t_c <= t:
                return v
        raise ValueError(f"battery {self.name}: voltage at tick {t} is older than the remembered steps")

    @property
    def soc(self) -> float:
        return self._soc

    @property
    def ocv(self) -> float:
        return self.ocv_empty + (self.ocv_full - self.ocv_empty) * self._soc

    @property
    def charge_ah(self) -> float:
        return self.charge_as / 3600.0

    def summary_entries(self) -> dict:
        return {"battery_v": round(self._v, 4), "battery_soc": round(self._soc, 6),
                "battery_min_v": round(self.min_voltage, 4), "battery_current": round(self.current, 4)}

    def __repr__(self):
        return (f"LeadAcidBank({self.name}: {self.count}× {self.capacity_ah:g} Ah, SOC {self._soc:.4f}, "
                f"{self._v:.4f} V, {self.current:.3g} A)")


class ConstantLoad:
    """A constant current ``amps`` drawn from the bus (``set(amps)`` changes it from now on): the
    controller electronics, lights, or a test load. A bank load (``supply_charge``/``set_supply``);
    ``supply`` is the last voltage it was given."""

    def __init__(self, kernel, amps: float = 0.0, name: str = "load"):
        self.kernel, self.name = kernel, name
        self.amps = float(amps)
        self.supply = None
        self._t = kernel.now
        self._q = 0.0

    def _acc(self):
        now = self.kernel.now
        self._q += self.amps * (now - self._t) / self.kernel.timebase.base_hz
        self._t = now

    def set(self, amps: float) -> None:
        self._acc()
        self.amps = float(amps)

    def supply_charge(self) -> float:
        self._acc()
        q, self._q = self._q, 0.0
        return q

    def set_supply(self, volts: float) -> None:
        self.supply = float(volts)


class VoltageDivider:
    """Ideal unloaded divider: ``voltage(t) = source_fn(t)·r_bottom/(r_top + r_bottom)``.

    The source impedance it presents (r_top ‖ r_bottom) and any series resistor on the board (the
    EDU-CIAA's 1.2 kΩ on the ADC input) belong to the ADC's sampling model, not to the ratio."""

    READERS = ("voltage",)

    def __init__(self, source_fn, r_top: float, r_bottom: float):
        r_top = _num("r_top", r_top, "divider", positive=True)
        r_bottom = _num("r_bottom", r_bottom, "divider", positive=True)
        if not callable(source_fn):
            raise ConfigError(f"divider: source {source_fn!r} is not callable")
        self.source_fn, self.r_top, self.r_bottom = source_fn, r_top, r_bottom
        self.ratio = r_bottom / (r_top + r_bottom)
        self.r_source = r_top * r_bottom / (r_top + r_bottom)

    def voltage(self, t: int | None = None) -> float:
        return self.source_fn(t) * self.ratio
