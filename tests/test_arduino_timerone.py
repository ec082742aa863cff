"""TimerOne on the 328P: register values and byte order written for initialize/setPeriod/pwm/start.

The fake bus holds the Timer1 registers with the datasheet's TEMP rule (§1.5): the high byte of a
16-bit register goes to the shared TEMP latch and the low-byte write commits both; a low-byte read
latches the high byte into TEMP.
"""

from hypothesis import given, settings
from hypothesis import strategies as st
from mcusim.fw.arduino.core_api import OUTPUT, DataBus
from mcusim.fw.arduino.timerone import TimerOne

TIMSK1, TCCR1A, TCCR1B = 0x6F, 0x80, 0x81
TCNT1, ICR1, OCR1A, OCR1B = 0x84, 0x86, 0x88, 0x8A
WIDE = {TCNT1, ICR1, OCR1A, OCR1B}


class Timer1Bus:
    def __init__(self):
        self.mem = {}
        self.temp = 0
        self.writes = []

    def write8(self, addr, value):
        assert 0 <= value <= 0xFF
        self.writes.append((addr, value))
        if addr - 1 in WIDE:                 # high byte: into TEMP only
            self.temp = value
        elif addr in WIDE:                   # low byte: TEMP:low into the register, same clock
            self.mem[addr], self.mem[addr + 1] = value, self.temp
        else:
            self.mem[addr] = value

    def read8(self, addr):
        if addr in WIDE:
            self.temp = self.mem.get(addr + 1, 0)
            return self.mem.get(addr, 0)
        if addr - 1 in WIDE:
            return self.temp
        return self.mem.get(addr, 0)

    def reg16(self, addr):
        return self.mem.get(addr, 0) | self.mem.get(addr + 1, 0) << 8


class Core:
    def __init__(self):
        self.modes = {}

    def pin_mode(self, pin, mode):
        self.modes[pin] = mode


def timer():
    bus, core = Timer1Bus(), Core()
    return bus, core, TimerOne(bus, core)


def test_fake_bus_satisfies_the_protocol():
    assert isinstance(Timer1Bus(), DataBus)


def test_initialize_50us_is_mode_8_n1_icr_400_running_vector_1():
    bus, _, t1 = timer()
    t1.initialize(50)
    assert bus.mem[TCCR1A] == 0x00 and bus.mem[TCCR1B] == 0x11 and bus.reg16(ICR1) == 400
    # TCCR1B = WGM13 (stopped), TCCR1A = 0, ICR1 high then low, then TCCR1B with CS10
    assert bus.writes == [(TCCR1B, 0x10), (TCCR1A, 0x00), (ICR1 + 1, 0x01), (ICR1, 0x90), (TCCR1B, 0x11)]


def test_pwm_on_d9_d10_sets_com_bits_and_ocr_vector_3():
    bus, core, t1 = timer()
    t1.initialize(50)
    t1.pwm(9, 512)
    t1.pwm(10, 256)
    assert core.modes == {9: OUTPUT, 10: OUTPUT}
    assert bus.mem[TCCR1A] == 0xA0 and bus.mem[TCCR1B] == 0x11
    assert bus.reg16(OCR1A) == 200 and bus.reg16(OCR1B) == 100
    assert bus.writes[-3:] == [(OCR1B + 1, 0), (OCR1B, 100), (TCCR1B, 0x11)]


def test_duty_1023_gives_ocr_399_vector_4():
    bus, _, t1 = timer()
    t1.initialize(50)
    t1.set_pwm_duty(9, 1023)
    assert bus.reg16(OCR1A) == 399


def test_duty_extremes_vector_5():
    bus, _, t1 = timer()
    t1.initialize(50)
    for duty, ocr in [(1024, 400), (0, 0), (2, 0), (3, 1)]:
        t1.set_pwm_duty(9, duty)
        assert bus.reg16(OCR1A) == ocr, duty
    t1.set_pwm_duty(11, 512)                      # not a Timer1 pin: no write
    assert bus.reg16(OCR1B) == 0


def test_duty_is_16_bit_unsigned_int_product_32_bit():
    bus, _, t1 = timer()
    t1.initialize(50)
    t1.set_pwm_duty(9, 65536 + 512)               # unsigned int parameter truncates to 512
    assert bus.reg16(OCR1A) == 200
    t1.set_period(2_000_000)                      # ICR1 = 62500 (N = 256)
    t1.set_pwm_duty(10, 65535)                    # 62500·65535 fits in 32 bits; >>10 then 16-bit store
    assert bus.reg16(OCR1B) == (62500 * 65535 >> 10) & 0xFFFF


def test_default_initialize_is_one_second_n256_vector_7():
    bus, _, t1 = timer()
    t1.initialize()
    assert bus.reg16(ICR1) == 31250 and bus.mem[TCCR1B] == 0x14


def test_set_period_10ms_is_n8_icr_10000_vector_8():
    bus, _, t1 = timer()
    t1.initialize(50)
    t1.set_period(10000)
    assert bus.reg16(ICR1) == 10000 and bus.mem[TCCR1B] == 0x12


def test_disable_pwm_clears_only_its_com_bit():
    bus, _, t1 = timer()
    t1.initialize(50)
    t1.pwm(9, 512)
    t1.pwm(10, 512)
    t1.disable_pwm(9)
    assert bus.mem[TCCR1A] == 0x20
    t1.disable_pwm(10)
    assert bus.mem[TCCR1A] == 0x00


def test_stop_start_resume():
    bus, _, t1 = timer()
    t1.initialize(50)
    t1.stop()
    assert bus.mem[TCCR1B] == 0x10
    bus.mem[TCNT1], bus.mem[TCNT1 + 1] = 0x34, 0x01
    bus.writes.clear()
    t1.start()
    assert bus.writes == [(TCCR1B, 0), (TCNT1 + 1, 0), (TCNT1, 0), (TCCR1B, 0x11)]
    t1.stop()
    t1.resume()
    assert bus.mem[TCCR1B] == 0x11 and bus.reg16(TCNT1) == 0


def test_attach_interrupt_overwrites_timsk1_with_toie1_and_isr_calls_callback():
    bus, _, t1 = timer()
    bus.mem[TIMSK1] = 0x26
    t1.timer1_ovf_vect()                          # isrDefaultUnused before any attach
    hits = []
    t1.attach_interrupt(lambda: hits.append(1))
    assert bus.mem[TIMSK1] == 0x01
    t1.timer1_ovf_vect()
    assert hits == [1]
    t1.detach_interrupt()
    assert bus.mem[TIMSK1] == 0x00


def test_overloads_with_microseconds_set_the_period_first():
    bus, _, t1 = timer()
    t1.initialize(50)
    t1.pwm(9, 512, 10000)
    assert bus.reg16(ICR1) == 10000 and bus.reg16(OCR1A) == 5000
    t1.attach_interrupt(lambda: None, 50)
    assert bus.reg16(ICR1) == 400
    t1.pwm(9, 512, 0)                              # 0: period untouched
    assert bus.reg16(ICR1) == 400


LADDER = [(1, 0b001), (8, 0b010), (64, 0b011), (256, 0b100), (1024, 0b101)]


def ladder(us):
    cycles = 160 * us // 20
    for n, cs in LADDER:
        if cycles < 65536 * n:
            return n, cycles // n, cs
    return 1024, 65535, 0b101


@settings(max_examples=300, deadline=None)
@given(st.one_of(st.integers(min_value=1, max_value=8_000_000),
                 st.sampled_from([8191, 8192, 65535, 65536, 65537, 524287, 524288, 1_048_575,
                                  1_048_576, 4_194_303, 4_194_304, 8_000_000])))
def test_prescaler_ladder_matches_formula(us):
    bus, _, t1 = timer()
    t1.initialize(us)
    n, icr, cs = ladder(us)
    assert bus.reg16(ICR1) == icr
    assert bus.mem[TCCR1B] == 0x10 | cs
    assert t1.pwm_period == icr and t1.clock_select_bits == cs
    assert icr <= 65535 and (n, cs) in LADDER


def test_period_beyond_ladder_saturates_and_unsigned_long_product_wraps():
    bus, _, t1 = timer()
    t1.initialize(8_400_000)                       # cycles 67 200 000 ≥ 65536·1024
    assert bus.reg16(ICR1) == 65535 and bus.mem[TCCR1B] == 0x15
    t1.set_period(26_843_546)                      # 160·us wraps modulo 2^32 to 64: cycles 3
    assert bus.reg16(ICR1) == 3 and bus.mem[TCCR1B] == 0x11
