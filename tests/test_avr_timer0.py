"""ATmega328P Timer/Counter0 as the Arduino core uses it (sheet §1.6, vector #12), and its other
modes against the per-clock oracle (tests/avr_timer_oracle.py)."""

import pytest
from avr_rig import bare_atmega328p
from avr_timer_oracle import MODES8, OCFA, TOV, Oracle
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from mcusim.periph.avr.timer0 import Timer0

from mcusim.errors import UnsupportedConfiguration

TIFR0, GTCCR, TCCR0A, TCCR0B, TCNT0, OCR0A, OCR0B, TIMSK0 = 0x35, 0x43, 0x44, 0x45, 0x46, 0x47, 0x48, 0x6E
OVF = 16


class Rig:
    def __init__(self, engine="reference"):
        self.mcu = bare_atmega328p(engine=engine)
        self.kernel, self.bus, self.clock = self.mcu.kernel, self.mcu.bus, self.mcu.core_clock
        self.tb = self.kernel.timebase
        self.t0 = Timer0("TIMER0", self.mcu, self.clock)
        self.bus.attach_registers(0, self.t0)
        self.P = self.clock.period
        self.edges = {"A": [], "B": []}
        for ch in "AB":
            self.t0.oc[ch].listen(lambda p, ch=ch: self.edges[ch].append((self.kernel.now, p.value)))

    def w(self, a, v):
        self.bus.write8(a, v)

    def r(self, a):
        return self.bus.read8(a)

    def arduino_init(self):
        """wiring.c init(): TCCR0A |= WGM01|WGM00; TCCR0B |= CS01|CS00; TIMSK0 |= TOIE0."""
        self.w(TCCR0A, self.r(TCCR0A) | 0x03)
        self.w(TCCR0B, self.r(TCCR0B) | 0x03)
        self.w(TIMSK0, self.r(TIMSK0) | 0x01)


class Millis:
    """The core's TIMER0_OVF ISR (wiring.c): MILLIS_INC = 1, FRACT_INC = 3, FRACT_MAX = 125."""

    def __init__(self, rig):
        self.millis, self.fract, self.overflows, self.rig = 0, 0, 0, rig
        self.times, self.steps = [], []
        rig.mcu.irq.line_listeners.append(self._line)

    def _line(self, vec, level):
        if vec == OVF and level:
            self.rig.mcu.irq.acknowledge(OVF)   # the response (I cleared), then
            self.rig.mcu.irq.entered(OVF)       # the vector entry clears TOV0
            self.times.append(self.rig.kernel.now)
            m, f = self.millis + 1, self.fract + 3
            if f >= 125:
                f -= 125
                m += 1
            self.steps.append(m - self.millis)
            self.millis, self.fract = m, f
            self.overflows += 1
            self.rig.mcu.irq.complete(OVF)


def test_vector12_arduino_timer0_125_overflows_2048000_clocks_millis_128():
    rig = Rig()
    ms = Millis(rig)
    rig.arduino_init()
    rig.kernel.run_until(2_048_000 * rig.P)
    assert ms.overflows == 125 and ms.millis == 128
    gaps = {b - a for a, b in zip(ms.times, ms.times[1:])}
    assert gaps == {16384 * rig.P}
    # per overflow +1, with an extra +1 three times per 125 overflows
    assert ms.steps.count(2) == 3 and ms.steps.count(1) == 122


def test_micros_inputs_tcnt0_and_tov0_readable():
    rig = Rig()
    rig.arduino_init()
    rig.w(TIMSK0, 0)                    # interrupts off, as inside micros() with cli()
    rig.kernel.run_until((16384 - 64) * rig.P)
    assert rig.r(TCNT0) == 255 and rig.r(TIFR0) & TOV == 0
    rig.kernel.run_until(16384 * rig.P)
    assert rig.r(TCNT0) == 0 and rig.r(TIFR0) & TOV   # the pending-overflow correction case
    assert rig.t0.counter == 0
    rig.w(TIFR0, TOV)
    assert rig.r(TIFR0) & TOV == 0


def test_prescaler_free_running_clk64_ticks_on_multiples_of_64():
    rig = Rig()
    rig.kernel.run_until(10 * rig.P)
    rig.w(TCCR0B, 3)
    rig.kernel.run_until(63 * rig.P)
    assert rig.t0.counter == 0
    rig.kernel.run_until(64 * rig.P)
    assert rig.t0.counter == 1


@pytest.mark.parametrize("reg, val, what", [(TCCR0B, 0x08, "WGM0"), (TCCR0B, 0x06, "CS0"),
                                            (GTCCR, 0x01, "PSRSYNC"), (GTCCR, 0x80, "TSM")])
def test_unsupported_raise_naming_field(reg, val, what):
    rig = Rig()
    if what == "WGM0":
        rig.w(TCCR0A, 0)                # WGM02=1, WGM01:0=00 -> mode 4 (reserved)
    with pytest.raises(UnsupportedConfiguration, match=what):
        rig.w(reg, val)


def test_fast_pwm_oc0a_high_ocr_plus_1():
    rig = Rig()
    rig.w(OCR0A, 100)
    rig.w(TCCR0A, 0x83)                 # COM0A1, mode 3
    rig.w(TCCR0B, 0x01)
    rig.kernel.run_until(256 * 4 * rig.P)
    rises = [t for t, v in rig.edges["A"] if v == 1]
    falls = [t for t, v in rig.edges["A"] if v == 0 and t > rises[1]]
    assert rises[2] - rises[1] == 256 * rig.P and falls[0] - rises[1] == 101 * rig.P


@pytest.mark.parametrize("engine", ["reference", "fast"])
@given(st.sampled_from(sorted(MODES8)), st.integers(3, 255), st.integers(0, 255),
       st.sampled_from([1, 2, 3]), st.sampled_from([1, 2, 3]))
@settings(max_examples=60, deadline=None)
def test_all_modes_match_oracle(engine, mode, top, ocrb, coma, comb):
    """Both engines (the fast one publishes PWM outputs as steady waveforms, edges expanded from
    the descriptor) against the per-clock oracle: edges, TCNT0 and the lazily set TIFR0."""
    # COM0B = 01 is reserved in the PWM modes (refused: test_com0b_01_in_a_pwm_mode_is_reserved...)
    assume(not (comb == 1 and MODES8[mode][0] in ("fast", "pc")))
    rig = Rig(engine)
    _, src = MODES8[mode]
    ocra = top if src == "A" else min(top, 255)
    rig.w(OCR0A, ocra)
    rig.w(OCR0B, ocrb)
    rig.w(TCCR0A, (coma << 6) | (comb << 4) | (mode & 3))
    rig.w(TCCR0B, ((mode & 4) << 1) | 1)
    orc = Oracle(mode, ocr=(ocra, ocrb), com=(coma, comb), max_=0xFF, modes=MODES8)
    n = 3 * 512 + 5
    orc.run(n)
    rig.kernel.run_until(n * rig.P)
    if engine == "fast" and MODES8[mode][0] in ("fast", "pc") and comb in (2, 3) and 0 < ocrb < top:
        assert rig.t0.oc["B"].wave is not None     # a PWM output strictly inside the cycle
    for ch in "AB":
        got = [(t // rig.P, v) for t, v in rig.edges[ch] if t > 0]
        assert got == orc.edges[ch]
    assert rig.t0.counter == orc.c
    assert rig.r(TIFR0) == orc.flags & 7
    assert OCFA == 2


@pytest.mark.parametrize("engine", ["reference", "fast"])
def test_a_tcnt0_write_while_stopped_blocks_the_first_compare_after_the_start(engine):
    """Datasheet, TC0 "Compare Match Blocking by TCNT0 Write": a write to TCNT0 blocks any compare
    match in the next timer clock "even when the timer is stopped", so OCR0A may equal TCNT0 at
    the start without a match."""
    import mcusim
    sim = mcusim.load("pro-mini", firmware=False, engine=engine)
    m = sim.mcu
    TIFR0, TCCR0B, TCNT0, OCR0A, OCR0B = 0x35, 0x45, 0x46, 0x47, 0x48
    m.write8(OCR0A, 5)
    m.write8(OCR0B, 200)
    m.write8(TCNT0, 5)
    m.write8(TCCR0B, 1)
    sim.run(cycles=1)
    assert m.read8(TIFR0) & 0x02 == 0
    sim.run(cycles=256)
    assert m.read8(TIFR0) & 0x02
    sim.close()


@pytest.mark.parametrize("wgm", [(1, 0), (3, 0), (1, 8), (3, 8)])
def test_com0b_01_in_a_pwm_mode_is_reserved_and_refused(wgm):
    """TC0's compare output tables for fast PWM and phase correct PWM list COM0B = 01 as
    "Reserved" (COM0A = 01 toggles OC0A there when WGM02 = 1)."""
    import mcusim
    sim = mcusim.load("pro-mini", firmware=False)
    a, b = wgm
    with pytest.raises(UnsupportedConfiguration, match="COM0B = 0x1 .reserved in the PWM modes"):
        sim.mcu.write8(0x44, 0x10 | a)
        sim.mcu.write8(0x45, b | 1)
    sim.close()
