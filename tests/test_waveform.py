"""The steady-waveform descriptor: its edges are exactly the level changes of level_at, tick by tick."""

from hypothesis import given
from hypothesis import strategies as st

from mcusim.engine.waveform import Waveform


@st.composite
def waves(draw):
    period = draw(st.integers(2, 40))
    width = draw(st.integers(1, period - 1))
    rise = draw(st.integers(-100, 100))
    end = draw(st.one_of(st.none(), st.integers(0, 200)))
    return Waveform(None, rise, period, width, end)


@given(waves(), st.integers(-50, 150), st.integers(0, 120))
def test_edges_are_the_level_changes_tick_by_tick(w, a, span):
    b = a + span
    want = [(t, w.level_at(t)) for t in range(a + 1, b + 1)
            if w.level_at(t) != w.level_at(t - 1) and (w.end is None or t < w.end)]
    assert list(w.edges(a, b)) == want


@given(waves(), st.integers(-50, 150))
def test_next_edge_is_the_first_change_after_t(w, t):
    tick, level = w.next_edge(t)
    assert tick > t and w.level_at(tick) == level != w.level_at(tick - 1)
    assert all(w.level_at(u) == w.level_at(t) for u in range(t, tick))


def test_high_for_the_width_from_each_rise():
    w = Waveform(None, 10, 20, 5)
    assert [w.level_at(t) for t in range(8, 32)] == [0, 0] + [1] * 5 + [0] * 15 + [1, 1]
