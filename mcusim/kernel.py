"""The event queue and the run loop.

Events are ordered by (time, priority, sequence number): the same inputs give the same order,
byte for byte. Cancelling is lazy (a flag), so a cancelled event costs one pop.

A model that is about to schedule an event at the very end of the event it is handling may ask
:meth:`Kernel.would_be_next` whether that event would be the next one the run loop pops; if so it
may advance ``now`` and do the work at once instead (the firmware runtime does this for an ISR's
return). That is exactly what the loop would do next: every queued event comes later in the
(time, priority, sequence) order, a new event's sequence number is larger than all queued ones,
and the run's end and ``stop`` are respected (``horizon``). ``events`` counts the events popped
from the queue, not the work done in place of an event.

While the loop runs, Python's cyclic garbage collector examines its youngest generation less
often (:data:`GC_YOUNG`, put back when the last of the runs in progress ends). The models make no
reference cycles (a test runs every board and finds none), so all they drop is freed by reference
counting; what a young collection would do is walk the objects that live a while (the fast
engine's cached period plans, thousands of small lists and tuples each millisecond on the rover),
~3-5 % of the run's wall time at Python's default of 700 allocations.
"""

from __future__ import annotations

import gc
import heapq
import threading

# Priorities within one base tick: hardware state changes first, then the plant, then the CPU
# (firmware sees the hardware state of its tick), then observers such as trace samplers.
PRIO_HW = 0
PRIO_INPUT = 5
PRIO_PLANT = 10
# the CPU takes its pick of the interrupts pended at a tick after every hardware and plant event of
# that tick (firmware.Cpu.request_dispatch), before any firmware code of the tick runs
PRIO_DISPATCH = 15
PRIO_CPU = 20
PRIO_OBSERVE = 30

#: allocations between two collections of the youngest generation while events run (Python's
#: default is 700); applied only where the threshold is smaller and not 0 (0: collections off)
GC_YOUNG = 20000


class _YoungCollections:
    """Raise the youngest generation's threshold while any run loop runs, and put back what was
    set before when the last one ends (runs nest, and simulations may run in several threads).
    Only a threshold this raised is put back: one that code run by an event (or another thread)
    set meanwhile stays, and so do the older generations' thresholds."""

    def __init__(self):
        self._lock = threading.Lock()
        self._depth = 0
        self._saved = None          # the youngest generation's threshold before, if raised

    def enter(self) -> None:
        with self._lock:
            if self._depth == 0:
                t = gc.get_threshold()
                self._saved = t[0] if 0 < t[0] < GC_YOUNG else None
                if self._saved is not None:
                    gc.set_threshold(GC_YOUNG, *t[1:])
            self._depth += 1

    def leave(self) -> None:
        with self._lock:
            self._depth -= 1
            if self._depth == 0 and self._saved is not None:
                t = gc.get_threshold()
                if t[0] == GC_YOUNG:
                    gc.set_threshold(self._saved, *t[1:])


_young_collections = _YoungCollections()


class Event:
    __slots__ = ("args", "cancelled", "fn", "time")

    def __init__(self, time, fn, args):
        self.time, self.fn, self.args, self.cancelled = time, fn, args, False

    def cancel(self):
        self.cancelled = True


class Kernel:
    """``Kernel(timebase, engine="reference")``: the event queue. ``engine`` ("fast" or "reference",
    :mod:`mcusim.engine`) is read by the models through ``kernel.fast``."""

    def __init__(self, timebase, engine: str = "reference"):
        from .engine import check_engine
        self.timebase = timebase
        self.engine = check_engine(engine)
        self.fast = engine == "fast"
        self.now = 0
        self._queue = []
        self._seq = 0
        self.events = 0  # events processed
        self.end = None    # while running: run_until's t_end (a CPU core runs no instruction past it)
        self.horizon = -1  # while running: the last tick an event may run at (-1: none, see would_be_next)
        self._in_event = False
        self._event_time = None
        self._event_prio = None
        self._post = []    # what runs when the event being handled returns (end_of_event)

    def at(self, time: int, fn, *args, prio: int = PRIO_HW) -> Event:
        if time < self.now:
            raise ValueError(f"cannot schedule in the past: {time} < now {self.now}")
        ev = Event(time, fn, args)
        self._seq += 1
        heapq.heappush(self._queue, (time, prio, self._seq, ev))
        return ev

    @property
    def in_event(self) -> bool:
        """An event is being handled (the run loop called it and it has not returned)."""
        return self._in_event

    @property
    def end_pending(self) -> bool:
        """Something is due at the end of the event being handled (:meth:`end_of_event`)."""
        return bool(self._post)

    def end_of_event(self, fn) -> bool:
        """Call ``fn()`` when the event being handled returns, before the next one (once, however
        often asked); False (and nothing queued) when no event is being handled, or when the event
        has moved ``now`` on from its own tick (work done in place of a later event: ``fn`` would
        run late)."""
        if not self._in_event or self.now != self._event_time:
            return False
        if fn not in self._post:
            self._post.append(fn)
        return True

    def early_in_tick(self, prio: int) -> bool:
        """The event being handled comes before the events of priority ``prio`` at its tick (its
        own priority is lower) and has not moved ``now`` on: what those events change at this tick
        it must not see yet. A model that computes a state lazily (an encoder counted from the shaft
        angle) asks this where the edge-by-edge model changes it in an event of priority ``prio``."""
        return self._in_event and self.now == self._event_time and self._event_prio < prio

    def after(self, delay: int, fn, *args, prio: int = PRIO_HW) -> Event:
        return self.at(self.now + delay, fn, *args, prio=prio)

    def would_be_next(self, time: int, prio: int) -> bool:
        """True if an event scheduled now at (``time``, ``prio``) would be the next one run, within
        the current ``run_until`` (never when it has a ``stop`` check, which runs between events)."""
        if time > self.horizon or self._post:   # what runs at the end of this event runs first
            return False
        q = self._queue
        while q:
            head = q[0]
            if head[3].cancelled:
                heapq.heappop(q)
                continue
            return head[0] > time or (head[0] == time and head[1] > prio)
        return True

    def queued(self):
        """The (time, priority, sequence, event) entries in the order the run loop would pop them,
        cancelled events left out, found lazily (a walk of the heap from its root): a scan that
        stops early pays for what it looked at. The queue must not change while it is iterated."""
        q = self._queue
        if not q:
            return
        todo = [(q[0], 0)]
        n = len(q)
        pop, push = heapq.heappop, heapq.heappush
        seq = self._seq
        while todo:
            entry, i = pop(todo)
            if not entry[3].cancelled:
                yield entry
                if self._seq != seq or len(q) != n:
                    raise RuntimeError("internal error: the event queue changed while it was scanned")
            c = 2 * i + 1
            if c < n:
                push(todo, (q[c], c))
                if c + 1 < n:
                    push(todo, (q[c + 1], c + 1))

    def first_queued(self):
        """The (time, priority, sequence, event) entry the run loop would pop first, leaving out
        cancelled events, or None; the queue is left as it is."""
        return next(self.queued(), None)

    def peek(self):
        """(time, priority) of the next event the run loop would pop, or None."""
        q = self._queue
        while q and q[0][3].cancelled:
            heapq.heappop(q)
        return (q[0][0], q[0][1]) if q else None

    def next_time(self):
        q = self._queue
        while q and q[0][3].cancelled:
            heapq.heappop(q)
        return q[0][0] if q else None

    def run_until(self, t_end: int, stop=None) -> None:
        """Process every event with time <= t_end; leave ``now`` at t_end.

        ``stop`` is an optional callable checked after each event; when it returns true the run
        ends at the current time.
        """
        q = self._queue
        pop = heapq.heappop
        n = 0
        outer, outer_end = self.horizon, self.end
        self.horizon = t_end if stop is None else -1
        self.end = t_end
        _young_collections.enter()
        try:
            while q and q[0][0] <= t_end:
                time, prio, _, ev = pop(q)
                if ev.cancelled:
                    continue
                if time < self.now:     # a model that jumped ``now`` past a queued event
                    raise RuntimeError(f"internal error: event {ev.fn!r} at tick {time} is before now ({self.now})")
                self.now = time
                ev.cancelled = True  # fired events count as done, so cancel() on them is harmless
                self._in_event = True
                self._event_time = time
                self._event_prio = prio
                ev.fn(*ev.args)
                post = self._post
                while post:
                    post.pop(0)()
                self._in_event = False
                n += 1
                if stop is not None and stop():
                    return
            self.now = max(self.now, t_end)
        finally:
            self._in_event = False
            self._post.clear()
            self.events += n
            self.horizon, self.end = outer, outer_end
            _young_collections.leave()
