"""Served ticks: a timer's overflow interrupt and the idle ``loop()`` pass it wakes, in closed form.

On the pro-mini, Timer0 overflows every 1.024 ms; its handler advances ``millis()`` and wakes
``loop()``, whose pass reads ``millis()``, finds the sample time not yet reached, burns its cycles
and waits again. Edge by edge that is half a dozen events a millisecond, and each one ends the
counted run of encoder edges (:mod:`mcusim.engine.served`) in progress. Where the handler and the
pass are declared in closed form (:class:`mcusim.firmware.TickForm`, :class:`mcusim.firmware.IdlePass`)
and the timer's queued event is a plain overflow (:meth:`AvrTimer.served_overflow
<mcusim.periph.avr.timer_served.ServedOverflows.served_overflow>`), a counted run takes the
overflows of its CPUs in its stride (:class:`TickRun`): the run goes on past an overflow at tick T if

* the CPU would take the request at once and do nothing else (``Cpu.served_tick``: no handler
  running or pending, every task blocked, the one task the handler's signal wakes in a declared
  idle wait, the lines untraced);
* the pass after it is idle: ``idle(millis)`` holds for the value the handler leaves;
* the handler and the pass end within the run's window: the pass ends at
  E = T + entry latency + handler cycles + pass cycles, and E ≤ R, the last tick a served
  handler may return at; and before the next overflow (which would otherwise find the task
  running, not waiting);
* no encoder edge of that CPU interacts: none whose handler would still run at T (it would delay
  the overflow's) and none from then to E (its request would wait for the overflow's handler, or
  preempt the pass). Checked from the shaft angle like a count: the encoder's position at the
  last tick whose edge's handler returns before T equals its position at E.

Otherwise the overflow ends the run's window there (handlers must return before T) and is run as
events. A run that is not counted serves no overflow. What a served overflow leaves is what the
edge-by-edge run leaves: ``millis()`` and the overflow count advanced, the signal counted (the
task stays blocked where it was, its coroutine not resumed: the pass only read), the handler count
and the CPU's busy time charged (entry latency and handler cycles, and the pass's cycles), TOVn
cleared by the vector's entry and the timer's next event planned after the last one served.
"""

from __future__ import annotations


def tick_run(ev, cpus=None):
    """The :class:`TickRun` of the queued event ``ev`` if it is a timer overflow (of one of
    ``cpus``, if given) that can be served now, else None."""
    owner = getattr(ev.fn, "__self__", None)
    served_overflow = getattr(owner, "served_overflow", None)
    if served_overflow is None:
        return None
    got = served_overflow(ev)
    if got is None:
        return None
    cpu, vector, K, L, clock_ticks = got
    if cpus is not None and cpu not in cpus:
        return None
    hit = cpu.served_tick(vector)
    if hit is None:
        return None
    entry, cost, form, idle = hit
    return TickRun(owner, cpu, vector, K, L, clock_ticks, entry, entry + cost, form, idle)


class TickRun:
    """The overflows of one timer that a counted run serves: at clocks K, K + L, ... (the first
    ``n`` of them, set by :meth:`limit`)."""

    __slots__ = ("K", "L", "clock_ticks", "cpu", "entry", "form", "idle", "isr_ticks", "last_end", "n",
                 "pass_ticks", "taken", "timer", "vector")

    def __init__(self, timer, cpu, vector, K, L, clock_ticks, entry, isr_ticks, form, idle):
        self.timer, self.cpu, self.vector = timer, cpu, vector
        self.K, self.L, self.clock_ticks = K, L, clock_ticks
        self.entry, self.isr_ticks, self.form, self.idle = entry, isr_ticks, form, idle
        self.taken = None       # the tick the last overflow served is taken at (its handler's request)
        self.pass_ticks = cpu.clock.cycles(idle.cycles)
        self.n = 0
        self.last_end = -1      # where the last overflow served is over (its pass's end)

    def limit(self, R: int, streams, base_hz: int) -> int:
        """Serve the overflows that fit a window whose handlers return by tick ``R`` (module
        docstring); returns R, lowered to before the first overflow that is not served."""
        stream = next((s for s in streams if self.cpu in s.cpus), None)
        n, last, taken = 0, -1, None
        T = self.K * self.clock_ticks
        step = self.L * self.clock_ticks
        peek, idle = self.form.peek, self.idle.idle
        while T <= R:
            if stream is None or not idle(peek(n + 1)) or last >= T:
                break           # (the pass before still runs at this overflow: it would see it)
            got = stream.tick_end(T, self.isr_ticks, self.pass_ticks, base_hz)
            if got is None or got[1] > R:
                break
            n, (taken, last) = n + 1, got
            T += step
        self.n, self.last_end, self.taken = n, last, taken
        return min(R, T - 1)

    def commit(self) -> None:
        """Apply the ``n`` overflows served."""
        n = self.n
        if not n:
            return
        cpu, v = self.cpu, self.vector
        self.form.apply(n)
        cpu.isr_count[v] = cpu.isr_count.get(v, 0) + n
        cpu.busy_ticks += n * (self.isr_ticks + self.pass_ticks)
        cpu.served_isrs += n
        # the last one's vector entry syncs the timer's flags up to its own clock (later than the
        # overflow's where an encoder handler delayed it, or at a fast prescaler)
        self.timer.commit_overflows(self.K + (n - 1) * self.L, (self.taken + self.entry) // self.clock_ticks)
