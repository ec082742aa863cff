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


def test_the_run_loop_collects_young_objects_less_often_and_restores_the_collectors_thresholds():
    from mcusim.kernel import GC_YOUNG, Kernel
    from mcusim.time import TimeBase

    seen = []
    k = Kernel(TimeBase([16_000_000]))
    k.at(10, lambda: seen.append(gc.get_threshold()))
    old = gc.get_threshold()
    try:
        gc.set_threshold(700, 10, 10)
        k.run_until(20)
        assert seen == [(GC_YOUNG, 10, 10)]
        assert gc.get_threshold() == (700, 10, 10)
        # a collector switched off by threshold 0 stays off, and a larger threshold stays as it is
        for thr in ((0, 10, 10), (GC_YOUNG * 2, 5, 5)):
            gc.set_threshold(*thr)
            k.at(k.now + 1, lambda: seen.append(gc.get_threshold()))
            k.run_until(k.now + 5)
            assert seen[-1] == thr and gc.get_threshold() == thr
        # a threshold set by code an event runs stays after the run
        gc.set_threshold(700, 10, 10)
        k.at(k.now + 1, lambda: gc.set_threshold(5000, 20, 20))
        k.run_until(k.now + 5)
        assert gc.get_threshold() == (5000, 20, 20)
    finally:
        gc.set_threshold(*old)


def test_runs_in_two_threads_leave_the_collectors_thresholds_as_they_were():
    """Runs overlap in threads (and nest): the threshold set before the first one is put back
    when the last one ends, whichever ends first (a run that ended first once put back the
    threshold it had found, and the other then left its own raised one behind)."""
    import threading

    from mcusim.kernel import GC_YOUNG, Kernel
    from mcusim.time import TimeBase

    old = gc.get_threshold()
    try:
        gc.set_threshold(700, 10, 10)
        a_started, b_started, a_done = threading.Event(), threading.Event(), threading.Event()
        ka, kb = Kernel(TimeBase([16_000_000])), Kernel(TimeBase([16_000_000]))
        seen = []

        def in_b():             # b's run goes on after a's has ended
            b_started.set()
            assert a_done.wait(10)
            seen.append(gc.get_threshold()[0])
        ka.at(5, lambda: (a_started.set(), b_started.wait(10)))
        kb.at(5, in_b)

        def run_a():
            ka.run_until(10)
            a_done.set()
        t = threading.Thread(target=run_a)
        t.start()
        assert a_started.wait(10)
        kb.run_until(10)
        t.join(10)
        assert not t.is_alive()
        assert seen == [GC_YOUNG]
        assert gc.get_threshold() == (700, 10, 10)
    finally:
        gc.set_threshold(*old)
