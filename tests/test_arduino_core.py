"""The Arduino core and TimerOne on the simulated ATmega328P (pro-mini board, no sketch)."""

import itertools

from mcusim.fw.arduino.core import OUTPUT, ArduinoCore
from mcusim.fw.arduino.timerone import TimerOne

import mcusim


def board():
    sim = mcusim.load("pro-mini", firmware=False)
    return sim, ArduinoCore(sim.mcu)


def edges(sim, pin, cycles):
    out = []
    sim.pin(pin).listen(lambda n: out.append((sim.now, n.level)))
    sim.run(cycles=cycles)
    return out


def periods_and_highs(ev):
    rises = [t for t, lv in ev if lv]
    falls = [t for t, lv in ev if not lv]
    periods = {b - a for a, b in itertools.pairwise(rises)}
    highs = {min(f for f in falls if f > r) - r for r in rises[:-1]}
    return periods, highs


def test_millis_advances_128_in_125_timer0_overflows():
    """Sheet §7 #12: 125 overflows = 2 048 000 clocks = exactly 128 ms, with three 2-ms steps."""
    sim, core = board()
    core.init()
    seen = []
    sim.run(cycles=100)  # sample 100 cycles after each overflow: its ISR runs 4 cycles after it
    for _ in range(125):
        sim.run(cycles=16384)
        seen.append(core.millis())
    assert seen[-1] == 128
    steps = [b - a for a, b in zip([0] + seen, seen)]
    assert steps.count(2) == 3 and steps.count(1) == 122


def test_micros_counts_4us_per_timer0_tick():
    sim, core = board()
    core.init()
    sim.run(cycles=16384 * 3 + 64 * 10 + 5)
    # three overflows (3 x 256 ticks) and 10 more ticks of 4 µs: (768 + 10) x 4
    assert core.micros() == (3 * 256 + 10) * 4


def test_analog_write_9_gives_490hz_phase_correct_pwm():
    """Sheet §7 #10: mode 1, N = 64: period 2·255·64 = 32 640 clocks, high 2·128·64 = 16 384."""
    sim, core = board()
    core.init()
    core.analog_write(9, 128)
    periods, highs = periods_and_highs(edges(sim, "PB1", 5 * 32640))
    assert periods == {32640} and highs == {16384}


def test_digital_write_on_pwm_pin_disconnects_timer():
    """Sheet §7 #11: digitalWrite(9, LOW) clears COM1A1; D9 stays low."""
    sim, core = board()
    core.init()
    core.analog_write(9, 128)
    sim.run(cycles=40000)
    core.digital_write(9, 0)
    assert sim.mcu.read8(0x80) & 0x80 == 0
    assert edges(sim, "PB1", 100000) == [] and sim.pin("PB1").level == 0


def test_timerone_20khz_on_d9_d10():
    """Sheet §7 #3: initialize(50), pwm(9,512), pwm(10,256): 800-clock period, 400 and 200 high."""
    sim, core = board()
    core.init()
    t1 = TimerOne(sim.mcu.bus, core)
    t1.initialize(50)
    t1.pwm(9, 512)
    t1.pwm(10, 256)
    sim.run(cycles=1600)
    ev9, ev10 = [], []
    sim.pin("PB1").listen(lambda n: ev9.append((sim.now, n.level)))
    sim.pin("PB2").listen(lambda n: ev10.append((sim.now, n.level)))
    sim.run(cycles=8000)
    assert periods_and_highs(ev9) == ({800}, {400})
    assert periods_and_highs(ev10) == ({800}, {200})
    assert sim.mcu.read8(0x80) == 0xA0 and sim.mcu.read8(0x81) == 0x11


def test_pin_mode_output_and_digital_read():
    sim, core = board()
    core.pin_mode(13, OUTPUT)
    core.digital_write(13, 1)
    assert sim.pin("PB5").level == 1 and core.digital_read(13) == 1
    sim.pin("PD4").drive(1)
    assert core.digital_read(4) == 1


def test_detach_interrupt_of_a_pin_without_one_does_nothing():
    """WInterrupts.c: detachInterrupt(digitalPinToInterrupt(pin)) with NOT_AN_INTERRUPT (-1, 255 as
    its uint8_t) fails ``interruptNum < EXTERNAL_NUM_INTERRUPTS`` and does nothing."""
    _sim, core = board()
    core.init()
    core.attach_interrupt(0, lambda: None, 1)
    core.attach_interrupt(1, lambda: None, 1)
    eimsk = core.read8(0x3D)
    core.detach_interrupt(core.digital_pin_to_interrupt(7))
    assert core.read8(0x3D) == eimsk == 0b11
    assert all(f is not None for f in core.int_func)


def test_delay_microseconds_counts_in_sixteen_bits_as_wiring_c_does():
    """wiring.c (16 MHz): ``if (us <= 1) return; us <<= 2; us -= 5;`` on an unsigned int, then 4
    cycles an iteration after ~20 of call and set-up: 16 cycles a microsecond up to 16383 µs, and
    a wrapped count beyond (20000 µs burns (80000 mod 65536 − 5)·4 + 20 = 57,856 cycles, 3.6 ms).
    The port had charged 16·us always."""
    sim = mcusim.load("pro-mini", firmware=False)
    core = ArduinoCore(sim.mcu)
    for us, cycles in ((0, 16), (1, 16), (2, 32), (2000, 32000), (16383, 262128), (20000, 57856)):
        core.debt_cycles = 0
        core.delay_microseconds(us)
        assert core.debt_cycles == cycles, us
    sim.close()


def test_analog_write_stores_the_ints_high_byte_too():
    """wiring_analog.c: ``OCR1A = val`` with an int val writes both bytes (TEMP first), so 300 on
    pin 9 is OCR1A = 300 (the port had written 0 as the high byte: 44)."""
    sim = mcusim.load("pro-mini", firmware=False)
    core = ArduinoCore(sim.mcu)
    core.analog_write(9, 300)
    assert sim.mcu.read8(0x88) | (sim.mcu.read8(0x89) << 8) == 300
    sim.close()


def test_wire_begin_enables_the_twi_before_setting_its_address_and_write_returns_the_count():
    """Wire.cpp: begin(address) is begin() (twi_init: the two cbi's of TWSR's prescaler bits, TWBR,
    TWCR) and then twi_setAddress; write() in slave mode returns the count given whether or not
    twi_transmit took the bytes (outside a request it takes none). The port had set TWAR first,
    cleared both prescaler bits in one write, and returned 0 for bytes not taken."""
    from mcusim.fw.arduino.wire import TwoWire
    sim = mcusim.load("pro-mini", firmware=False)
    core = ArduinoCore(sim.mcu)
    writes = []
    bus = sim.mcu.bus
    real = bus.write

    def spy(addr, value, size):
        if 0xB8 <= addr <= 0xBD:
            writes.append(addr)
        return real(addr, value, size)
    bus.write = spy
    wire = TwoWire(core)
    wire.begin(0x10)
    assert writes == [0xB9, 0xB9, 0xB8, 0xBC, 0xBA]      # TWSR, TWSR, TWBR, TWCR, then TWAR
    assert wire.write(b"\x01\x02") == 2
    sim.close()
