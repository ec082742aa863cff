"""Run one command line under both engines and compare what they wrote (the equality contract).

Identical digital traces: every scalar VCD signal (pins, interrupt lines, bus wires) changes at the
same ticks to the same values, and the register-access logs are identical line for line (each MCU's
own log; several MCUs' accesses at one tick may interleave differently, see _log_differences). Plant
variables (the VCD's real-valued samples and the summary's numbers) agree within 1e-9 relative.
A mismatch is reported with the signal, the first differing time and both values; a moved encoder
edge (a float rounding that put a plant crossing on the other side of a tick) shows up there as a
pin edge at different ticks, never silently tolerated.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from mcusim.cli import main

REL = 1e-9
# faults of generated rover runs: scenario lines keyed by name (None: no fault)
ROVER_FAULTS = {
    "estop": 'fault = { kind = "estop", estop = "estop" }',
    "silent": 'fault = { kind = "i2c_silent", board = "mcm2" }',
    "sag": 'fault = { kind = "battery_sag", battery = "battery", soc = 0.15, amps = 40 }',
    "none": None,
}

WALL_KEYS = {"wall_s", "realtime_factor", "engine", "events"}




def read_vcd(path: Path):
    """{name: [(time_ps, value), ...]} and {name: type} from a VCD file."""
    names, types, changes = {}, {}, {}
    scope = []
    t = 0
    with open(path) as f:
        in_defs = True
        for line in f:
            tok = line.split()
            if not tok:
                continue
            if in_defs:
                if tok[0] == "$scope":
                    scope.append(tok[2])
                elif tok[0] == "$upscope":
                    scope.pop()
                elif tok[0] == "$var":
                    name = ".".join(scope + [tok[4]])
                    names.setdefault(tok[3], []).append(name)
                    types[name] = tok[1]
                    changes[name] = []
                elif tok[0] == "$enddefinitions":
                    in_defs = False
                continue
            if tok[0].startswith("#"):
                t = int(tok[0][1:])
            elif tok[0] in ("$dumpvars", "$end", "$dumpall"):
                continue
            elif tok[0][0] in "rR":
                for n in names[tok[1]]:
                    changes[n].append((t, float(tok[0][1:])))
            elif tok[0][0] in "bB":
                for n in names[tok[1]]:
                    changes[n].append((t, tok[0][1:]))
            else:
                for n in names[tok[0][1:]]:
                    changes[n].append((t, tok[0][0]))
    return changes, types


def scalar_lines(path: Path) -> list[tuple[str, list[str]]]:
    """The VCD's digital part as written: (timestamp line, its scalar and vector change lines) for
    every timestamp that has any, in file order (real-valued lines left out)."""
    out, t, cur = [], None, None
    with open(path) as f:
        for line in f:
            if line.startswith("#"):
                t, cur = line.strip(), None
            elif t is not None and line[:1] not in ("r", "R", "$", "\n") and line.strip():
                if cur is None:
                    cur = (t, [])
                    out.append(cur)
                cur[1].append(line.rstrip("\n"))
    return out


def _close(a: float, b: float, scale: float) -> bool:
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return abs(a - b) <= REL * max(abs(a), abs(b), scale)


def real_mismatch(a, b):
    """Where two VCD real signals (lists of (time, value) changes) differ by more than REL of the
    signal's full scale, or None. A VCD holds a real variable's *changes* only: where the engines'
    values differ in the last bits, one engine records a sample that the other, seeing a bit-equal
    value, leaves out (a current at its steady state). So the two step functions are compared at
    every time either engine recorded."""
    scale = max((abs(v) for _, v in a + b), default=0.0)
    ia = ib = 0
    va = vb = None
    for t in sorted({t for t, _ in a} | {t for t, _ in b}):
        while ia < len(a) and a[ia][0] <= t:
            va = a[ia][1]
            ia += 1
        while ib < len(b) and b[ib][0] <= t:
            vb = b[ib][1]
            ib += 1
        if va is None or vb is None:
            return f"at {t} ps: only {'fast' if va is None else 'reference'} has a value"
        if not _close(va, vb, scale):
            return f"at {t} ps: reference {va!r}, fast {vb!r}"
    return None


def _pose_scale(d: dict) -> float:
    """One scale for a pose's x, y and yaw: yaw comes from differences of wheel travels, so its
    rounding is relative to the distance travelled, not to yaw itself (a straight run's yaw is a
    rounding residue of ~1e-19 rad where the engines' wheel angles differ in the last bit); and a
    turn in place leaves x and y as residues of wheel travels of about |yaw|·track/2 each (found:
    x = -3e-23 m against -3e-20 m after 0.5 rad/s), so |yaw| times 1 m, more than any shipped
    rover's track, counts as a length too."""
    vals = [abs(d[k]) for k in ("x", "y") if isinstance(d.get(k), (int, float))]
    if isinstance(d.get("yaw"), (int, float)):
        vals.append(abs(d["yaw"]) * 1.0)
    return max(vals + [1e-12])


def _compare_values(where: str, a, b, problems: list, scale: float = 1e-12) -> None:
    if isinstance(a, dict) and isinstance(b, dict):
        sub = max(_pose_scale(a), _pose_scale(b)) if {"x", "y", "yaw"} <= set(a) else 1e-12
        for k in sorted(set(a) | set(b)):
            if k in WALL_KEYS:
                continue
            if k not in a or k not in b:
                problems.append(f"{where}.{k}: only in one engine's summary")
            else:
                _compare_values(f"{where}.{k}", a[k], b[k], problems, sub)
    elif isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b)):
            _compare_values(f"{where}[{i}]", x, y, problems)
    elif isinstance(a, float) or isinstance(b, float):
        if not (isinstance(a, (int, float)) and isinstance(b, (int, float)) and _close(a, b, scale)):
            problems.append(f"{where}: reference {a!r}, fast {b!r}")
    elif a != b:
        problems.append(f"{where}: reference {a!r}, fast {b!r}")


def _mcu_of(line: str):
    return json.loads(line).get("mcu")


def _log_differences(la: list[str], lb: list[str]) -> list[str]:
    """Differences of two register logs. Each MCU's accesses must be identical line by line (same
    ticks, same order). Only the interleaving of *different* MCUs' accesses at one and the same
    tick may differ: the kernel orders same-tick events of independent MCUs by when they were
    scheduled, which differs between the engines (e.g. two identical motors' encoder edges at the
    same tick, one located at a PWM edge, the other inside a chunk); nothing links them at that tick.
    """
    out = []
    by_a, by_b = {}, {}
    for lines, by in ((la, by_a), (lb, by_b)):
        for line in lines:
            by.setdefault(_mcu_of(line), []).append(line)
    for mcu in sorted(set(by_a) | set(by_b), key=str):
        a, b = by_a.get(mcu, []), by_b.get(mcu, [])
        if a != b:
            first = next((i for i, (p, q) in enumerate(zip(a, b)) if p != q), min(len(a), len(b)))
            out.append(f"register log of {mcu}, its line {first + 1} differs: reference "
                       f"{a[first] if first < len(a) else 'end'}, fast {b[first] if first < len(b) else 'end'}")
    if not out:
        ta = [json.loads(x)["t_s"] for x in la]
        tb = [json.loads(x)["t_s"] for x in lb]
        if ta != tb:    # (cannot happen when every MCU's log agrees; kept as a guard)
            out.append("register log: the accesses are interleaved across different ticks")
    return out


def run_both(tmp_path: Path, argv: list[str], vcd: bool = True, reglog: bool = True) -> dict:
    """Run ``mcusim run`` with ``argv`` under each engine; returns {engine: (exit, dir)}. Without
    ``vcd`` no pin is watched, so the fast engine counts the STM32 encoders lazily; without
    ``reglog`` too, it serves the AVR encoder and Timer0 handlers in closed form (a traced pin or
    a logged PIND read runs them edge by edge), and only the summaries are compared."""
    out = {}
    for engine in ("reference", "fast"):
        d = tmp_path / engine
        d.mkdir(parents=True, exist_ok=True)
        trace = ["--vcd", str(d / "t.vcd")] if vcd else []
        log = ["--register-log", str(d / "t.jsonl")] if reglog else []
        code = main(["run", *argv, "--engine", engine, "--quiet", *trace, *log,
                     "--summary", str(d / "t.json")])
        out[engine] = (code, d)
    return out


def scalar_mismatch(name: str, a, b, tick_ps) -> str:
    """The first difference of two VCD scalar signals (lists of (time ps, value)). Where it is the
    same change at most one base tick (``tick_ps()``, ps) apart, with as many changes in both, it
    says that this is how a rounding tie shows (still a difference)."""
    first = next((i for i, (p, q) in enumerate(zip(a, b)) if p != q), min(len(a), len(b)))
    pa = a[first] if first < len(a) else "end"
    pb = b[first] if first < len(b) else "end"
    hint = ""
    if (pa != "end" and pb != "end" and pa[1] == pb[1] and len(a) == len(b)
            and abs(pa[0] - pb[0]) <= tick_ps() + 1):
        hint = (" - the same change one base tick apart: how a plant crossing within float rounding "
                "of a tick boundary shows (a rounding tie, docs/engine.md), if the plant values "
                "there agree to ~1e-15")
    return (f"VCD {name}: change #{first} differs: reference {pa}, fast {pb} "
            f"({len(a)} and {len(b)} changes){hint}")


def _tick_ps(board: str) -> float:
    """The base tick of ``board`` (a profile name or path) in ps, as the VCD's times round it."""
    import mcusim
    return 1e12 / mcusim.load(board, firmware=False).timebase.base_hz


def _output(d: Path, name: str) -> Path | None:
    """What a run left of its output ``name``: the file, or the ``.part`` a failed run leaves (the
    same up to where it stopped), or None."""
    for path in (d / name, d / (name + ".part")):
        if path.exists():
            return path
    return None


def differences(tmp_path: Path, argv: list[str], vcd: bool = True, reglog: bool = True) -> list[str]:
    """Everything in which the two engines' outputs differ (empty when they agree). A run that
    fails (a fault found during it, exit status 1) leaves its traces as ``.part`` files up to
    where it stopped: those are compared, and so are the exit statuses."""
    runs = run_both(tmp_path, argv, vcd, reglog)
    (code_r, ref), (code_f, fast) = runs["reference"], runs["fast"]
    problems = []
    if code_r != code_f:
        problems.append(f"exit status: reference {code_r}, fast {code_f}")
    if code_r not in (0, 1) or _output(ref, "t.jsonl" if reglog else "t.json") is None:
        # (exit status 2: the command line was refused, nothing ran; a typo must not compare equal)
        problems.append(f"the reference run did not run (exit status {code_r}): nothing to compare")
    outs = {}
    for name in ("t.vcd",) * vcd + ("t.jsonl",) * reglog + ("t.json",):
        a, b = _output(ref, name), _output(fast, name)
        if (a is None) != (b is None):
            problems.append(f"{name}: only the {'fast' if a is None else 'reference'} engine's run wrote it")
        outs[name] = (a, b) if a is not None and b is not None else None
    if outs.get("t.vcd") is None:
        vcd = False
    va, types = read_vcd(outs["t.vcd"][0]) if vcd else ({}, {})
    vb, _ = read_vcd(outs["t.vcd"][1]) if vcd else ({}, {})
    for name in sorted(set(va) | set(vb)):
        a, b = va.get(name), vb.get(name)
        if a is None or b is None:
            problems.append(f"VCD {name}: only in one engine's trace")
            continue
        if types[name] == "real":
            bad = real_mismatch(a, b)
            if bad:
                problems.append(f"VCD {name} {bad}")
        elif a != b:
            problems.append(scalar_mismatch(name, a, b, lambda: _tick_ps(argv[0])))
    if vcd and not problems:    # the same changes: then also written the same, byte for byte
        ba, bb = scalar_lines(outs["t.vcd"][0]), scalar_lines(outs["t.vcd"][1])
        if ba != bb:
            i = next((i for i, (p, q) in enumerate(zip(ba, bb)) if p != q), min(len(ba), len(bb)))
            problems.append(f"VCD digital lines differ at timestamp #{i}: reference "
                            f"{ba[i] if i < len(ba) else 'end'}, fast {bb[i] if i < len(bb) else 'end'}")
    if outs.get("t.jsonl") is not None:
        la, lb = (p.read_text().splitlines() for p in outs["t.jsonl"])
        if la != lb:
            problems.extend(_log_differences(la, lb))
    if outs["t.json"] is not None:
        sa, sb = (json.loads(p.read_text()) for p in outs["t.json"])
        _compare_values("summary", sa, sb, problems)
    return problems
