"""Lazy encoder counting on the STM32 (fast engine): the counter computed from the shaft angle when
a register is read, not from edges, gives the reference engine's register values at every access.

The rig is the nucleo-f746 board without firmware: motor 1 turned by bridge A (steady levels or
TIM1 PWM on IN1, direction changes and load torques that reverse the shaft), its encoder on PB4/PB5
into TIM3 in encoder mode (RM0385 §4: x4 decoding, ICxF filter with CKD, CCxP, the CNT capture
into CCR1/CCR2 that HAL_TIM_Encoder_Start enables, wraps both ways with UIE), and register reads and
writes at generated ticks. Every read value, the TIM3 interrupt line and the final counter must be
the same in both engines; the lazy path must actually have run (``lazy_stretches``).
"""

import os

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import mcusim
from mcusim.kernel import PRIO_CPU

N = int(os.environ.get("ENGINE_FUZZ_EXAMPLES", "80"))
MS = 216_000
TIM1, TIM3 = 0x40010000, 0x40000400
GPIOB, GPIOE = 0x40020400, 0x40021000
REG = {"CR1": 0x00, "SMCR": 0x08, "DIER": 0x0C, "SR": 0x10, "EGR": 0x14, "CCMR1": 0x18, "CCMR2": 0x1C,
       "CCER": 0x20, "CNT": 0x24, "PSC": 0x28, "ARR": 0x2C, "CCR1": 0x34, "CCR2": 0x38, "CCR3": 0x3C,
       "CCR4": 0x40}
TIM3_IRQ = 29


def _af(m, port, pin, number):
    reg = port + (0x20 if pin < 8 else 0x24)
    sh = 4 * (pin % 8)
    m.write32(reg, (m.read32(reg) & ~(0xF << sh)) | (number << sh))
    m.write32(port, (m.read32(port) & ~(3 << 2 * pin)) | (2 << 2 * pin))


def run_rig(engine, spec):
    sim = mcusim.load("nucleo-f746", firmware=False, engine=engine, overrides=spec.get("overrides", {}))
    m, k = sim.mcu, sim.kernel
    _af(m, GPIOB, 4, 2)
    _af(m, GPIOB, 5, 2)
    tim = lambda r: TIM3 + REG[r]
    m.write32(tim("ARR"), spec["arr"])
    m.write32(tim("SMCR"), 3)
    m.write32(tim("CCMR1"), 0x0101 | (spec["icf"] << 4) | (spec["icf"] << 12) | (spec["icpsc"] << 2))
    m.write32(tim("CCR3"), spec["ccr3"])
    m.write32(tim("CCER"), 0x11 | spec["pol"])
    m.write32(tim("DIER"), spec["dier"])
    m.write32(tim("CNT"), spec["cnt0"])
    m.write32(tim("CR1"), 1 | (spec["ckd"] << 8))
    sim.pin("PF15").drive(1)                          # bridge A enabled
    if spec["pwm"]:
        _af(m, GPIOE, 9, 1)
        t1 = lambda r: TIM1 + REG[r]
        m.write32(t1("ARR"), 4319)
        m.write32(t1("CCR1"), spec["pwm"])
        m.write32(t1("CCMR1"), 0x68)                  # PWM1, preload
        m.write32(t1("EGR"), 1)
        m.write32(t1("CCER"), 1)
        m.write32(TIM1 + 0x44, 1 << 15)               # MOE
        m.write32(t1("CR1"), 1)
    else:
        sim.pin("PE9").drive(1)
    sim.pin("PE11").drive(0)
    log, lines = [], []
    sim.mcu.nvic.line_listeners.append(lambda irq, lv: lines.append((k.now, lv)) if irq == TIM3_IRQ else None)
    motor, enc = sim.part("motor1"), sim.part("encoder1")
    # half a step off the start angle 0, a threshold of every encoder: a shaft leaving rest exactly
    # on one dips across it by rounding (1e-14 rad), on ticks the engines may place apart; such
    # ties are reported, not compared, by the plant tests (tests/diff_plant.py, RoundingTie)
    motor.set_state(angle=0.5 * enc.step)

    def op(kind, reg, v):
        if kind == "r":
            log.append((k.now, reg, m.read32(tim(reg))))
        elif kind == "w":
            try:
                m.write32(tim(reg), v)
                log.append((k.now, reg, "w", v))
            except mcusim.McusimError as e:     # a refused configuration: the same in both engines
                log.append((k.now, reg, "w", v, str(e)))
        elif kind == "dir":             # bridge A's inputs: reverse the drive (IN2 high, IN1 low)
            sim.pin("PE11").drive(v)
            if not spec["pwm"]:
                sim.pin("PE9").drive(1 - v)
        elif kind == "load":
            motor.apply_load_torque(v)
        elif kind == "glitch":
            enc.glitch("A", v)
        elif kind == "drop":
            enc.drop_edges(v)
        elif kind == "state":
            motor.set_state(speed=v)
        elif kind == "pin":             # an external stimulus takes PB4 from the encoder, or gives it back
            if v is None:
                sim.pin("PB4").release()
            else:
                sim.pin("PB4").drive(v)
        elif kind == "moder":           # the firmware takes PB4 out of its alternate function, or back
            _af(m, GPIOB, 4, 2) if v else m.write32(GPIOB, m.read32(GPIOB) & ~(3 << 8))
    for t, kind, reg, v in spec["ops"]:
        k.at(t, op, kind, reg, v, prio=PRIO_CPU)
    sim.run(seconds=spec["ms"] / 1000)
    final = {r: m.read32(tim(r)) for r in ("CNT", "SR", "CR1", "CCR1", "CCR2")}
    return {"log": log, "lines": lines, "final": final, "position": enc.position, "edges": enc.edges,
            "angle": motor.angle}, enc.lazy_stretches


def assert_engines_agree(spec):
    ref, _ = run_rig("reference", spec)
    fast, stretches = run_rig("fast", spec)
    for key in ("log", "lines", "final", "position", "edges"):
        if ref[key] != fast[key]:
            if key == "log":
                i = next(i for i, (a, b) in enumerate(zip(ref["log"], fast["log"])) if a != b)
                raise AssertionError(f"first differing access {i}: reference {ref['log'][i]}, fast {fast['log'][i]}")
            raise AssertionError(f"{key}: reference {ref[key]}, fast {fast[key]}")
    assert abs(ref["angle"] - fast["angle"]) <= 1e-9 * max(1.0, abs(ref["angle"]))
    return stretches


READS = ["CNT", "SR", "CR1", "CCR1", "CCR2"]


@st.composite
def specs(draw):
    ms = draw(st.integers(4, 30))
    end = ms * MS
    ops = []
    for _ in range(draw(st.integers(5, 40))):
        t = draw(st.integers(1, end - 1))
        kind = draw(st.sampled_from(["r"] * 6 + ["w", "dir", "load", "glitch", "drop", "state"]))
        if kind == "r":
            ops.append((t, "r", draw(st.sampled_from(READS)), 0))
        elif kind == "w":
            reg = draw(st.sampled_from(["SR", "CNT", "ARR", "DIER", "CCER", "CCMR1", "EGR", "PSC", "CCR3"]))
            v = {"SR": st.sampled_from([0, 0xFFFE, 0xFDF9, 0xFFF9]), "CNT": st.integers(0, 70),
                 "ARR": st.integers(1, 80), "DIER": st.sampled_from([0, 1, 2]),
                 "CCER": st.sampled_from([0x11, 0x13, 0x31, 0x33, 0x10]),
                 "CCMR1": st.sampled_from([0x0101, 0x3131, 0xF1F1, 0x0505]), "EGR": st.just(1),
                 "PSC": st.sampled_from([0, 0, 1]), "CCR3": st.integers(0, 70)}[reg]
            ops.append((t, "w", reg, draw(v)))
        elif kind == "dir":
            ops.append((t, "dir", None, draw(st.integers(0, 1))))
        elif kind == "load":
            ops.append((t, "load", None, draw(st.sampled_from([-3.0, -0.5, 0.0, 0.5, 3.0]))))
        elif kind == "glitch":
            ops.append((t, "glitch", None, draw(st.sampled_from([1, 5, 400]))))
        elif kind == "drop":
            ops.append((t, "drop", None, draw(st.integers(0, 2))))
        else:
            ops.append((t, "state", None, draw(st.sampled_from([-300.0, 0.0, 200.0]))))
    ops.sort(key=lambda o: o[0])
    return {"ms": ms, "arr": draw(st.integers(1, 80)), "cnt0": draw(st.integers(0, 80)),
            "icf": draw(st.sampled_from([0, 0, 3, 7, 15])), "ckd": draw(st.integers(0, 2)),
            "icpsc": draw(st.integers(0, 3)), "pol": draw(st.sampled_from([0, 2, 0x20, 0x22])),
            "dier": draw(st.sampled_from([0, 1, 1, 2])), "ccr3": draw(st.integers(0, 80)),
            "pwm": draw(st.sampled_from([0, 0, 1000, 2600, 4000])), "ops": ops,
            "overrides": {"motor1.J": draw(st.sampled_from([5e-6, 5e-5])),
                          "motor1.load_torque": draw(st.sampled_from([0.0, 0.3, -0.3]))}}


@pytest.mark.heavy
@settings(max_examples=max(10, N // 2), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(spec=specs())
def test_lazy_encoder_counting_gives_the_reference_register_values(spec):
    assert_engines_agree(spec)


def _steady_spec(**kw):
    spec = {"ms": 40, "arr": 1919, "cnt0": 0, "icf": 0, "ckd": 0, "icpsc": 0, "pol": 0, "dier": 1,
            "ccr3": 0, "pwm": 2600, "overrides": {}, "ops": []}
    spec.update(kw)
    return spec


def test_a_turning_shaft_is_counted_lazily_and_read_alike():
    """The nucleo's HAL set-up (x4, CC1/CC2 capture on, UIE) with reads every 0.5 ms: the stretches
    run lazily and every read gives the edge-by-edge value."""
    ops = [(t * MS // 2, "r", r, 0) for t in range(1, 80) for r in ("CNT", "CR1")]
    assert assert_engines_agree(_steady_spec(ops=ops)) >= 1


def test_lazy_stretch_ends_before_the_counter_wraps_so_uif_comes_at_its_tick():
    """ARR = 4: the counter wraps every 5 counts. Each stretch ends at the crossing before the wrap,
    which then runs edge by edge (UEV, UIF, the interrupt line at the same tick as edge by edge)."""
    ops = [(t * MS // 4, "r", r, 0) for t in range(1, 160) for r in ("CNT", "SR")]
    ops += [(t * MS + 7, "w", "SR", 0xFFFE) for t in range(1, 40)]
    ops.sort(key=lambda o: o[0])
    assert assert_engines_agree(_steady_spec(arr=4, ops=ops)) >= 3


def test_lazy_counting_down_through_reversals_and_underflow():
    """Reversed drive and a load torque that turns the shaft back: DIR and the underflow to ARR."""
    ops = [(t * MS // 2, "r", r, 0) for t in range(1, 80) for r in ("CNT", "CR1", "SR")]
    ops += [(5 * MS, "dir", None, 1), (15 * MS, "dir", None, 0), (25 * MS, "load", None, -3.0)]
    ops.sort(key=lambda o: o[0])
    assert assert_engines_agree(_steady_spec(arr=99, cnt0=5, ops=ops)) >= 1


def test_lazy_captures_with_a_prescaler_and_overcapture_flag():
    """CC1S = CC2S = 01 with IC1PSC = /8 and a filter: CCR1/CCR2 hold CNT at the last counted
    capture and CC1OF is set when a capture finds CC1IF set (§ capture rules)."""
    ops = [(t * MS // 3, "r", r, 0) for t in range(1, 110) for r in ("CCR1", "CCR2", "SR")]
    ops += [(t * MS + 3, "w", "SR", 0xFDF9) for t in range(2, 36, 3)]
    ops.sort(key=lambda o: o[0])
    assert assert_engines_agree(_steady_spec(icf=5, ckd=1, icpsc=3, pol=0x20, ops=ops)) >= 1


def test_traced_encoder_pins_keep_edge_by_edge_counting():
    """A listener that needs every edge (a VCD of the pins) takes the descriptors away: no stretch."""
    sim = mcusim.load("nucleo-f746", firmware=False, engine="fast")
    seen = []
    sim.pin("PB4").listen(lambda n: seen.append(n.level))
    _af(sim.mcu, GPIOB, 4, 2)
    _af(sim.mcu, GPIOB, 5, 2)
    sim.mcu.write32(TIM3 + REG["ARR"], 1919)
    sim.mcu.write32(TIM3 + REG["SMCR"], 3)
    sim.mcu.write32(TIM3 + REG["CR1"], 1)
    sim.pin("PF15").drive(1)
    sim.pin("PE9").drive(1)
    sim.pin("PE11").drive(0)
    sim.run(seconds=0.02)
    assert sim.part("encoder1").lazy_stretches == 0
    assert len(seen) == sim.part("encoder1").edges // 2 > 0


def _crossing_ticks(spec, n):
    """The first ``n`` encoder edges' ticks, from an edge-by-edge run watching the pins."""
    sim = mcusim.load("nucleo-f746", firmware=False, engine="reference", overrides=spec["overrides"])
    seen = []
    for pin in ("PB4", "PB5"):
        sim.pin(pin).listen(lambda net: seen.append(sim.kernel.now))
    sim.pin("PF15").drive(1)
    sim.pin("PE9").drive(1)
    sim.pin("PE11").drive(0)
    sim.run(seconds=spec["ms"] / 1000)
    return sorted(seen)[:n]


@pytest.mark.parametrize("icf,ckd", [(0, 0), (3, 0), (5, 2), (12, 1)])
def test_reads_at_each_crossings_effect_tick_see_it_exactly_then(icf, ckd):
    """RM0385 input stage: an edge at tick t is sampled at the first f_SAMPLING edge after t, passes
    the filter after N samples and reaches the counter 2 CK_INT cycles later. Reads one tick before,
    at and after that tick of every crossing (and of CCR3 = a value CNT steps onto) must see the
    same CNT, SR and DIR as edge by edge."""
    P = 2                                   # TIM3 at 108 MHz: 2 base ticks per CK_INT cycle
    div, src, n = {0: (1, "dts", 1), 3: (1, "ck", 8), 5: (2, "dts", 8), 12: (16, "dts", 8)}[icf]
    sp = div * P * (1 if src == "ck" else 1 << ckd)
    spec = _steady_spec(ms=25, arr=1919, icf=icf, ckd=ckd, pwm=0, ccr3=7, dier=0,
                        overrides={"motor1.J": 5e-7})
    ops = []
    for t in _crossing_ticks(spec, 40):
        t_eff = (t // sp + n) * sp + 2 * P
        for when in (t, t + 1, t_eff - 1, t_eff, t_eff + 1):
            ops += [(when, "r", "CNT", 0), (when, "r", "SR", 0), (when, "r", "CR1", 0)]
        ops.append((t_eff + 2, "w", "SR", 0))
    ops.sort(key=lambda o: o[0])
    assert assert_engines_agree({**spec, "ops": ops}) >= 1


def test_a_pin_taken_from_the_encoder_mid_stretch_ends_it_and_counting_goes_on_edge_by_edge():
    """Found in review: a drive of PB4 (or PB4 leaving its alternate function) took the descriptor
    off TI1, the timer stopped counting lazily but the encoder stayed lazy, and nothing counted the
    other channel's edges (then the forced net tried to expand the descriptor and crashed)."""
    reads = [(t * MS // 4, "r", r, 0) for t in range(1, 100) for r in ("CNT", "CR1")]
    for ops in ([(6 * MS, "pin", None, 1), (7 * MS, "pin", None, None)],
                [(6 * MS, "moder", None, 0), (7 * MS, "moder", None, 1)]):
        spec = _steady_spec(ms=25, pwm=0, overrides={"motor1.J": 5e-7}, ops=sorted(reads + ops, key=lambda o: o[0]))
        assert assert_engines_agree(spec) >= 2


def test_lowering_the_capture_prescaler_makes_the_next_rise_capture():
    """Found in review: with IC1PSC lowered from /8 to /1 while 5 rises were counted, edge by edge the
    next rise captures and the count restarts; the lazy count had added phantom captures (CC1OF)."""
    ops = [(t * MS // 3, "r", r, 0) for t in range(1, 60) for r in ("CCR1", "SR")]
    ops += [(10 * MS, "w", "CCMR1", 0x0101), (10 * MS + 5, "w", "SR", 0)]
    spec = _steady_spec(ms=20, pwm=0, icpsc=3, overrides={"motor1.J": 5e-7}, ops=sorted(ops, key=lambda o: o[0]))
    assert assert_engines_agree(spec) >= 2
