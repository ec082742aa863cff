"""The runtime firmware runs in: a CPU that executes ISRs and tasks, each costing core cycles.

* **ISRs** are plain functions bound to a vector with a declared cost in cycles:
  ``cpu.vector(28, tim2_irq_handler, cost=120)``. When the NVIC has a pending, enabled interrupt
  more urgent than what runs, the CPU takes it: ``entry_latency`` cycles (12 on Cortex-M) of
  stacking, then the handler's Python body runs at that instant, then the CPU stays busy for the
  declared cost; then the handler returns (tail-chaining into the next pending one, if any).
* **Tasks** are coroutines in simulated time::

      async def pid_task():
          while True:
              pos = encoder_get_position(enc)
              await cpu.cycles(900)            # the cost of the computation
              pwm_set_duty(...)
              await rtos.delay_until(wake)     # RTOS ticks

  The Python code between two awaits runs atomically at one instant; ``cycles(n)`` is CPU time
  that ISRs and higher-priority tasks preempt (its end moves later by the time they take).
* An :class:`Rtos` schedules tasks by priority, FreeRTOS style: delays in ticks, the tick from a
  SysTick exception whose handler has a cost, preemption at tick and interrupt boundaries.

Simplifications, stated: a late-arriving more urgent interrupt preempts the entry sequence of a
less urgent one instead of taking over its stacking; tail-chaining costs a full entry latency.
"""

from __future__ import annotations

import atexit
import weakref

from .errors import McusimError
from .kernel import PRIO_CPU, PRIO_DISPATCH

THREAD_PRIO = 1 << 16  # execution priority of thread mode: below every exception (also in irq.py)


class _Req:
    """An awaitable request a task hands to the runtime."""
    __slots__ = ("arg", "kind")

    def __init__(self, kind, arg):
        self.kind, self.arg = kind, arg

    def __await__(self):
        return (yield self)   # the runtime sends the request's result (wait_signal: fired or not)


class Signal:
    """A notification a peripheral model fires when a state that firmware may be polling changes
    (an ADC conversion completing, a bus byte done). Busy-wait loops in firmware ports
    ``await rtos.wait_signal(sig)`` between polls instead of spinning; it carries no data: the
    firmware still reads the registers to see what changed.

    ``count`` is how many times it has fired: a poll that read the state at some instant waits with
    ``wait_signal(sig, since=count_then)`` and does not miss a change that came in between."""

    __slots__ = ("_waiters", "count")

    def __init__(self):
        self._waiters = []
        self.count = 0

    def fire(self) -> None:
        self.count += 1
        waiters, self._waiters = self._waiters, []
        for fn in waiters:
            fn()

    def _wait(self, fn) -> None:
        self._waiters.append(fn)

    def _unwait(self, fn) -> None:
        """Withdraw a waiter that gave up (a wait that timed out): a signal that never fires must
        not collect them (the rover's MAVLink task waits on one ten times a second)."""
        try:
            self._waiters.remove(fn)
        except ValueError:
            pass


class ClosedForm:
    """A handler's effect as a pure function of pin levels, for the fast engine's served edges
    (:mod:`mcusim.engine.served`): ``step(*levels)``, given the levels of ``nets`` at the handler's
    entry, does what ``handler`` does, and nothing else: it reads no time, fires no Signal and
    schedules nothing. It applies only while ``handler`` is the one bound to the vector and
    ``valid()`` holds: whatever the declarer needs, e.g. that the handler still calls the same
    function and that no register log watches the reads the step skips. ``walk(levels)``, optional,
    does ``step(*l)`` for each ``l`` of the sequence ``levels`` in order, at once; forms sharing one
    ``walk`` change one state, so a run of edges through any of them may be walked together.
    ``levels`` supports ``len``, indexing and slicing; where it has ``cycle`` = p, its items repeat
    every p (a quadrature walk in one direction: 4), so a walk may cost O(p), not O(len)."""

    __slots__ = ("handler", "nets", "step", "valid", "walk")

    def __init__(self, handler, nets, step, valid, walk=None):
        self.handler, self.nets, self.step, self.valid = handler, tuple(nets), step, valid
        self.walk = walk


class TickForm:
    """A periodic interrupt's handler in closed form, for the fast engine's served ticks
    (:mod:`mcusim.engine.ticks`): Timer0's overflow advancing ``millis()``. ``peek(n)`` is the
    value the handler keeps (``timer0_millis``) after ``n`` more runs, computed without changing
    anything; ``apply(n)`` does what ``n`` runs do, firing ``signal`` only by counting it
    (``signal.count += n``: the task it would wake serves its pass as an :class:`IdlePass`). The
    handler reads no register and schedules nothing. It applies while ``handler`` is the one
    bound to the vector and ``valid()`` holds."""

    __slots__ = ("apply", "handler", "peek", "signal", "valid")

    def __init__(self, handler, signal, peek, apply, valid=lambda: True):
        self.handler, self.signal, self.peek, self.apply, self.valid = handler, signal, peek, apply, valid


class IdlePass:
    """What a task waiting on a :class:`Signal` does when it fires, declared for the fast engine
    (``rtos.wait_signal(signal, idle=IdlePass(...))``): where ``idle(value)`` holds for the value the
    signal's :class:`TickForm` reports after the firing, the task's pass only reads (no register
    write, no state kept from one pass to the next), costs ``cycles`` and waits on the signal
    again. Such passes may then be served without resuming the task's coroutine; it resumes at
    the first firing after which ``idle`` does not hold, exactly where it would have. ``valid()``:
    whatever else the declarer needs (no register log watching the pass's reads)."""

    __slots__ = ("cycles", "idle", "valid")

    def __init__(self, cycles: int, idle, valid=lambda: True):
        self.cycles, self.idle, self.valid = int(cycles), idle, valid


class Context:
    """Something that occupies the CPU: a task or an exception handler."""

    def __init__(self, name):
        self.name = name
        self.remaining = None  # base ticks of busy work left while preempted
        self.end_ev = None
        self.on_done = None

    def __repr__(self):
        return f"<{type(self).__name__} {self.name}>"


class IsrContext(Context):
    def __init__(self, irqn, prio, handler, cost):
        super().__init__(f"irq{irqn}")
        self.irqn, self.prio, self.handler, self.cost = irqn, prio, handler, cost


class Task(Context):
    def __init__(self, name, coro, priority):
        super().__init__(name)
        self.priority = priority
        if callable(coro) and not hasattr(coro, "send"):
            # the task's function (xTaskCreate's pvTaskCode, with its parameter bound): its
            # coroutine is made at the task's first step, so a simulation loaded and never run
            # leaves none behind (Python warns about a coroutine that was never awaited)
            self.coro, self._make = None, coro
        else:
            self.coro, self._make = coro, None
            if hasattr(coro, "close"):
                _unstarted.add(coro)
        self.state = "ready"  # ready | blocked | done
        self.wake_tick = None
        self.started = False
        self.result = None     # sent into the coroutine when it resumes
        self.deadline = None   # RTOS tick at which a wait_signal(timeout=) gives up
        self.wait_token = None
        self.waiting_on = None  # while blocked in wait_signal: (signal, its IdlePass or None)
        self.wait_fn = None     # and the waiter it left on the signal

    def __del__(self):
        # a simulation dropped before its tasks ran: end the coroutine quietly (Python warns
        # about a coroutine that was never awaited)
        coro = getattr(self, "coro", None)
        if coro is not None and coro in _unstarted:
            coro.close()

    def close(self) -> None:
        """End the task's coroutine (a simulation that will not run on); a task that never ran
        and was given its function has none."""
        self._make = None
        if self.coro is not None:
            self.coro.close()


# the task coroutines not started yet: closed at exit, where a simulation loaded and never run
# would otherwise leave "coroutine ... was never awaited" (objects in a cycle are finalized in no
# set order, so Task.__del__ alone does not always come first)
_unstarted = weakref.WeakSet()


@atexit.register
def _close_unstarted() -> None:
    for coro in list(_unstarted):
        coro.close()


class Cpu:
    """A single core executing ISRs (from the NVIC) and RTOS tasks, with cycle costs.

    Each stretch of busy time is one kernel event at its end (``_busy``), moved when something
    preempts it. An ISR is entered by one event (its entry latency elapsed: the handler body runs);
    its return, when :meth:`Kernel.would_be_next` says nothing can come in between, is done in the
    same event at the return tick instead of an event of its own (same tick, same order)."""

    _MAX_INLINE = 8  # tail-chained returns/entries done in place before falling back to events

    def __init__(self, kernel, clock, nvic, entry_latency=12, name="cpu"):
        # ``nvic`` is the interrupt controller: mcusim.irq.Nvic or AvrInterrupts (same protocol)
        self.kernel, self.clock, self.nvic, self.name = kernel, clock, nvic, name
        self.entry_latency = entry_latency
        nvic.cpu = self
        self.vectors: dict[int, tuple] = {}
        self.stack: list[IsrContext] = []
        self.rtos: Rtos | None = None
        self._in_code = False
        self._dispatch_wanted = False
        self._arb_ev = None         # a dispatch decision due at this tick (request_dispatch)
        self.isr_count: dict[int, int] = {}
        self.busy_ticks = 0
        self._inline_depth = 0
        self.closed_forms: dict[int, ClosedForm] = {}
        self.tick_forms: dict[int, TickForm] = {}
        self.served_isrs = 0   # fast engine: handler runs applied in closed form (engine.served)

    # --- firmware-facing ------------------------------------------------------------------
    def vector(self, irqn: int, handler, cost: int = 0) -> None:
        """Bind ``handler()`` to interrupt ``irqn`` with a declared cost in core cycles."""
        self.vectors[irqn] = (handler, cost)

    def closed_form(self, irqn: int, form: ClosedForm | None) -> None:
        """Declare (or with None withdraw) the closed form of interrupt ``irqn``'s handler."""
        if form is None:
            self.closed_forms.pop(irqn, None)
        else:
            self.closed_forms[irqn] = form

    def tick_form(self, irqn: int, form: TickForm | None) -> None:
        """Declare (or with None withdraw) the closed form of periodic interrupt ``irqn``'s handler."""
        if form is None:
            self.tick_forms.pop(irqn, None)
        else:
            self.tick_forms[irqn] = form

    def _taken_at_once(self, forms: dict, irqn: int):
        """The form ``forms`` holds for ``irqn`` if a request of it raised now would be taken at
        once: no handler running, no firmware code in progress, global interrupts on, nothing
        pending, the lines untraced. Else None."""
        form = forms.get(irqn)
        if form is None or self.stack or self._in_code:
            return None
        quiet = getattr(self.nvic, "quiet", None)
        return form if quiet is not None and quiet() else None

    def _handler_ticks(self, irqn: int, form):
        """(entry ticks, handler ticks) of ``irqn`` while its vector runs ``form``'s handler and
        the form stands, else None."""
        vec = self.vectors.get(irqn)
        if vec is None or vec[0] is not form.handler or not form.valid():
            return None
        period = self.clock.period
        return self.entry_latency * period, vec[1] * period

    def served_tick(self, irqn: int):
        """(entry ticks, handler ticks, form, idle pass) when a request of ``irqn`` raised now
        would be taken at once and be all the CPU does until its handler returns (as
        :meth:`served`, with no task running: all are blocked), its handler has a
        :class:`TickForm` that stands, and the one task its signal wakes serves an
        :class:`IdlePass`. Else None."""
        form = self._taken_at_once(self.tick_forms, irqn)
        rtos = self.rtos
        if form is None or rtos is None or rtos.current is not None or rtos._wfi_blocked:
            return None
        idle = None
        for t in rtos.tasks:
            if t.state == "ready":
                return None
            w = t.waiting_on
            if t.state == "blocked" and w is not None and w[0] is form.signal:
                if idle is not None or w[1] is None or t.deadline is not None or not w[1].valid():
                    return None
                idle = w[1]
        ticks = None if idle is None else self._handler_ticks(irqn, form)
        return None if ticks is None else ticks + (form, idle)

    def served(self, irqn: int):
        """(entry ticks, handler ticks, form) when a request of ``irqn`` raised now would be taken at
        once and be all the CPU does until its handler returns, and the handler has a closed form
        that stands: no handler running, global interrupts on, nothing pending, interrupt lines
        untraced, no task waiting for an interrupt, none ready but the current one, and that one
        (if any) in a busy wait (:meth:`busy_task`). Else None."""
        form = self._taken_at_once(self.closed_forms, irqn)
        if form is None:
            return None
        rtos = self.rtos
        if rtos is not None:
            cur = rtos.current
            if rtos._wfi_blocked or (cur is not None and cur.end_ev is None):
                return None
            for t in rtos.tasks:        # (a loop: this runs for every stream of every served run)
                if t.state == "ready" and t is not cur:
                    return None
        ticks = self._handler_ticks(irqn, form)
        return None if ticks is None else ticks + (form,)

    def busy_task(self):
        """The task in a busy wait (``await cpu.cycles(n)``, its end queued) that a handler taken
        now would preempt, or None. Such a task only waits for its end: a handler dispatched at
        tick t and returning at r (entry latency and its cycles) moves that end by r − t
        (``_pause`` at the dispatch, ``_resume`` at the return), which is all it sees of the
        handler. A served handler moves it the same way (:meth:`delay_busy_task`)."""
        rtos = self.rtos
        if rtos is None or self.stack:
            return None
        cur = rtos.current
        return cur if cur is not None and cur.end_ev is not None else None

    def delay_busy_task(self, ticks: int) -> None:
        """Served handlers took ``ticks`` (their dispatch to return) out of the busy task's wait:
        its end moves as edge by edge, where each one pauses and resumes it."""
        task = self.busy_task()
        ev = task.end_ev
        ev.cancel()
        task.end_ev = self.kernel.at(ev.time + ticks, self._finish, task, prio=PRIO_CPU)

    @staticmethod
    def cycles(n: int) -> _Req:
        """``await cpu.cycles(n)``: spend n core cycles (preemptible)."""
        return _Req("cycles", n)

    @property
    def now_cycles(self) -> int:
        return self.kernel.now // self.clock.period

    # --- contexts ---------------------------------------------------------------------------
    def _top(self):
        if self.stack:
            return self.stack[-1]
        rtos = self.rtos
        return rtos.current if rtos is not None else None

    def _busy(self, ctx: Context, ticks: int, on_done) -> None:
        """``ctx`` is busy for ``ticks`` from now, then ``on_done(ctx)`` (paused while preempted)."""
        ctx.on_done = on_done
        if ctx is self._top():
            ctx.remaining = None
            ctx.end_ev = self.kernel.at(self.kernel.now + ticks, self._finish, ctx, prio=PRIO_CPU)
        else:
            ctx.remaining = ticks

    def _finish(self, ctx):
        ctx.end_ev = None
        done, ctx.on_done = ctx.on_done, None
        done(ctx)

    def _pause(self, ctx):
        if ctx is not None and ctx.end_ev is not None:
            ctx.remaining = ctx.end_ev.time - self.kernel.now
            ctx.end_ev.cancel()
            ctx.end_ev = None

    def _resume(self, ctx):
        if ctx is not None and ctx.remaining is not None and ctx.on_done is not None:
            ticks, ctx.remaining = ctx.remaining, None
            ctx.end_ev = self.kernel.at(self.kernel.now + ticks, self._finish, ctx, prio=PRIO_CPU)

    def run_code(self, fn, *args):
        """Run firmware Python code atomically; interrupt dispatch waits until it returns."""
        outer = self._in_code
        self._in_code = True
        try:
            return fn(*args)
        finally:
            self._in_code = outer
            if not outer and self._dispatch_wanted:
                self._dispatch_wanted = False
                self._dispatch()

    # --- interrupts -------------------------------------------------------------------------
    def current_priority(self) -> int:
        return self.stack[-1].prio if self.stack else THREAD_PRIO

    def request_dispatch(self) -> None:
        """An interrupt may need taking. From firmware code: when that code returns. Otherwise once
        every hardware and plant event of this tick has run, so that of two interrupts pended at
        one tick the controller's arbitration picks (the lower IRQ number at equal priority on the
        NVIC, the lower vector on the AVR), whichever was pended first: at the end of this event if
        no other event of this tick comes before ``PRIO_DISPATCH``, else (or outside the run loop:
        a host driving a pin between runs) in an event of its own there."""
        if self._in_code:
            self._dispatch_wanted = True
            return
        ev = self._arb_ev
        if ev is not None and not ev.cancelled:
            return                      # the decision is already due at this tick
        kernel = self.kernel
        if kernel.in_event:
            if not kernel.end_of_event(self._arbitrate):
                self._dispatch()        # in the middle of work done in place: at its tick
            return
        best = self.nvic.best_pending()
        if best is not None and best[0] < self.current_priority():
            self._arb_ev = kernel.at(kernel.now, self._arbitrated, prio=PRIO_DISPATCH)

    def _arbitrate(self) -> None:
        kernel = self.kernel
        head = kernel.peek()
        if head is not None and head[0] == kernel.now and head[1] < PRIO_DISPATCH:
            self._arb_ev = kernel.at(kernel.now, self._arbitrated, prio=PRIO_DISPATCH)
            return
        self._dispatch(last=True)       # in place only if nothing else is due first (would_be_next)

    def _arbitrated(self) -> None:
        self._dispatch(last=True)

    def _dispatch(self, last=False) -> None:
        """Take the most urgent pending interrupt if it may preempt what runs. ``last``: the caller
        does nothing after this in the current event (so the entry may be done in place)."""
        nvic = self.nvic
        best = nvic.best_pending()
        if best is None:
            return
        prio, irqn = best
        if prio >= (self.stack[-1].prio if self.stack else THREAD_PRIO):
            return
        vec = self.vectors.get(irqn)
        if vec is None:
            raise McusimError(f"interrupt {irqn} is enabled and pending but the firmware has no handler for it")
        kernel = self.kernel
        taken = self.clock.next_edge(kernel.now)
        if taken != kernel.now:
            # the core takes a request at its own clock edge: one raised between edges (by the I2C
            # bus of a faster controller) is decided there, or the handler and the task it preempts
            # would run off the CPU's clock grid for good (and what ends before that edge, a busy
            # task's end, ends first)
            ev = self._arb_ev
            if ev is None or ev.cancelled:
                self._arb_ev = kernel.at(taken, self._arbitrated, prio=PRIO_DISPATCH)
            return
        self._pause(self._top())
        nvic.acknowledge(irqn)
        ctx = IsrContext(irqn, nvic.context_priority(irqn), vec[0], vec[1])
        self.stack.append(ctx)
        t = kernel.now + self.entry_latency * self.clock.period
        if last and self._inline_depth < self._MAX_INLINE and kernel.would_be_next(t, PRIO_CPU):
            # the entry event would be the next one: enter now, at its tick
            ctx.remaining = None
            kernel.now = t
            self._inline_depth += 1
            try:
                self._enter(ctx)
            finally:
                self._inline_depth -= 1
        else:
            ctx.on_done = self._enter
            ctx.remaining = None
            ctx.end_ev = kernel.at(t, self._finish, ctx, prio=PRIO_CPU)

    def _enter(self, ctx: IsrContext) -> None:
        irqn = ctx.irqn
        self.nvic.entered(irqn)
        count = self.isr_count
        count[irqn] = count.get(irqn, 0) + 1
        period = self.clock.period
        self.busy_ticks += (self.entry_latency + ctx.cost) * period
        self.run_code(ctx.handler)
        ticks = ctx.cost * period
        if (self.stack[-1] is ctx and self._inline_depth < self._MAX_INLINE
                and self.kernel.would_be_next(self.kernel.now + ticks, PRIO_CPU)):
            # the return event would be the next one: return now, at its tick
            ctx.remaining = None
            self.kernel.now += ticks
            self._inline_depth += 1
            try:
                self._exit(ctx)
            finally:
                self._inline_depth -= 1
        else:
            self._busy(ctx, ticks, self._exit)

    def _exit(self, ctx: IsrContext) -> None:
        assert self.stack[-1] is ctx
        self.stack.pop()
        nvic = self.nvic
        nvic.complete(ctx.irqn)
        rtos = self.rtos
        if rtos is not None:
            rtos.interrupt_done()
        best = nvic.best_pending()
        if best is not None and best[0] < (self.stack[-1].prio if self.stack else THREAD_PRIO):
            self._dispatch(last=True)  # tail-chain or nested preemption of what was below
            return
        if not self.stack and rtos is not None:
            rtos.reschedule()
        self._resume(self._top())


class Rtos:
    """FreeRTOS-like scheduler: priorities (higher number = more urgent), tick delays, preemption.

    The tick comes from the SysTick exception (``systick_handler``, bound by the board's
    firmware to exception -1 with its cost); ``tick_hz`` is configTICK_RATE_HZ.
    """

    def __init__(self, cpu: Cpu, tick_hz: int = 1000):
        self.cpu, self.kernel, self.tick_hz = cpu, cpu.kernel, tick_hz
        cpu.rtos = self
        self.tasks: list[Task] = []
        self.current: Task | None = None
        self.tick_count = 0
        self._wfi_blocked = 0   # tasks blocked in wait_for_interrupt (interrupt_done wakes them)

    def create_task(self, name: str, coro, priority: int) -> Task:
        """xTaskCreate: the task is ready and runs when the scheduler picks it. ``coro`` is its
        function (called with no argument at its first step: bind a parameter with
        ``functools.partial``) or a coroutine already made."""
        t = Task(name, coro, priority)
        self.tasks.append(t)
        if self.kernel is not None:
            self.kernel.after(0, self._kick, prio=PRIO_CPU)
        return t

    def _kick(self):
        if not self.cpu.stack:
            self.reschedule()
            self.cpu._resume(self.current)

    # awaitables
    @staticmethod
    def delay(ticks: int) -> _Req:
        """vTaskDelay(ticks)."""
        return _Req("delay", ticks)

    @staticmethod
    def wait_for_interrupt() -> _Req:
        """Block until the next interrupt handler returns.

        A polling loop (Arduino ``loop()``, a HAL busy-wait) that found nothing to do awaits this:
        what it polls can only change through an interrupt, so the passes in between are not
        simulated one by one; their cycles are part of the waiting time.
        """
        return _Req("wfi", None)

    @staticmethod
    def wait_signal(signal: Signal, timeout: int | None = None, since: int | None = None,
                    idle: IdlePass | None = None) -> _Req:
        """Block until ``signal`` fires (a busy-wait on a peripheral flag, see :class:`Signal`).

        With ``timeout`` (RTOS ticks, like NuttX's ``nxsem_tickwait``) the task also wakes when the
        tick count has advanced by that much; ``await`` returns True if the signal fired, False on
        a timeout. With ``since`` (``signal.count`` when the poll read its state) a signal that
        fired after that returns True at once: the next poll would see the change. ``idle``
        declares the passes that find nothing to do (:class:`IdlePass`)."""
        return _Req("signal", (signal, timeout, since, idle))

    def interrupt_done(self) -> None:
        if not self._wfi_blocked:
            return
        self._wfi_blocked = 0
        for t in self.tasks:
            if t.state == "blocked" and t.wake_tick == "wfi":
                t.state, t.wake_tick = "ready", None

    @staticmethod
    def delay_until(wake_tick: int) -> _Req:
        """vTaskDelayUntil: block until the tick count reaches ``wake_tick``."""
        return _Req("delay_until", wake_tick)

    def systick_handler(self) -> None:
        """xPortSysTickHandler: advance the tick, unblock tasks whose delay expired."""
        self.tick_count += 1
        for t in self.tasks:
            if t.state == "blocked" and isinstance(t.wake_tick, int) and t.wake_tick <= self.tick_count:
                t.state, t.wake_tick = "ready", None
            elif (t.state == "blocked" and t.wake_tick == "signal" and t.deadline is not None
                  and t.deadline <= self.tick_count):
                t.state, t.wake_tick, t.deadline, t.result = "ready", None, None, False
                t.waiting_on[0]._unwait(t.wait_fn)
                t.waiting_on = t.wait_fn = None

    def reschedule(self) -> None:
        """Pick the most urgent ready task (called in thread mode, after exceptions return)."""
        best = None
        for t in self.tasks:   # the first of the most urgent ready tasks
            if t.state == "ready" and (best is None or t.priority > best.priority):
                best = t
        cur = self.current
        if cur is not None and cur.state == "ready" and best is not None and best.priority <= cur.priority:
            best = cur  # equal priority does not preempt (no time slicing)
        if best is cur:
            if cur is not None and not cur.started:
                self._start(cur)
            return
        self.cpu._pause(cur)
        self.current = best
        if best is not None and not best.started:
            self._start(best)

    def _start(self, task: Task):
        task.started = True
        self.kernel.after(0, self._step, task, prio=PRIO_CPU)

    def _step(self, task: Task) -> None:
        if self.current is not task or self.cpu.stack:
            task.remaining, task.on_done = 0, self._step
            return
        result, task.result = task.result, None
        if task.coro is None:
            if task._make is None:          # closed before it ran
                task.state = "done"
                self._switch()
                return
            task.coro, task._make = task._make(), None
        _unstarted.discard(task.coro)       # its first step: awaited from here on
        try:
            req = self.cpu.run_code(task.coro.send, result)
        except StopIteration:
            task.state = "done"
            self._switch()
            return
        if req.kind == "cycles":
            self.cpu.busy_ticks += self.cpu.clock.cycles(req.arg)
            self.cpu._busy(task, self.cpu.clock.cycles(req.arg), self._step)
        elif req.kind == "signal":
            signal, timeout, since, idle = req.arg
            if since is not None and signal.count != since:
                task.result = True
                self.kernel.after(0, self._step, task, prio=PRIO_CPU)
                return
            task.state, task.wake_tick, task.waiting_on = "blocked", "signal", (signal, idle)
            task.deadline = None if timeout is None else self.tick_count + max(1, int(timeout))
            task.on_done = self._step
            task.remaining = 0

            token = task.wait_token = object()   # a waiter left behind by a timeout must not wake a later wait

            def wake(task=task, token=token):
                if task.state == "blocked" and task.wake_tick == "signal" and task.wait_token is token:
                    task.state, task.wake_tick, task.deadline, task.result = "ready", None, None, True
                    task.waiting_on = task.wait_fn = None
                    if not self.cpu.stack:
                        self.reschedule()
                        self.cpu._resume(self.current)
            task.wait_fn = wake
            signal._wait(wake)
            self._switch()
        elif req.kind == "wfi":
            task.state, task.wake_tick = "blocked", "wfi"
            self._wfi_blocked += 1
            task.on_done = self._step
            task.remaining = 0
            self._switch()
        elif req.kind in ("delay", "delay_until"):
            wake = self.tick_count + req.arg if req.kind == "delay" else req.arg
            if wake <= self.tick_count:
                self.kernel.after(0, self._step, task, prio=PRIO_CPU)
                return
            task.state, task.wake_tick = "blocked", wake
            task.on_done = self._step
            task.remaining = 0
            self._switch()
        else:
            raise TypeError(f"task {task.name} awaited an unknown request {req.kind}")

    def _switch(self):
        self.current = None
        self.reschedule()
        self.cpu._resume(self.current)
