"""The timed actions of ``[[at]]`` tables: one class per action kind, registered in
:data:`ACTION_KINDS`. Each checks its value in the file (``parse``, when the scenario is loaded)
and, against the built simulation, returns what it does at its tick (``prepare``, when the
scenario is applied: a function the kernel calls at ``PRIO_INPUT``). Faults (``fault = { kind =
... }``) are one action whose kinds are in :mod:`.faults`.

The functions get the :class:`~.model.Scenario`: its checked-value and name methods
(:class:`~.check.Checker`), ``_done`` (the log of what was done) and the state a later action
takes over (``_turns``: the hand turning each shaft)."""

from __future__ import annotations

from typing import ClassVar

from ..errors import McusimError
from ..kernel import PRIO_INPUT
from ..time import parse_duration
from .check import _fmt_time
from .faults import FAULTS
from .mavlink import SendMavlink

TURN_STEP = "1ms"                  # the hand of a "turn" re-sets the shaft speed this often


class Action:
    """One kind of action. ``fields``: its keys, ``{name: (type, required)}``."""

    fields: ClassVar[dict] = {}

    def parse(self, sc, i: int, name: str, spec) -> dict:
        """The checked value of ``name = spec`` in ``[[at]]`` #i+1 (ConfigError at its line)."""
        return sc._fields("at", i, (name,), spec, self.fields)

    def prepare(self, sc, sim, spec: dict, line: int, where: str):
        """Check ``spec`` against ``sim``; return the function that does the action."""
        raise NotImplementedError


class Publish(Action):
    """``publish = { "<topic>" = value, ... }``: messages to the firmware's inputs."""

    def parse(self, sc, i, name, spec):
        where, line = f"[[at]] #{i + 1}", sc._line("at", i, name)
        if not isinstance(spec, dict) or not spec:
            raise sc._err(line, f"{where}: publish = {spec!r}: expected a table "
                          "{ \"/topic\" = value, ... }")
        for topic, value in spec.items():
            if not isinstance(value, (bool, int, float, str)):
                raise sc._err(sc._line("at", i, name, topic),
                              f"{where}: publish {topic!r} = {value!r}: expected a number, "
                              "true/false or a string")
        return dict(spec)

    def prepare(self, sc, sim, spec, line, where):
        msgs = []
        for topic, value in spec.items():
            fw, name = sc._firmware_for(sim, topic, line, where)
            others = [m for m, ns in sim.members.items() if ns["firmware"] is not sim.firmware]
            sc._check_input(fw, name, line, where, value, others if fw is sim.firmware else ())
            msgs.append((fw, name, topic, value))

        def fn():
            for fw, name, topic, value in msgs:
                fw.publish(name, value)
                sc._done(f"publish {topic} = {value!r}")
        return fn


class Torque(Action):
    """``torque = { motor, nm }``: the motor's external load torque from now on."""

    fields: ClassVar[dict] = {"motor": ("str", True), "nm": ("number", True)}

    def parse(self, sc, i, name, spec):
        out = super().parse(sc, i, name, spec)
        _bounded(sc, out, i, name, "nm", 1000.0, "N·m")
        return out

    def prepare(self, sc, sim, spec, line, where):
        motor = sc._part(sim, spec["motor"], "motor", line, where)
        if getattr(motor, "load_owner", None) is not None:    # the action would be overwritten
            raise sc._err(line, f"{where}: {spec['motor']}: {motor.owned_load_reason()}; a wheel held back "
                          "is a fault = { kind = \"stall\", ... } on its motor")

        def fn():
            motor.apply_load_torque(spec["nm"])
            sc._done(f"torque {spec['motor']} {spec['nm']:g} N·m")
        return fn


def _positive_duration(sc, out: dict, i: int, name: str, key: str, default: str, least: str = "0s") -> dict:
    """Give ``out[key]`` its default duration and check that it is positive (and at least
    ``least``: a forwarder every nanosecond would be a run that never ends)."""
    out.setdefault(key, parse_duration(default))
    if out[key] <= 0 or out[key] < parse_duration(least):
        raise sc._err(sc._line("at", i, name, key), f"[[at]] #{i + 1}: {name}.{key} must be "
                      + ("positive" if least == "0s" else f"at least {least}"))
    return out


def _bounded(sc, out: dict, i: int, name: str, key: str, limit: float, unit: str) -> None:
    """|``out[key]``| at most ``limit``: physical sizes, so that a typo is not a runaway run."""
    if abs(out[key]) > limit:
        raise sc._err(sc._line("at", i, name, key), f"[[at]] #{i + 1}: {name}.{key} = {out[key]:g}: must be "
                      f"from {-limit:g} to {limit:g} {unit}")


HAND_SPEED = 100.0                 # rad/s: the fastest a hand turns an output shaft (955 rpm)


class Turn(Action):
    """``turn = { motor, angle, over }``: a hand turns the output shaft."""

    fields: ClassVar[dict] = {"motor": ("str", True), "angle": ("number", True), "over": ("duration", False)}

    def parse(self, sc, i, name, spec):
        out = _positive_duration(sc, super().parse(sc, i, name, spec), i, name, "over", "100ms", TURN_STEP)
        _bounded(sc, out, i, name, "angle", 1000.0, "rad")
        # its speed is the distance from where the shaft is at the action's tick, over ``over``:
        # checked then (prepare's fn), as the start is not known before
        return out

    def prepare(self, sc, sim, spec, line, where):
        """A hand turns the output shaft to ``angle`` over ``over``, at constant speed: every
        TURN_STEP it sets the shaft speed that reaches the next point of the ramp (so the shaft
        moves continuously and the encoder emits every edge at its tick), and stops it at the end."""
        motor = sc._part(sim, spec["motor"], "motor", line, where)
        tb, kernel = sim.timebase, sim.kernel
        over = sc._ticks(tb, spec["over"], line, f"{where}: over")
        n = max(1, over // tb.ticks(TURN_STEP))
        hz = tb.base_hz

        def fn():
            token = object()
            sc._turns[spec["motor"]] = token       # a later turn of the same shaft takes over
            t0 = kernel.now
            n_ratio = motor.params.gear_ratio
            a0, a1 = motor.angle, spec["angle"] * n_ratio
            speed = abs(a1 - a0) / n_ratio / float(spec["over"])      # output shaft, rad/s
            if speed > HAND_SPEED:
                raise sc._err(line, f"{where}: from {a0 / n_ratio:g} rad to {spec['angle']:g} rad over "
                              f"{_fmt_time(spec['over'])} is {speed:.4g} rad/s, faster than a hand turns a "
                              f"shaft (at most {HAND_SPEED:g} rad/s): give a longer over")
            sc._done(f"turn {spec['motor']} to {spec['angle']:g} rad over {_fmt_time(spec['over'])}")

            def step(k):
                if sc._turns.get(spec["motor"]) is not token:
                    return
                if spec["motor"] in sc._stalls:
                    # a shaft a stall fault jams does not turn for a hand either (10^6 N·m of
                    # stiction): the hand gives up (catching up with its ramp once the fault
                    # cleared would turn the shaft faster than a hand can)
                    if k < n:
                        sc._done(f"turn {spec['motor']}: the shaft is jammed (stall), the hand lets go")
                    return
                if k == n:
                    motor.set_state(speed=0.0)
                    return
                t_next = t0 + ((k + 1) * over) // n
                target = a0 + (a1 - a0) * (k + 1) / n
                motor.set_state(speed=(target - motor.angle) * hz / (t_next - kernel.now))
                kernel.at(t_next, step, k + 1, prio=PRIO_INPUT)
            step(0)
        return fn


class Follow(Action):
    """``follow = { from, to, period }``: a host-side forwarder from an output to an input."""

    fields: ClassVar[dict] = {"from": ("str", True), "to": ("str", True), "period": ("duration", False)}

    def parse(self, sc, i, name, spec):
        return _positive_duration(sc, super().parse(sc, i, name, spec), i, name, "period", "10ms", "100us")

    def prepare(self, sc, sim, spec, line, where):
        src_fw, src = sc._firmware_for(sim, spec["from"], line, where)
        sc._check_output(src_fw, src, line, where)
        dst_fw, dst = sc._firmware_for(sim, spec["to"], line, where)
        # the output's value now stands for its kind (a number, true/false): one the input does
        # not take is refused here, not at the first forward in the middle of the run
        sc._check_input(dst_fw, dst, line, where, value=_sample_value(src_fw, src))
        kernel = sim.kernel
        period = sc._ticks(sim.timebase, spec["period"], line, f"{where}: period")

        def forward():
            value = src_fw.topic(src)
            if value is not None:
                try:
                    dst_fw.publish(dst, value)
                except McusimError as exc:      # a value the input refuses, later in the run
                    raise sc._err(line, f"{where}: at {kernel.now / sim.timebase.base_hz:.6g} s "
                                  f"{spec['from']} = {value!r}: {exc}") from None
            kernel.at(kernel.now + period, forward, prio=PRIO_INPUT)

        def fn():
            sc._done(f"follow {spec['from']} -> {spec['to']} every {_fmt_time(spec['period'])}")
            forward()
        return fn


def _sample_value(fw, name):
    """A value of the kind output ``name`` gives: its value now, or for a topic not published yet
    one of its declared type (a Python type, or an ELF topic map's "bool"/"f32"/"u16"...)."""
    value = fw.topic(name)
    topic = getattr(fw, "topics", {}).get(name) if value is None else None
    t = getattr(topic, "type", None)
    if isinstance(t, type):
        return t()
    if isinstance(t, str):
        return False if t == "bool" else 0.0 if t.startswith("f") else 0
    return value


class Fault(Action):
    """``fault = { kind, <part key> = ..., <the kind's keys>, clear }``: injects a fault or ends
    it; the kinds are :data:`~.faults.FAULTS`."""

    def parse(self, sc, i, name, spec):
        key = (name,)
        where = f"[[at]] #{i + 1}: fault"
        line = sc._line("at", i, *key)
        if not isinstance(spec, dict):
            raise sc._err(line, f"{where} = {spec!r}: expected a table {{ kind = \"...\", ... }}")
        if "kind" not in spec:
            raise sc._err(line, f"{where}: missing kind = \"...\" (kinds: {', '.join(FAULTS)})")
        kind = spec["kind"]
        if not isinstance(kind, str) or kind not in FAULTS:
            raise sc._err(sc._line("at", i, *key, "kind"),
                          f"{where}: unknown fault kind {kind!r} (kinds: {', '.join(FAULTS)})")
        fault = FAULTS[kind]
        fields = fault.fields
        clear = sc._value("at", i, key + ("clear",), spec["clear"], "bool") if "clear" in spec else False
        if clear and not fault.clearable:
            raise sc._err(sc._line("at", i, *key, "clear"), f"{where}: {kind} cannot be cleared "
                          "(it is momentary)")
        if clear:   # ending a fault: only which part (and the side of a bridge)
            fields = {k: (t, False) for k, (t, _) in fields.items() if k == "side"}
        allowed = {fault.part_key: ("str", True), **fields}
        rest = {k: v for k, v in spec.items() if k not in ("kind", "clear")}
        out = sc._fields("at", i, key, rest, allowed)
        out["kind"], out["clear"] = kind, clear

        def bad(msg, *field):
            return sc._err(sc._line("at", i, *key, *field), f"{where}: {msg}")
        fault.check(out, clear, bad)
        return out

    def prepare(self, sc, sim, spec, line, where):
        kind, clear = spec["kind"], spec["clear"]
        fault = FAULTS[kind]
        target = spec[fault.part_key]
        what = f"fault {kind} {target}" + (" cleared" if clear else "")
        act = fault.prepare(sc, sim, fault.resolve(sc, sim, target, line, where), spec, line, where)

        def fn():
            act()
            sc._done(what)
        return fn


# the actions an [[at]] table may hold, in the order the messages list them
ACTION_KINDS = {"publish": Publish(), "torque": Torque(), "turn": Turn(), "follow": Follow(), "fault": Fault(),
                "mavlink": SendMavlink()}
ACTIONS = tuple(ACTION_KINDS)
