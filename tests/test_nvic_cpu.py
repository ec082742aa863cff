"""Cortex-M NVIC and the firmware runtime: entry latency, priorities, preemption, cycle costs."""

import pytest
from cortexm_rig import NVIC, enable, rig
from hypothesis import given, settings
from hypothesis import strategies as st

from mcusim.errors import McusimError
from mcusim.firmware import Cpu, Rtos
from mcusim.irq import SYSTICK, Nvic
from mcusim.kernel import Kernel
from mcusim.time import TimeBase


@pytest.fixture
def m():
    return rig()


def test_handler_runs_12_cycles_after_the_line_rises(m):
    seen = []

    def handler():  # clears its source on the second entry
        seen.append(m.kernel.now)
        if len(seen) == 2:
            m.nvic.set_line(28, False)
    m.cpu.vector(28, handler, cost=50)
    enable(m, 28, 5)
    m.kernel.at(1000, m.nvic.set_line, 28, True)
    m.kernel.run_until(10_000)
    # 216 MHz core: one cycle is one base tick. The line is still high when the first handler
    # returns, so the interrupt is pending again (level-sensitive) and is re-entered at once.
    assert seen == [1000 + 12, 1000 + 12 + 50 + 12]
    assert not m.read32(NVIC + 0x100) & (1 << 28)


def test_disabled_interrupt_stays_pending(m):
    m.cpu.vector(3, lambda: None)
    m.nvic.set_line(3, True)
    m.kernel.run_until(1000)
    assert m.read32(NVIC + 0x100) == 1 << 3 and m.cpu.isr_count == {}


def test_more_urgent_interrupt_preempts_and_less_urgent_waits(m):
    log = []
    m.cpu.vector(10, lambda: log.append(("low", m.kernel.now)), cost=100)
    m.cpu.vector(11, lambda: log.append(("high", m.kernel.now)), cost=20)
    enable(m, 10, 8)
    enable(m, 11, 2)

    def raise_(n):
        m.nvic.set_line(n, True)
        m.nvic.set_line(n, False)
    m.kernel.at(0, raise_, 10)
    m.kernel.at(30, raise_, 11)   # during the low handler's body: preempts
    m.kernel.run_until(1000)
    assert log == [("low", 12), ("high", 42)]
    assert m.cpu.isr_count == {10: 1, 11: 1}


def test_equal_priority_does_not_preempt_and_tail_chains(m):
    log = []
    m.cpu.vector(10, lambda: log.append(("a", m.kernel.now)), cost=100)
    m.cpu.vector(11, lambda: log.append(("b", m.kernel.now)), cost=10)
    enable(m, 10, 4)
    enable(m, 11, 4)
    for t, n in ((0, 10), (20, 11)):
        m.kernel.at(t, m.nvic.set_pending, n)
    m.kernel.run_until(1000)
    assert log == [("a", 12), ("b", 12 + 100 + 12)]


@pytest.mark.parametrize("order", [(30, 29), (29, 30)])
def test_two_equal_priority_interrupts_pended_at_one_tick_enter_the_lower_irq_number_first(m, order):
    """NVIC arbitration (ARMv7-M ARM B1.5.4): of pending exceptions with the same group priority,
    the lowest exception number is taken first. Two peripherals' events pend IRQ 30 and IRQ 29 at
    the same tick: 29 enters first whichever event ran first (TIM3 before TIM4 when two encoder
    counters wrap at one tick; it once went by the order of the events)."""
    log = []
    for n in (29, 30):
        m.cpu.vector(n, lambda n=n: log.append((n, m.kernel.now)), cost=40)
        enable(m, n, 5)
    for n in order:
        m.kernel.at(500, m.nvic.set_pending, n)
    m.kernel.run_until(2000)
    assert log == [(29, 512), (30, 512 + 40 + 12)]


def test_a_more_urgent_interrupt_pended_later_in_the_tick_is_taken_first(m):
    log = []
    m.cpu.vector(40, lambda: log.append((40, m.kernel.now)), cost=40)
    m.cpu.vector(41, lambda: log.append((41, m.kernel.now)), cost=40)
    enable(m, 40, 6)
    enable(m, 41, 1)
    m.kernel.at(500, m.nvic.set_pending, 40)
    m.kernel.at(500, m.nvic.set_pending, 41, prio=10)       # a plant event of the same tick
    m.kernel.run_until(2000)
    assert log == [(41, 512), (40, 512 + 40 + 12)]


def test_an_interrupt_pended_on_another_cpu_by_a_handler_run_in_place_enters_at_that_tick():
    """CPU A's handler (entered and returned in place of events) pends IRQ 3 on CPU B, as a GPIO
    wired to B's EXTI would: B enters 12 cycles after the pend, whether or not an unrelated event
    lies between (the arbitration hook must not wait for A's whole in-place chain)."""
    def run(extra_event):
        tb = TimeBase([1_000_000])
        k = Kernel(tb)
        clk = tb.clock("cpu", 1_000_000)
        na, nb = Nvic(num_irqs=16), Nvic(num_irqs=16)
        a, b = Cpu(k, clk, na, name="a"), Cpu(k, clk, nb, name="b")
        log = []

        def ha():
            log.append(("A", k.now))
            nb.set_pending(3)
        a.vector(2, ha, cost=400)
        b.vector(3, lambda: log.append(("B", k.now)), cost=10)
        na.enabled.add(2)
        nb.enabled.add(3)
        k.at(100, na.set_pending, 2)
        if extra_event:
            k.at(300, lambda: None)
        k.run_until(5000)
        return log
    assert run(False) == run(True) == [("A", 112), ("B", 124)]


def test_an_exception_inside_an_event_leaves_the_cpu_taking_interrupts(m):
    """An event pends an interrupt and then raises (a model error, Ctrl-C in a notebook): the
    decision it left undone does not stop the CPU from taking the next ones."""
    log = []
    m.cpu.vector(28, lambda: log.append(m.kernel.now), cost=20)
    enable(m, 28, 5)

    def pend_and_fail():
        m.nvic.set_pending(28)
        raise KeyboardInterrupt
    m.kernel.at(100, pend_and_fail)
    with pytest.raises(KeyboardInterrupt):
        m.kernel.run_until(1000)
    m.kernel.at(500, m.nvic.set_pending, 28)
    m.kernel.run_until(2000)
    assert log == [500 + 12]


def test_interrupts_pended_between_runs_at_one_tick_are_arbitrated_too(m):
    """A host pends IRQ 30 and then IRQ 29 between two runs: 29 enters first when the run resumes."""
    log = []
    for n in (29, 30):
        m.cpu.vector(n, lambda n=n: log.append((n, m.kernel.now)), cost=40)
        enable(m, n, 5)
    m.kernel.run_until(500)
    m.nvic.set_pending(30)
    m.nvic.set_pending(29)
    m.kernel.run_until(2000)
    assert log == [(29, 512), (30, 512 + 40 + 12)]


def test_task_cycles_are_stretched_by_interrupts(m):
    done = []

    async def task():
        await m.cpu.cycles(1000)
        done.append(m.kernel.now)
    m.rtos.create_task("t", task(), 1)
    m.cpu.vector(5, lambda: None, cost=88)
    enable(m, 5, 0)
    m.kernel.at(500, m.nvic.set_pending, 5)
    m.kernel.run_until(10_000)
    assert done == [1000 + 12 + 88]


def test_rtos_delay_until_wakes_on_the_systick_and_higher_priority_preempts(m):
    from mcusim.fw.stm32hal.cortex import HAL_SYSTICK_Config
    from mcusim.fw.stm32hal.regs import Stm32f7
    log = []

    async def slow():
        while True:
            log.append(("slow", m.rtos.tick_count, m.kernel.now))
            await m.cpu.cycles(300_000)  # longer than a tick

    async def fast():
        wake = 0
        while True:
            log.append(("fast", m.rtos.tick_count, m.kernel.now))
            await m.cpu.cycles(100)
            wake += 1
            await m.rtos.delay_until(wake)
    m.cpu.vector(SYSTICK, m.rtos.systick_handler, cost=40)
    m.rtos.create_task("slow", slow(), 1)
    m.rtos.create_task("fast", fast(), 3)
    HAL_SYSTICK_Config(Stm32f7(m.bus), 216_000)
    m.kernel.run_until(3 * 216_000 + 1000)
    fast = [e for e in log if e[0] == "fast"]
    # the fast task runs at every tick, 12 + 40 cycles after the SysTick wrap
    assert [t for _, _, t in fast] == [0, 216_000 + 52, 2 * 216_000 + 52, 3 * 216_000 + 52]
    slow = [t for name, _, t in log if name == "slow"]
    # the slow task starts when fast blocks (100 cycles), and its 300k cycles are stretched by
    # one tick interrupt (12 + 40) and one pass of the fast task (100)
    assert slow[:2] == [100, 100 + 300_000 + 152]


def test_pending_interrupt_without_handler_is_a_clear_error(m):
    enable(m, 7, 1)
    m.nvic.set_pending(7)       # outside the run: decided when the run takes the tick up
    with pytest.raises(McusimError, match="no handler"):
        m.kernel.run_until(100)


def test_systick_period_is_load_plus_one(m):
    hits = []
    m.cpu.vector(SYSTICK, lambda: hits.append(m.kernel.now), cost=0)
    m.write32(0xE000E014, 99)   # LOAD
    m.write32(0xE000E018, 0)    # VAL
    m.write32(0xE000E010, 0b111)
    m.kernel.run_until(1000)
    assert hits == [100 + 12 + 100 * k for k in range(9)]


def test_systick_disable_freezes_val_and_enable_resumes(m):
    S = 0xE000E010
    m.write32(S + 4, 9)
    m.write32(S + 8, 0)
    m.write32(S, 0b101)              # ENABLE, processor clock
    m.kernel.run_until(4)            # clocks 1..4: load 9, then 8, 7, 6
    assert m.read32(S + 8) == 6
    m.write32(S, 0)                  # disabling (CLKSOURCE cleared too) holds the count
    m.kernel.run_until(100)
    assert m.read32(S + 8) == 6
    m.write32(S, 0b101)
    m.kernel.run_until(101)
    assert m.read32(S + 8) == 5


def test_systick_load_write_takes_effect_at_next_reload(m):
    S = 0xE000E010
    m.write32(S + 4, 9)
    m.write32(S + 8, 0)
    m.write32(S, 0b101)
    m.kernel.run_until(3)            # VAL = 7
    m.write32(S + 4, 3)
    vals = []
    for t in range(4, 15):
        m.kernel.run_until(t)
        vals.append((m.read32(S + 8), m.read32(S) >> 16 & 1))
    # 6..0 with the old count, then reload the new LOAD = 3: COUNTFLAG on each step to 0
    assert [v for v, _ in vals] == [6, 5, 4, 3, 2, 1, 0, 3, 2, 1, 0]
    assert [f for _, f in vals] == [0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 1]


def test_clear_pending_has_no_effect_while_level_line_is_asserted(m):
    m.nvic.set_line(29, True)
    m.write32(NVIC + 0x180, 1 << 29)  # ICPR
    assert m.read32(NVIC + 0x100) & (1 << 29)


def _rtos_ticking(task, ticks: int):
    """A 1 MHz core running ``task(rtos)`` (a coroutine function) under an RTOS whose SysTick
    comes every 1000 ticks, ``ticks`` times; returns (kernel, rtos) before anything runs."""
    tb = TimeBase([1_000_000])
    k = Kernel(tb)
    cpu = Cpu(k, tb.clock("cpu", 1_000_000), Nvic(num_irqs=16))
    rtos = Rtos(cpu)
    rtos.create_task("t", task(rtos), priority=1)

    def tick():
        rtos.systick_handler()
        rtos.reschedule()
        cpu._resume(rtos.current)
    for n in range(1, ticks + 1):
        k.at(n * 1000, tick)
    return k, rtos


def test_wait_signal_timeout_returns_false_and_a_late_fire_does_not_wake_a_later_wait():
    """nxsem_tickwait semantics: the wait ends after ``timeout`` RTOS ticks with False; a signal
    firing later must not wake the task out of its next, unrelated wait."""
    from mcusim.firmware import Signal
    a, b = Signal(), Signal()
    seen = []

    async def task(rtos):
        seen.append(("a", await rtos.wait_signal(a, timeout=3), rtos.tick_count))
        seen.append(("b", await rtos.wait_signal(b), rtos.tick_count))
        seen.append(("a2", await rtos.wait_signal(a, timeout=100), rtos.tick_count))

    k, _ = _rtos_ticking(task, 9)
    k.at(6500, a.fire)      # the stale waiter of the first wait must not wake the wait on b
    k.at(7500, b.fire)
    k.at(8500, a.fire)
    k.run_until(10_000)
    assert seen == [("a", False, 3), ("b", True, 7), ("a2", True, 8)]


def test_waits_that_time_out_leave_no_waiter_on_a_signal_that_never_fires():
    """A task polling with a timeout (the rover's MAVLink task, ten times a second) on a signal
    that never fires: each timed-out wait withdraws its waiter, so memory stays flat however long
    the run (the waiters piled up, one per wait, before)."""
    from mcusim.firmware import Signal
    quiet = Signal()
    results = []

    async def task(rtos):
        for _ in range(50):
            results.append(await rtos.wait_signal(quiet, timeout=2))

    k, _ = _rtos_ticking(task, 119)
    k.run_until(120_000)
    assert results == [False] * 50
    assert len(quiet._waiters) == 0


@settings(max_examples=200, deadline=None)
@given(ops=st.lists(st.tuples(st.integers(1, 25), st.booleans()), max_size=40))
def test_avr_quiet_means_no_line_high_whatever_the_order_they_were_set(ops):
    """``AvrInterrupts.quiet`` keeps a count of the lines that are high (it is asked at every
    served edge); it must say what scanning the lines says."""
    from mcusim.irq import AvrInterrupts
    irq = AvrInterrupts()
    irq.i_flag = True
    for vector, level in ops:
        irq.set_line(vector, level)
        assert irq.quiet() == (not any(irq.lines.values()))


def test_priority_fields_of_interrupts_the_part_lacks_read_as_zero_and_ignore_writes():
    """Armv7-M B3.4 (NVIC_IPRn): the priority fields of interrupts not implemented are RAZ/WI. The
    STM32F746 has 98 interrupts (0-97): IPR24's bytes for 98 and 99 and all of IPR25 stay 0 (a
    compiled image read back the 0x50 it had written for IRQ 100)."""
    import mcusim
    sim = mcusim.load("nucleo-f746", firmware=False)
    m = sim.mcu
    m.write32(0xE000E400 + 4 * 24, 0x50505050)
    m.write32(0xE000E400 + 4 * 25, 0x50505050)
    assert m.read32(0xE000E400 + 4 * 24) == 0x00005050
    assert m.read32(0xE000E400 + 4 * 25) == 0
    sim.close()


def test_a_request_between_clock_edges_is_taken_at_the_next_edge_after_a_task_ending_before_it():
    """A core decides on interrupts at its own clock edges. A request raised between two (by the
    bus of a faster controller) waits for the next edge; a busy task whose end falls before that
    edge ends first. (Pausing that task at the edge had left it a negative remainder: 'cannot
    schedule in the past'.)"""
    from mcusim.firmware import Signal
    from mcusim.kernel import PRIO_HW
    from mcusim.time import Clock
    tb = TimeBase([4, 1])                   # base 4 ticks per second; the core at 1 Hz: period 4
    k = Kernel(tb)
    nvic = Nvic()
    cpu = Cpu(k, Clock("cpu", 1, tb), nvic, entry_latency=2)
    rt = Rtos(cpu)
    sig, log = Signal(), []

    def handler():
        log.append(("isr", k.now))
        nvic.set_line(5, False)
    cpu.vector(5, handler, cost=1)
    nvic.enabled.add(5)

    async def task():
        await rt.wait_signal(sig)
        await cpu.cycles(10)
        log.append(("done", k.now))
        while True:
            await rt.delay(1000)
    rt.create_task("t", task, 1)
    k.at(1, sig.fire)                                           # woken between edges
    k.at(41, lambda: nvic.set_line(5, True), prio=PRIO_HW)      # the request at the task's end
    k.at(61, lambda: nvic.set_line(5, True), prio=PRIO_HW)      # and one with the core idle
    k.run_until(200)
    # the request at 41 is decided at the edge at 44 (after the task's end at 41): entry 2 cycles
    # later, 52; the one at 61 at the edge at 64, entry at 72
    assert log == [("done", 41), ("isr", 52), ("isr", 72)]
