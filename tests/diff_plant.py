"""Plant-level differential: L6206 + DcMotor (+ encoder) driven by waveform segments, both engines."""
import math

from mcusim.engine.waveform import Waveform
from mcusim.kernel import PRIO_HW, PRIO_OBSERVE, Kernel
from mcusim.plant.dcmotor import DcMotor
from mcusim.plant.encoder import QuadratureEncoder
from mcusim.plant.l6206 import L6206Bridge
from mcusim.signals import Net
from mcusim.time import TimeBase


def run(engine, segs, n_end, motor_kw=None, bridge_kw=None, samples=400, enc=True, param_changes=()):
    """segs: {net: [(t, spec)]}, spec = int level or (rise_off, period, width) relative to t;
    param_changes: [(t, {motor parameter: value})] applied with ``DcMotor.set_params`` at t."""
    tb = TimeBase([216_000_000])
    k = Kernel(tb, engine)
    nets = {n: Net(n) for n in ("in1", "in2", "en")}
    for n in nets.values():
        n.set("drv", 0)
    m = DcMotor(k, "m", **(motor_kw or {}))
    br = L6206Bridge(k, m, nets["in1"], nets["in2"], nets["en"], "br", **(bridge_kw or {}))
    out = {"ocd": [], "enc": [], "state": []}
    br.ocd.listen(lambda n: out["ocd"].append((k.now, n.level)))
    if enc:
        a, b = Net("A"), Net("B")
        e = QuadratureEncoder(k, m, a, b, 64, "e")
        a.listen(lambda n: out["enc"].append((k.now, "A", n.level)))
        b.listen(lambda n: out["enc"].append((k.now, "B", n.level)))
        out["theta_at"] = {}
        a.listen(lambda n: out["theta_at"].setdefault(k.now, m.angle))
        b.listen(lambda n: out["theta_at"].setdefault(k.now, m.angle))
        out["step"] = e.step
    for name, lst in segs.items():
        net = nets[name]
        for idx, (t, spec) in enumerate(lst):
            t_next = lst[idx + 1][0] if idx + 1 < len(lst) else n_end + 1
            if isinstance(spec, int):
                k.at(t, net.set, "drv", spec, prio=PRIO_HW)
            elif engine == "fast":
                ro, P, w = spec
                k.at(t, lambda net=net, t=t, ro=ro, P=P, w=w: net.set_wave("drv", Waveform(k, t + ro, P, w)), prio=PRIO_HW)
            else:
                ro, P, w = spec
                wv = Waveform(k, t + ro, P, w)
                k.at(t, net.set, "drv", wv.level_at(t), prio=PRIO_HW)
                tt = t
                while True:
                    tt, lv = wv.next_edge(tt)
                    if tt >= t_next:
                        break
                    k.at(tt, net.set, "drv", lv, prio=PRIO_HW)
    for t, kw in param_changes:
        k.at(t, lambda kw=kw: m.set_params(**kw), prio=PRIO_HW)
    step = max(1, n_end // samples)
    for s in range(0, n_end + 1, step):
        k.at(s, lambda: out["state"].append((k.now, m.current, m.speed, m.angle)), prio=PRIO_OBSERVE)
    k.run_until(n_end)
    out["trips"] = br.ocd_trips
    out["peak"] = m.peak_current
    out["segments"] = m.segments
    out["final"] = (m.current, m.speed, m.angle)
    return out


class RoundingTie(Exception):
    """The engines place an encoder edge on different ticks because the shaft angle sits within
    float rounding of a threshold there (both angles agree to 1e-9; the threshold splits them)."""


def rounding_tie(a, b, ticks, tol=1e-12, ulps=16):
    """A description of the tie if, at the first differing edge tick, either run's angle lies within
    ``tol`` rad, or ``ulps`` units in the last place of the angle, of an encoder threshold; else
    None. (The engines' angles agree to a few ulps of the angle itself: at a large angle, 1e6 rad
    with an ulp of 1.2e-10 rad, that is far more than ``tol``.)"""
    step = a.get("step")
    for t in ticks:
        for run in (a, b):
            th = run["theta_at"].get(t)
            if th is None or not step:
                continue
            near = max(tol, ulps * math.ulp(th))
            if abs(th - round(th / step) * step) <= near:
                return (f"encoder threshold tie at tick {t}: shaft angle {th!r} rad is within {near:.3g} rad "
                        "of a threshold")
    return None


def close(a, b, rel=1e-9):
    return abs(a - b) <= rel * max(abs(a), abs(b), 1e-12)


def compare(segs, n_end, **kw):
    a = run("reference", segs, n_end, **kw)
    b = run("fast", segs, n_end, **kw)
    for key in ("ocd", "enc"):
        if a[key] != b[key]:
            x, y = a[key], b[key]
            i = next((i for i, (p, q) in enumerate(zip(x, y)) if p != q), min(len(x), len(y)))
            if key == "enc":
                tie = rounding_tie(a, b, [e[0] for e in (x[i:i + 1] + y[i:i + 1])])
                if tie:
                    raise RoundingTie(tie)
            return f"{key} #{i}: ref {x[i] if i < len(x) else 'end'} fast {y[i] if i < len(y) else 'end'} (n {len(x)} vs {len(y)})", a, b
    if a["trips"] != b["trips"]:
        return f"trips {a['trips']} vs {b['trips']}", a, b
    # 1e-9 relative, with a floor far below anything physical for values near zero (1e-12 A,
    # 1e-9 rad/s, 1e-12 rad: a shaft that hardly moved differs by rounding of nanoradians)
    floor = (None, 1e-12, 1e-9, 1e-12)
    scale = [max(abs(s[j]) for s in a["state"]) for j in (1, 2, 3)]
    for sa, sb in zip(a["state"], b["state"]):
        for j in (1, 2, 3):
            if abs(sa[j] - sb[j]) > max(1e-9 * max(abs(sa[j]), abs(sb[j]), scale[j - 1] * 1e-3), floor[j]):
                return f"state at {sa[0]} comp {j}: ref {sa[j]!r} fast {sb[j]!r}", a, b
    if not close(a["peak"], b["peak"]):
        return f"peak {a['peak']} vs {b['peak']}", a, b
    return None, a, b
