"""Timer0's overflows and the idle loop() passes they wake, served in closed form (mcusim.engine.ticks).

Edge by edge, every 1.024 ms the overflow interrupt advances millis() and wakes loop(), whose pass
reads millis(), finds the sample time not reached and waits again. The fast engine serves such an
overflow inside a counted run of encoder edges: the states it leaves are the edge-by-edge ones at
every observation point, the passes that found work run at the same ticks, and only passes that
found nothing are skipped. Encoder edges next to an overflow are queued as the CPU queues them
(an edge whose handler still runs delays the overflow's; one that comes during it waits)."""

import contextlib

import pytest
from engine_compare import differences
from hypothesis import example, given, settings
from hypothesis import strategies as st
from mcusim.fw.openrover_mcm import sketch
from test_served_edges import _close, run_both, served, snapshot

import mcusim
from mcusim.engine import ticks


def _passes(sim):
    """``sim`` and the list of (tick, found work) of each loop() pass of its pro-mini's sketch."""
    fw = sim.firmware
    log, loop = [], fw.loop

    async def logged():
        worked = await loop()
        log.append((sim.kernel.now, worked))
        return worked
    fw.loop = logged
    return sim, log


def _served_ticks(monkeypatch):
    """Count the overflows the fast engine serves (TickRun.commit)."""
    count = [0]
    commit = ticks.TickRun.commit

    def counting(self):
        count[0] += self.n
        commit(self)
    monkeypatch.setattr(ticks.TickRun, "commit", counting)
    return count


@settings(max_examples=6, deadline=None)
@given(v=st.floats(-40.0, 40.0), sample_ms=st.sampled_from([1, 2, 10, 25]), idle=st.integers(1, 400),
       load=st.floats(-10.0, 10.0))
def test_served_overflows_leave_every_state_and_every_pass_that_found_work_as_edge_by_edge(v, sample_ms,
                                                                                           idle, load):
    sets = {"velocity": v, "firmware.sample_ms": sample_ms, "firmware.cycles_loop_idle": idle,
            "motor.load_torque": load}
    logs = {}

    def build(engine):
        sim, logs[engine] = _passes(mcusim.load("pro-mini", overrides=sets, engine=engine))
        return sim
    run_both(build, 0.15, 0.0071)
    ref, fast = logs["reference"], logs["fast"]
    assert [p for p in ref if p[1]] == [p for p in fast if p[1]]          # every working pass
    assert set(fast) <= set(ref) and all(not worked for p, worked in set(ref) - set(fast))


def test_most_overflows_of_the_bench_are_served_edges_next_to_them_queued_as_edge_by_edge(monkeypatch):
    """At 20 rpm an encoder edge lies within a handler's reach of an overflow about half the time:
    those are queued (the encoder's handler first if it is running, else after the overflow's), so
    nearly every overflow is served, and every state agrees with the reference at 2 ms steps."""
    count = _served_ticks(monkeypatch)
    fast = run_both(lambda e: mcusim.load("pro-mini", overrides={"velocity": 20}, engine=e), 0.2, 0.002)
    overflows = fast.mcu.cpu.isr_count[16]
    assert count[0] > 0.8 * overflows > 150
    assert served(fast) > count[0]


def test_a_register_log_of_sreg_runs_every_pass(tmp_path, monkeypatch):
    """An idle pass reads and writes SREG (millis(): cli, then SREG restored): while a register log
    watches it, every pass runs; a log of other peripherals leaves them served, and the two
    engines' logs and summaries agree either way."""
    count = _served_ticks(monkeypatch)
    argv = ["pro-mini", "--duration", "40ms", "--set", "velocity=20"]
    assert differences(tmp_path / "cpu", [*argv, "--register-log-filter", "CPU"], vcd=False) == []
    assert count[0] == 0
    assert differences(tmp_path / "timers", [*argv, "--register-log-filter", "TIMER0,TIMER1,EXINT"], vcd=False) == []
    assert count[0] > 20


def test_a_handler_bound_over_the_overflow_vector_is_run_not_the_closed_form(monkeypatch):
    """The closed form stands for the core's own ISR only: bound to another handler, the vector runs it."""
    count = _served_ticks(monkeypatch)
    sim = mcusim.load("pro-mini", overrides={"velocity": 20})
    calls = []
    sim.mcu.cpu.vector(16, lambda: calls.append(sim.kernel.now), cost=80)
    sim.run(seconds=0.05)
    # Timer0 runs from init(), 2 ms after reset (the Encoder constructor's wait): 48 ms / 1.024 ms
    assert count[0] == 0 and len(calls) == 46


def _overflow_ticks(sets, n, prescale=64):
    """The ticks of the first ``n`` Timer0 overflows of a pro-mini run (its clock runs free from
    init(), 2 ms after reset: the first one, taken with nothing else running, and every 256 ×
    prescale cycles on)."""
    sim = mcusim.load("pro-mini", overrides=sets, engine="reference")
    cpu = sim.mcu.cpu
    seen, (handler, cost) = [], cpu.vectors[16]
    cpu.vector(16, lambda: (seen.append(sim.kernel.now), handler()), cost=cost)
    sim.run(seconds=0.004)
    first = seen[0] - cpu.entry_latency * cpu.clock.period
    return [first + k * 256 * prescale * cpu.clock.period for k in range(n)]


@contextlib.contextmanager
def _timer0_prescaler(prescale):
    """The sketch runs Timer0 at clk/``prescale`` (``TCCR0B = CS0``: the faster-PWM idiom for pins
    5 and 6; millis() then runs fast, as on the chip)."""
    setup = sketch.OpenRoverMcm.setup

    def faster(self):
        setup(self)
        self.core._w(0x45, {64: 3, 8: 2}[prescale])      # TCCR0B: CS0
    sketch.OpenRoverMcm.setup = faster
    try:
        yield
    finally:
        sketch.OpenRoverMcm.setup = setup


def _compare_at(stops, build):
    ref, fast = build("reference"), build("fast")
    for t in stops:
        ref.run(until_tick=t)
        fast.run(until_tick=t)
        a, b = snapshot(ref), snapshot(fast)
        bad = [k for k in a if not _close(a[k], b[k])]
        assert not bad, (t, bad, [a[k] for k in bad][:2], [b[k] for k in bad][:2])


@settings(max_examples=10, deadline=None)
# the review's cases: a pass whose edges carry it into the next overflow (Timer0 at clk/8), and a
# second edge in the stretch the first one adds to a pass
@example(v=3.0, idle=1700, sample_ms=100, prescale=8, gap=251, offsets=[(True, 0, 160)] * 60)
@example(v=14.0, idle=1000, sample_ms=10, prescale=64, gap=1, offsets=[(True, 0, 160)] * 60)
@given(v=st.sampled_from([3.0, 8.0, 14.0, 20.0, -30.0, 45.0]), idle=st.sampled_from([40, 200, 1000, 1700]),
       sample_ms=st.sampled_from([10, 100]), prescale=st.sampled_from([64, 8]), gap=st.integers(1, 5),
       offsets=st.lists(st.tuples(st.booleans(), st.integers(-320, 720), st.integers(0, 340)),
                        min_size=60, max_size=60))
@pytest.mark.heavy
def test_runs_stopped_inside_an_overflows_reach_see_the_edge_by_edge_timeline(v, idle, sample_ms, prescale, gap,
                                                                             offsets):
    """Stop both engines near each overflow, from before the encoder handler that would delay it
    to after the (possibly delayed) idle pass, half of the stops within two encoder handlers'
    length after the pass's own end (each edge in the pass moves it, and the stretch it adds may
    hold the next one): at every stop the task's state, the CPU's queued ends and every register
    agree. A run that serves an overflow whose handler or pass would still be in flight at the
    stop (its end worked out too early) shows here as a task running in one engine and blocked in
    the other. With Timer0 at clk/8 (2048 cycles between overflows) a long idle pass and the
    edges that preempt it reach the next overflow, which then finds the task running: that one
    is left to the events. Stops come near every ``gap``-th overflow, so that runs span several."""
    sets = {"velocity": v, "firmware.cycles_loop_idle": idle, "firmware.sample_ms": sample_ms}
    pass_end = 4 + 80 + idle        # entry latency, the handler's cycles, the pass (1 tick = 1 cycle)
    n = 60 * 64 // prescale         # the overflows of the first 61 ms
    with _timer0_prescaler(prescale):
        stops = [t + (pass_end + near if at_end else off)
                 for i, t in enumerate(_overflow_ticks(sets, n + 1, prescale)[1:]) if (i + 1) % gap == 0
                 for at_end, off, near in [offsets[i % len(offsets)]]]
        _compare_at(sorted(stops), lambda e: mcusim.load("pro-mini", overrides=sets, engine=e))


def test_the_timer0_flags_stored_after_an_overflow_delayed_by_an_encoder_handler_are_the_reference_ones():
    """Where an encoder handler delays an overflow's, its vector entry falls timer clocks after the
    overflow, and the entry brings the flags up to that clock: a compare flag the firmware cleared
    is set again there, in both engines (the stored TIFR0, compared here every 3.7 ms)."""
    loop = sketch.OpenRoverMcm.loop

    async def clearing(self):
        worked = await loop(self)
        if worked:
            self.core._w(0x35, 0x06)     # TIFR0: clear OCF0A and OCF0B (write 1 to clear)
        return worked
    sketch.OpenRoverMcm.loop = clearing
    try:
        run_both(lambda e: mcusim.load("pro-mini", overrides={"velocity": 20}, engine=e), 0.3, 0.0037)
    finally:
        sketch.OpenRoverMcm.loop = loop


@pytest.mark.heavy
@settings(max_examples=2, deadline=None)
@given(offsets=st.lists(st.integers(-320, 720), min_size=48, max_size=48))
def test_rover_runs_stopped_inside_the_modules_overflows_reach_see_the_edge_by_edge_timeline(offsets):
    """The same on the rover at speed, where a run serves the four wheels' edges together and each
    module's overflows in its stride (an edge queued behind an overflow on one module may return
    after another module's edge that the run leaves out: nothing of that reaches the other CPU)."""
    sets = {"cmd_vel.linear": 0.5, "cmd_vel.angular": 0.2}
    ref, fast = (mcusim.load("elementall", overrides=sets, engine=e) for e in ("reference", "fast"))
    for sim in (ref, fast):
        sim.run(seconds=0.4)
    timers = [m["mcu"].periph["TIMER0"] for m in ref.members.values() if "TIMER0" in m["mcu"].periph]
    cycle = ref.kernel.timebase.base_hz // 16_000_000      # base ticks per AVR cycle (16 MHz)
    period = 256 * 64 * cycle
    firsts = [t._ev.time for t in timers]
    overflows = sorted(f + k * period for f in firsts for k in range(12))
    for t, off in zip(overflows, offsets):
        stop = max(t + off * cycle, ref.now)
        ref.run(until_tick=stop)
        fast.run(until_tick=stop)
        a, b = snapshot(ref), snapshot(fast)
        bad = [k for k in a if not _close(a[k], b[k])]
        assert not bad, (stop, bad, [a[k] for k in bad][:2], [b[k] for k in bad][:2])
