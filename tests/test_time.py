"""Integer time base and unit parsing (architecture invariant 1)."""

from fractions import Fraction

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mcusim.errors import TimeError
from mcusim.time import TimeBase, parse_duration, parse_frequency


def test_base_frequency_is_lcm_of_clocks():
    assert TimeBase([216_000_000, 108_000_000, 54_000_000]).base_hz == 216_000_000
    assert TimeBase([216_000_000, 16_000_000, 204_000_000]).base_hz == 7_344_000_000  # lcm(216, 16, 204) MHz


@pytest.mark.parametrize("text,seconds", [("2s", Fraction(2)), ("500ms", Fraction(1, 2)), ("10us", Fraction(1, 100000)),
                                          ("1.5ms", Fraction(3, 2000)), ("20ns", Fraction(1, 50_000_000)),
                                          ("0.25", Fraction(1, 4)), ("1e-3s", Fraction(1, 1000))])
def test_durations_parse_exactly(text, seconds):
    assert parse_duration(text) == seconds


@pytest.mark.parametrize("text,hz", [("50kHz", 50_000), ("216MHz", 216_000_000), ("16e6", 16_000_000), ("1.5kHz", 1500)])
def test_frequencies_parse_exactly(text, hz):
    assert parse_frequency(text) == hz


@pytest.mark.parametrize("bad", ["2 parsecs", "ms", "-1s", "", "1..2s"])
def test_bad_duration_names_the_input(bad):
    with pytest.raises(TimeError, match="bad duration"):
        parse_duration(bad)


def test_inexact_conversion_raises_unless_rounding_asked():
    tb = TimeBase([216_000_000])
    assert tb.ticks("20us") == 4320
    with pytest.raises(TimeError, match="not a whole number of base ticks"):
        tb.ticks("1ps")
    assert tb.ticks("1ps", rounding=True) == 0


def test_clock_that_does_not_divide_base_is_refused():
    tb = TimeBase([216_000_000])
    assert tb.clock("apb1", "108MHz").period == 2
    with pytest.raises(TimeError, match="does not divide"):
        tb.clock("odd", "100MHz")


@given(st.integers(min_value=0, max_value=10**12))
def test_ticks_round_trip_through_seconds_exactly(n):
    tb = TimeBase([216_000_000])
    assert tb.ticks(Fraction(n, tb.base_hz)) == n
