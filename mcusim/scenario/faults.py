"""The fault kinds of ``fault = { kind = "...", ... }`` actions: one class per kind, registered
in :data:`FAULTS` (the order the messages list them). A kind names the key of its part and what
that part must be, its other keys and whether ``clear = true`` ends it; ``check`` completes and
checks its keys when the scenario is loaded, ``resolve`` finds its part and ``prepare`` returns
what it does (or undoes) when the scenario is applied. The models are in ``docs/scenarios.md``."""

from __future__ import annotations

from typing import ClassVar

from ..time import parse_duration

JAM_TORQUE = 1.0e6                 # N·m of stiction on the motor shaft while a "stall" fault holds it


class FaultKind:
    """``part_key``: the key naming the part, ``part_kind``: what it must be (``PART_KINDS``),
    ``fields``: the kind's other keys ``{name: (type, required)}``, ``clearable``: whether
    ``clear = true`` ends the fault (else it is momentary)."""

    part_key = part_kind = ""
    fields: ClassVar[dict] = {}
    clearable = True

    def check(self, out: dict, clear: bool, bad) -> None:
        """Defaults and ranges of the kind's keys in ``out`` (the checked table);
        ``bad(msg, *field)`` is the ConfigError at the line of ``field`` (none: the fault's)."""

    def resolve(self, sc, sim, name, line, where):
        """The part named ``name`` (ConfigError at ``line`` if there is none of the right kind)."""
        return sc._part(sim, name, self.part_kind, line, where)

    def prepare(self, sc, sim, part, spec: dict, line, where):
        """The function that injects the fault (or with ``spec["clear"]`` ends it)."""
        raise NotImplementedError


class EncoderGlitch(FaultKind):
    part_key = part_kind = "encoder"
    fields: ClassVar[dict] = {"channel": ("str", False), "width": ("duration", False)}
    clearable = False

    def check(self, out, clear, bad):
        out.setdefault("channel", "A")
        out.setdefault("width", parse_duration("1us"))
        if out["channel"] not in ("A", "B"):
            raise bad("channel must be \"A\" or \"B\"", "channel")
        if not 0 < out["width"] <= 1:
            raise bad("width must be positive and at most 1s", "width")

    def prepare(self, sc, sim, part, spec, line, where):
        width = sc._ticks(sim.timebase, spec["width"], line, f"{where}: width")

        def act():
            part.glitch(spec["channel"], width)
        return act


class MissingEdges(FaultKind):
    part_key = part_kind = "encoder"
    fields: ClassVar[dict] = {"count": ("int", True)}

    def check(self, out, clear, bad):
        if not clear and not 0 < out["count"] <= 1_000_000:
            raise bad("count must be from 1 to 1000000", "count")

    def prepare(self, sc, sim, part, spec, line, where):
        def act():
            part.drop_edges(0 if spec["clear"] else spec["count"])
        return act


class Stall(FaultKind):
    part_key = part_kind = "motor"

    def prepare(self, sc, sim, part, spec, line, where):
        target, clear = spec[self.part_key], spec["clear"]

        def act():
            if clear:
                saved = sc._stalls.pop(target, None)
                if saved is not None:
                    part.set_params(tau_s=saved)
            else:
                sc._stalls.setdefault(target, part.params.tau_s)
                part.set_params(tau_s=JAM_TORQUE)
                part.set_state(speed=0.0)
        return act


class I2cSilent(FaultKind):
    part_key = part_kind = "board"

    def resolve(self, sc, sim, name, line, where):
        """The I2C slave interfaces (TWIs on a bus) of the board or system member ``name``."""
        member = sim.members.get(name)
        if member is None:
            raise sc._err(line, f"{where}: no board {name!r} (boards: {', '.join(sim.members)})")
        twis = [p for p in member["mcu"].periph.values()
                if getattr(p, "i2c_slave", False) and hasattr(getattr(p, "bus", None), "detach")]
        if not twis:
            raise sc._err(line, f"{where}: board {name!r} has no I2C slave interface")
        return twis

    def prepare(self, sc, sim, twis, spec, line, where):
        clear = spec["clear"]

        def act():
            for twi in twis:
                bus = twi.bus
                if clear:
                    bus.attach(twi)
                elif twi in bus.slaves:
                    bus.detach(twi)
                    # it stops answering at once, also within a transfer that addressed it
                    bus._selected = [s for s in bus._selected if s is not twi]
        return act


class BatterySag(FaultKind):
    part_key = part_kind = "battery"
    fields: ClassVar[dict] = {"soc": ("number", False), "amps": ("number", False)}

    def check(self, out, clear, bad):
        if clear:
            return
        if "soc" not in out and "amps" not in out:
            raise bad("battery_sag needs soc = (0..1) and/or amps = (extra load, A)")
        if "soc" in out and not 0 <= out["soc"] <= 1:
            raise bad("soc must be in [0, 1]", "soc")
        if "amps" in out and not 0 <= out["amps"] <= 1000:
            raise bad("amps must be from 0 to 1000 A", "amps")

    def prepare(self, sc, sim, part, spec, line, where):
        target, clear = spec[self.part_key], spec["clear"]
        kernel = sim.kernel

        def act():
            load = sc._sag_loads.get(target)
            if clear:
                if load is not None:
                    load.set(0.0)
                return
            if "soc" in spec:
                part.set_soc(spec["soc"])
            if "amps" in spec:
                if load is None:
                    from ..plant.battery import ConstantLoad
                    load = sc._sag_loads[target] = ConstantLoad(kernel, 0.0, name=f"{target}.sag")
                    part.connect(load)
                load.set(spec["amps"])
        return act


class Estop(FaultKind):
    part_key = part_kind = "estop"

    def prepare(self, sc, sim, part, spec, line, where):
        clear = spec["clear"]

        def act():
            (part.release if clear else part.press)()
        return act


class Overtemperature(FaultKind):
    part_key, part_kind = "bridge", "bts7960"
    fields: ClassVar[dict] = {"side": ("str", False)}

    def check(self, out, clear, bad):
        out.setdefault("side", "both")
        if out["side"] not in ("R", "L", "both"):
            raise bad("side must be \"R\", \"L\" or \"both\"", "side")

    def prepare(self, sc, sim, part, spec, line, where):
        clear = spec["clear"]

        def act():
            (part.clear_overtemperature if clear else part.overtemperature)(spec["side"])
        return act


# fault kind -> its class (the order the messages list them)
FAULTS = {
    "encoder_glitch": EncoderGlitch(),
    "missing_edges": MissingEdges(),
    "stall": Stall(),
    "i2c_silent": I2cSilent(),
    "battery_sag": BatterySag(),
    "estop": Estop(),
    "overtemperature": Overtemperature(),
}
