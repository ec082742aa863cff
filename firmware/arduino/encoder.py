"""Encoder.h, PJRC Encoder 1.4.4, on the ATmega328P (CORE_INT0_PIN = 2, CORE_INT1_PIN = 3).

``PIN_TO_BASEREG``/``PIN_TO_BITMASK`` and ``DIRECT_PIN_READ`` read the PINx register through the
injected Arduino core (see ``core_api``), as the C does: not ``digitalRead``, which would also turn
off a PWM output on the pin. ``attachInterrupt``/``noInterrupts``/``interrupts``/
``delayMicroseconds`` go through the core too.
The port adds one thing the C has not: ``update_from_levels``, the state table of ``update`` as a
function of the two pin levels it reads, declared to the core (``attach_closed_form``) so that the
fast engine can serve encoder edges nothing else interacts with without running ``update`` edge by
edge (``update`` itself stays as the C has it, and a test holds the two equal).
The build is the default one: ``ENCODER_USE_INTERRUPTS`` through the core's ``attachInterrupt``
trampoline, not ``ENCODER_OPTIMIZE_INTERRUPTS``.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

from mcusim.fw.arduino.core_api import CHANGE, INPUT_PULLUP, ArduinoCore

CORE_NUM_INTERRUPT = 2      # interrupt_pins.h, __AVR_ATmega328P__
ENCODER_ARGLIST_SIZE = CORE_NUM_INTERRUPT

# CPU cycles of one isr0/isr1 run through the attachInterrupt trampoline, vector entry (I cleared)
# to RETI done, measured with avr-gcc 5.4 -Os on simavr (avr_arduino.md §3: 146–148). Add 4–5
# cycles of interrupt response.
ISR_CYCLES = 148


def _int32(x: int) -> int:
    return ((x + 0x80000000) & 0xFFFFFFFF) - 0x80000000


# the position change of update()'s table, indexed by (new pin2, new pin1, old pin2, old pin1)
_STEP = (0, 1, -1, 2, -1, 0, -2, 1, 1, -2, 0, -1, 2, -1, 1, 0)


@dataclass
class EncoderInternalState:
    """Encoder_internal_state_t, with the core whose data space the pin registers are in."""
    core: ArduinoCore
    pin1_register: int
    pin2_register: int
    pin1_bitmask: int
    pin2_bitmask: int
    state: int = 0
    position: int = 0


def direct_pin_read(core: ArduinoCore, base: int, mask: int) -> int:
    """direct_pin_read.h, AVR: ``(((*(base)) & (mask)) ? 1 : 0)``."""
    return 1 if core.read8(base) & mask else 0


class InterruptArgs:
    """The static ``interruptArgs[]`` of class Encoder and the static ``isr0``/``isr1`` using it.

    The C has one table per firmware image; here there is one per core (per simulated MCU), so two
    simulations in one process do not share it. ``isr0``/``isr1`` are zero-argument callables for
    binding to the INT0/INT1 vectors.
    """

    def __init__(self):
        self.args: list[EncoderInternalState | None] = [None] * ENCODER_ARGLIST_SIZE
        self.isr = (self.isr0, self.isr1)

    def isr0(self) -> None:
        Encoder.update(self.args[0])

    def isr1(self) -> None:
        Encoder.update(self.args[1])


_interrupt_args: dict[int, InterruptArgs] = {}   # id(core) -> table, dropped when the core dies


def interrupt_args_for(core: ArduinoCore) -> InterruptArgs:
    """The interruptArgs table of the firmware image running on ``core`` (which must be weak-referenceable)."""
    table = _interrupt_args.get(id(core))
    if table is None:
        table = _interrupt_args[id(core)] = InterruptArgs()
        weakref.finalize(core, _interrupt_args.pop, id(core), None)
    return table


class Encoder:
    ISR_CYCLES = ISR_CYCLES

    def __init__(self, core: ArduinoCore, pin1: int, pin2: int):
        self.core = core
        self._pin1, self._pin2 = pin1, pin2      # simulation: for attach_closed_form
        self._walks = {}                         # simulation: the closed forms' walk per state
        self.interrupt_args = interrupt_args_for(core)
        core.pin_mode(pin1, INPUT_PULLUP)
        core.pin_mode(pin2, INPUT_PULLUP)
        self.encoder = EncoderInternalState(
            core, pin1_register=core.port_input_register(pin1), pin2_register=core.port_input_register(pin2),
            pin1_bitmask=core.digital_pin_to_bit_mask(pin1), pin2_bitmask=core.digital_pin_to_bit_mask(pin2))
        self.encoder.position = 0
        # allow time for a passive R-C filter to charge
        # through the pullup resistors, before reading
        # the initial state
        core.delay_microseconds(2000)
        s = 0
        if direct_pin_read(core, self.encoder.pin1_register, self.encoder.pin1_bitmask):
            s |= 1
        if direct_pin_read(core, self.encoder.pin2_register, self.encoder.pin2_bitmask):
            s |= 2
        self.encoder.state = s
        self.interrupts_in_use = self.attach_interrupt(pin1, self.encoder)
        self.interrupts_in_use += self.attach_interrupt(pin2, self.encoder)

    def read(self) -> int:
        if self.interrupts_in_use < 2:
            self.core.no_interrupts()
            Encoder.update(self.encoder)
        else:
            self.core.no_interrupts()
        ret = self.encoder.position
        self.core.interrupts()
        return ret

    def read_and_reset(self) -> int:
        if self.interrupts_in_use < 2:
            self.core.no_interrupts()
            Encoder.update(self.encoder)
        else:
            self.core.no_interrupts()
        ret = self.encoder.position
        self.encoder.position = 0
        self.core.interrupts()
        return ret

    def write(self, p: int) -> None:
        self.core.no_interrupts()
        self.encoder.position = _int32(p)   # int32_t parameter
        self.core.interrupts()

    #                           _______         _______
    #               Pin1 ______|       |_______|       |______ Pin1
    # negative <---         _______         _______         __      --> positive
    #               Pin2 __|       |_______|       |_______|   Pin2

    #   new     new     old     old
    #   pin2    pin1    pin2    pin1    Result
    #   ----    ----    ----    ----    ------
    #   0       0       0       0       no movement
    #   0       0       0       1       +1
    #   0       0       1       0       -1
    #   0       0       1       1       +2  (assume pin1 edges only)
    #   0       1       0       0       -1
    #   0       1       0       1       no movement
    #   0       1       1       0       -2  (assume pin1 edges only)
    #   0       1       1       1       +1
    #   1       0       0       0       +1
    #   1       0       0       1       -2  (assume pin1 edges only)
    #   1       0       1       0       no movement
    #   1       0       1       1       -1
    #   1       1       0       0       +2  (assume pin1 edges only)
    #   1       1       0       1       -1
    #   1       1       1       0       +1
    #   1       1       1       1       no movement

    @staticmethod
    def update(arg: EncoderInternalState) -> None:
        p1val = direct_pin_read(arg.core, arg.pin1_register, arg.pin1_bitmask)
        p2val = direct_pin_read(arg.core, arg.pin2_register, arg.pin2_bitmask)
        state = arg.state & 3
        if p1val:
            state |= 4
        if p2val:
            state |= 8
        arg.state = state >> 2
        if state in (1, 7, 8, 14):
            arg.position = _int32(arg.position + 1)
        elif state in (2, 4, 11, 13):
            arg.position = _int32(arg.position - 1)
        elif state in (3, 12):
            arg.position = _int32(arg.position + 2)
        elif state in (6, 9):
            arg.position = _int32(arg.position - 2)

    @staticmethod
    def update_from_levels(arg: EncoderInternalState, p1val: int, p2val: int) -> None:
        """Simulation: what ``update(arg)`` does when it reads ``p1val`` and ``p2val``."""
        state = (arg.state & 3) | (4 if p1val else 0) | (8 if p2val else 0)
        arg.state = state >> 2
        d = _STEP[state]
        if d:
            arg.position = _int32(arg.position + d)

    @staticmethod
    def update_walk(arg: EncoderInternalState, levels) -> None:
        """Simulation: what ``update_from_levels(arg, p1val, p2val)`` does for each
        (p1val, p2val) of ``levels`` in order (the position wraps once at the end: the same int32).
        Where ``levels.cycle`` is p (the levels repeat every p steps), a long walk costs O(p)."""
        state, position = arg.state, arg.position
        n, p = len(levels), getattr(levels, "cycle", 0)
        if p and n > 3 * p:
            steps = []
            for p1val, p2val in levels[:p + 1]:
                s = (state & 3) | (4 if p1val else 0) | (8 if p2val else 0)
                state = s >> 2
                steps.append(_STEP[s])
            # a step's table entry depends on its levels and the previous step's alone, so steps
            # p+1, p+2, ... repeat steps 1, 2, ...: whole cycles, then the start of one
            cyc = steps[1:]
            q, r = divmod(n - 1 - p, p)
            position += sum(steps) + q * sum(cyc) + sum(cyc[:r])
            p1val, p2val = levels[n - 1]
            state = (1 if p1val else 0) | (2 if p2val else 0)
        else:
            for p1val, p2val in levels:
                s = (state & 3) | (4 if p1val else 0) | (8 if p2val else 0)
                state = s >> 2
                position += _STEP[s]
        arg.state, arg.position = state, _int32(position)

    def attach_interrupt(self, pin: int, state: EncoderInternalState) -> int:
        # The C switches on CORE_INT0_PIN/CORE_INT1_PIN (2, 3 on the 328P); asking the core's
        # digitalPinToInterrupt gives the same mapping without hard-coding the variant.
        n = self.core.digital_pin_to_interrupt(pin)
        if not 0 <= n < CORE_NUM_INTERRUPT:
            return 0
        self.interrupt_args.args[n] = state
        self.core.attach_interrupt(n, self.interrupt_args.isr[n], CHANGE)
        # simulation: isr<n> is update(state), a function of the levels of this encoder's pins
        pins = (self._pin1, self._pin2)
        walk = self._walks.get(id(state))      # one per state: both pins' handlers step it alike
        if walk is None:
            walk = self._walks[id(state)] = lambda levels: Encoder.update_walk(state, levels)
        self.core.attach_closed_form(n, pins, lambda p1, p2: Encoder.update_from_levels(state, p1, p2), walk)
        return 1
