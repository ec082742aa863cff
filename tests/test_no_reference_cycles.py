"""A run leaves no reference cycles behind: everything it stops using is freed by reference
counting at once, not left to Python's cyclic garbage collector.

A cycle made per event is garbage the collector must find: the rover's served runs once made
~160 k such objects per simulated second (each committed crossing referred to its stream, which
kept the last one), about a tenth of the rover's wall time in collections.
"""

import gc

import pytest

import mcusim

RUNS = [
    ("nucleo-f746", {"/motor1/set_pos": 9.42477796076938, "/motor2/set_pos": -1.5707963267948966}, 0.3),
    ("pro-mini", {}, 0.3),
    # the wheels turn from about 0.11 s: served and counted runs of encoder edges on four modules
    ("elementall", {"cmd_vel.linear": 0.5, "cmd_vel.angular": 0.2}, 0.3),
]


def _garbage_of_run(board, overrides, seconds, engine):
    sim = mcusim.load(board, overrides=dict(overrides), engine=engine)
    sim.run(seconds=0.15)
    gc.collect()
    flags = gc.get_debug()
    gc.set_debug(gc.DEBUG_SAVEALL)
    try:
        sim.run(seconds=seconds)
        gc.collect()
        garbage = list(gc.garbage)
    finally:
        gc.set_debug(flags)
        gc.garbage.clear()
    return sorted({type(o).__qualname__ for o in garbage}), len(garbage)


@pytest.mark.parametrize("board,overrides,seconds", RUNS, ids=[r[0] for r in RUNS])
def test_a_fast_run_leaves_no_reference_cycles(board, overrides, seconds):
    kinds, n = _garbage_of_run(board, overrides, seconds, "fast")
    assert n == 0, f"{n} objects in reference cycles, of types {kinds}"
