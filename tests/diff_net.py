"""Differential harness: the GPIO/net layer around a TIM3 PWM pin under both engines."""
from mcusim.periph.stm32.gpio import Gpio
from tim_oracle import Rig

from mcusim.kernel import PRIO_CPU

GPIOA = 0x4002_0000
GOFF = {"MODER": 0, "OTYPER": 4, "PUPDR": 0xC, "IDR": 0x10, "ODR": 0x14, "AFRL": 0x20}


def run(engine, init, script, n, listen_at=None, wave_listener=False, sample=True):
    rig = Rig("TIM3", 108, engine=engine)
    k = rig.kernel
    rig.mcu.periph["TIM3"] = rig.tim
    g = Gpio("GPIOA", rig.mcu, "A")
    rig.mcu.periph["GPIOA"] = g
    rig.bus.attach(GPIOA, g)
    net = rig.mcu.pins["PA6"]
    out = {"edges": [], "samples": [], "log": [], "wl": []}
    t0 = [0]

    def rec(n_):
        out["edges"].append((k.now - t0[0], n_.level))
    if listen_at is None:
        net.listen(rec)
    if wave_listener:
        net.listen(lambda n_: out["wl"].append((k.now - t0[0], n_.level)), waves=True)

    def w(reg, v):
        if reg in GOFF:
            rig.bus.write32(GPIOA + GOFF[reg], v)
        else:
            rig.w(reg, v)
    for reg, v in init:
        w(reg, v)
    t0[0] = k.now
    P = rig.P

    def do(op, a, b, cyc):
        try:
            if op == "w":
                w(a, b)
            elif op == "r":
                out["log"].append((cyc, a, rig.bus.read32(GPIOA + GOFF[a]) if a in GOFF else rig.r(a)))
            elif op == "drive":
                net.drive(a)
            elif op == "release":
                net.release()
            elif op == "ext":
                net.set("ext", a)
            elif op == "listen":
                net.listen(rec)
            elif op == "pull":
                net.set_pull(a)
        except Exception as e:
            out["log"].append((cyc, op, a, type(e).__name__, str(e)[:80]))
            raise
    for cyc, op, a, b in script:
        k.at(t0[0] + cyc * P, do, op, a, b, cyc, prio=PRIO_CPU)
    if listen_at is not None:
        k.at(t0[0] + listen_at * P, net.listen, rec, prio=PRIO_CPU)
    if sample:
        def smp():
            out["samples"].append(net.level)
        for c in range(n + 1):
            k.at(t0[0] + c * P, smp, prio=PRIO_CPU + 5)
    try:
        k.run_until(t0[0] + n * P)
    except Exception as e:  # noqa: BLE001 (the error itself is compared)
        out["log"].append(("run", k.now - t0[0], type(e).__name__, str(e)[:80]))
    return out


def compare(init, script, n, **kw):
    a = run("reference", init, script, n, **kw)
    b = run("fast", init, script, n, **kw)
    for key in ("edges", "samples", "log"):
        if a[key] != b[key]:
            x, y = a[key], b[key]
            i = next((i for i, (p, q) in enumerate(zip(x, y)) if p != q), min(len(x), len(y)))
            return f"{key} #{i}: ref {x[i] if i < len(x) else 'end'} fast {y[i] if i < len(y) else 'end'}", a, b
    return None, a, b

BASE = [("MODER", 2 << 12), ("AFRL", 2 << 24), ("ARR", 9), ("CCR1", 3), ("CCMR1", 0x60), ("CCER", 1),
        ("EGR", 1), ("SR", 0), ("CR1", 1)]
