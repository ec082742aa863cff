"""Served encoder edges (``mcusim.engine.served``): where nothing interacts, the fast engine applies
the PJRC Encoder's ISR in closed form instead of running each edge's four events, and must leave
every state exactly as the edge-by-edge (reference) engine leaves it.

The VCD and register-log equality tests cannot show this: a trace of the encoder pins or a log
of the PIND reads makes the fast engine run each edge one by one (tests below pin that too).
Here the runs have no trace, and the whole state is compared at observation points instead:
every register of every MCU, every pin level, each handler's run count, the CPU's busy time,
ExtInt's lost-edge counts, the firmware's encoder state, the plant encoder and the motor.
"""

import math

import pytest
from engine_compare import ROVER_FAULTS
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

import mcusim
from mcusim.scenario import load_scenario

EDGES_PER_OUTPUT_RAD = 2048 * 50 / (2 * math.pi)    # pro-mini: AMT10 (512 PPR ×4) on the motor, 1:50


def snapshot(sim) -> dict:
    out = {}
    for mname, m in sim.members.items():
        mcu = m["mcu"]
        out[f"{mname}: handler runs"] = dict(mcu.cpu.isr_count)
        out[f"{mname}: CPU busy ticks"] = mcu.cpu.busy_ticks
        for pname, p in mcu.periph.items():
            if hasattr(p, "value"):
                out[f"{mname}: {pname} registers"] = dict(p.value)
            if hasattr(p, "edges_lost"):
                out[f"{mname}: {pname} edges lost"] = list(p.edges_lost)
            if hasattr(p, "tx_log"):        # a USART: what it sent and when, and where it stands
                out[f"{mname}: {pname} sent"] = (list(p.tx_log), p.tx_done.count, list(p._txq), p._tsr,
                                                 p.interrupt_id())
        out[f"{mname}: pins"] = {n: net.level for n, net in mcu.pins.items()}
        fw = m.get("firmware")
        if fw is not None and hasattr(fw, "encoder"):
            e = fw.encoder.encoder
            out[f"{mname}: firmware encoder (state, position)"] = (e.state, e.position)
    # the CPUs' timing: every queued end of a busy stretch (a handler's entry or return, a task's
    # cycles) at its tick, and where each task stands. A handler served while edge by edge it
    # would still run when another event comes moves these (the later events' ticks)
    cpus = {id(m["mcu"].cpu): mname for mname, m in sim.members.items()}
    out["CPU events queued"] = sorted(
        (e[0], e[1], cpus[id(e[3].fn.__self__)], e[3].args[0].name) for e in sim.kernel._queue
        if not e[3].cancelled and getattr(e[3].fn, "__name__", "") == "_finish")
    for mname, m in sim.members.items():
        rtos = m["mcu"].rtos
        if rtos is not None:
            out[f"{mname}: tasks"] = [(t.name, t.state, t.wake_tick if not callable(t.wake_tick) else None)
                                      for t in rtos.tasks]
    for name, part in sim.parts.items():
        if type(part).__name__ == "QuadratureEncoder":
            out[f"{name} (position, edges, dropped)"] = (part.position, part.edges, part.dropped)
        if type(part).__name__ == "DcMotor":
            out[f"{name} (i, ω, θ)"] = (part.current, part.speed, part.angle)
    return out


def _close(a, b) -> bool:
    if isinstance(a, float):
        return abs(a - b) <= 1e-9 * max(1.0, abs(a), abs(b))
    if isinstance(a, tuple):
        return len(a) == len(b) and all(_close(x, y) for x, y in zip(a, b))
    return a == b


def served(sim) -> int:
    return sum(m["mcu"].cpu.served_isrs for m in sim.members.values())


def run_both(build, seconds: float, step: float = 0.004):
    """Run the reference and the fast engine side by side and compare their states every ``step``
    seconds; returns the fast simulation. ``build(engine)`` makes one simulation."""
    ref, fast = build("reference"), build("fast")
    t = 0.0
    while t < seconds - 1e-12:
        dt = min(step, seconds - t)
        ref.run(seconds=dt)
        fast.run(seconds=dt)
        t += dt
        a, b = snapshot(ref), snapshot(fast)
        bad = [k for k in a if not _close(a[k], b[k])]
        assert not bad, (f"at {fast.time_s:.6f} s the engines differ in {bad}: reference "
                         f"{[a[k] for k in bad][:2]}, fast {[b[k] for k in bad][:2]}")
    assert ref.now == fast.now
    return fast


def test_the_promini_bench_command_serves_most_edges_and_leaves_every_state_as_edge_by_edge():
    fast = run_both(lambda e: mcusim.load("pro-mini", overrides={"velocity": 20}, engine=e), 0.25)
    edges = fast.part("encoder").edges
    assert edges > 3000
    assert served(fast) > 0.8 * edges       # the point of it: most edges have no event of their own
    # and most of those are counted, not located one by one (served._count)
    assert fast.part("encoder").counted_edges > 0.7 * edges


@settings(max_examples=200, deadline=None)
@given(period=st.integers(1, 40), ticks=st.integers(1, 4000), R=st.integers(-100, 10**6))
def test_a_counted_window_ends_at_the_last_tick_whose_handler_returns_by_the_barrier(period, ticks, R):
    """Route.returns(t) = the first clock edge at or after t, plus the handler's ticks: the window's
    last tick returns by R, the tick after it does not, and neither does any later tick."""
    from mcusim.engine.served import Route, last_tick_returning_by
    from mcusim.time import Clock, TimeBase

    clock = Clock("cpu", 1_000_000, TimeBase([1_000_000 * period]))     # ``period`` base ticks a cycle
    route = Route(clock, None, 0, ticks, None)
    t = last_tick_returning_by(clock, ticks, R)
    assert route.returns(t) <= R
    assert all(route.returns(u) > R for u in range(t + 1, t + 2 * period + 2))


def _compare_counted_with_planned(build, seconds: float, step: float):
    """Run ``build()`` twice in the fast engine, once with counting off (every served run planned
    crossing by crossing); the states agree at every ``step``. Returns the counted simulation."""
    import mcusim.engine.served as served_mod

    a, b = build(), build()
    t = 0.0
    while t < seconds - 1e-12:
        dt = min(step, seconds - t)
        a.run(seconds=dt)
        keep = served_mod.COUNT_MIN
        served_mod.COUNT_MIN = 10**12
        try:
            b.run(seconds=dt)
        finally:
            served_mod.COUNT_MIN = keep
        t += dt
        sa, sb = snapshot(a), snapshot(b)
        bad = [k for k in sa if not _close(sa[k], sb[k])]
        assert not bad, (a.time_s, bad, [sa[k] for k in bad][:2], [sb[k] for k in bad][:2])
    assert not any(p.counted_edges for p in b.parts.values() if hasattr(p, "counted_edges"))
    return a


@pytest.mark.heavy
def test_counted_runs_of_the_rovers_four_wheels_end_where_no_handler_is_in_flight():
    """Four streams on four CPUs: a run's cut moves back to a stream's last crossing whose handler
    would still run at the first crossing left out (else that crossing's event, still queued, would
    come before ``now``: the kernel refuses to run it). From standstill to speed, 0.45 s."""
    a = _compare_counted_with_planned(
        lambda: mcusim.load("elementall", overrides={"cmd_vel.linear": 0.5, "cmd_vel.angular": 0.2}), 0.45, 0.05)
    assert sum(p.counted_edges for p in a.parts.values() if hasattr(p, "counted_edges")) > 1000


def test_edges_during_a_busy_loop_pass_are_served_and_delay_its_end_as_edge_by_edge():
    """A handler taken while ``loop()`` burns its cycles pauses it: edge by edge the pass's end
    moves by the handler's dispatch-to-return ticks (``Cpu._pause``/``_resume``). A served
    handler moves it the same way (``Cpu.delay_busy_task``). Here the work pass takes 6 of every
    10 ms, so most edges fall inside one; they are served, and every state (the queued ends of
    the pass among them) agrees with the reference at observation points that cut passes."""
    sets = {"velocity": 20, "firmware.cycles_loop_work": 100_000}
    fast = run_both(lambda e: mcusim.load("pro-mini", overrides=sets, engine=e), 0.06, 0.0013)
    assert served(fast) > 0.8 * fast.part("encoder").edges


def _with_task_steps(sim):
    """``sim`` and the list of ticks at which its pro-mini's task code runs (``Rtos._step``): where
    each loop pass ends, the timing ``loop()`` sees of the handlers that preempted it. Every pass
    runs its code: Timer0's overflows are not served with the idle passes they wake (those are
    skipped by design, see test_served_ticks.py)."""
    mcu = sim.members[next(iter(sim.members))]["mcu"]
    mcu.cpu.tick_form(16, None)
    rtos = mcu.rtos
    log, step = [], rtos._step

    def logged(task):
        log.append(sim.kernel.now)
        return step(task)
    rtos._step = logged             # before the first pass: every later wait ends in ``logged``
    return sim, log


@settings(max_examples=6, deadline=None)
@example(v=-20.0, work=20_000, idle=200, sample_ms=10)
@given(v=st.floats(-25.0, 25.0), work=st.integers(1, 60_000), idle=st.integers(1, 3000),
       sample_ms=st.sampled_from([1, 2, 10]))
@pytest.mark.heavy
def test_loop_passes_end_at_the_same_ticks_when_the_edges_inside_them_are_served(v, work, idle, sample_ms):
    """Loop passes of any length against edges of any rate: each pass's end lands before, at and
    after the served edges' dispatches (a dispatch at the pass's end tick still comes first, one
    a tick later does not), and the task's code runs at the same ticks as edge by edge. (The
    example: a rule that served edges dispatched up to 16 ticks after a pass's end fails it.)"""
    sets = {"velocity": v, "firmware.cycles_loop_work": work, "firmware.cycles_loop_idle": idle,
            "firmware.sample_ms": sample_ms}
    (ref, a), (fast, b) = (_with_task_steps(mcusim.load("pro-mini", overrides=sets, engine=e))
                           for e in ("reference", "fast"))
    ref.run(seconds=0.2)
    fast.run(seconds=0.2)
    assert a == b
    sa, sb = snapshot(ref), snapshot(fast)
    assert not [k for k in sa if not _close(sa[k], sb[k])]


def test_a_run_judged_doomed_before_locating_any_crossing_would_serve_nothing(monkeypatch):
    """``_stranger_first`` and ``_doomed`` settle a run from first crossings and earliest returns
    only: wherever either says no run can serve the owner's first crossing, the same run without
    them (which locates every crossing it needs) serves nothing either. A run that serves nothing
    changes nothing, so it can be tried again. Checked on the rover, whose wheels' edges fall on
    nearby ticks of four modules (most failed runs end there)."""
    import mcusim.engine.served as served_mod

    real_run, real_stranger, real_doomed = served_mod.serve_run, served_mod._stranger_first, served_mod._doomed
    fired = []

    def stranger(*a):
        got = real_stranger(*a)
        fired.append(got)
        return got

    def doomed(*a):
        got = real_doomed(*a)
        fired.append(got)
        return got

    judged = {"stranger": 0, "doomed": 0}

    def checked(kernel, owner):
        fired.clear()
        done = real_run(kernel, owner)
        if not done and any(fired):
            judged["stranger" if fired[0] else "doomed"] += 1
            monkeypatch.setattr(served_mod, "_stranger_first", lambda *a: False)
            monkeypatch.setattr(served_mod, "_doomed", lambda *a: False)
            try:
                assert not real_run(kernel, owner)
            finally:
                monkeypatch.setattr(served_mod, "_stranger_first", stranger)
                monkeypatch.setattr(served_mod, "_doomed", doomed)
        return done

    monkeypatch.setattr(served_mod, "_stranger_first", stranger)
    monkeypatch.setattr(served_mod, "_doomed", doomed)
    monkeypatch.setattr(served_mod, "serve_run", checked)
    sim = mcusim.load("elementall", overrides={"cmd_vel.linear": 0.5, "cmd_vel.angular": 0.2})
    sim.run(seconds=0.6)
    assert judged["stranger"] > 100 and judged["doomed"] > 20, judged


@settings(max_examples=4, deadline=None)
@example(v=20.0, load=0.0, j_scale=1.0, ms=120, step_ms=1.3)
@given(v=st.floats(-80.0, 80.0), load=st.floats(-25.0, 25.0), j_scale=st.sampled_from([0.5, 1.0, 4.0]),
       ms=st.integers(40, 120), step_ms=st.sampled_from([1.3, 4.0, 13.0]))
def test_counted_runs_leave_every_state_as_runs_planned_crossing_by_crossing(v, load, j_scale, ms, step_ms):
    """The same fast engine with counting off: the state agrees at observation points spaced so
    that they cut counted runs anywhere."""
    sets = {"velocity": v, "motor.load_torque": load, "motor.J": 2e-5 * j_scale}
    _compare_counted_with_planned(lambda: mcusim.load("pro-mini", overrides=sets), ms / 1000, step_ms / 1000)


def test_the_reference_engine_never_serves():
    sim = mcusim.load("pro-mini", overrides={"velocity": 20}, engine="reference")
    sim.run(seconds=0.1)
    assert sim.part("encoder").edges > 1000 and served(sim) == 0


@settings(max_examples=6, deadline=None)
@example(v=20.0, load=0.0, i_cl=60.0, j_scale=1.0, ms=90)
@example(v=-75.0, load=10.0, i_cl=9.0, j_scale=0.5, ms=120)
@given(v=st.floats(-80.0, 80.0), load=st.floats(-25.0, 25.0), i_cl=st.sampled_from([60.0, 15.0, 9.0]),
       j_scale=st.sampled_from([0.5, 1.0, 4.0]), ms=st.integers(40, 140))
def test_served_edges_leave_every_state_as_edge_by_edge_on_generated_promini_runs(v, load, i_cl, j_scale, ms):
    """Velocity steps either way from standstill, load torques helping or opposing, current limits
    down to tripping, light and heavy shafts: edge rates from none to beyond the ISR bound."""
    sets = {"velocity": v, "motor.load_torque": load, "motor.J": 2e-5 * j_scale, "ibt2.I_CLH": i_cl,
            "ibt2.I_CLL": 0.7 * i_cl}
    run_both(lambda e: mcusim.load("pro-mini", overrides=sets, engine=e), ms / 1000)


def _turn_scenario(tmp_path, rate, sign, over_ms, back):
    angle = sign * rate / EDGES_PER_OUTPUT_RAD * over_ms / 1000
    body = (f'[scenario]\nboard = "pro-mini"\nduration = "{2 * over_ms + 10}ms"\n\n'
            f'[[at]]\ntime = "2ms"\nturn = {{ motor = "motor", angle = {angle!r}, over = "{over_ms}ms" }}\n')
    if back:
        body += (f'\n[[at]]\ntime = "{over_ms + 4}ms"\n'
                 f'turn = {{ motor = "motor", angle = {-angle / 3!r}, over = "{over_ms}ms" }}\n')
    path = tmp_path / "turn.toml"
    path.write_text(body)
    return path


def _build(path, engine):
    sc = load_scenario(path)        # a scenario applies to one simulation
    sim = sc.build(None, None, True, engine)
    sc.apply(sim)
    return sim, sc.duration


@settings(max_examples=5, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@example(rate=105_000, sign=1, over_ms=6, back=True)
@given(rate=st.sampled_from([30_000, 60_000, 95_000, 105_000, 115_000, 160_000]), sign=st.sampled_from([1, -1]),
       over_ms=st.integers(3, 10), back=st.booleans())
def test_edges_near_and_above_the_isr_bound_are_lost_alike_when_the_others_are_served(tmp_path, rate, sign,
                                                                                     over_ms, back):
    """A hand turns the shaft at edge rates around the PJRC Encoder's ISR bound (~105 k edges/s:
    4 + 148 cycles at 16 MHz). An edge closer to the next than a handler's run is never served, so
    the flags that absorb edges above the bound absorb the same ones in both engines."""
    path = _turn_scenario(tmp_path, rate, sign, over_ms, back)
    run_both(lambda engine: _build(path, engine)[0], _build(path, "fast")[1], step=0.002)


def test_a_turn_below_the_isr_bound_is_served_and_one_above_it_is_not(tmp_path):
    """At 30 k edges/s (33 µs apart, a handler takes 9.5 µs) edges are served; at 160 k edges/s
    (6 µs apart) none can be: each comes before the previous handler returns."""
    counts = {}
    for rate in (30_000, 160_000):
        sim, _ = _build(_turn_scenario(tmp_path, rate, 1, 8, False), "fast")
        enc = sim.part("encoder")
        sim.run(seconds=0.002)
        e0, s0 = enc.edges, served(sim)
        sim.run(seconds=0.008)
        counts[rate] = (enc.edges - e0, served(sim) - s0)
    assert counts[30_000][1] > 0.8 * counts[30_000][0]
    assert counts[160_000][0] > 1000 and counts[160_000][1] == 0


@settings(max_examples=5, deadline=None)
@given(v=st.sampled_from([15.0, -25.0, 40.0]), t_fault=st.integers(20, 60), kind=st.sampled_from(["glitch", "drop"]),
       n=st.integers(1, 5), channel=st.sampled_from(["A", "B"]))
def test_served_edges_agree_through_encoder_glitches_and_dropped_edges(v, t_fault, kind, n, channel):
    """A noise spike on one output (then an edge where both outputs change, never served) and
    dropped crossings (the outputs slip behind the position)."""
    def build(engine):
        sim = mcusim.load("pro-mini", overrides={"velocity": v}, engine=engine)
        enc = sim.part("encoder")
        fault = (lambda: enc.glitch(channel, 16 * n)) if kind == "glitch" else (lambda: enc.drop_edges(n))
        sim.kernel.at(sim.timebase.base_hz * t_fault // 1000, fault)
        return sim
    run_both(build, 0.1, step=0.002)


def test_a_register_log_of_the_pin_reads_makes_edges_run_one_by_one(tmp_path):
    """Serving skips the handler's PIND reads: while a register log watches PORTD each edge runs
    its handler; a log of other peripherals does not stop serving."""
    watched = mcusim.load("pro-mini", overrides={"velocity": 20})
    watched.trace_registers(tmp_path / "d.jsonl", filter="PORTD")
    other = mcusim.load("pro-mini", overrides={"velocity": 20})
    other.trace_registers(tmp_path / "t.jsonl", filter="TIMER1")
    for sim in (watched, other):
        sim.run(seconds=0.1)
        sim.close()
    assert watched.part("encoder").edges > 1000 and served(watched) == 0
    assert served(other) > 0.5 * other.part("encoder").edges


def test_a_trace_of_the_encoder_pins_makes_edges_run_one_by_one(tmp_path):
    """A VCD trace listens to the encoder pins (it needs every edge at its tick): nothing is served."""
    sim = mcusim.load("pro-mini", overrides={"velocity": 20})
    sim.trace_vcd(tmp_path / "t.vcd")
    sim.run(seconds=0.1)
    sim.close()
    assert sim.part("encoder").edges > 1000 and served(sim) == 0


def test_a_handler_bound_over_the_encoder_isr_is_run_not_the_closed_form():
    """Firmware that binds its own handler to INT0/INT1 (an ISR(INT0_vect) of its own) takes the
    vector from the PJRC Encoder: from then on each edge runs that handler, in both engines."""
    def build(engine):
        sim = mcusim.load("pro-mini", overrides={"velocity": 20}, engine=engine)
        cpu = sim.mcu.cpu
        sim.hits = []

        def rebind():
            for vector in (1, 2):
                cpu.vector(vector, lambda: sim.hits.append(sim.now), cost=148)
        sim.kernel.at(sim.timebase.base_hz // 50, rebind)      # at 20 ms
        return sim
    fast = run_both(build, 0.05, step=0.005)
    before = served(fast)
    fast.run(seconds=0.02)
    assert before > 0 and served(fast) == before and len(fast.hits) > 100


def test_detaching_and_attaching_the_encoder_isr_again_serves_again():
    """detachInterrupt stops the edges' handler; attaching the same function again restores the
    closed form (it stands for that function), and both engines agree throughout."""
    def build(engine):
        sim = mcusim.load("pro-mini", overrides={"velocity": 20}, engine=engine)
        core = sim.firmware.core
        fn = core.int_func[0]
        hz = sim.timebase.base_hz
        sim.kernel.at(hz * 20 // 1000, core.detach_interrupt, 0)
        sim.kernel.at(hz * 30 // 1000, lambda: core.attach_interrupt(0, fn, 1))
        return sim
    fast = run_both(build, 0.06, step=0.002)
    assert fast.mcu.cpu.isr_count[1] < fast.mcu.cpu.isr_count[2]     # INT0 was off for 10 ms
    before = served(fast)
    fast.run(seconds=0.02)
    assert served(fast) > before + 100


@pytest.mark.heavy
def test_the_rover_serves_the_edges_of_wheels_that_turn_alike_and_agrees():
    """The ElementAll rover driving straight: the two wheels of a side turn alike, so their
    encoders' edges fall on the same ticks, on two modules. One served run takes both modules'
    crossings in time order (each module's handler is its own), and every state agrees."""
    fast = run_both(lambda e: mcusim.load("elementall", overrides={"cmd_vel.linear": 0.5}, engine=e),
                    0.3, step=0.01)
    edges = sum(fast.part(f"mcm{i}.encoder").edges for i in range(1, 5))
    assert edges > 1000 and served(fast) > 0.5 * edges




@pytest.mark.heavy
def test_runs_pass_over_the_mid_burst_frame_ends_of_the_rovers_telemetry_and_agree(monkeypatch):
    """The controller sends MAVLink telemetry in bursts of 16 bytes (the THRE handler fills the
    FIFO); a frame end in the middle of a burst changes nothing outside its USART, so a served run
    on the modules passes over it (``served.inert_until``) where edge by edge it would end the run.
    Every state, the bytes sent and their ticks among them, agrees with the reference engine."""
    from mcusim.periph.lpc43xx.uart import Usart

    passed = []
    inert = Usart.served_inert

    def counting(self, ev):
        got = inert(self, ev)
        if got is not None:
            passed.append(got)
        return got
    monkeypatch.setattr(Usart, "served_inert", counting)
    fast = run_both(lambda e: mcusim.load("elementall", overrides={"cmd_vel.linear": 0.5, "cmd_vel.angular": 0.2},
                                          engine=e), 0.35, step=0.01)
    assert len(fast.members["rcm"]["mcu"].periph["USART3"].tx_log) > 200
    assert len(passed) > 50


@settings(max_examples=3, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(lin=st.floats(-0.6, 0.6), ang=st.floats(-0.5, 0.5), fault=st.sampled_from(sorted(ROVER_FAULTS)),
       t_fault=st.integers(160, 260), unequal=st.booleans())
@pytest.mark.heavy
def test_served_edges_agree_on_generated_rover_runs(tmp_path, lin, ang, fault, t_fault, unequal):
    """Drive and turn, an E-stop, a module dropping off the bus or a battery sag while the wheels
    turn, with wheels alike or one heavier (then their edges fall apart)."""
    body = (f'[scenario]\nboard = "elementall"\nduration = "280ms"\n\n'
            f'[[at]]\ntime = "0s"\npublish = {{ "cmd_vel.linear" = {lin!r}, "cmd_vel.angular" = {ang!r} }}\n')
    if ROVER_FAULTS[fault]:
        body += f'\n[[at]]\ntime = "{t_fault}ms"\n{ROVER_FAULTS[fault]}\n'
    if unequal:
        body += '\n[set]\n"mcm3.motor.J" = 3e-5\n'
    path = tmp_path / "rover.toml"
    path.write_text(body)
    run_both(lambda engine: _build(path, engine)[0], 0.28, step=0.01)
