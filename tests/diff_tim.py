"""Differential harness: one timer Rig under fast and reference engines, same register script."""
from tim_oracle import Rig

from mcusim.kernel import PRIO_CPU

MOE = 1 << 15


def run_script(engine, name, init, script, n_cycles, rec="edges", mhz=None, pins=False):
    """init: list of (reg, val) before CEN; script: list of (cycle, op, reg, val) ops 'w'/'r'.
    rec: 'edges' (edge listener on ports) or 'waves' (descriptor listener + per-cycle sampling)."""
    mhz = mhz or (216 if name in ("TIM1", "TIM8") else 108)
    rig = Rig(name, mhz, engine=engine)
    k = rig.kernel
    log = []
    lines = []
    rig.nvic.line_listeners.append(lambda irq, lv: lines.append((k.now, irq, lv)))
    edges = {ch: [] for ch in (1, 2, 3, 4)}
    samples = {ch: [] for ch in (1, 2)}
    if rec == "edges":
        for ch in (1, 2, 3, 4):
            rig.tim.oc[ch].listen(lambda p, ch=ch: edges[ch].append((k.now, p.value)))
    else:
        for ch in (1, 2, 3, 4):
            rig.tim.oc[ch].listen(lambda p, ch=ch: edges[ch].append((k.now, p.value, repr(p.wave))), waves=True)
    for reg, v in init:
        rig.w(reg, v)
    t0 = k.now
    P = rig.P

    def do(op, reg, v, cyc):
        if op == "w":
            try:
                rig.w(reg, v)
                log.append((cyc, "w", reg, v))
            except Exception as e:  # noqa: BLE001 (the error itself is compared)
                log.append((cyc, "w", reg, v, type(e).__name__, str(e)))
        else:
            log.append((cyc, "r", reg, rig.r(reg)))
    for i, (cyc, op, reg, v) in enumerate(script):
        k.at(t0 + cyc * P, do, op, reg, v, cyc, prio=PRIO_CPU)
    if rec == "waves":
        # sample port values every cycle (a level read, no listener)
        def sample():
            for ch in (1, 2):
                samples[ch].append(rig.tim.oc[ch].value)
        for c in range(n_cycles + 1):
            k.at(t0 + c * P, sample, prio=PRIO_CPU + 5)
    k.run_until(t0 + n_cycles * P)
    final = {r: rig.r(r) for r in ("CNT", "SR", "CR1")}
    out = {"log": log, "lines": [(t - t0, i, l) for t, i, l in lines], "final": final}
    if rec == "edges":
        out["edges"] = {ch: [(t - t0, v) for t, v in e] for ch, e in edges.items()}
    else:
        out["samples"] = samples
    return out


def first_diff(a, b):
    for key in a:
        if a[key] != b[key]:
            x, y = a[key], b[key]
            if isinstance(x, dict):
                for kk in x:
                    if x[kk] != y[kk]:
                        xs, ys = x[kk], y[kk]
                        i = next((i for i, (p, q) in enumerate(zip(xs, ys)) if p != q), min(len(xs), len(ys)))
                        return f"{key}[{kk}] #{i}: ref {xs[i] if i < len(xs) else 'end'} fast {ys[i] if i < len(ys) else 'end'}"
            i = next((i for i, (p, q) in enumerate(zip(x, y)) if p != q), min(len(x), len(y)))
            return f"{key} #{i}: ref {x[i] if i < len(x) else 'end'} fast {y[i] if i < len(y) else 'end'}"
    return None


def compare(name, init, script, n, rec="edges"):
    a = run_script("reference", name, init, script, n, rec)
    b = run_script("fast", name, init, script, n, rec)
    return first_diff(a, b), a, b
