"""Generated register scripts on TIM1/TIM2/TIM3 (CCR/ARR/PSC with and without preload, CR1 bits,
UG, DIER, SR clears and reads, CNT writes, CCMR modes, CCER, MOE, RCR) at arbitrary cycles: the fast
engine's port edges, interrupt lines and read values equal the reference engine's, seen by an edge
listener or by a waveform listener sampling every cycle."""

import os

from diff_tim import MOE, compare
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

CEN, UDIS, URS, OPM, DIR, ARPE, UIFREMAP = 1, 2, 4, 8, 16, 128, 1 << 11
N = int(os.environ.get("ENGINE_FUZZ_EXAMPLES", "80"))


@st.composite
def scripts(draw):
    name = draw(st.sampled_from(["TIM1", "TIM3", "TIM2"]))
    arr = draw(st.integers(1, 8))
    psc = draw(st.integers(0, 2))
    cr1 = draw(st.sampled_from([0, ARPE, DIR, ARPE | DIR]))
    m1 = draw(st.sampled_from([6, 7])); m2 = draw(st.sampled_from([6, 7, 4, 5, 0]))
    pe1 = draw(st.booleans()); pe2 = draw(st.booleans())
    ccmr1 = (m1 << 4) | (8 if pe1 else 0) | ((m2 << 12) | (0x800 if pe2 else 0))
    ccer = 1 | 0x10 | (draw(st.integers(0, 1)) << 1) | (draw(st.integers(0, 1)) << 5)
    init = [("CR1", cr1), ("ARR", arr), ("PSC", psc)]
    if name == "TIM1":
        init.append(("RCR", draw(st.integers(0, 2))))
    init += [("EGR", 1), ("SR", 0), ("CCR1", draw(st.integers(0, arr + 1))), ("CCR2", draw(st.integers(0, arr + 1))),
             ("CCMR1", ccmr1), ("CCER", ccer)]
    if name == "TIM1":
        init.append(("BDTR", MOE))
    init.append(("CR1", cr1 | CEN))
    ops = []
    cyc = 0
    for _ in range(draw(st.integers(0, 8))):
        cyc += draw(st.integers(0, 12))
        kind = draw(st.sampled_from(["ccr", "arr", "psc", "cr1", "egr", "dier", "sr", "rsr", "rcnt", "ccmr", "ccer",
                                     "bdtr", "cnt", "rcr"]))
        if kind == "ccr":
            ops.append((cyc, "w", draw(st.sampled_from(["CCR1", "CCR2"])), draw(st.integers(0, 10))))
        elif kind == "arr":
            ops.append((cyc, "w", "ARR", draw(st.integers(1, 10))))
        elif kind == "psc":
            ops.append((cyc, "w", "PSC", draw(st.integers(0, 2))))
        elif kind == "cr1":
            bits = draw(st.sets(st.sampled_from([CEN, UDIS, URS, OPM, DIR, ARPE, UIFREMAP, 1 << 5, 2 << 5, 3 << 5])))
            v = sum(bits)
            if draw(st.booleans()):
                v |= CEN
            ops.append((cyc, "w", "CR1", v))
        elif kind == "egr":
            ops.append((cyc, "w", "EGR", 1))
        elif kind == "dier":
            ops.append((cyc, "w", "DIER", draw(st.sampled_from([0, 1, 2, 4, 3, 7]))))
        elif kind == "sr":
            ops.append((cyc, "w", "SR", draw(st.sampled_from([0, 0xFFFE, 0xFFFD, 0xFFFB, 0xFFFF]))))
        elif kind == "rsr":
            ops.append((cyc, "r", "SR", 0))
        elif kind == "rcnt":
            ops.append((cyc, "r", "CNT", 0))
        elif kind == "ccmr":
            a = draw(st.sampled_from([0, 4, 5, 6, 7])); b = draw(st.sampled_from([0, 4, 5, 6, 7]))
            ops.append((cyc, "w", "CCMR1", (a << 4) | (b << 12) | (8 if draw(st.booleans()) else 0)
                        | (0x800 if draw(st.booleans()) else 0)))
        elif kind == "ccer":
            ops.append((cyc, "w", "CCER", draw(st.sampled_from([0, 1, 3, 0x11, 0x13, 0x31, 0x10, 0x33]))))
        elif kind == "bdtr":
            ops.append((cyc, "w", "BDTR", draw(st.sampled_from([0, MOE]))))
        elif kind == "cnt":
            ops.append((cyc, "w", "CNT", draw(st.integers(0, 10))))
        elif kind == "rcr":
            ops.append((cyc, "w", "RCR", draw(st.integers(0, 2))))
    ops.append((cyc + 1, "r", "SR", 0))
    return name, init, ops


@settings(max_examples=N, deadline=None, suppress_health_check=list(HealthCheck))
@given(scripts(), st.sampled_from(["edges", "waves"]))
def test_fast_equals_reference(s, rec):
    name, init, ops = s
    n = (ops[-1][0] if ops else 0) + 120
    d, _a, _b = compare(name, init, ops, n, rec)
    assert d is None, (d, name, init, ops)
