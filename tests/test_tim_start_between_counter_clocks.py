"""TIM2-TIM5 count at 108 MHz on the nucleo-f746, one counter clock every two base ticks of
216 MHz: a write that starts the counter (CEN, UG, ARR from 0) can fall between two of its
clocks. The counter then starts at the next clock edge, and until it does the outputs hold the
level of its present value. The fast engine published the PWM waveform at the write, anchored at
that edge, and showed the tail of a period before it for one tick (two extra edges on the pin;
found by a review against RM0385). Both engines must give the same edges at any tick."""

from hypothesis import given, settings
from hypothesis import strategies as st

import mcusim

TIM2, GPIOA = 0x40000000, 0x40020000
CR1, EGR, SR, CCMR1, CCER, CNT, ARR, CCR1 = 0x00, 0x14, 0x10, 0x18, 0x20, 0x24, 0x2C, 0x34


def _edges(engine, arr, ccr, mode, wait, start, ug_at):
    sim = mcusim.load("nucleo-f746", firmware=False, engine=engine)
    m = sim.mcu
    m.write32(GPIOA, (m.read32(GPIOA) & ~3) | 2)          # PA0: alternate function
    m.write32(GPIOA + 0x20, (m.read32(GPIOA + 0x20) & ~0xF) | 1)   # AF1: TIM2_CH1
    edges = []
    sim.pin("PA0").listen(lambda n: edges.append((sim.kernel.now, n.level)))
    sim.run(until_tick=wait)
    m.write32(TIM2 + ARR, arr if start != "arr" else 0)
    m.write32(TIM2 + EGR, 1)
    m.write32(TIM2 + SR, 0)
    m.write32(TIM2 + CCR1, ccr)
    m.write32(TIM2 + CCMR1, mode)
    m.write32(TIM2 + CCER, 1)
    sim.run(until_tick=sim.kernel.now + 7)
    if start == "arr":
        m.write32(TIM2 + CR1, 1)
        sim.run(until_tick=sim.kernel.now + 5)
        m.write32(TIM2 + ARR, arr)                          # ARR from 0: the counter starts
    else:
        m.write32(TIM2 + CR1, 1)
    if ug_at:
        sim.run(until_tick=sim.kernel.now + ug_at)
        m.write32(TIM2 + EGR, 1)                             # UG: counter back to 0, anew
    sim.run(until_tick=sim.kernel.now + 900)
    out = (edges, m.read32(TIM2 + CNT), m.read32(TIM2 + SR))
    sim.close()
    return out


@settings(max_examples=40, deadline=None)
@given(arr=st.integers(2, 60), ccr=st.integers(0, 62), mode=st.sampled_from([0x60, 0x68, 0x70, 0x78]),
       wait=st.integers(0, 3), start=st.sampled_from(["cen", "arr"]), ug_at=st.integers(0, 9))
def test_a_counter_started_between_its_clocks_gives_the_same_edges_in_both_engines(arr, ccr, mode, wait, start,
                                                                                     ug_at):
    assert _edges("fast", arr, ccr, mode, wait, start, ug_at) == _edges("reference", arr, ccr, mode, wait, start,
                                                                       ug_at)


def test_the_case_the_review_found_holds_the_level_until_the_first_match():
    """CEN on an odd tick, ARR = 99, CCR1 = 50, PWM1 with preload: the pin stays high from the
    UG until CNT reaches 50, 101 ticks after the write (the counter's first clock is one tick
    later), in both engines."""
    for engine in ("fast", "reference"):
        edges, _, _ = _edges(engine, 99, 50, 0x68, 0, "cen", 0)
        t0 = 7              # the set-up at tick 0, CEN 7 ticks later: an odd tick
        assert [(t - t0, lv) for t, lv in edges if t > t0][:2] == [(101, 0), (201, 1)], engine
