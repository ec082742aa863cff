"""Served edges: a run of pin edges whose interrupt handlers act in closed form (fast engine).

Edge by edge, a quadrature encoder on an AVR's INT0/INT1 costs for every edge: the plant event
that finds it, the net change, the external-interrupt flag, the dispatch, the handler's entry
(which reads the pins) and its return. The handler's effect, though, is a pure function of the
pin levels it reads (the PJRC Encoder's ``update``: a state table). Where nothing else can happen
between one edge and the next handler's return, the fast engine *serves* the edge instead: the
handler's declared closed form (:class:`mcusim.firmware.ClosedForm`) is applied to the levels
the handler would read, and the CPU is charged the cycles and the handler count the edge-by-edge
run charges, at the same ticks, without the events.

An edge on ``net`` is served when all of this holds at its tick (:func:`route` and
:meth:`Route.returns` check it; the plant side adds the last two):

* the net's only listener is an interrupt source whose whole response to the edge is one request
  of one vector (:meth:`served_vector`, e.g. INTn in any-change mode, enabled, its flag clear), the
  net has one driver and is neither forced nor a waveform;
* the CPU would take that request at once and do nothing else (:meth:`mcusim.firmware.Cpu.served`:
  no handler running or pending, global interrupts on, no task running, ready or waiting for an
  interrupt, interrupt lines not traced) and the handler declares a closed form that still
  stands for it (the handler bound, no register log watching the reads it skips);
* the handler's return, ``next CPU clock edge after the edge + (entry latency + cost) cycles``,
  would come before every queued event and within the run (:meth:`Kernel.would_be_next`);
* the next edge comes after that return (otherwise the handler would read the later levels, or
  the next request would wait for the return: timing interacts, and that edge runs edge by edge);
* exactly one served net changes level at the edge.

The levels the handler reads are the ones after its edge: the next edge is later than its return.
Flags set and cleared, the I flag cleared at entry and set by RETI, the pending-line bits: none of
these outlive the handler, so serving leaves them as the edge-by-edge run leaves them.
"""

from __future__ import annotations

from ..kernel import PRIO_CPU


class Route:
    """How an edge on one net reaches firmware when it is served: the CPU, the vector, the clock
    the request is synchronised to, the handler's ticks from request to return, its closed form."""

    __slots__ = ("clock", "cpu", "form", "kernel", "ticks", "vector")

    def __init__(self, kernel, clock, cpu, vector, ticks, form):
        self.kernel, self.clock, self.cpu, self.vector = kernel, clock, cpu, vector
        self.ticks, self.form = ticks, form

    def returns(self, t: int):
        """The tick at which the handler of an edge at ``t`` returns, if nothing queued comes before
        it and the run reaches it; else None."""
        r = self.clock.next_edge(t) + self.ticks
        return r if self.kernel.would_be_next(r, PRIO_CPU) else None

    def serve(self, levels) -> None:
        """The handler's effect, at its entry, with the levels of the form's nets given by
        ``levels`` (a mapping Net -> level for the nets the caller drives; others keep theirs)."""
        cpu, v = self.cpu, self.vector
        cpu.isr_count[v] = cpu.isr_count.get(v, 0) + 1
        cpu.busy_ticks += self.ticks        # entry latency + handler cycles, as _enter charges
        cpu.served_isrs += 1
        self.form.step(*[levels.get(n, n.level) for n in self.form.nets])


def route(net, kernel):
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
    return Route(kernel, clock, cpu, vector, entry + cost, form)
