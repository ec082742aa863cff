"""Timing rules of the firmware runtime that its event-saving paths must keep.

The runtime returns from an ISR (and takes a SysTick entry) in place, inside the event that is
running, when :meth:`Kernel.would_be_next` shows nothing could come in between. Each rule here is
checked both on a quiet queue (the in-place path) and with unrelated events queued inside the
ISR's window (the event path): the ticks must be the same, as the Armv7-M exception model gives
them (12-cycle entry, the handler's declared cost, tail-chaining with a full entry latency).
"""

import pytest
from cortexm_rig import NVIC, enable, rig

from mcusim.irq import SYSTICK
from mcusim.kernel import PRIO_CPU, PRIO_HW, PRIO_OBSERVE, Kernel
from mcusim.registers import Bus, Peripheral, Register
from mcusim.time import TimeBase

ENTRY = 12   # Cortex-M exception entry latency in cycles; one cycle is one base tick here



def noise(m, start, stop, step=1, prio=PRIO_OBSERVE):
    """Unrelated events (an observer sampling) inside a window: they force the event path."""
    for t in range(start, stop, step):
        m.kernel.at(t, lambda: None, prio=prio)


@pytest.mark.parametrize("noisy", [False, True])
def test_isr_return_frees_the_cpu_exactly_cost_cycles_after_the_body(noisy):
    m = rig()
    done = []

    async def task():
        await m.cpu.cycles(1000)
        done.append(m.kernel.now)
    m.rtos.create_task("t", task(), 1)
    m.cpu.vector(5, lambda: None, cost=88)
    enable(m, 5, 0)
    m.kernel.at(500, m.nvic.set_pending, 5)
    if noisy:
        noise(m, 500, 700)
    m.kernel.run_until(10_000)
    assert done == [1000 + ENTRY + 88]
    assert m.cpu.busy_ticks == ENTRY + 88 + 1000


@pytest.mark.parametrize("noisy", [False, True])
def test_tail_chaining_takes_a_full_entry_latency_after_the_return(noisy):
    m = rig()
    log = []
    m.cpu.vector(10, lambda: log.append(("a", m.kernel.now)), cost=100)
    m.cpu.vector(11, lambda: log.append(("b", m.kernel.now)), cost=10)
    enable(m, 10, 4)
    enable(m, 11, 4)
    m.kernel.at(0, m.nvic.set_pending, 10)
    m.kernel.at(20, m.nvic.set_pending, 11)
    if noisy:
        noise(m, 0, 300, 7)
    m.kernel.run_until(1000)
    assert log == [("a", ENTRY), ("b", ENTRY + 100 + ENTRY)]
    assert m.cpu.stack == [] and m.cpu.isr_count == {10: 1, 11: 1}


def test_urgent_interrupt_at_the_return_tick_preempts_before_the_return():
    """A hardware event at the very tick a handler's cost ends comes first (hardware before CPU
    within a tick): the more urgent interrupt is taken while the other is still active, so the
    return of the first cannot be done early."""
    m = rig()
    log = []
    m.cpu.vector(10, lambda: log.append(("low", m.kernel.now)), cost=100)
    m.cpu.vector(11, lambda: log.append(("high", m.kernel.now)), cost=20)
    enable(m, 10, 8)
    enable(m, 11, 2)
    m.kernel.at(0, m.nvic.set_pending, 10)
    seen_active = []
    m.kernel.at(ENTRY + 100, lambda: (seen_active.append(m.read32(NVIC + 0x200)), m.nvic.set_pending(11)),
                prio=PRIO_HW)
    m.kernel.run_until(1000)
    assert seen_active == [1 << 10]           # IABR: the low handler had not returned yet
    assert log == [("low", ENTRY), ("high", ENTRY + 100 + ENTRY)]


def test_interrupt_one_tick_after_the_return_finds_the_cpu_free():
    m = rig()
    log = []
    m.cpu.vector(10, lambda: log.append(("low", m.kernel.now)), cost=100)
    m.cpu.vector(11, lambda: log.append(("high", m.kernel.now)), cost=20)
    enable(m, 10, 8)
    enable(m, 11, 8)                          # equal priority: would have to wait if still active
    m.kernel.at(0, m.nvic.set_pending, 10)
    m.kernel.at(ENTRY + 101, m.nvic.set_pending, 11)
    m.kernel.run_until(1000)
    assert log == [("low", ENTRY), ("high", ENTRY + 101 + ENTRY)]


def systick_task_rig(noisy):
    from mcusim.fw.stm32hal.cortex import HAL_SYSTICK_Config
    from mcusim.fw.stm32hal.regs import Stm32f7
    m = rig()
    ends = []

    async def worker():
        await m.rtos.delay(1)                 # start right after the first tick
        t0 = m.kernel.now
        await m.cpu.cycles(1_000_000)         # spans four more SysTick periods of 216_000
        ends.append((t0, m.kernel.now))
    m.cpu.vector(SYSTICK, m.rtos.systick_handler, cost=40)
    m.rtos.create_task("w", worker(), 1)
    HAL_SYSTICK_Config(Stm32f7(m.bus), 216_000)
    if noisy:
        for k in range(1, 7):
            noise(m, k * 216_000, k * 216_000 + 60, 5, prio=PRIO_CPU)
    m.kernel.run_until(7 * 216_000)
    return m, ends


@pytest.mark.parametrize("noisy", [False, True])
def test_systick_preemption_of_a_running_task_is_charged_at_each_tick(noisy):
    m, ends = systick_task_rig(noisy)
    (t0, t1), = ends
    # the task resumes 12 + 40 cycles after the first wrap; each later wrap inside its work steals
    # 12 + 40 cycles, so the work ends after four more ticks (wraps at 2..5 x 216_000)
    assert t0 == 216_000 + ENTRY + 40
    assert t1 == t0 + 1_000_000 + 4 * (ENTRY + 40)
    assert m.rtos.tick_count == 6 and m.cpu.isr_count == {SYSTICK: 6}
    assert m.cpu.busy_ticks == 6 * (ENTRY + 40) + 1_000_000


def test_systick_ticks_with_and_without_other_events_give_the_same_timing():
    quiet = systick_task_rig(False)
    noisy = systick_task_rig(True)
    assert quiet[1] == noisy[1]
    assert quiet[0].cpu.busy_ticks == noisy[0].cpu.busy_ticks


def test_a_systick_tick_on_a_quiet_cpu_is_one_kernel_event():
    """Issue 9, "a leaner runtime": the wrap is the tick's only event; entry, handler and return
    are done in it when nothing else is queued inside the handler's 12 + cost cycles."""
    from mcusim.fw.stm32hal.cortex import HAL_SYSTICK_Config
    from mcusim.fw.stm32hal.regs import Stm32f7
    m = rig()
    m.cpu.vector(SYSTICK, m.rtos.systick_handler, cost=40)
    HAL_SYSTICK_Config(Stm32f7(m.bus), 216_000)
    m.kernel.run_until(10 * 216_000 + 100)
    assert m.rtos.tick_count == 10 and m.cpu.busy_ticks == 10 * (ENTRY + 40)
    assert m.kernel.events == 10


def test_register_accesses_of_a_handler_are_logged_at_its_body_tick():
    """The handler's body runs at entry + 12 cycles whichever path the runtime takes; its register
    accesses carry that tick (what the register log and VCD show)."""
    class Dev(Peripheral):
        SIZE = 0x10
        REGISTERS = (Register("DR", 0x0),)
    for noisy in (False, True):
        m = rig()
        dev = Dev("DEV")
        m.bus.attach(0x40000000, dev)
        seen = []
        dev.access_log = lambda kind, p, reg, value, old, seen=seen, m=m: seen.append((kind, reg.name, value, m.kernel.now))
        m.cpu.vector(7, lambda m=m: m.write32(0x40000000, 0x5A), cost=30)
        enable(m, 7, 1)
        m.kernel.at(1000, m.nvic.set_pending, 7)
        m.kernel.at(1100, lambda m=m: m.read32(0x40000000))
        if noisy:
            noise(m, 1000, 1060)
        m.kernel.run_until(2000)
        assert seen == [("write", "DR", 0x5A, 1000 + ENTRY), ("read", "DR", 0x5A, 1100)]


def test_would_be_next_follows_the_queue_order_and_the_run_end():
    k = Kernel(TimeBase([1000]))
    assert not k.would_be_next(0, PRIO_CPU)             # not running: nothing may be done in place
    answers = []

    def probe():
        answers.append((k.would_be_next(20, PRIO_CPU), k.would_be_next(30, PRIO_CPU),
                        k.would_be_next(30, PRIO_HW), k.would_be_next(31, PRIO_CPU),
                        k.would_be_next(60, PRIO_CPU)))
    k.at(10, probe)
    k.at(30, lambda: None, prio=PRIO_CPU)               # already queued: runs before a new (30, CPU)
    k.run_until(50)
    assert answers == [(True, False, True, False, False)]   # 60 is past the end of the run
    answers.clear()
    k.at(70, probe)
    k.run_until(100, stop=lambda: False)                 # a stop check runs between events: never
    assert answers == [(False, False, False, False, False)]


def test_bus_accessors_resolved_once_still_fault_and_follow_a_late_log():
    from mcusim.errors import BusFault

    class Dev(Peripheral):
        SIZE = 0x10
        ACCESS_SIZES = (4,)
        REGISTERS = (Register("DR", 0x0),)
    bus = Bus()
    dev = Dev("DEV")
    bus.attach(0x1000, dev)
    bus.write32(0x1000, 7)
    assert bus.read32(0x1000) == 7
    for bad in (lambda: bus.read32(0x1002), lambda: bus.read8(0x1000), lambda: bus.read32(0x1008)):
        for _ in range(2):                               # a fault is not cached as an accessor
            with pytest.raises(BusFault):
                bad()
    seen = []
    dev.access_log = lambda kind, p, reg, value, old: seen.append((kind, value, old))
    bus.write32(0x1000, 9)
    assert bus.read32(0x1000) == 9
    assert seen == [("write", 9, 7), ("read", 9, 9)]
