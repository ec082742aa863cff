"""A chunk of stuck pieces is screened at its first and last period only (``PeriodPlan._stuck_ends``):
wherever that says "clean", the full screening of every period must say the same, with the same
states and bounds. The plans and states are the nucleo-f746's own while it holds a position (static
friction, the PID moving the duty every step), and hypothesis moves the current and the horizon
about them, up to and across the guards (breakaway, current reaching zero)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from screening_switch import with_and_without

import mcusim
from mcusim.engine import screening


@pytest.fixture(scope="module")
def held_plans():
    """(plan, x0, n, extra guards) of every all-stuck screening in 0.3 s of a nucleo-f746 hold."""
    calls = []
    full = screening.PeriodPlan.first_flag

    def spy(self, x0, n, extra):
        if all(self._stuck_t):
            calls.append((self, tuple(x0), n, extra))
        return full(self, x0, n, extra)
    sim = mcusim.load("nucleo-f746", overrides={"/motor1/set_pos": 1.0, "/motor2/set_pos": -0.5})
    sim.run(seconds=0.5)                        # moves, then holds
    screening.PeriodPlan.first_flag = spy
    try:
        sim.run(seconds=0.3)
    finally:
        screening.PeriodPlan.first_flag = full
    assert len(calls) > 50
    return calls


def _both(plan, x0, n, extra):
    return with_and_without("STUCK_ENDS", plan, x0, n, extra)


def _same(fast, full):
    assert fast[0] == full[0]
    assert np.array_equal(fast[1], full[1])
    assert fast[2] == pytest.approx(full[2], rel=1e-12, abs=1e-300)
    assert fast[3] == pytest.approx(full[3], rel=1e-12, abs=1e-300)


def test_the_ends_of_a_held_chunk_decide_as_every_period_does(held_plans):
    shortcut = 0
    for plan, x0, n, extra in held_plans:
        fast, full = _both(plan, x0, n, extra)
        _same(fast, full)
        shortcut += plan._stuck_ends(plan.table.augmented_states(x0, n), n, extra) is not None
    assert shortcut > 0.9 * len(held_plans)     # holding, nearly every chunk is settled at its ends


@settings(max_examples=300, deadline=None)
@given(pick=st.integers(0, 10**6), di=st.floats(-20.0, 20.0), scale=st.floats(0.0, 3.0),
       n=st.sampled_from([3, 4, 17, 64, 256, 512]))
def test_a_held_chunk_moved_towards_its_guards_still_decides_as_every_period_does(held_plans, pick, di, scale, n):
    """The current moved by up to ±20 A and scaled (towards the breakaway threshold and across
    zero), and horizons from 3 to 512 periods: the ends either decline or agree exactly."""
    plan, x0, _, extra = held_plans[pick % len(held_plans)]
    x = (x0[0] * scale + di, x0[1], x0[2])
    fast, full = _both(plan, x, n, extra)
    _same(fast, full)


def test_a_held_chunks_current_in_closed_form_is_the_power_tables_to_the_rounding(held_plans):
    """``i_k = i0 + (a^k − 1)(i0 − i*)`` against the period map's powers (delta form), over 512
    periods of every held plan: the same to ~1e-15 of the current's scale (measured 1.0e-15), far
    below the engines' 1e-9 plant tolerance."""
    for plan, x0, _, _ in held_plans:
        if plan._held is None or x0[1] != 0.0:
            continue
        a, b = plan._held_states(x0, 512), plan.table.augmented_states(x0, 512)
        assert np.array_equal(a[:, 1:], b[:, 1:])          # ω, θ held exactly
        assert np.abs(a[:, 0] - b[:, 0]).max() <= 4e-15 * np.abs(b[:, 0]).max()


@settings(max_examples=150, deadline=None)
@given(pick=st.integers(0, 10**6), di=st.floats(-20.0, 20.0), scale=st.floats(0.0, 3.0),
       n=st.sampled_from([3, 17, 256, 512]))
def test_a_held_chunk_is_screened_alike_from_closed_form_and_power_table_states(held_plans, pick, di, scale, n):
    """The screening's answer does not depend on where the held plan's period-start states come
    from: the same first flagged period, states within 4e-15 of the current's scale."""
    plan, x0, _, extra = held_plans[pick % len(held_plans)]
    x = (x0[0] * scale + di, x0[1], x0[2])
    closed = plan.first_flag(x, n, extra)
    held, plan._held = plan._held, None
    try:
        table = plan.first_flag(x, n, extra)
    finally:
        plan._held = held
    assert closed[0] == table[0]
    assert np.abs(closed[1] - table[1]).max() <= 4e-15 * max(1.0, np.abs(table[1][:, 0]).max())
    assert closed[2] == pytest.approx(table[2], rel=1e-12, abs=1e-300)
