"""PJRC Encoder 1.4.4: the 16-entry transition table, sign convention, ±2 guesses and int32 position.

Run against a tiny fake Arduino core: D2/D3 are INT0/INT1 and a level change on an attached pin
runs its CHANGE handler (deferred while interrupts are disabled).
"""

import inspect

from hypothesis import given, settings
from hypothesis import strategies as st
from mcusim.fw.arduino import encoder as enc_mod
from mcusim.fw.arduino.core import TCCR1A
from mcusim.fw.arduino.core import ArduinoCore as RealCore
from mcusim.fw.arduino.core_api import CHANGE, INPUT_PULLUP, NOT_AN_INTERRUPT, ArduinoCore
from mcusim.fw.arduino.encoder import ISR_CYCLES, Encoder, EncoderInternalState

import mcusim


class FakeCore:
    def __init__(self, levels=None):
        self.levels = dict(levels or {})
        self.modes = {}
        self.handlers = {}          # interrupt number -> (fn, mode)
        self.enabled = True
        self.pending = []
        self.delays = []
        self.log = []
        self.forms = {}             # interrupt number -> (pins, step) declared closed forms
        self.walks = {}             # interrupt number -> the walk declared with it

    # ArduinoCore
    def digital_read(self, pin):
        return self.levels.get(pin, 1 if self.modes.get(pin) == INPUT_PULLUP else 0)

    def pin_mode(self, pin, mode):
        self.modes[pin] = mode

    def attach_interrupt(self, n, fn, mode):
        self.handlers[n] = (fn, mode)

    def digital_pin_to_interrupt(self, pin):
        return {2: 0, 3: 1}.get(pin, NOT_AN_INTERRUPT)

    def no_interrupts(self):
        self.enabled = False
        self.log.append("cli")

    def interrupts(self):
        self.enabled = True
        self.log.append("sei")
        while self.pending:
            self.pending.pop(0)()

    def delay_microseconds(self, us):
        self.delays.append(us)

    # pin registers: pin p reads as bit 0 of a register at 1000 + p
    def port_input_register(self, pin):
        return 1000 + pin

    def digital_pin_to_bit_mask(self, pin):
        return 1

    def read8(self, addr):
        return self.digital_read(addr - 1000)

    def attach_closed_form(self, n, pins, step, walk=None):
        self.forms[n] = (tuple(pins), step)
        self.walks[n] = walk

    # test side
    def set_pin(self, pin, level):
        if self.levels.get(pin) == level:
            return
        self.levels[pin] = level
        n = self.digital_pin_to_interrupt(pin)
        if n in self.handlers:
            fn, _ = self.handlers[n]
            if self.enabled:
                fn()
            else:
                self.pending.append(fn)


def make(p1=0, p2=0, pins=(2, 3)):
    core = FakeCore({pins[0]: p1, pins[1]: p2})
    return core, Encoder(core, *pins)


# sign convention: (pin2, pin1) sequence with pin2 leading counts positive
FORWARD = [(0, 0), (1, 0), (1, 1), (0, 1)]

TABLE = {0: 0, 5: 0, 10: 0, 15: 0, 1: 1, 7: 1, 8: 1, 14: 1, 2: -1, 4: -1, 11: -1, 13: -1,
         3: 2, 12: 2, 6: -2, 9: -2}


def test_fake_core_satisfies_the_protocol():
    assert isinstance(FakeCore(), ArduinoCore)


def test_constructor_sets_pullups_waits_2000us_reads_state_and_attaches_change_interrupts():
    core, enc = make(1, 0)
    assert core.modes == {2: INPUT_PULLUP, 3: INPUT_PULLUP}
    assert core.delays == [2000]
    assert enc.encoder.state == 0b01                      # pin1 → bit 0, pin2 → bit 1
    assert {n: mode for n, (_, mode) in core.handlers.items()} == {0: CHANGE, 1: CHANGE}
    assert enc.interrupts_in_use == 2


def test_update_table_index_is_new2_new1_old2_old1():
    for index, delta in TABLE.items():
        core = FakeCore({2: (index >> 2) & 1, 3: (index >> 3) & 1})
        st_ = EncoderInternalState(core, 1002, 1003, 1, 1, state=index & 3, position=0)
        Encoder.update(st_)
        assert st_.position == delta, index
        assert st_.state == index >> 2


@given(st.integers(min_value=0, max_value=15), st.integers(min_value=-(2**31), max_value=2**31 - 1))
def test_declared_closed_form_of_each_isr_does_what_update_does(index, position):
    """The fast engine applies the declared closed form instead of running isr0/isr1: for every
    old state and pair of levels read, it must leave state and position as update() does."""
    p1, p2 = (index >> 2) & 1, (index >> 3) & 1
    core, enc = make()
    assert set(core.forms) == {0, 1}
    for n in (0, 1):
        pins, step = core.forms[n]
        assert pins == (2, 3)
        ref = EncoderInternalState(FakeCore({2: p1, 3: p2}), 1002, 1003, 1, 1, state=index & 3,
                                   position=position)
        Encoder.update(ref)
        enc.encoder.state, enc.encoder.position = index & 3, position
        step(p1, p2)
        assert (enc.encoder.state, enc.encoder.position) == (ref.state, ref.position)


@given(state=st.integers(0, 3), position=st.integers(-(2**31), 2**31 - 1),
       levels=st.lists(st.tuples(st.integers(0, 1), st.integers(0, 1)), max_size=300))
def test_the_declared_walk_does_what_the_closed_form_does_level_by_level(state, position, levels):
    """The fast engine applies a counted run's edges with the walk both ISRs declare (one state,
    one object): any sequence of levels, from any state, across the int32 wrap, must leave state
    and position as stepping them one by one."""
    core, enc = make()
    assert core.walks[0] is not None and core.walks[0] is core.walks[1]
    _, step = core.forms[0]
    enc.encoder.state, enc.encoder.position = state, position
    for p1, p2 in levels:
        step(p1, p2)
    stepped = (enc.encoder.state, enc.encoder.position)
    enc.encoder.state, enc.encoder.position = state, position
    core.walks[1](levels)
    assert (enc.encoder.state, enc.encoder.position) == stepped


class _Repeating:
    """``n`` levels repeating ``pattern`` (a sequence that declares its cycle, as the fast engine's
    quadrature walks do)."""

    def __init__(self, pattern, n):
        self.pattern, self.n, self.cycle = pattern, n, len(pattern)

    def __len__(self):
        return self.n

    def __getitem__(self, j):
        if isinstance(j, slice):
            return [self[i] for i in range(*j.indices(self.n))]
        if j < 0:
            j += self.n
        if not 0 <= j < self.n:
            raise IndexError(j)
        return self.pattern[j % self.cycle]


@given(state=st.integers(0, 3), position=st.integers(-(2**31), 2**31 - 1),
       pattern=st.lists(st.tuples(st.integers(0, 1), st.integers(0, 1)), min_size=1, max_size=6),
       n=st.integers(0, 300))
def test_a_walk_over_levels_that_repeat_does_what_stepping_them_one_by_one_does(state, position, pattern, n):
    """A walk over levels that declare a cycle takes whole cycles at once: from any state, for any
    repeating pattern (a quadrature walk, a bounce, invalid jumps) and length, across the int32
    wrap, the state and position are those of stepping every level."""
    core, enc = make()
    _, step = core.forms[0]
    levels = _Repeating(pattern, n)
    enc.encoder.state, enc.encoder.position = state, position
    for j in range(n):
        step(*levels[j])
    stepped = (enc.encoder.state, enc.encoder.position)
    enc.encoder.state, enc.encoder.position = state, position
    core.walks[0](levels)
    assert (enc.encoder.state, enc.encoder.position) == stepped


def test_pin1_leading_counts_negative_vector_13():
    core, enc = make()
    seen = []
    for pin, level in [(2, 1), (3, 1), (2, 0), (3, 0)]:
        core.set_pin(pin, level)
        seen.append(enc.read())
    assert seen == [-1, -2, -3, -4]
    core, enc = make()
    for pin, level in [(3, 1), (2, 1), (3, 0), (2, 0)]:
        core.set_pin(pin, level)
    assert enc.read() == 4


def test_double_step_counts_plus_2_for_00_11_and_minus_2_for_01_10_vector_14():
    for (a1, a2), (b1, b2), expected in [((0, 0), (1, 1), 2), ((1, 1), (0, 0), 2),
                                         ((1, 0), (0, 1), -2), ((0, 1), (1, 0), -2)]:
        core, enc = make(a1, a2)
        core.no_interrupts()                     # both edges land while the ISR is held off
        core.set_pin(2, b1)
        core.set_pin(3, b2)
        core.interrupts()                        # first ISR applies ±2, second sees no change
        assert enc.read() == expected, ((a1, a2), (b1, b2))


def forward_step(core, k):
    p2, p1 = FORWARD[(k + 1) % 4]
    core.set_pin(2, p1)
    core.set_pin(3, p2)


def test_write_then_read_and_reset_vector_15():
    core, enc = make()
    enc.write(1000)
    for k in range(3):
        forward_step(core, k)
    assert enc.read_and_reset() == 1003
    assert enc.read() == 0


def test_position_wraps_as_int32():
    core, enc = make()
    enc.write(2**31 - 1)
    forward_step(core, 0)
    assert enc.read() == -(2**31)
    enc.write(2**31)                             # int32_t parameter: wraps on the way in
    assert enc.read() == -(2**31)
    core.set_pin(3, 0)                           # one step back (pin2 falls from 10 → 00: −1)
    assert enc.read() == 2**31 - 1


def test_read_is_atomic_and_reenables_interrupts():
    core, enc = make()
    core.log.clear()
    enc.read()
    enc.write(5)
    enc.read_and_reset()
    assert core.log == ["cli", "sei"] * 3


def test_without_interrupt_pins_read_polls_update():
    core, enc = make(pins=(4, 5))
    assert enc.interrupts_in_use == 0 and core.handlers == {}
    core.levels[5] = 1                           # pin2 leads: +1, seen only when polled
    assert enc.read() == 1
    core.levels[4] = 1
    assert enc.read_and_reset() == 2 and enc.read() == 0


def test_isr_routines_are_plain_callables_with_declared_cost():
    core, _ = make()
    for n in (0, 1):
        fn, _ = core.handlers[n]
        assert callable(fn) and len(inspect.signature(fn).parameters) == 0
    assert ISR_CYCLES == 148 and Encoder.ISR_CYCLES == 148


def test_interrupt_args_are_per_core():
    core_a, enc_a = make()
    core_b, enc_b = make()
    core_a.set_pin(3, 1)
    assert (enc_a.read(), enc_b.read()) == (1, 0)
    assert enc_mod.interrupt_args_for(core_a) is not enc_mod.interrupt_args_for(core_b)


@settings(max_examples=200, deadline=None)
@given(st.integers(min_value=0, max_value=3), st.integers(min_value=-(2**31), max_value=2**31 - 1),
       st.lists(st.sampled_from([1, -1]), max_size=200))
def test_single_quadrature_steps_count_exactly(phase, start, steps):
    p2, p1 = FORWARD[phase]
    core, enc = make(p1, p2)
    enc.write(start)
    for d in steps:
        phase = (phase + d) % 4
        p2, p1 = FORWARD[phase]
        core.set_pin(2, p1)                      # only one of these changes a level
        core.set_pin(3, p2)
    true = start + sum(steps)
    assert enc.read() == ((true + 2**31) % 2**32) - 2**31


def test_update_reads_pin_registers_directly_and_leaves_a_pwm_output_on():
    """Encoder.h reads PINx with DIRECT_PIN_READ, not digitalRead, whose turnOffPWM would
    disconnect Timer1 from a PWM pin the encoder shares. On the simulated 328P: pin2 on D9
    with analogWrite(9, 128) running; read() polls update() (D9 has no interrupt) and OC1A stays
    connected (COM1A1 set)."""
    sim = mcusim.load("pro-mini", firmware=False)
    core = RealCore(sim.mcu)
    core.init()
    core.analog_write(9, 128)
    enc = Encoder(core, 2, 9)
    assert enc.interrupts_in_use == 1
    sim.run(cycles=5000)
    enc.read()
    assert core.read8(TCCR1A) & (1 << 7)                  # COM1A1: PWM still on D9
    assert enc.encoder.pin2_register == 0x23 and enc.encoder.pin2_bitmask == 1 << 1   # PINB, bit 1


class _Disc:
    """What a served walk reads of a quadrature encoder: its levels at a position."""

    def __init__(self, slip):
        self.slip = slip

    def levels(self, k):
        return ((0, 0), (1, 0), (1, 1), (0, 1))[(k - self.slip) & 3]


@given(k=st.integers(-10**6, 10**6), d=st.sampled_from((1, -1)), m=st.integers(0, 40), swap=st.booleans(),
       slip=st.integers(0, 3))
def test_a_served_walk_lists_the_levels_after_each_step_and_they_repeat_every_four(k, d, m, swap, slip):
    from mcusim.plant.encoder_served import Walk
    disc = _Disc(slip)
    walk = Walk(disc, k, d, m, swap)
    want = [disc.levels(k + d * j) for j in range(1, m + 1)]
    want = [(b, a) for a, b in want] if swap else want
    assert len(walk) == m and list(walk) == want and walk[:] == want and walk[1:3] == want[1:3]
    assert all(walk[j] == walk[j + walk.cycle] for j in range(m - walk.cycle))
    if m:
        assert walk[-1] == want[-1]
    for bad in (m, -m - 1):
        try:
            walk[bad]
        except IndexError:
            pass
        else:
            raise AssertionError(f"index {bad} of {m} levels accepted")


def test_the_encoder_constructors_two_millisecond_wait_comes_before_init():
    """PJRC Encoder.h: the constructor sets the pull-ups and waits delayMicroseconds(2000) before
    reading the pins; as a C++ global it runs before main(), so init() (Timer0 started: TCCR0B =
    CS01|CS00) comes 2 ms after reset. The port had paid the wait after setup(), so every start-up
    write came 2 ms early (a review against the library)."""
    import mcusim
    sim = mcusim.load("pro-mini")
    sim.run(seconds="1.99ms")
    assert sim.mcu.read8(0x45) == 0          # TCCR0B: init() has not run yet
    sim.run(seconds="0.2ms")
    assert sim.mcu.read8(0x45) == 0x03
    sim.close()
