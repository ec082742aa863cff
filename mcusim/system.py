"""System profiles: several boards on one event queue and one time base, plus shared plant.

A system profile (``boards/elementall.toml``) has a ``[system]`` table instead of ``[board]``::

    [system]
    name = "elementall"
    main = "rcm"                      # the board whose firmware takes the system's inputs

    [[member]]                        # one board instance; its parts become "mcm1.motor" ...
    name = "mcm1"
    board = "pro-mini"
    plant = true                      # false: the board without its own [[part]]/[pins]/[analog]
    set = { "firmware.i2c_address" = 0x08 }   # --set style overrides for this instance

    [links]                           # a system part's output net drives board part terminals
    "estop.enable_out" = ["mcm1.ibt2.R_EN", "mcm1.ibt2.L_EN"]

    [pins]                            # board pins wired to system part terminals
    "rcm.GPIO3_3" = "estop.enable_in"

    [[part]]                          # system-level plant; parameters may name board parts
    name = "body"
    kind = "rover-body"
    motors = ["mcm1.motor", "mcm2.motor"]

    [analog]                          # a board's analog input follows a system part
    "rcm.CH1" = "vbat_divider"

The time base is the lcm of every member's clocks (204 MHz and 16 MHz give 816 MHz). I2C buses
with the same name in several boards are one bus. ``--set`` keys: ``<member>.present=false``
leaves that board unpowered (built without firmware: its TWI does not answer, its pins stay
undriven, its motor and bridge stay in the plant); ``<member>.<key>`` is the member's own
``--set`` key (``mcm2.motor.R=0.2``, ``mcm1.firmware.kp=0.03``, ``mcm1.velocity=10``);
``<part>.<param>`` sets a system part's parameter (``battery.count=2``); ``firmware.<x>`` is a
parameter of the main board's firmware; any other key is an input of the main firmware
(``cmd_vel.linear=0.5``).
"""

from __future__ import annotations

import re

from .board import (
    _firmware_inputs,
    _located,
    _PartError,
    board_clocks,
    build,
    build_parts,
    located_part_error,
    read_profile,
    split_overrides,
)
from .errors import ConfigError, key_of_message, with_member
from .kernel import Kernel
from .signals import Net
from .time import TimeBase


def is_system(profile: dict) -> bool:
    return "system" in profile


def _truth(value, key):
    if isinstance(value, bool):
        return value
    if value in (0, 1):
        return bool(value)
    raise ConfigError(f"--set {key}={value!r}: expected true or false")


def split_system_overrides(profile: dict, overrides: dict, where: str, inputs=frozenset()):
    members = {m["name"]: {} for m in profile.get("member", [])}
    present = {name: True for name in members}
    parts = {p["name"]: {} for p in profile.get("part", [])}
    main_fw, topics = {}, []
    for key, value in overrides.items():
        head, dot, rest = key.partition(".")
        if dot and head in members:
            if rest == "present":
                present[head] = _truth(value, key)
            else:
                members[head][rest] = value
        elif dot and head in parts:
            parts[head][rest] = value
        elif dot and head == "firmware":
            main_fw[rest] = value
        elif key in inputs or not dot:
            topics.append((key, value))
        else:
            raise ConfigError(f"--set {key}: no board or part {head!r}; boards: {', '.join(members)}; "
                              f"parts: {', '.join(parts)}; controller inputs: {', '.join(sorted(inputs))}")
    return members, present, parts, main_fw, topics


def given_present(overrides) -> set:
    """The members whose presence ``overrides`` (``--set``) sets: those win over the file's."""
    return {k.rpartition(".")[0] for k in (overrides or {}) if k.endswith(".present")}


def close_firmware_tasks(members: dict) -> None:
    """End the task coroutines of every board's firmware (a simulation that will not run on)."""
    for ns in members.values():
        rtos = ns["mcu"].rtos
        for task in (rtos.tasks if rtos is not None else ()):
            task.close()


def _build_member(m, prof, pwhere, user_sets, present, main_fw, with_firmware, kernel, buses, external):
    """One board of the system: its profile's ``set`` and the user's keys for it; without
    firmware (absent, or --no-firmware) firmware keys are mistakes."""
    name = m["name"]
    sets = {**{k: v for k, v in m.get("set", {}).items() if k != "present"}, **user_sets}
    try:
        p_parts, p_fw, p_topics = split_overrides(prof, sets)
    except ConfigError as exc:
        raise with_member(exc, name, user_sets) from None
    p_fw.update(main_fw)
    fw_on = with_firmware and present
    if not fw_on:
        topic_keys = {k for k, _ in p_topics}
        given = [f"{name}.{k}" for k in user_sets if k.startswith("firmware.") or k in topic_keys]
        given += [f"firmware.{k}" for k in main_fw]
        if given:
            why = "is not present" if not present else "runs without firmware (--no-firmware)"
            raise ConfigError(f"--set {', '.join(given)}: {name} {why}")
        p_fw, p_topics = {}, []
    try:
        ns = build(prof, pwhere, p_parts, fw_on, p_fw, buses=buses, kernel=kernel, external=external)
    except ConfigError as exc:
        raise with_member(exc, name, user_sets) from None
    ns["present"], ns["topics"], ns["fw_params"] = present, p_topics, p_fw
    return ns


def _check_owned_loads(members: dict, member_sets: dict, specs: list, profile, where: str) -> None:
    """A wheel motor's load_torque or load_inertia given by ``--set`` or by a member's own ``set``
    in the system file: the rover body owns them and sets them from the vehicle's motion (the
    value would be overwritten before the first step)."""
    for index, m in enumerate(specs):
        name = m["name"]
        ns = members[name]
        for key in list(member_sets[name]) + [k for k in m.get("set", {}) if k not in member_sets[name]]:
            part, _, param = key.rpartition(".")
            motor = ns["parts"].get(part)
            owner = getattr(motor, "load_owner", None)
            if owner is None or param not in getattr(motor, "_OWNED", ()):
                continue
            msg = motor.owned_load_reason()
            if key in member_sets[name]:
                raise ConfigError(f"--set {name}.{key}: {msg}")
            raise _located(profile, where, f"member {name}: set: {key}: {msg}", "member", index, "set", key)


def _check_unique_params(members: dict, where: str, profile=None) -> None:
    """Firmware parameters declared ``unique`` (a bus address) must differ between the boards,
    else two slaves answer one address: a configuration error, found before the run."""
    seen: dict = {}
    for name, ns in members.items():
        fw = ns.get("firmware")
        for key, decl in getattr(type(fw), "PARAMS", {}).items() if fw is not None else ():
            tag = getattr(decl, "unique", None)
            if tag is None:
                continue
            value = ns["fw_params"].get(key, decl.default)
            other = seen.setdefault((tag, value), name)
            if other != name:
                shown = f"{value:#04x}" if isinstance(value, int) else repr(value)
                msg = f"{other} and {name} both have firmware.{key} = {shown}; each board needs its own"
                index = next((i for i, m in enumerate((profile or {}).get("member", [])) if m.get("name") == name),
                             None)
                if profile is None or index is None:
                    raise ConfigError(f"{where}: {msg}")
                raise _located(profile, where, msg, "member", index)


def _build_system_parts(profile, where, part_params, members, link_nets, kernel) -> dict:
    """The system's own parts, wired to board pins ([pins]) and to their output nets ([links]),
    and the board analog inputs that follow them ([analog])."""
    def lookup(dotted):
        member, _, part = dotted.partition(".")
        return members.get(member, {}).get("parts", {}).get(part)

    wiring: dict = {}
    for pin, target in profile.get("pins", {}).items():
        member, _, pin_name = pin.partition(".")
        if member not in members:
            raise _located(profile, where, f"[pins] {pin!r}: no member {member!r} (members: "
                           f"{', '.join(members)})", "pins", None, pin)
        part, _, term = target.partition(".")
        try:
            net = members[member]["mcu"].pin(pin_name)
        except ConfigError as exc:
            raise _located(profile, where, f"[pins] {pin!r}: {exc}", "pins", None, pin) from None
        wiring.setdefault(part, {})[term.upper()] = net
    declared = [sp.get("name") for sp in profile.get("part", [])]
    for source, net in link_nets.items():
        part, _, term = source.partition(".")
        if part not in declared:
            raise _located(profile, where, f"[links] {source!r} names part {part!r}, which is not declared "
                           f"(parts: {', '.join(sorted(str(d) for d in declared if d))})", "links", None, source)
        wiring.setdefault(part, {})[term.upper()] = net
    try:
        sys_parts = build_parts(kernel, profile.get("part", []), part_params, wiring, where, lookup=lookup)
    except _PartError as exc:      # at the system file's line, as a board's parts are named
        raise located_part_error(profile, where, exc) from None

    for target, source in profile.get("analog", {}).items():
        member, _, net_name = target.partition(".")
        mcu = members.get(member, {}).get("mcu")
        if mcu is None or net_name not in mcu.analog:
            raise _located(profile, where, f"[analog] {target!r}: no analog input {net_name!r} on {member!r}",
                           "analog", None, target)
        part_name, _, term = source.partition(".")
        src = sys_parts.get(part_name)
        if term:
            src = getattr(src, term.lower(), None)
        if src is None or not hasattr(src, "voltage"):
            raise _located(profile, where, f"[analog] {target} = {source!r}: no such analog output",
                           "analog", None, target)
        if mcu.analog[net_name].source is not None:
            raise _located(profile, where, f"[analog] {target} = {source!r}: {member}'s {net_name} already "
                           "follows an output of its own board's plant (one analog input, one source; give "
                           "the member plant = false to wire its plant here)", "analog", None, target)
        mcu.analog[net_name].source = src.voltage
    return sys_parts


def _with_member_hint(exc: ConfigError, main: str, main_fw: dict, member_profiles: dict) -> ConfigError:
    """``firmware.<key>`` is the main board's firmware: where the key is unknown there but another
    member's firmware takes it (the rover's wheel PID on the modules), say how to reach that one."""
    if "unknown firmware parameter" not in str(exc):
        return exc
    params = {name: _firmware_params(prof, name) for name, (prof, _) in member_profiles.items()}
    unknown = [k for k in main_fw if k not in params[main]]
    takers = {}
    for key in unknown:
        for name, declared in params.items():
            if key in declared:
                takers.setdefault(key, []).append(name)
    if len(takers) != 1 or len(unknown) != 1:
        return exc          # several unknown keys, or one no member takes: the full message
    key, names = next(iter(takers.items()))
    return ConfigError(f"firmware.{key}: not a parameter of the main board's firmware; the firmware of "
                       f"{', '.join(names)} takes it: --set {names[0]}.firmware.{key}=...")


def _firmware_params(board: dict, where: str) -> dict:
    """The parameters the firmware kind of a board profile declares (none without firmware)."""
    from . import kinds
    kind = (board.get("firmware") or {}).get("kind")
    return getattr(kinds.lookup("firmware", kind, where).load(), "PARAMS", {}) if kind else {}


def _check_link_source(profile, where, source) -> None:
    """A [links] source is a terminal the system part drives (an E-stop's ENABLE_OUT), and one its
    [pins] do not wire too: a link from an input would carry nothing, and the part would lose
    the pin its input reads."""
    from . import kinds
    part, _, term = source.partition(".")
    spec = next((p for p in profile.get("part", []) if p.get("name") == part), None)
    if spec is None:
        return                  # build_parts names the unknown part
    kind = kinds.lookup("part", spec.get("kind"), where)
    outputs = kind.outputs
    if outputs is not None and term.upper() not in outputs:
        raise _located(profile, where, f"[links] {source}: {term} is not an output of {part} ({kind.name}); a "
                       f"link carries what a part drives (its outputs: {', '.join(outputs) or 'none'})",
                       "links", None, source)
    pin = _pin_wiring(profile, part, term)
    if pin is not None:
        raise _located(profile, where, f"[links] {source}: [pins] wires it to {pin} as well; a terminal has "
                       "one net", "links", None, source)


def _pin_wiring(profile, part: str, term: str):
    """The pin a profile's [pins] wire to terminal ``term`` of ``part``, or None."""
    return next((p for p, t in profile.get("pins", {}).items() if t.partition(".")[0] == part
                 and t.partition(".")[2].upper() == term.upper()), None)


def _check_link_target(profile, where, source, target, board, part, term) -> None:
    """A [links] target names a part of the member's board and one of its kind's terminals: the
    mistake is the system file's, at its [links] line (the board's own check would blame the
    board's profile)."""
    from . import kinds
    spec = next((p for p in board.get("part", []) if p.get("name") == part), None)
    if spec is None:
        names = ", ".join(p.get("name", "?") for p in board.get("part", []))
        raise _located(profile, where, f"[links] {source}: {target!r}: the board has no part {part!r} "
                       f"(parts: {names})", "links", None, source)
    required, optional = kinds.lookup("part", spec.get("kind"), where).terminals
    if term.upper() not in required + optional:
        raise _located(profile, where, f"[links] {source}: {target!r}: part {part} ({spec.get('kind')}) has "
                       f"no terminal {term}; terminals: {', '.join(required + optional) or 'none'}",
                       "links", None, source)
    pin = _pin_wiring(board, part, term)
    if pin is not None:
        raise _located(profile, where, f"[links] {source}: {target!r}: the board's own [pins] wire it to its "
                       f"pin {pin}; a terminal has one net", "links", None, source)


def build_system(profile: dict, where: str, overrides: dict, with_firmware: bool,
                 engine: str = "reference") -> dict:
    system = profile["system"]
    specs = profile.get("member", [])
    if not specs:
        raise ConfigError(f"{where}: a system needs at least one [[member]]")
    names = [m.get("name") for m in specs]
    if len(set(names)) != len(names) or None in names:
        raise ConfigError(f"{where}: every [[member]] needs a distinct name")
    main = system.get("main", names[0])
    if main not in names:
        raise _located(profile, where, f"[system] main = {main!r} is not a member ({', '.join(names)})",
                       "system", None, "main")
    member_profiles = {}
    clocks = []
    for i, m in enumerate(specs):
        if "board" not in m:
            raise _located(profile, where, f"member {m['name']}: missing board = \"...\"", "member", i)
        try:
            prof, pwhere = read_profile(m["board"])
        except ConfigError as exc:      # a board the system names: at the line that names it
            if re.match(r"\S+:\d+: ", str(exc)):
                raise               # a mistake inside that board's own file: its file:line first
            raise _located(profile, where, f"[[member]] {m['name']}: {exc}", "member", i, "board") from None
        if is_system(prof):
            raise _located(profile, where, f"member {m['name']}: {m['board']} is a system, not a board",
                           "member", i, "board")
        if m.get("plant", True) is False:   # the board alone; the system provides its plant
            prof = {k: v for k, v in prof.items() if k not in ("part", "pins", "analog")}
        member_profiles[m["name"]] = (prof, pwhere)
        clocks += board_clocks(prof)
    member_sets, present, part_params, main_fw, topics = split_system_overrides(
        profile, overrides, where, _firmware_inputs(member_profiles[main][0]))
    for index, m in enumerate(specs):     # a member's own set may say present = false too
        own = m.get("set", {})
        if "present" in own and m["name"] not in given_present(overrides):
            try:
                present[m["name"]] = _truth(own["present"], f"{m['name']}.present")
            except ConfigError as exc:
                raise _located(profile, where, f"member {m['name']}: set: {str(exc).removeprefix('--set ')}",
                               "member", index, "set", "present") from None
            if m["name"] == main and not present[main]:
                raise _located(profile, where, f"member {main}: set: present = false: {main} is the "
                               "system's main board", "member", index, "set", "present")
    if not present[main]:
        raise ConfigError(f"--set {main}.present=false: {main} is the system's main board")
    kernel = Kernel(TimeBase(clocks), engine)

    # nets that system parts drive into board parts: created first, handed to both sides
    link_nets, external = {}, {name: {} for name in names}
    for source, targets in profile.get("links", {}).items():
        _check_link_source(profile, where, source)
        net = link_nets[source] = Net(source, pull=0)
        for target in ([targets] if isinstance(targets, str) else targets):
            member, _, rest = target.partition(".")
            part, _, term = rest.partition(".")
            if not part or not term:
                raise _located(profile, where, f"[links] {source}: {target!r} is not member.part.TERMINAL",
                               "links", None, source)
            if member not in external:
                raise _located(profile, where, f"[links] {source}: {target!r}: no board {member!r} in this "
                               f"system (boards: {', '.join(external)})", "links", None, source)
            _check_link_target(profile, where, source, target, member_profiles[member][0], part, term)
            terms = external[member].setdefault(part, {})
            if term in terms:
                raise _located(profile, where, f"[links] {source}: {target!r} is driven by {terms[term].name} "
                               "too; a terminal has one net", "links", None, source)
            terms[term] = net

    buses: dict = {}
    members: dict = {}
    try:
        for index, m in enumerate(specs):
            name = m["name"]
            try:
                members[name] = _build_member(
                    m, *member_profiles[name], member_sets[name], present[name],
                    main_fw if name == main else {}, with_firmware, kernel, buses, external[name])
            except ConfigError as exc:
                exc = _with_member_hint(exc, main, main_fw if name == main else {}, member_profiles)
                msg = str(exc)
                # a value of the member's own ``set`` in this file (not a --set of the user's): its line
                key = key_of_message(msg, [k for k in m.get("set", {}) if k not in member_sets[name]],
                                     set_too=False)
                if key is not None:
                    raise _located(profile, where, f"member {name}: set: {msg}", "member", index, "set",
                                   key) from None
                raise exc from None
        _check_unique_params(members, where, profile)
        sys_parts = _build_system_parts(profile, where, part_params, members, link_nets, kernel)
        _check_owned_loads(members, member_sets, specs, profile, where)
    except Exception:
        close_firmware_tasks(members)    # firmware that will never run: end its coroutines quietly
        raise

    parts = dict(sys_parts)
    for name, ns in members.items():
        for pname, part in ns["parts"].items():
            parts[f"{name}.{pname}"] = part
    m = members[main]
    return {"timebase": kernel.timebase, "kernel": kernel, "mcu": m["mcu"], "parts": parts,
            "firmware": m["firmware"], "board": {"name": system["name"], **system}, "profile": profile,
            "members": members, "buses": buses, "main": main, "topics": topics}
