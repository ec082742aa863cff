"""Served edges: runs of pin edges whose interrupt handlers act in closed form (fast engine).

Edge by edge, a quadrature encoder on an AVR's INT0/INT1 costs for every edge: the plant event
that finds it, the net change, the external-interrupt flag, the dispatch, the handler's entry
(which reads the pins) and its return. The handler's effect, though, is a pure function of the
pin levels it reads (the PJRC Encoder's ``update``: a state table). Where nothing can interact
with it, the fast engine *serves* the edge instead: the handler's declared closed form
(:class:`mcusim.firmware.ClosedForm`) is applied to the levels the handler would read, and the
CPU is charged the cycles and the handler count the edge-by-edge run charges, without the events.

:func:`serve_run` serves a run of edges, from the crossing whose event runs now. One edge of one
encoder (a *stream* of crossings, the plant side: ``QuadratureEncoder.crossing_stream``) is served
when:

* each of its outputs' nets has one listener, an interrupt source whose whole response to an edge
  is one request of one vector (``served_vector``: INTn in any-change mode, enabled, its flag
  clear), one driver, no force, no waveform (:func:`route`);
* the CPU would take that request at once and do nothing else (``Cpu.served``: no handler running
  or pending, global interrupts on, no task waiting for an interrupt or ready but the current one,
  which may only be in a busy wait, interrupt lines not traced) and the handler declares a closed
  form that still stands for it (the handler bound, no register log watching the reads it skips).
  Both are looked up when the stream joins the run and hold at its later crossings because no
  event that is not a served crossing or an inert event comes before them (the barrier below);
* exactly one output changes, by one threshold;
* its handler's return (:meth:`Route.returns`: first CPU clock edge at or after the edge, plus
  entry latency and handler cycles) comes before the first queued event that is neither a
  crossing absorbed into the run nor an inert event passed over (:func:`inert_until`), and before
  the bound of those passed over (together: the *barrier*), and within the run's horizon;
* the stream's next crossing comes after that return (otherwise the handler would read the later
  levels, or the next request would wait or be lost: timing interacts).

**Busy tasks.** A task in a busy wait (``await cpu.cycles(n)``: ``loop()``'s pass) only waits for
its end. Edge by edge a handler pauses it at the dispatch and resumes it at the return, moving the
end by the handler's ticks. A served handler moves it the same way: after the run, by the busy time
the served handlers on its CPU were charged (``Cpu.delay_busy_task``). Its end is no barrier then,
but where it comes before the barrier it bounds the run: an edge on its CPU is served if its
request is dispatched by the end as moved so far (dispatch precedes a task's end within a tick),
any other handler must return before it (:func:`_plan`; such runs are not counted).

Several streams on different CPUs share a run (the rover's wheels that turn alike put their edges
on the same ticks of two modules): a queued crossing event of another encoder that comes before
the barrier is *absorbed*, its stream planned with the others in time order. The run commits the
longest prefix of planned crossings whose handlers all return before the first crossing left out,
whichever stream that is: edge by edge, that crossing's events come after all of them. Absorbed
events are cancelled only if their stream committed; the others stay queued as they were.

**Counted runs.** Planning a run locates every crossing on the motor's trajectory (~10 µs each).
Where each stream's motor is in a chunk of PWM periods (θ monotone) whose speed bound keeps its
crossings more than twice a handler's reach apart (so the last two conditions above hold for
every crossing), :func:`_count` does not locate them: the crossings whose handlers return before
the barrier are those up to one tick (:func:`last_tick_returning_by`), and their number is the
position the encoder's guards reach at that tick, from the shaft angle there, less the position
now. Only the first crossing left out of each stream is located, for the cut: the first crossing
left out, of any stream, or earlier where another stream's last handler would still run then. The
last crossing served is located only where its handler could still run at the cut (the latest
return of a crossing at the window's last tick is not before it). The handlers are applied one
after the other, as a planned run applies them.

The levels a handler reads are the ones after its edge: the next edge comes after its return.
Flags set and cleared, the I flag cleared at entry and set by RETI, the pending-line bits: none of
these outlive the handler, so serving leaves them as the edge-by-edge run leaves them.
"""

from __future__ import annotations

from ..kernel import PRIO_CPU, PRIO_HW, PRIO_PLANT
from .ticks import tick_run


class Route:
    """How an edge on one net reaches firmware when it is served: the CPU, the vector, the clock
    the request is synchronised to, the handler's ticks from request to return, its closed form."""

    __slots__ = ("clock", "cpu", "form", "ticks", "vector")

    def __init__(self, clock, cpu, vector, ticks, form):
        self.clock, self.cpu, self.vector, self.ticks, self.form = clock, cpu, vector, ticks, form

    def returns(self, t: int) -> int:
        """The tick at which the handler of an edge at ``t`` returns, edge by edge: the request is
        taken at the first clock edge at or after ``t``, then entry latency and handler cycles."""
        return self.clock.next_edge(t) + self.ticks

    def serve(self, levels) -> None:
        """The handler's effect, at its entry, with the levels of the form's nets given by
        ``levels`` (a mapping Net -> level for the nets the caller drives; others keep theirs)."""
        cpu, v = self.cpu, self.vector
        cpu.isr_count[v] = cpu.isr_count.get(v, 0) + 1
        cpu.busy_ticks += self.ticks        # entry latency + handler cycles, as _enter charges
        cpu.served_isrs += 1
        self.form.step(*[levels.get(n, n.level) for n in self.form.nets])

    def charge(self, n: int) -> None:
        """The handler count and CPU time of ``n`` handler runs (:meth:`serve` without the step)."""
        if not n:
            return
        cpu, v = self.cpu, self.vector
        cpu.isr_count[v] = cpu.isr_count.get(v, 0) + n
        cpu.busy_ticks += n * self.ticks
        cpu.served_isrs += n

    def stepper(self, a, b):
        """``step(la, lb)``: the form's step with the levels of nets ``a`` and ``b`` given (others
        as they are now: nothing else moves during a run)."""
        nets, step = self.form.nets, self.form.step
        if nets == (a, b):
            return step
        if nets == (b, a):
            return lambda la, lb: step(lb, la)
        return lambda la, lb: step(*[la if n is a else lb if n is b else n.level for n in nets])


def route(net):
    """The :class:`Route` of an edge on ``net`` now, or None when it would not be served."""
    if net.wave is not None or net.forced or len(net._drivers) != 1 or net._wlisteners:
        return None
    listeners = net._listeners
    if len(listeners) != 1:
        return None
    served_vector = getattr(listeners[0], "served_vector", None)
    if served_vector is None:
        return None
    hit = served_vector()
    if hit is None:
        return None
    clock, cpu, vector = hit
    got = cpu.served(vector)
    if got is None:
        return None
    entry, cost, form = got
    if any(n.wave is not None for n in form.nets):
        return None         # a level the handler reads would depend on the tick
    return Route(clock, cpu, vector, entry + cost, form)


class Item:
    """One crossing a stream may serve: its tick, its handler's return, the stream's next
    crossing (tick, direction, the guards firing there) or None, what the stream needs to
    commit it, and the :class:`Route` its edge takes (None for a counted run's last one)."""

    __slots__ = ("data", "nxt", "ret", "route", "stream", "t")

    def __init__(self, stream, t, ret, nxt, data, route=None):
        self.stream, self.t, self.ret, self.nxt, self.data = stream, t, ret, nxt, data
        self.route = route


def inert_until(ev):
    """Where the queued event ``ev`` is *inert*, the (tick, priority) before which neither it nor
    anything it schedules changes a state outside its own peripheral that firmware, another
    peripheral or the plant can see (its owner's ``served_inert(ev)``: a USART frame end in the
    middle of a FIFO burst, :meth:`mcusim.periph.lpc43xx.uart.Usart.served_inert`); else None.

    A run passes over an inert event and leaves it queued: it fires at its tick after the run has
    committed crossings beyond it, which it does not see, as it does nothing they could see. The
    first tick at which its consequences may stop being inert bounds the run like a barrier."""
    owner = getattr(ev.fn, "__self__", None)
    served_inert = getattr(owner, "served_inert", None)
    if served_inert is None:
        return None
    tick = served_inert(ev)
    return None if tick is None else (tick, PRIO_HW)


def _stream_of(ev, cpus):
    """The stream of crossings whose queued event ``ev`` is (a motor's next encoder crossing whose
    edges could be served on CPUs other than ``cpus``), or None."""
    owner = getattr(ev.fn, "__self__", None)
    served_stream = getattr(owner, "served_stream", None)
    if served_stream is None:
        return None
    stream = served_stream(ev)
    if stream is None or stream.cpus & cpus:
        return None
    return stream


#: a counted run costs about three searches of the trajectory per stream; where the crossings its
#: window can hold are fewer, they are planned one by one
COUNT_MIN = 4


def last_tick_returning_by(clock, ticks: int, R: int) -> int:
    """The last tick t whose edge's handler returns by tick ``R`` (:meth:`Route.returns`: the first
    edge of ``clock`` at or after t, plus ``ticks``); every earlier tick's returns by R too."""
    return (R - ticks) // clock.period * clock.period


def serve_run(kernel, owner) -> bool:
    """Serve the crossings of the stream ``owner``, whose first crossing is due now, and of the
    streams of other encoders whose queued crossings come before the *barrier* (the first queued
    event that is not such a crossing, a busy end the run moves, a timer overflow it serves or an
    inert event, or the bound of the inert events passed over, if earlier). Their events are
    *absorbed*: they are cancelled if their stream serves. Returns False if not even the first
    crossing is served (nothing changed); else each stream has committed its crossings and
    scheduled what comes next (``finish``), all after the last handler's return. ``kernel.now``
    stays at the run's first crossing: the only queued events before the barrier are inert ones,
    which fire at their ticks after the run without seeing what it changed (nor it them).

    The run is counted (:func:`_count`) where it can be, else planned crossing by crossing
    (:func:`_plan`)."""
    if kernel.end_pending:
        return False            # what this event still has to do at its own tick comes first
    streams = [owner]
    cpus = set(owner.cpus)
    busy = {}                   # end event of a busy task of the run's CPUs -> that CPU
    ends = {}                   # those before the barrier: CPU -> tick
    _note_busy(owner.cpus, busy)
    if _stranger_first(kernel, owner, busy):
        return False
    ticks = []                  # timer overflows a counted run may serve (mcusim.engine.ticks)
    plain = None                # the barrier of a run that serves none: the first of them
    inert = None                # the first tick at which a passed inert event may stop being so
    # the queue in order: each event the loop goes past is absorbed, the first one it stops at is
    # the barrier (nothing below changes the queue)
    head = None
    for head in kernel.queued():
        ev = head[3]
        if inert is not None and (head[0], head[1]) >= inert:
            break               # beyond the bound set by inert events passed over
        until = inert_until(ev)
        if until is not None:
            inert = until if inert is None else min(inert, until)
            continue
        if ev in busy:          # moved by the handlers the run serves on its CPU: not a barrier
            ends[busy[ev]] = ev.time
            continue
        other = _stream_of(ev, cpus)
        if other is None:
            tick = tick_run(ev, cpus) if not ends else None
            if tick is None or any(t.cpu is tick.cpu for t in ticks):
                break
            ticks.append(tick)
            if plain is None:
                plain = (head[0], head[1])
            continue
        streams.append(other)
        cpus.update(other.cpus)
        _note_busy(other.cpus, busy)
    else:
        head = None
    barrier = None if head is None else (head[0], head[1])
    if inert is not None and (barrier is None or inert < barrier):
        barrier = inert
    if plain is None:       # (an overflow absorbed came before any inert bound: the loop stops there)
        plain = barrier
    if barrier is not None and _doomed(streams, barrier):
        return False
    charged = {cpu: cpu.busy_ticks for cpu in busy.values()}
    last = {}       # busy CPU -> (return, plan index) of its last handler served
    # (a CPU whose overflow may be served has no busy task: all its tasks are blocked)
    if ends or len(charged) > 1:
        done = _plan(kernel, streams, plain, ends, last)
    else:           # every handler served returns before the barrier, so before each busy task's end
        done = _count(kernel, streams, barrier, ticks)
        if done:
            for tick in ticks:
                tick.commit()
        else:
            done = _plan(kernel, streams, plain, None, last)
    if done:
        # the handlers served on a busy task's CPU moved its end by their ticks: the busy time
        # they were charged (Route.serve, Route.charge). Edge by edge each end is queued again at
        # its CPU's last handler's return: ends that land on one tick keep that order
        for cpu in sorted(charged, key=lambda c: last.get(c, (0, 0))):
            if cpu.busy_ticks != charged[cpu]:
                cpu.delay_busy_task(cpu.busy_ticks - charged[cpu])
    return done


def _stranger_first(kernel, owner, busy) -> bool:
    """True where the first queued event that no run could absorb comes before the owner's first
    handler could return, settled without making any other stream (:func:`_doomed` after them).
    Passed over: the motors' events (a crossing may join the run), the ``busy`` tasks' ends of
    the owner's CPUs, the timer overflows a run may serve (:mod:`.ticks`: the owner's handler
    may delay one, or another module's stream joins the run first) and inert events (whose bound
    counts as a queued event). What is left bounds the owner's first handler: either it is the barrier (or comes after it), or it is the busy end of
    another module whose stream joins the run, before which :func:`_before_ends` wants every
    other CPU's handlers returned."""
    bound = None                # the tick at which inert events passed over may stop being so
    for head in kernel.queued():
        ev = head[3]
        until = inert_until(ev)
        if until is not None:
            bound = until if bound is None else min(bound, until)
        elif (ev not in busy and not hasattr(getattr(ev.fn, "__self__", None), "served_stream")
                and tick_run(ev) is None):
            if bound is not None and bound < (head[0], head[1]):
                head = bound
            return (owner.first_return(), PRIO_CPU) >= (head[0], head[1])
    return bound is not None and (owner.first_return(), PRIO_CPU) >= bound


def _note_busy(cpus, busy) -> None:
    """Add the end events of the busy tasks (:meth:`mcusim.firmware.Cpu.busy_task`) of ``cpus``
    to ``busy`` (event -> CPU)."""
    for cpu in cpus:
        task = cpu.busy_task()
        if task is not None:
            busy[task.end_ev] = cpu


def _doomed(streams, barrier) -> bool:
    """True where no run can serve the owner's first crossing (``streams[0]``), judged from each
    stream's first crossing and the earliest its handler could return (``first_return``), before
    any crossing is located. A served handler must return before the barrier; and a crossing of
    another stream that comes before a served handler returns must be served too (the prefix rule
    of :func:`_plan`, which :func:`_count` keeps), so its handler must also return before the
    barrier. Where the wheels' edges fall on nearby ticks of several modules and the barrier is a
    handler of one of them, this settles most failed runs at a fraction of their planning."""
    top = streams[0].first_return()
    if (top, PRIO_CPU) >= barrier:
        return True
    for s in sorted(streams[1:], key=lambda x: x.pending[0]):
        if s.pending[0] >= top:
            break           # not needed by the owner's crossing (nor is any later one)
        ret = s.first_return()
        if (ret, PRIO_CPU) >= barrier:
            return True
        top = max(top, ret)
    return False


def _count(kernel, streams, barrier, ticks=()) -> bool:
    """A run without locating every crossing: where each stream's motor is in a chunk of PWM
    periods whose speed bounds keep its crossings further apart than a handler takes, a stream's
    crossings up to a tick are counted from the shaft angle there (the position its encoder's
    guards would reach: θ is monotone), and only the last one served and the first one left out
    are located. Every handler served returns before the barrier, and the run ends where no handler
    is in flight: every crossing it serves :func:`_plan` would serve too (where INT0's and INT1's
    handlers cost differently, the window is the costlier one's, so a cheap edge just before the
    barrier may be left to the next run). False if the run is not counted (nothing changed)."""
    R = kernel.horizon
    if barrier is not None:     # a handler's return at (t, PRIO_CPU) must come before the barrier
        R = min(R, barrier[0] if PRIO_CPU < barrier[1] else barrier[0] - 1)
    hz = kernel.timebase.base_hz
    # the timer overflows served on the way (their own window rules); where one timer's stop
    # lowers the window below the end of another's last one served, that one is done again
    for tick in ticks:
        R = tick.limit(R, streams, hz)
    while any(tick.last_end > R for tick in ticks):
        for tick in ticks:
            R = tick.limit(R, streams, hz)
    if sum(s.count_bound(R, hz) for s in streams) < COUNT_MIN:
        return False
    total = 0
    owner = streams[0]
    for s in streams:
        n = s.count_window(R, hz)
        if n is None or (s is owner and n == 0):
            return False
        total += n
    if total < COUNT_MIN:
        return False
    # the cut: the first crossing left out, if every handler before it has returned by then (else
    # earlier, at the last crossing of a stream whose handler would still run)
    c = None
    for s in streams:
        nxt = s.locate_next()
        if nxt is not None and (c is None or nxt[0] < c):
            c = nxt[0]
    for _ in range(2 * len(streams) + 2):
        cuts = [s.cut(c) for s in streams]
        if None in cuts:
            return False
        late = [x[1] for x in cuts if x[0] and c is not None and x[2] is not None and x[2] >= c]
        if not late:
            break
        c = min(late)
    else:
        return False
    if not cuts[0][0]:
        return False
    for s, (m, L, _) in zip(streams, cuts):
        if m:
            s.commit_count(m, L)
    for s in streams:
        s.finish()
    return True


def _plan(kernel, streams, barrier, ends=None, last=None) -> bool:
    """The run crossing by crossing, in time order, as long as each one is served (module
    docstring). Of the planned crossings, the longest prefix in time order is committed whose
    handlers all return before the first crossing left out: edge by edge, that crossing's events
    come after them all, whichever stream it belongs to.

    ``ends``: CPU -> the end tick of its busy task (:meth:`mcusim.firmware.Cpu.busy_task`). The
    task's code runs there, so it bounds the run as a barrier does, except that each handler
    served on that CPU moves it by the handler's ticks (dispatch to return): a crossing is served
    there if its request is dispatched by then (dispatch comes before a task's end at one tick),
    and every other handler must return before it. ``last`` (a dict, if given) gets, per CPU, the
    (return, plan index) of its last handler committed."""
    horizon = kernel.horizon
    plan = []
    t_stop = None
    ends = dict(ends) if ends else {}

    def before_barrier(time, prio):
        return barrier is None or (time, prio) < barrier

    while True:
        s = t = None            # the stream with the earliest crossing (the first one on a tie)
        for x in streams:
            p = x.pending
            if p is not None and (t is None or p[0] < t):
                s, t = x, p[0]
        if s is None:
            break
        if t > horizon or not before_barrier(t, PRIO_PLANT):
            t_stop = t
            break
        item = s.plan(t, s.pending[1])
        if (item is None or item.ret > horizon or (item.nxt is not None and item.nxt[0] <= item.ret)
                or not before_barrier(item.ret, PRIO_CPU)
                or (ends and not _before_ends(item, ends))):
            t_stop = t
            break
        cpu = item.route.cpu
        if cpu in ends:
            ends[cpu] += item.route.ticks
        plan.append(item)
        s.pending = item.nxt
    # the longest prefix whose handlers all return before the first crossing left out
    top, best = -1, 0
    for j, item in enumerate(plan):
        top = max(top, item.ret)
        nxt_t = plan[j + 1].t if j + 1 < len(plan) else t_stop
        if nxt_t is None or top < nxt_t:
            best = j + 1
    if best == 0:
        return False
    for j, item in enumerate(plan[:best]):
        item.stream.commit(item)
        if last is not None:
            last[item.route.cpu] = (item.ret, j)
    for s in streams:
        s.finish()
    return True


def _before_ends(item, ends) -> bool:
    """Whether ``item`` comes before the busy tasks' ends (``ends``, as moved so far): its request
    dispatched by its own CPU's (the dispatch at PRIO_DISPATCH precedes the task's end at
    PRIO_CPU in one tick), its return before the others'."""
    route = item.route
    for cpu, end in ends.items():
        if cpu is route.cpu:
            if item.ret - route.ticks > end:
                return False
        elif item.ret >= end:
            return False
    return True
