"""Generated GPIO and net scripts around a routed TIM3 PWM output (mode, open drain, pulls, AF,
ODR, forced drives, a second driver, listeners attached mid-run, timer writes): the fast engine's
pin edges, levels and IDR reads equal the reference engine's."""

import os

from diff_net import compare
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

N = int(os.environ.get("ENGINE_FUZZ_EXAMPLES", "80"))


@st.composite
def scripts(draw):
    arr = draw(st.integers(1, 9))
    otyper = draw(st.integers(0, 1)) << 6
    pupd = draw(st.sampled_from([0, 1, 2])) << 12
    init = [("MODER", 2 << 12), ("AFRL", 2 << 24), ("OTYPER", otyper), ("PUPDR", pupd), ("ARR", arr),
            ("CCR1", draw(st.integers(0, arr + 1))), ("CCMR1", draw(st.sampled_from([0x60, 0x70, 0x68]))),
            ("CCER", draw(st.sampled_from([1, 3]))), ("EGR", 1), ("SR", 0), ("CR1", 1)]
    if draw(st.booleans()):
        init = init[2:] + init[:2]   # AF routing after the timer starts
    ops = []
    cyc = 0
    for _ in range(draw(st.integers(0, 7))):
        cyc += draw(st.integers(0, 9))
        kind = draw(st.sampled_from(["moder", "otyper", "pupdr", "odr", "afrl", "drive", "release", "ext", "extnone",
                                     "ccr", "ccer", "ccmr", "ridr", "pull", "cr1"]))
        if kind == "moder":
            ops.append((cyc, "w", "MODER", draw(st.integers(0, 3)) << 12))
        elif kind == "otyper":
            ops.append((cyc, "w", "OTYPER", draw(st.integers(0, 1)) << 6))
        elif kind == "pupdr":
            ops.append((cyc, "w", "PUPDR", draw(st.integers(0, 2)) << 12))
        elif kind == "odr":
            ops.append((cyc, "w", "ODR", draw(st.integers(0, 1)) << 6))
        elif kind == "afrl":
            ops.append((cyc, "w", "AFRL", draw(st.sampled_from([0, 2])) << 24))
        elif kind == "drive":
            ops.append((cyc, "drive", draw(st.integers(0, 1)), 0))
        elif kind == "release":
            ops.append((cyc, "release", 0, 0))
        elif kind == "ext":
            ops.append((cyc, "ext", draw(st.integers(0, 1)), 0))
        elif kind == "extnone":
            ops.append((cyc, "ext", None, 0))
        elif kind == "ccr":
            ops.append((cyc, "w", "CCR1", draw(st.integers(0, 11))))
        elif kind == "ccer":
            ops.append((cyc, "w", "CCER", draw(st.sampled_from([0, 1, 3]))))
        elif kind == "ccmr":
            ops.append((cyc, "w", "CCMR1", draw(st.sampled_from([0, 0x40, 0x50, 0x60, 0x70]))))
        elif kind == "ridr":
            ops.append((cyc, "r", "IDR", 0))
        elif kind == "pull":
            ops.append((cyc, "pull", draw(st.sampled_from([None, 0, 1])), 0))
        elif kind == "cr1":
            ops.append((cyc, "w", "CR1", draw(st.sampled_from([0, 1]))))
    listen_at = draw(st.one_of(st.none(), st.integers(0, cyc + 5)))
    wl = draw(st.booleans())
    sample = draw(st.booleans())
    return init, ops, listen_at, wl, sample


@settings(max_examples=N, deadline=None, suppress_health_check=list(HealthCheck))
@given(scripts())
# found by a soak: the pin made open drain while it was an input (its route dropped), then routed
# again, kept the timer output's push-pull choice (the waveform passed on without its edges): the
# fast engine lost every edge after the first (the GPIO refreshed only the output routed now)
@example(([("MODER", 8192), ("AFRL", 33554432), ("OTYPER", 0), ("PUPDR", 0), ("ARR", 1), ("CCR1", 1),
           ("CCMR1", 96), ("CCER", 1), ("EGR", 1), ("SR", 0), ("CR1", 1)],
          [(0, "w", "MODER", 0), (0, "w", "OTYPER", 64), (0, "w", "MODER", 8192)], None, False, False))
# found by a soak: an external driver joined a PWM pin, then a compare value went into the preload
# register: the contention expander planned from the old waveform expanded its rise at the update
# event, where the new waveform ends, and the fast engine reported a contention edge by edge never saw
@example(([("MODER", 8192), ("AFRL", 33554432), ("OTYPER", 0), ("PUPDR", 0), ("ARR", 1), ("CCR1", 0),
           ("CCMR1", 104), ("CCER", 1), ("EGR", 1), ("SR", 0), ("CR1", 1)],
          [(0, "w", "CCR1", 1), (3, "ext", 0, 0), (3, "w", "CCR1", 0)], None, False, False))
# found by a soak: a disabled PWM channel switched to frozen mode at a wrap the fast engine passed
# without its event kept a stale OCxREF (its compare matches only refresh a driven output); edge
# by edge the wrap had set it from the old mode's comparison, and the re-enabled output rose
@example(([("MODER", 8192), ("AFRL", 33554432), ("OTYPER", 0), ("PUPDR", 0), ("ARR", 1), ("CCR1", 0),
           ("CCMR1", 96), ("CCER", 1), ("EGR", 1), ("SR", 0), ("CR1", 1)],
          [(0, "w", "CCR1", 1), (1, "w", "CCER", 0), (2, "w", "CCMR1", 0), (2, "w", "CCER", 1)],
          None, False, False))
def test_nets_fast_equals_reference(s):
    init, ops, listen_at, wl, sample = s
    n = (ops[-1][0] if ops else 0) + 60
    d, _a, _b = compare(init, ops, n, listen_at=listen_at, wave_listener=wl, sample=sample)
    assert d is None, (d, s)
