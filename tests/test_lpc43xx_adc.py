"""LPC4337 ADC0/ADC1 (NXP UM10503 (project LPC43xx notes) §1): transfer function, software and burst
timing at the sheet's CLKDIV values, the 4.5 MHz limit, DONE/OVERRUN rules, the interrupt line
through the NVIC, the sampling instant, and the configurations that are refused."""

import warnings
from fractions import Fraction

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from lpc_rig import CORE_HZ, bare_lpc4337
from mcusim.periph.lpc43xx.adc import Adc, AdcClockWarning, AdcInputWarning

from mcusim.errors import BusFault, McusimError, UnsupportedConfiguration
from mcusim.signals import AnalogNet

ADC0, ADC1 = 0x400E3000, 0x400E4000
CR, GDR, INTEN, STAT = 0x000, 0x004, 0x00C, 0x030
NVIC_ISER0, NVIC_ISPR0, NVIC_ICPR0 = 0xE000E100, 0xE000E200, 0xE000E280


def DR(n):
    return 0x010 + 4 * n


PDN, BURST, START_NOW = 1 << 21, 1 << 16, 1 << 24
DONE, OVERRUN = 1 << 31, 1 << 30
VREF = Fraction(33, 10)


def CLKDIV(d):
    return d << 8


def CLKS(c):
    return c << 17


def make(volts=(0.0,) * 8, pclk=None, extra_hz=(), strict=False, cpu=False):
    mcu = bare_lpc4337(cpu=cpu, extra_hz=extra_hz)
    clock = mcu.core_clock if pclk is None else mcu.kernel.timebase.clock("PCLK_ADC", pclk)
    nets = {n: AnalogNet(f"ADC0_{n}", v) for n, v in enumerate(volts)}
    adc = Adc("ADC0", mcu, clock, nets, irq=17, vref=3.3, strict=strict)
    mcu.bus.attach(ADC0, adc)
    return mcu, adc, nets


def rd(mcu, off, base=ADC0):
    return mcu.read32(base + off)


def wr(mcu, off, v, base=ADC0):
    mcu.write32(base + off, v)


def wait_stat(mcu, ch, base=ADC0):
    mcu.kernel.run_until(mcu.kernel.now + 10**7, stop=lambda: rd(mcu, STAT, base) >> ch & 1)
    assert rd(mcu, STAT, base) >> ch & 1, "no conversion completed"


def sw_read(mcu, ch=0, clkdiv=45):
    """LPCOpen/sAPI single read (§1.4): CR |= SEL, START = 1, poll STAT, read DRn, clear START."""
    cfg = PDN | CLKDIV(clkdiv) | 1 << ch
    wr(mcu, CR, cfg)
    wr(mcu, CR, cfg | START_NOW)
    wait_stat(mcu, ch)
    value = rd(mcu, DR(ch))
    wr(mcu, CR, cfg)
    return value >> 6 & 0x3FF


def ideal(v, bits=10):
    """§1.5: code = min(1023, floor(Vin * 1024 / VDDA)), on the exact decimal value; low bits cut."""
    n = int(Fraction(repr(v)) * (1 << bits) // VREF)
    return max(0, min((1 << bits) - 1, n)) << (10 - bits)


# --- transfer function (§1.5) --------------------------------------------------------------------

@pytest.mark.parametrize("vin,code", [
    (0.0, 0), (3.3, 1023), (1.65, 512),
    (1.6499, 511),                    # just below the 511/512 boundary at exactly 1.65 V
    (0.00322265625, 1),               # exactly 1 LSB = 3.3 / 1024
    (0.003222656, 0),                 # just below 1 LSB
    (3.29677734375, 1023),            # exactly 1023 * 3.3 / 1024
    (3.2967773, 1022),
    (5.0, 1023), (-0.2, 0),           # above VDDA reads 0x3FF; below VSSA reads 0
])
@pytest.mark.filterwarnings("ignore::mcusim.periph.lpc43xx.adc.AdcInputWarning")    # 5.0 and -0.2 V
def test_transfer_function_floor_v_times_1024_over_vdda_exact(vin, code):
    mcu, _adc, nets = make()
    nets[0].set(vin)
    assert sw_read(mcu) == code


@settings(max_examples=150, deadline=None)
@given(st.floats(min_value=0.0, max_value=3.3, allow_nan=False), st.integers(0, 5000))
def test_property_code_brackets_the_input_voltage(v, t_req):
    mcu, _adc, nets = make()
    nets[0].set(v)
    mcu.kernel.run_until(t_req)
    code = sw_read(mcu)
    x = Fraction(repr(v))
    if code == 1023:
        assert x >= 1023 * VREF / 1024
    else:
        assert code * VREF / 1024 <= x < (code + 1) * VREF / 1024


# --- software-mode timing (§1.3) -------------------------------------------------------------------

@pytest.mark.parametrize("clkdiv,mhz,ksps,us", [(45, "4.4348", "403.2", "2.48"), (92, "2.1935", "199.4", "5.01")])
def test_software_conversion_takes_11_adc_clocks(clkdiv, mhz, ksps, us):
    mcu, adc, _nets = make((1.65,))
    k = mcu.kernel
    k.run_until(1000)
    wr(mcu, CR, PDN | CLKDIV(clkdiv) | 1 | START_NOW)
    wait_stat(mcu, 0)
    ticks = 11 * (clkdiv + 1)                       # the base tick is one 204 MHz PCLK cycle
    assert k.now - 1000 == ticks
    # the sheet's worked values (§1.3 table); 5.01 us: the sheet prints 5.02, 1023 / 204 MHz = 5.0147 us
    assert round(float(adc.adc_clock_hz) / 1e6, 4) == float(mhz)
    assert round(CORE_HZ / ticks / 1e3, 1) == float(ksps)
    assert round(ticks / CORE_HZ * 1e6, 2) == float(us)
    assert rd(mcu, DR(0)) >> 6 & 0x3FF == 512


def test_nuttx_12mhz_apb3_clkdiv2_gives_4mhz_and_363_6_ksps():
    mcu, adc, _nets = make((1.0,), pclk=12_000_000)
    k = mcu.kernel
    period = k.timebase.base_hz // 12_000_000
    wr(mcu, CR, PDN | CLKDIV(2) | 1 | START_NOW)
    wait_stat(mcu, 0)
    assert adc.adc_clock_hz == 4_000_000
    assert k.now == 11 * 3 * period
    assert round(Fraction(k.timebase.base_hz, k.now) / 1000, 1) == Fraction(3636, 10)


def test_adc_clock_phase_conversion_starts_at_first_pclk_edge_at_or_after_the_write():
    # base clock 816 MHz (lcm with 16 MHz): one 204 MHz PCLK cycle is 4 base ticks
    mcu, adc, _nets = make((1.0,), extra_hz=(16_000_000,))
    k = mcu.kernel
    assert mcu.core_clock.period == 4
    k.run_until(1001)                                # between PCLK edges
    wr(mcu, CR, PDN | CLKDIV(45) | 1 | START_NOW)
    wait_stat(mcu, 0)
    assert adc.history[0][0] == 1004 and k.now == 1004 + 11 * 46 * 4
    rd(mcu, DR(0))
    k.run_until(4000)                                # on a PCLK edge: starts at the write tick
    wr(mcu, CR, PDN | CLKDIV(45) | 1 | START_NOW)
    wait_stat(mcu, 0)
    assert adc.history[1][0] == 4000 and k.now == 4000 + 11 * 46 * 4


# --- sampling instant (choice: end of the first ADC clock) ------------------------------------------

def test_sampling_instant_is_one_adc_clock_after_start():
    mcu, _adc, nets = make()
    seen = []
    t0, pt = 2000, 46
    nets[0].source = lambda t: (seen.append(t), 3.3 if t >= t0 + pt else 0.0)[1]
    mcu.kernel.run_until(t0)
    wr(mcu, CR, PDN | CLKDIV(45) | 1 | START_NOW)
    wait_stat(mcu, 0)
    assert rd(mcu, DR(0)) >> 6 & 0x3FF == 1023       # the step at exactly the sample tick is seen
    assert seen == [t0 + pt]                        # read once, at that tick
    t1 = 4000
    seen.clear()
    nets[0].source = lambda t: (seen.append(t), 3.3 if t >= t1 + pt + 1 else 0.0)[1]
    mcu.kernel.run_until(t1)
    wr(mcu, CR, PDN | CLKDIV(45) | 1 | START_NOW)
    wait_stat(mcu, 0)
    assert rd(mcu, DR(0)) >> 6 & 0x3FF == 0          # a step one tick later is not
    assert seen == [t1 + pt]


def test_burst_samples_one_adc_clock_after_each_start():
    mcu, adc, nets = make()
    nets[0].source = lambda t: t / 10_000            # a ramp, 0.1 V per 1000 ticks
    wr(mcu, INTEN, 0)
    wr(mcu, CR, PDN | CLKDIV(45) | CLKS(1) | BURST | 1)
    mcu.kernel.run_until(5 * 460)
    assert [h[1] for h in adc.history] == [k * 460 + 46 for k in range(5)]
    assert [h[4] for h in adc.history] == [ideal((k * 460 + 46) / 10_000, 9) for k in range(5)]


# --- the 4.5 MHz limit -------------------------------------------------------------------------------

def test_adc_clock_above_4_5_mhz_warns_once_per_configuration():
    mcu, adc, _nets = make((1.65,))
    with pytest.warns(AdcClockWarning) as rec:
        assert sw_read(mcu, clkdiv=44) == 512        # 204 / 45 = 4.533 MHz: converts anyway
    assert len(rec) == 1
    msg = str(rec[0].message)
    assert "ADC0" in msg and "CLKDIV 44" in msg and "4.5333 MHz" in msg and "4.5 MHz" in msg
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sw_read(mcu, clkdiv=44)                      # same configuration: no second warning
        sw_read(mcu, clkdiv=45)                      # 4.4348 MHz: fine
    t = mcu.kernel.now
    with pytest.warns(AdcClockWarning, match="CLKDIV 0"):
        sw_read(mcu, clkdiv=0)                       # 204 MHz: 11 PCLK cycles
    assert adc.history[-1][2] - adc.history[-1][0] == 11
    assert len(adc.warnings) == 2 and adc.warnings[0] == msg and mcu.kernel.now - t == 11


def test_adc_clock_above_4_5_mhz_raises_in_strict_mode_and_leaves_cr():
    mcu, adc, _nets = make((1.65,), strict=True)
    with pytest.raises(McusimError) as e:
        wr(mcu, CR, PDN | CLKDIV(44) | 1 | START_NOW)
    msg = str(e.value)
    assert "ADC0" in msg and "CLKDIV 44" in msg and "4.5333 MHz" in msg and "4.5 MHz" in msg
    assert rd(mcu, CR) == 0 and not adc.busy
    mcu.kernel.run_until(10_000)
    assert adc.conversions == 0
    assert sw_read(mcu, clkdiv=45) == 512


def test_exactly_4_5_mhz_is_allowed():
    mcu, adc, _nets = make((1.65,), pclk=9_000_000, extra_hz=(9_000_000,), strict=True)
    assert sw_read(mcu, clkdiv=1) == 512 and adc.adc_clock_hz == 4_500_000


def test_burst_clock_checked_at_every_cr_write():
    mcu, adc, _nets = make((1.0,), strict=True)
    wr(mcu, CR, PDN | CLKDIV(45) | BURST | 1)
    with pytest.raises(McusimError, match="CLKDIV 20"):
        wr(mcu, CR, PDN | CLKDIV(20) | BURST | 1)
    mcu.kernel.run_until(506 * 3)
    assert adc.conversions == 3                      # the burst goes on at the old clock


# --- DONE / OVERRUN rules (§1.2, §1.4) ---------------------------------------------------------------

def test_done_flags_set_at_completion_and_cleared_by_their_own_reads_only():
    mcu, _adc, _nets = make((0.0, 0.0, 1.65))
    cfg = PDN | CLKDIV(45) | 1 << 2
    wr(mcu, CR, cfg | START_NOW)
    wait_stat(mcu, 2)
    assert rd(mcu, STAT) == 1 << 2 | 1 << 16         # DONE2 and ADINT (ADGINTEN reset 1)
    assert rd(mcu, STAT) == 1 << 2 | 1 << 16         # reading STAT clears nothing
    g = rd(mcu, GDR)
    assert g == DONE | 2 << 24 | 512 << 6
    assert rd(mcu, GDR) == 2 << 24 | 512 << 6        # GDR read cleared GDR.DONE ...
    assert rd(mcu, STAT) == 1 << 2                   # ... not DR2.DONE (independent)
    assert rd(mcu, DR(2)) == DONE | 512 << 6
    assert rd(mcu, DR(2)) == 512 << 6 and rd(mcu, STAT) == 0
    wr(mcu, CR, cfg | START_NOW)                     # START stays 001: a second write starts again
    wait_stat(mcu, 2)
    wr(mcu, CR, cfg)                                 # a CR write clears GDR.DONE, not DR2.DONE
    assert rd(mcu, GDR) & DONE == 0 and rd(mcu, DR(2)) & DONE


def test_software_mode_overwrite_sets_no_overrun():
    mcu, _adc, _nets = make((1.0,))
    for _ in range(2):
        wr(mcu, CR, PDN | CLKDIV(45) | 1 | START_NOW)
        wait_stat(mcu, 0)
    assert rd(mcu, STAT) >> 8 & 0xFF == 0
    assert rd(mcu, DR(0)) == DONE | ideal(1.0) << 6


def test_burst_overrun_when_unread_result_is_overwritten():
    mcu, _adc, _nets = make((1.0,))
    k = mcu.kernel
    wr(mcu, INTEN, 0)
    wr(mcu, CR, PDN | CLKDIV(45) | BURST | 1)
    k.run_until(506)
    assert rd(mcu, STAT) == 1                        # DONE0, no OVERRUN yet
    k.run_until(2 * 506)
    assert rd(mcu, STAT) == 1 | 1 << 8               # second result overwrote an unread one
    assert rd(mcu, DR(0)) == DONE | OVERRUN | ideal(1.0) << 6   # DONE still set
    assert rd(mcu, DR(0)) == ideal(1.0) << 6 and rd(mcu, STAT) == 0
    assert rd(mcu, GDR) == DONE | OVERRUN | ideal(1.0) << 6
    assert rd(mcu, GDR) == ideal(1.0) << 6
    k.run_until(3 * 506)
    assert rd(mcu, DR(0)) == DONE | ideal(1.0) << 6  # read in time: no OVERRUN


# --- burst mode (§1.4) -------------------------------------------------------------------------------

def test_burst_scans_sel_channels_from_lowest_and_wraps():
    volts = (0.0, 0.0, 0.5, 0.0, 0.0, 1.5, 0.0, 3.0)
    mcu, adc, _nets = make(volts)
    wr(mcu, INTEN, 0)
    mcu.kernel.run_until(100)
    wr(mcu, CR, PDN | CLKDIV(45) | BURST | 0b1010_0100)
    mcu.kernel.run_until(100 + 7 * 506)
    assert [h[3] for h in adc.history] == [2, 5, 7, 2, 5, 7, 2]
    assert [h[0] for h in adc.history] == [100 + k * 506 for k in range(7)]
    assert [h[2] for h in adc.history] == [100 + (k + 1) * 506 for k in range(7)]
    assert rd(mcu, STAT) & 0xFF == 0b1010_0100
    assert rd(mcu, GDR) >> 24 & 7 == 2
    for ch in (2, 5, 7):
        assert rd(mcu, DR(ch)) >> 6 & 0x3FF == ideal(volts[ch])


BURST_KSPS = (403, 443, 493, 554, 633, 739, 887, 1109)   # §1.3 table at 4.4348 MHz


@pytest.mark.parametrize("clks", range(8))
def test_burst_clks_sets_clocks_and_valid_bits(clks):
    mcu, _adc, _nets = make((1.0,))
    wr(mcu, INTEN, 0)
    wr(mcu, CR, PDN | CLKDIV(45) | CLKS(clks) | BURST | 1)
    n = (11 - clks) * 46
    for k in (1, 2):
        wait_stat(mcu, 0)
        assert mcu.kernel.now == k * n
        v = rd(mcu, DR(0))
        assert v >> 6 & 0x3FF == ideal(1.0, 10 - clks)          # 10 - CLKS valid bits, the rest 0
        assert v >> 6 & ((1 << clks) - 1) == 0
    assert abs(Fraction(CORE_HZ, n) / 1000 - BURST_KSPS[clks]) < 1


def test_clearing_burst_lets_the_running_conversion_complete_then_stops():
    mcu, adc, _nets = make((1.0,))
    wr(mcu, INTEN, 0)
    wr(mcu, CR, PDN | CLKDIV(45) | BURST | 1)
    mcu.kernel.run_until(506 + 100)
    wr(mcu, CR, PDN | CLKDIV(45) | 1)
    mcu.kernel.run_until(10_000)
    assert adc.conversions == 2 and adc.history[-1][2] == 2 * 506
    assert not adc.busy


def test_burst_cr_write_keeping_burst_applies_sel_from_the_next_conversion():
    mcu, adc, _nets = make((0.5, 1.0, 1.5, 2.0))
    wr(mcu, INTEN, 0)
    wr(mcu, CR, PDN | CLKDIV(45) | BURST | 0b0101)
    mcu.kernel.run_until(100)                        # converting channel 0
    wr(mcu, CR, PDN | CLKDIV(45) | BURST | 0b1010)
    mcu.kernel.run_until(4 * 506)
    assert [h[3] for h in adc.history] == [0, 1, 3, 1]   # not restarted; next selected above 0, wrap
    assert [h[2] for h in adc.history] == [506, 1012, 1518, 2024]


def test_one_sample_and_one_completion_event_per_conversion():
    mcu, adc, _nets = make((1.0,))
    wr(mcu, INTEN, 0)
    wr(mcu, CR, PDN | CLKDIV(45) | BURST | 1)
    mcu.kernel.run_until(100 * 506)
    assert adc.conversions == 100 and mcu.kernel.events == 200


# --- CR writes during a conversion (choice: abort and restart) ------------------------------------

def test_start_written_during_a_conversion_aborts_sets_gdr_done_and_restarts():
    mcu, adc, _nets = make((1.0, 2.0))
    k = mcu.kernel
    assert sw_read(mcu, 0) == ideal(1.0)             # GDR now holds channel 0's result, DONE set
    k.run_until(1000)
    wr(mcu, CR, PDN | CLKDIV(45) | 1 | START_NOW)    # clears GDR.DONE and starts channel 0
    assert rd(mcu, GDR) & DONE == 0
    k.run_until(1200)
    wr(mcu, CR, PDN | CLKDIV(45) | 2 | START_NOW)    # while converting: abort, DONE set, restart on ch1
    assert rd(mcu, GDR) == DONE | ideal(1.0) << 6     # previous result and CHN 0
    wait_stat(mcu, 1)
    assert k.now == 1200 + 506
    assert rd(mcu, STAT) & 0xFF == 1 << 1            # the aborted channel-0 conversion wrote nothing
    assert rd(mcu, DR(1)) >> 6 & 0x3FF == ideal(2.0)
    assert adc.conversions == 2


def test_cr_write_without_start_lets_the_running_conversion_complete():
    mcu, _adc, _nets = make((1.0,))
    wr(mcu, CR, PDN | CLKDIV(45) | 1 | START_NOW)
    mcu.kernel.run_until(100)
    wr(mcu, CR, PDN | CLKDIV(45) | 1)                # sAPI's "CR &= ~START"
    wait_stat(mcu, 0)
    assert mcu.kernel.now == 506 and rd(mcu, GDR) & DONE


def test_power_down_aborts_and_start_with_pdn_0_raises():
    mcu, adc, _nets = make((1.0,))
    with pytest.raises(UnsupportedConfiguration) as e:
        wr(mcu, CR, CLKDIV(45) | 1 | START_NOW)
    assert (e.value.periph, e.value.register, e.value.field) == ("ADC0", "CR", "PDN")
    assert rd(mcu, CR) == 0
    with pytest.raises(UnsupportedConfiguration):
        wr(mcu, CR, CLKDIV(45) | BURST | 1)
    wr(mcu, CR, PDN | CLKDIV(45) | 1 | START_NOW)
    mcu.kernel.run_until(200)
    wr(mcu, CR, CLKDIV(45) | 1)                      # PDN = 0 while converting: lost, no DONE
    mcu.kernel.run_until(5000)
    assert adc.conversions == 0 and rd(mcu, STAT) == 0 and rd(mcu, GDR) & DONE == 0


# --- interrupt (§1.4) ------------------------------------------------------------------------------

def test_interrupt_line_17_follows_adint_through_the_nvic():
    mcu, _adc, _nets = make((1.0,))
    nvic = mcu.nvic
    mcu.write32(NVIC_ISER0, 1 << 17)
    assert rd(mcu, INTEN) == 0x100                   # reset: ADGINTEN = 1
    wr(mcu, CR, PDN | CLKDIV(45) | 1 | START_NOW)
    mcu.kernel.run_until(505)
    assert not nvic.lines.get(17) and not mcu.read32(NVIC_ISPR0) >> 17 & 1
    mcu.kernel.run_until(506)
    assert nvic.lines[17] and mcu.read32(NVIC_ISPR0) >> 17 & 1
    assert rd(mcu, STAT) >> 16 & 1
    rd(mcu, GDR)                                     # GDR.DONE cleared: ADINT drops (DR0.DONE not enabled)
    assert not nvic.lines[17] and rd(mcu, STAT) == 1
    wr(mcu, INTEN, 0x01)                             # enabling channel 0 raises it again
    assert nvic.lines[17]
    rd(mcu, DR(0))
    assert not nvic.lines[17] and rd(mcu, STAT) == 0
    mcu.write32(NVIC_ICPR0, 1 << 17)                 # line low: the latched pending bit can be cleared
    assert not mcu.read32(NVIC_ISPR0) >> 17 & 1


def test_nuttx_style_burst_isr_reads_dr_every_conversion():
    mcu, _adc, _nets = make((1.0,), cpu=True)
    seen = []

    def isr():
        seen.append((mcu.kernel.now, rd(mcu, DR(0))))
    mcu.cpu.vector(17, isr, cost=50)
    mcu.write32(NVIC_ISER0, 1 << 17)
    wr(mcu, INTEN, 0x01)                             # ADGINTEN = 0 in burst mode
    wr(mcu, CR, PDN | CLKDIV(45) | BURST | 1)
    mcu.kernel.run_until(5 * 506 + 100)
    assert [t for t, _ in seen] == [k * 506 + 12 for k in range(1, 6)]   # 12-cycle entry latency
    assert all(v == DONE | ideal(1.0) << 6 for _, v in seen)             # never OVERRUN


def test_adc1_at_0x400e4000_drives_irq_21():
    mcu, _adc0, nets = make((1.0,))
    adc1 = Adc("ADC1", mcu, mcu.core_clock, nets, irq=21)
    mcu.bus.attach(ADC1, adc1)
    wr(mcu, CR, PDN | CLKDIV(45) | 1 | START_NOW, base=ADC1)
    wait_stat(mcu, 0, base=ADC1)
    assert mcu.nvic.lines.get(21) and not mcu.nvic.lines.get(17)
    assert rd(mcu, DR(0), base=ADC1) >> 6 & 0x3FF == ideal(1.0)  # shares the pin with ADC0_0
    assert rd(mcu, STAT) == 0


def test_done_signal_fires_after_registers_are_written():
    mcu, adc, _nets = make((1.0,))
    seen = []

    def waiter():
        seen.append((mcu.kernel.now, rd(mcu, STAT) & 1))
        adc.done._wait(waiter)
    adc.done._wait(waiter)
    sw_read(mcu)
    sw_read(mcu)
    assert seen == [(506, 1), (1012, 1)]


# --- register map and refused configurations -----------------------------------------------------

def test_reset_values_and_read_only_registers_ignore_writes():
    mcu, _adc, _nets = make((1.0,))
    assert [rd(mcu, o) for o in (CR, GDR, INTEN, STAT)] == [0, 0, 0x100, 0]
    assert [rd(mcu, DR(n)) for n in range(8)] == [0] * 8
    wr(mcu, CR, PDN | CLKDIV(45) | 1 | START_NOW)
    wait_stat(mcu, 0)
    for off in (GDR, DR(0), STAT):
        wr(mcu, off, 0)                              # ignored: no flag cleared
    assert rd(mcu, STAT) == 1 | 1 << 16
    assert rd(mcu, DR(0)) == DONE | ideal(1.0) << 6
    wr(mcu, CR, 0xFFFF_FFFF & ~(7 << 24) & ~BURST)   # reserved CR bits read 0
    assert rd(mcu, CR) == 0xFF | 0xFF << 8 | 7 << 17 | PDN | 1 << 27   # SEL CLKDIV CLKS PDN EDGE


def test_reserved_offset_and_narrow_accesses_are_bus_faults():
    mcu, _adc, _nets = make()
    with pytest.raises(BusFault, match="0x400e3008"):
        rd(mcu, 0x008)
    with pytest.raises(BusFault):
        rd(mcu, 0x034)
    with pytest.raises(BusFault):
        mcu.read8(ADC0 + STAT)
    with pytest.raises(BusFault):
        mcu.write16(ADC0 + CR, 0)


@pytest.mark.parametrize("start", [2, 3, 4, 5, 6, 7])
def test_hardware_start_triggers_and_reserved_start_raise(start):
    mcu, _adc, _nets = make()
    with pytest.raises(UnsupportedConfiguration) as e:
        wr(mcu, CR, PDN | CLKDIV(45) | 1 | start << 24)
    assert (e.value.register, e.value.field, e.value.value) == ("CR", "START", start)
    assert rd(mcu, CR) == 0


def test_burst_with_start_not_000_raises():
    mcu, _adc, _nets = make()
    with pytest.raises(UnsupportedConfiguration) as e:
        wr(mcu, CR, PDN | CLKDIV(45) | BURST | 1 | START_NOW)
    assert (e.value.field, e.value.value) == ("START", 1)


def test_software_mode_with_two_sel_bits_raises_and_sel_0_is_channel_0():
    mcu, adc, _nets = make((2.0,))
    with pytest.raises(UnsupportedConfiguration) as e:
        wr(mcu, CR, PDN | CLKDIV(45) | 0b11 | START_NOW)
    assert str(e.value).startswith("ADC0.CR.SEL = 0x3")
    wr(mcu, CR, PDN | CLKDIV(45) | START_NOW)        # SEL = 0 behaves like 0x01
    wait_stat(mcu, 0)
    assert adc.history[0][3] == 0 and rd(mcu, DR(0)) >> 6 & 0x3FF == ideal(2.0)


def test_channel_without_analog_net_raises_naming_it():
    mcu, _adc, _nets = make((1.0, 1.0))
    with pytest.raises(McusimError, match="channel 3"):
        wr(mcu, CR, PDN | CLKDIV(45) | 1 << 3 | START_NOW)
    with pytest.raises(McusimError, match="channel 6"):
        wr(mcu, CR, PDN | CLKDIV(45) | BURST | 1 << 6 | 1)
    assert rd(mcu, CR) == 0


# --- the input range ---------------------------------------------------------------------------------

def test_an_input_outside_0_to_vdda_saturates_and_warns_once_per_channel_and_side():
    """DS Table 37 (VIA): a pin in analog mode takes 0 V .. VDDA, its absolute maximum. A battery
    wired without its divider read 1023 without a word; the code still saturates as the transfer
    function says, and the sample warns (raises with strict)."""
    mcu, adc, _nets = make((12.75, -0.2))
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        codes = sw_read(mcu, ch=0), sw_read(mcu, ch=1)
    assert codes == (1023, 0)
    assert [type(r.message) for r in rec] == [AdcInputWarning] * 2
    assert [str(r.message) for r in rec] == adc.warnings
    assert "channel 0 samples 12.75 V, above VDDA (3.3 V)" in adc.warnings[0]
    assert "channel 1 samples -0.2 V, below 0 V" in adc.warnings[1]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert sw_read(mcu, ch=0) == 1023           # once per channel and side
    mcu, _adc, _nets = make((4.0,), strict=True)
    with pytest.raises(McusimError, match="channel 0 samples 4 V, above VDDA"):
        sw_read(mcu, ch=0)
