"""ATmega328P ADC: transfer function (vector #20), conversion timing (vector #21), sampling
instant, ADIF, free running, data-register lock, unsupported configurations."""

from fractions import Fraction

import pytest
from avr_rig import bare_atmega328p
from hypothesis import given, settings
from hypothesis import strategies as st
from mcusim.periph.avr.adc import Adc

from mcusim.errors import UnsupportedConfiguration
from mcusim.signals import AnalogNet

ADCL, ADCH, ADCSRA, ADCSRB, ADMUX, DIDR0 = 0x78, 0x79, 0x7A, 0x7B, 0x7C, 0x7E
ADEN, ADSC, ADATE, ADIF, ADIE = 0x80, 0x40, 0x20, 0x10, 0x08
AVCC = 0x40  # REFS = 01


def make(volts=(0.0,) * 8, aref=None, cpu=False):
    mcu = bare_atmega328p(cpu=cpu)
    nets = {n: AnalogNet(f"ADC{n}", v) for n, v in enumerate(volts)}
    adc = Adc("ADC", mcu, mcu.core_clock, nets, avcc=5.0, aref=aref)
    mcu.bus.attach_registers(0, adc)
    return mcu, adc, nets


def analog_read(mcu, ch=0, t_limit=10**7):
    """Arduino analogRead: ADMUX = AVcc | ch, set ADSC, busy-wait, read ADCL then ADCH."""
    k = mcu.kernel
    mcu.write8(ADMUX, AVCC | ch)
    mcu.write8(ADCSRA, mcu.read8(ADCSRA) | ADSC)
    k.run_until(t_limit, stop=lambda: not mcu.read8(ADCSRA) & ADSC)
    lo = mcu.read8(ADCL)
    return mcu.read8(ADCH) << 8 | lo


def init(mcu):
    """Arduino init(): ADPS = 111 (/128), ADEN = 1, at the current tick."""
    mcu.write8(ADCSRA, ADEN | 7)


@pytest.mark.parametrize("vin,code", [(2.5, 512), (1.0, 204), (5.0, 1023), (0.0, 0), (4.999, 1023),
                                      (0.004, 0), (0.005, 1), (6.0, 1023), (-0.3, 0)])
def test_vector20_transfer_function(vin, code):
    mcu, _adc, nets = make()
    init(mcu)
    nets[0].set(vin)
    assert analog_read(mcu) == code


def test_vector21_first_conversion_25_then_13_adc_clocks_exact_ticks():
    mcu, adc, _nets = make((2.5,))
    k = mcu.kernel
    init(mcu)                                  # ADEN at tick 0: ADC clock edges at 128k
    k.run_until(1000)
    t0 = k.now
    assert analog_read(mcu) == 512
    # ADSC at 1000 -> start at the next edge 1024; 25 ADC clocks -> done at 1024 + 3200
    assert k.now == 1024 + 25 * 128
    assert 25 * 128 < k.now - t0 <= 26 * 128
    assert adc.history[0][:3] == (1024, 1024 + 13 * 128 + 64, 4224)
    k.run_until(5000)
    t1 = k.now
    analog_read(mcu)
    # ADSC at 5000 -> start at 5120; 13 ADC clocks
    assert k.now == 5120 + 13 * 128
    assert 13 * 128 < k.now - t1 <= 14 * 128
    # a request exactly on an ADC clock edge waits for the next one (strictly after)
    k.run_until(7680)
    analog_read(mcu)
    assert adc.history[-1][0] == 7680 + 128 and k.now == 7680 + 14 * 128


def test_prescaler_phase_counts_from_aden():
    mcu, adc, _nets = make((1.0,))
    k = mcu.kernel
    mcu.write8(ADMUX, AVCC)
    k.run_until(1000)
    mcu.write8(ADCSRA, ADEN | ADSC | 7)        # enable and start together: first edge one clock later
    k.run_until(10**6, stop=lambda: not mcu.read8(ADCSRA) & ADSC)
    assert adc.history[0][0] == 1128 and k.now == 1128 + 3200
    mcu.write8(ADCSRA, 7)                      # disable ...
    k.run_until(20_000)
    mcu.write8(ADCSRA, ADEN | 4)               # ... re-enable at 20000 with /16: first conversion again
    k.run_until(20_030)
    mcu.write8(ADCSRA, ADEN | ADSC | 4)
    k.run_until(10**6, stop=lambda: not mcu.read8(ADCSRA) & ADSC)
    assert adc.history[1][0] == 20_032 and k.now == 20_032 + 25 * 16


@pytest.mark.parametrize("adps,div", [(0, 2), (1, 2), (2, 4), (3, 8), (4, 16), (5, 32), (6, 64), (7, 128)])
def test_every_prescaler_even_outside_50_200_khz(adps, div):
    mcu, _adc, _nets = make((2.5,))
    mcu.write8(ADCSRA, ADEN | adps)
    assert analog_read(mcu) == 512             # first: 25 clocks
    t = mcu.kernel.now
    assert analog_read(mcu) == 512
    assert mcu.kernel.now - t == 14 * div      # done on an edge: one clock of sync, 13 of conversion


def test_sampling_instant_is_one_and_a_half_adc_clocks_after_start():
    mcu, _adc, nets = make()
    seen = []

    def source(t):
        seen.append(t)
        return 3.0 if t >= 1024 + 13 * 128 + 64 else 1.0   # changes exactly at the first sample tick
    nets[0].source = source
    init(mcu)
    mcu.kernel.run_until(1000)
    assert analog_read(mcu) == 614              # floor(3.0 * 1024 / 5)
    assert seen == [1024 + 13 * 128 + 64]       # 13.5 ADC clocks after the start, read once
    mcu.kernel.run_until(6000)
    seen.clear()
    nets[0].source = lambda t: (seen.append(t), 2.5 if t == 6016 + 192 else 0.0)[1]
    assert analog_read(mcu) == 512
    assert seen == [6016 + 192]                 # start 6016 (next edge after 6000) + 1.5 * 128


def test_adif_set_at_completion_cleared_by_writing_one_not_zero():
    mcu, _adc, _nets = make((1.0,))
    init(mcu)
    analog_read(mcu)
    assert mcu.read8(ADCSRA) & ADIF
    mcu.write8(ADCSRA, ADEN | 7)                # ADIF written 0: stays
    assert mcu.read8(ADCSRA) & ADIF
    mcu.write8(ADCSRA, ADEN | ADIF | 7)         # written 1: cleared
    assert not mcu.read8(ADCSRA) & ADIF


def test_adif_cleared_on_vector_21_entry():
    mcu, _adc, _nets = make((2.5,), cpu=True)
    seen = []
    mcu.cpu.vector(21, lambda: seen.append((mcu.kernel.now, mcu.read8(ADCSRA) & ADIF,
                                            mcu.read8(ADCL) | mcu.read8(ADCH) << 8)), cost=60)
    mcu.irq.set_i(True)
    mcu.write8(ADMUX, AVCC)
    mcu.write8(ADCSRA, ADEN | ADSC | ADIE | 7)  # tick 0: start at 128, done at 128 + 3200
    mcu.kernel.run_until(10_000)
    assert seen == [(3328 + 4, 0, 512)]
    assert not mcu.read8(ADCSRA) & ADIF
    assert not mcu.irq.lines[21]


def test_free_running_restarts_at_completion_and_keeps_adsc():
    mcu, adc, nets = make()
    nets[0].source = lambda t: t / 10_000        # a ramp: 0.1 V per 1000 ticks
    mcu.write8(ADMUX, AVCC)
    mcu.write8(ADCSRA, ADEN | ADSC | ADATE | 7)
    mcu.kernel.run_until(128 + 3200 + 4 * 1664)
    starts = [h[0] for h in adc.history]
    assert starts == [128, 3328, 4992, 6656, 8320]
    for t_start, t_sample, t_done, code in adc.history:
        first = t_start == 128
        assert t_sample - t_start == (1728 if first else 192)
        assert t_done - t_start == (3200 if first else 1664)
        assert code == min(1023, int(Fraction(repr(t_sample / 10_000)) * 1024 / 5))
    assert mcu.read8(ADCSRA) & ADSC
    mcu.write8(ADCSRA, ADEN | ADSC | 7)          # clear ADATE: the running conversion finishes, then stop
    mcu.kernel.run_until(20_000)
    assert len(adc.history) == 6 and adc.history[-1][2] == 9984 + 1664
    assert not mcu.read8(ADCSRA) & ADSC


def test_mux_written_after_start_applies_to_next_conversion():
    mcu, adc, _nets = make((1.0, 4.0))
    mcu.write8(ADMUX, AVCC | 0)
    mcu.write8(ADCSRA, ADEN | ADSC | ADATE | 7)
    mcu.kernel.run_until(3328 + 10)              # first done at 3328, second started at 3328
    mcu.write8(ADMUX, AVCC | 1)                  # after the start of conversion 2 (still before its sample)
    mcu.kernel.run_until(3328 + 2 * 1664)
    assert [h[3] for h in adc.history] == [204, 204, 819]


def test_adlar_and_adcl_read_locks_data_registers():
    mcu, adc, _nets = make((2.5, 1.0))
    init(mcu)
    assert analog_read(mcu) == 512
    mcu.write8(ADMUX, AVCC | 0x20)               # ADLAR: presentation changes at once
    assert (mcu.read8(ADCH), mcu.read8(ADCL)) == (512 >> 2, 0)
    mcu.write8(ADMUX, AVCC | 0x20 | 1)
    mcu.read8(ADCL)                              # lock
    mcu.write8(ADCSRA, mcu.read8(ADCSRA) | ADSC)
    mcu.kernel.run_until(10**6, stop=lambda: not mcu.read8(ADCSRA) & ADSC)
    assert mcu.read8(ADCSRA) & ADIF              # ADIF set although the result is lost
    assert adc.results_lost == 1
    assert mcu.read8(ADCH) == 512 >> 2           # still the old result; this read unlocks
    assert analog_read(mcu, 1) == 204


def test_internal_references_and_fixed_channels():
    mcu, _adc, _nets = make((0.55,))
    init(mcu)
    mcu.write8(ADMUX, 0xC0)                      # internal 1.1 V, ADC0 = 0.55 V -> 512
    mcu.write8(ADCSRA, mcu.read8(ADCSRA) | ADSC)
    mcu.kernel.run_until(10**6, stop=lambda: not mcu.read8(ADCSRA) & ADSC)
    assert mcu.read8(ADCL) | mcu.read8(ADCH) << 8 == 512
    assert analog_read(mcu, 14) == 225           # bandgap 1.1 V at AVcc 5 V
    assert analog_read(mcu, 15) == 0             # GND


def test_aref_reference_when_given():
    mcu, _adc, _nets = make((1.65,), aref=3.3)
    init(mcu)
    mcu.write8(ADMUX, 0x00)
    mcu.write8(ADCSRA, mcu.read8(ADCSRA) | ADSC)
    mcu.kernel.run_until(10**6, stop=lambda: not mcu.read8(ADCSRA) & ADSC)
    assert mcu.read8(ADCL) | mcu.read8(ADCH) << 8 == 512


@pytest.mark.parametrize("admux,field", [(0x00, "REFS"), (0x80, "REFS"), (0x48, "MUX"), (0x4A, "MUX")])
def test_unsupported_references_and_channels_raise_at_request(admux, field):
    mcu, _adc, _nets = make()
    init(mcu)
    mcu.write8(ADMUX, admux)
    with pytest.raises(UnsupportedConfiguration) as e:
        mcu.write8(ADCSRA, ADEN | ADSC | 7)
    assert e.value.register == "ADMUX" and e.value.field == field
    assert not mcu.read8(ADCSRA) & ADSC          # the refused write left ADCSRA as it was


def test_unconnected_channel_raises():
    mcu, _adc, _nets = make((1.0,))
    init(mcu)
    mcu.write8(ADMUX, AVCC | 5)
    with pytest.raises(UnsupportedConfiguration, match="ADC5"):
        mcu.write8(ADCSRA, ADEN | ADSC | 7)


def test_auto_trigger_sources_other_than_free_running_raise():
    mcu, _adc, _nets = make()
    mcu.write8(ADCSRB, 0b011)                    # allowed while ADATE = 0
    with pytest.raises(UnsupportedConfiguration) as e:
        mcu.write8(ADCSRA, ADEN | ADATE | 7)
    assert (e.value.register, e.value.field, e.value.value) == ("ADCSRB", "ADTS", 3)
    mcu.write8(ADCSRB, 0)
    mcu.write8(ADCSRA, ADEN | ADATE | 7)
    with pytest.raises(UnsupportedConfiguration):
        mcu.write8(ADCSRB, 0b110)


def test_clearing_aden_aborts_conversion():
    mcu, adc, _nets = make((2.5,))
    mcu.write8(ADMUX, AVCC)
    mcu.write8(ADCSRA, ADEN | ADSC | 7)
    mcu.kernel.run_until(2000)
    mcu.write8(ADCSRA, 7)
    assert not mcu.read8(ADCSRA) & ADSC
    mcu.kernel.run_until(10_000)
    assert adc.history == [] and not mcu.read8(ADCSRA) & ADIF
    mcu.write8(DIDR0, 0x3F)
    assert mcu.read8(DIDR0) == 0x3F


def test_one_event_per_sample_and_per_completion():
    mcu, adc, _nets = make((2.5,))
    mcu.write8(ADMUX, AVCC)
    mcu.write8(ADCSRA, ADEN | ADSC | ADATE | 7)
    mcu.kernel.run_until(128 + 3200 + 99 * 1664)
    assert len(adc.history) == 100 and mcu.kernel.events == 200


def test_done_signal_fires_at_each_completion_after_registers_are_written():
    mcu, adc, _nets = make((2.5,))
    seen = []

    def waiter():
        seen.append((mcu.kernel.now, mcu.read8(ADCSRA) & ADSC))
        adc.done._wait(waiter)
    adc.done._wait(waiter)
    init(mcu)
    analog_read(mcu)
    analog_read(mcu)
    assert seen == [(3328, 0), (3328 + 14 * 128, 0)]


@settings(max_examples=200, deadline=None)
@given(st.floats(min_value=0.0, max_value=5.5, allow_nan=False), st.integers(0, 3000))
def test_result_is_floor_of_v_times_1024_over_vref(v, t_req):
    mcu, _adc, _nets = make((v,))
    init(mcu)
    mcu.kernel.run_until(t_req)
    code = analog_read(mcu)
    assert code == min(1023, int(Fraction(repr(v)) * 1024 // 5))


@settings(max_examples=500, deadline=None)
@given(v=st.floats(allow_nan=False, allow_infinity=False))
def test_exact_voltage_is_the_floats_shortest_decimal_for_every_finite_float(v):
    """The ADC's exact input (``floor(V·1024/Vref)`` decides code boundaries exactly): the float's
    repr as a Fraction, the same on a second call (answered from the cache)."""
    from mcusim.signals import exact_voltage

    assert exact_voltage(v) == Fraction(repr(v)) == exact_voltage(v)


def test_exact_voltage_refuses_what_is_not_a_finite_number():
    from mcusim.errors import McusimError
    from mcusim.signals import exact_voltage

    for v in (float("nan"), float("inf"), float("-inf")):
        with pytest.raises(McusimError, match="not a finite number"):
            exact_voltage(v)


@pytest.mark.parametrize("refs", [0b01, 0b11])
def test_internal_reference_options_are_refused_while_an_external_voltage_is_on_aref(refs):
    # ADMUX REFS1:0 (datasheet 8271 §24.9.1): "The internal voltage reference options may not be
    # used if an external reference voltage is being applied to the AREF pin" (AVcc or the 1.1 V
    # reference would be shorted to it through the AREF pin).
    mcu, _adc, _nets = make((1.0,), aref=3.3)
    init(mcu)
    with pytest.raises(UnsupportedConfiguration) as e:
        mcu.write8(ADMUX, refs << 6)
    assert e.value.register == "ADMUX" and e.value.field == "REFS" and "AREF" in str(e.value)
    assert mcu.read8(ADMUX) == 0x00              # the refused write left ADMUX as it was
    mcu.write8(ADMUX, 0x00)                      # REFS = 00 (AREF) stays allowed


def test_didr0_turns_the_digital_input_of_an_adc_pin_off_so_pinc_reads_zero():
    """Datasheet DIDR0: "When this bit is written logic one, the digital input buffer on the
    corresponding ADC pin is disabled. The corresponding PIN Register bit will always read as zero
    when this bit is set." It had been stored only: PC2 with its pull-up read 1."""
    import mcusim
    sim = mcusim.load("pro-mini", firmware=False)
    m = sim.mcu
    m.write8(0x28, 0x04)                 # PORTC: pull-up on PC2
    assert m.read8(0x26) & 0x04
    m.write8(0x7E, 0x04)                 # DIDR0: ADC2D
    assert m.read8(0x26) & 0x04 == 0 and m.read8(0x7E) == 0x04
    m.write8(0x7E, 0)
    assert m.read8(0x26) & 0x04
    sim.close()
