"""LPC4337 USART (UM10503 USART0_2_3, 16550-style) and the host serial endpoints.

Timing facts are checked against the exact rational formula: a frame lasts
``bits * 16 * DL * (MULVAL + DIVADDVAL) / MULVAL`` PCLK cycles and the n-th back-to-back frame ends
at the first PCLK edge at or after ``t0 + n * frame`` (the model's documented rounding rule).
"""

import math
import os
import time
from fractions import Fraction

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from lpc_rig import CORE_HZ, bare_lpc4337
from mcusim.periph.lpc43xx.uart import Usart

from mcusim.errors import BusFault, UnsupportedConfiguration
from mcusim.hostserial import BufferEndpoint, PtyEndpoint

BASE, IRQ = 0x400C1000, 26            # USART2 (UART_USB on the EDU-CIAA)
RBR = THR = DLL = BASE + 0x00
IER = DLM = BASE + 0x04
IIR = FCR = BASE + 0x08
LCR, LSR, SCR = BASE + 0x0C, BASE + 0x14, BASE + 0x1C
ACR, ICR, FDR, OSR = BASE + 0x20, BASE + 0x24, BASE + 0x28, BASE + 0x2C
HDEN, SCICTRL, RS485CTRL, RS485ADRMATCH = BASE + 0x40, BASE + 0x48, BASE + 0x4C, BASE + 0x50
RS485DLY, SYNCCTRL, TER = BASE + 0x54, BASE + 0x58, BASE + 0x5C
ISER0 = 0xE000E100


def set_baud_fdr(pclk: int, baud: int):
    """LPCOpen ``Chip_UART_SetBaudFDR`` (lpc_chip_43xx uart_18xx_43xx.c), in uint32/uint64 arithmetic.
    Returns (divisor, DIVADDVAL, MULVAL, returned rate)."""
    m32 = (1 << 32) - 1
    sdiv, sm, sd, odiff = 0, 1, 0, m32
    m = 1
    while odiff and m < 16:
        for d in range(m):
            dval = (((pclk << 28) * m) // (baud * (m + d))) & ((1 << 64) - 1)
            diff, div = dval & m32, dval >> 32
            if diff >= 1 << 31:                      # (int)diff < 0: closer to the next div
                diff, div = (-diff) & m32, div + 1
            if odiff < diff or not div or div >> 16 or (div < 3 and d):
                continue
            sdiv, sd, sm, odiff = div, d, m, diff
            if not diff:
                break
        m += 1
    return sdiv, sd, sm, (pclk >> 4) * sm // (sdiv * (sm + sd))


def lpcopen_init(mcu, baud=115200, pclk=CORE_HZ):
    """Chip_UART_Init + Chip_UART_SetBaudFDR + Chip_UART_TXEnable, register by register."""
    w = mcu.write32
    w(FCR, 0x07)                     # FIFO_EN | RX_RS | TX_RS
    w(TER, 0)                        # Chip_UART_TXDisable
    w(IER, 0)
    w(LCR, 0)
    w(ACR, 0)
    w(RS485CTRL, 0)
    w(RS485DLY, 0)
    w(RS485ADRMATCH, 0)
    w(LCR, 0x03)                     # 8N1, DLAB = 0
    w(FDR, 0x10)
    dl, d, m, _ = set_baud_fdr(pclk, baud)
    w(LCR, mcu.read32(LCR) | 0x80)
    w(DLL, dl & 0xFF)
    w(DLM, dl >> 8 & 0xFF)
    w(LCR, mcu.read32(LCR) & ~0x80 & 0xFF)
    w(FDR, m << 4 | d)
    w(TER, 1)                        # Chip_UART_TXEnable


def rig(cpu=False, endpoint=None, extra_hz=()):
    mcu = bare_lpc4337(cpu=cpu, extra_hz=extra_hz)
    pclk = mcu.core_clock
    u = Usart("USART2", mcu, pclk, IRQ, endpoint=endpoint)
    mcu.periph["USART2"] = u
    mcu.bus.attach(BASE, u)
    return mcu, u


# 115200 8N1 from 204 MHz with LPCOpen's choice: DL = 83, DIVADDVAL = 5, MULVAL = 15
F115200 = Fraction(10 * 16 * 83 * (15 + 5), 15)        # PCLK cycles per frame = 53120/3


def test_lpcopen_set_baud_fdr_picks_dl_83_divaddval_5_mulval_15_for_115200_at_204mhz():
    dl, d, m, ret = set_baud_fdr(204_000_000, 115200)
    assert (dl, d, m) == (83, 5, 15)
    rate = Fraction(204_000_000, 16 * dl) * Fraction(m, m + d)
    assert rate == Fraction(9562500, 83)                 # 115210.843... baud
    assert (rate - 115200) / 115200 == Fraction(3, 31872)  # +0.00941 % exactly
    assert ret == 115210                                  # what the C function returns
    assert F115200 == Fraction(53120, 3)


def test_reset_values():
    mcu, _u = rig()
    assert mcu.read32(LSR) == 0x60 and mcu.read32(IIR) == 0x01
    assert mcu.read32(FDR) == 0x10 and mcu.read32(TER) == 0x01 and mcu.read32(OSR) == 0xF0
    mcu.write32(LCR, 0x80)
    assert mcu.read32(DLL) == 0x01 and mcu.read32(DLM) == 0


def test_115200_8n1_tx_frame_ends_are_exact_over_100_back_to_back_bytes():
    ep = BufferEndpoint()
    mcu, u = rig(endpoint=ep)
    lpcopen_init(mcu)
    assert u.frame_cycles == F115200
    data = bytes((7 * i + 3) & 0xFF for i in range(100))
    todo = list(data)

    def pump():                       # a polling driver: refill while THRE, wake on tx_done
        while todo and mcu.read32(LSR) & 0x20:
            mcu.write32(THR, todo.pop(0))
        if todo:
            u.tx_done._wait(pump)

    t0 = 1001
    mcu.kernel.at(t0, pump)
    mcu.kernel.run_until(t0 + math.ceil(101 * F115200))
    assert bytes(b for _, b in u.tx_log) == data == bytes(ep.sent)
    ends = [t for t, _ in u.tx_log]
    assert ends == [t0 + math.ceil(n * F115200) for n in range(1, 101)]
    assert ep.log == u.tx_log
    assert mcu.read32(LSR) & 0x60 == 0x60                # THRE and TEMT after the last frame
    # long-run rate is exact: 100 frames take 100 * 53120/3 cycles, rounded up once
    assert ends[-1] - t0 == math.ceil(Fraction(5312000, 3)) == 1770667


@settings(max_examples=60, deadline=None)
@given(dll=st.integers(1, 255), dlm=st.integers(0, 2), mul=st.integers(1, 15), add=st.integers(0, 14),
       wls=st.integers(0, 3), sbs=st.integers(0, 1), pe=st.integers(0, 1), ps=st.integers(0, 3),
       n=st.integers(1, 17), write_tick=st.integers(0, 50))
def test_property_nth_back_to_back_frame_ends_at_ceil_of_exact_rational_time(
        dll, dlm, mul, add, wls, sbs, pe, ps, n, write_tick):
    dl = dlm << 8 | dll
    assume(add < mul and (add == 0 or dl >= 3))
    mcu, u = rig(extra_hz=(16_000_000,))               # base 816 MHz: a PCLK cycle is 4 base ticks
    period = mcu.core_clock.period
    assert period == 4
    lcr = wls | sbs << 2 | pe << 3 | ps << 4
    mcu.write32(FCR, 1)
    mcu.write32(LCR, lcr | 0x80)
    mcu.write32(DLL, dll)
    mcu.write32(DLM, dlm)
    mcu.write32(LCR, lcr)
    mcu.write32(FDR, mul << 4 | add)

    def burst():
        for _ in range(n):
            mcu.write32(THR, 0xFF)                      # TSR + 16 FIFO bytes: back to back

    mcu.kernel.at(write_tick, burst)
    data = 5 + wls
    stop = (Fraction(3, 2) if data == 5 else 2) if sbs else 1
    bits = 1 + data + pe + stop
    frame = bits * 16 * dl * Fraction(mul + add, mul)
    mcu.kernel.run_until(write_tick + period * math.ceil((n + 1) * frame) + period)
    t0 = -(-write_tick // period)                       # first PCLK edge at or after the write
    assert [t for t, _ in u.tx_log] == [period * (t0 + math.ceil(k * frame)) for k in range(1, n + 1)]
    for k, (t, b) in enumerate(u.tx_log, 1):
        assert 0 <= Fraction(t, period) - (t0 + k * frame) < 1   # within one PCLK of exact
        assert b == (1 << data) - 1                     # masked to the word length


def test_tx_fifo_holds_16_bytes_behind_the_shift_register_and_a_write_to_a_full_fifo_is_lost():
    mcu, u = rig()
    lpcopen_init(mcu)
    for b in range(18):
        mcu.write32(THR, b)
    assert u.tx_overflows == 1                          # 1 in the TSR + 16 in the FIFO
    assert mcu.read32(LSR) & 0x60 == 0
    mcu.kernel.run_until(math.ceil(18 * F115200))
    assert [b for _, b in u.tx_log] == list(range(17))


def test_ter_txen_0_holds_bytes_in_the_fifo_until_enabled():
    mcu, u = rig()
    lpcopen_init(mcu)
    mcu.write32(TER, 0)
    for b in range(17):
        mcu.write32(THR, b)
    assert u.tx_overflows == 1 and mcu.read32(LSR) & 0x60 == 0
    mcu.kernel.run_until(100_000)
    assert u.tx_log == []
    mcu.write32(TER, 1)
    t0 = mcu.kernel.now
    mcu.kernel.run_until(t0 + math.ceil(17 * F115200))
    assert [t for t, _ in u.tx_log] == [t0 + math.ceil(k * F115200) for k in range(1, 17)]


def test_without_fifos_the_holding_register_is_one_byte():
    mcu, u = rig()
    lpcopen_init(mcu)
    mcu.write32(FCR, 0)
    assert mcu.read32(IIR) == 0x01                      # FIFOENABLE bits read 00
    mcu.write32(TER, 0)
    mcu.write32(THR, 1)
    mcu.write32(THR, 2)
    assert u.tx_overflows == 1


def test_thre_interrupt_refills_the_fifo_and_frames_stay_back_to_back():
    mcu, u = rig(cpu=True)
    lpcopen_init(mcu)
    mcu.write32(ISER0, 1 << IRQ)
    data = list(range(40))
    entries = []

    def isr():                                          # Chip_UART_TXIntHandlerRB-like
        iir = mcu.read32(IIR)
        entries.append((mcu.kernel.now, iir))
        if iir & 0x0E == 0x02:
            for _ in range(16):
                if not data:
                    mcu.write32(IER, 0)                 # ring buffer empty: THRE interrupt off
                    break
                mcu.write32(THR, data.pop(0))

    mcu.cpu.vector(IRQ, isr, cost=100)
    mcu.kernel.at(500, mcu.write32, IER, 0x02)          # THREIE with THR empty: interrupt at once
    mcu.kernel.run_until(500 + 12 + math.ceil(45 * F115200))
    t1 = 500 + 12                                       # 12-cycle entry latency
    f = F115200
    # bytes 0-15 at t1 (0 to the TSR, 15 in the FIFO); the FIFO empties when byte 15 starts, at t1 +
    # 15 F, and had held >= 2 bytes: THRE at once; the ISR writes 16-31 then, and 32-39 (and turns
    # THREIE off, its buffer being empty) at t1 + 31 F
    assert entries == [(t1, 0xC2), (t1 + math.ceil(15 * f) + 12, 0xC2), (t1 + math.ceil(31 * f) + 12, 0xC2)]
    assert mcu.cpu.isr_count[IRQ] == 3 and not mcu.irq.lines[IRQ]
    assert [t for t, _ in u.tx_log] == [t1 + math.ceil(k * f) for k in range(1, 41)]
    assert [b for _, b in u.tx_log] == list(range(40))


def test_thre_interrupt_after_a_single_byte_waits_one_character_minus_the_stop_bit():
    mcu, _u = rig()
    lpcopen_init(mcu)
    lines = []
    mcu.irq.line_listeners.append(lambda n, level: lines.append((mcu.kernel.now, level)))
    mcu.write32(IER, 0x02)
    assert lines == [(0, True)] and mcu.read32(IIR) == 0xC2
    assert mcu.read32(IIR) == 0xC1 and lines[-1] == (0, False)   # the IIR read cleared THRE
    t0 = 1000
    mcu.kernel.at(t0, mcu.write32, THR, 0x55)           # one byte to an idle transmitter
    mcu.kernel.run_until(t0 + math.ceil(F115200))
    bit = Fraction(16 * 83 * 20, 15)
    assert lines[2:] == [(t0 + math.ceil(9 * bit), True)]        # start + 8 data + start bits
    assert mcu.read32(IIR) == 0xC2
    mcu.write32(THR, 0x56)                              # a THR write also clears it
    assert mcu.read32(IIR) == 0xC1


def test_rx_trigger_level_8_and_character_timeout_after_4_character_times():
    ep = BufferEndpoint()
    mcu, u = rig(endpoint=ep)
    lpcopen_init(mcu)
    mcu.write32(FCR, 0x81)                              # FIFO on, trigger level 2 = 8 characters
    mcu.write32(IER, 0x01)
    t0 = 2000
    mcu.kernel.at(t0, ep.feed, bytes(range(10, 18)))
    ends = [t0 + math.ceil(k * F115200) for k in range(1, 9)]
    mcu.kernel.run_until(ends[6])
    assert mcu.read32(LSR) & 1 and mcu.read32(IIR) == 0xC1      # 7 bytes < 8: no interrupt
    mcu.kernel.run_until(ends[7] - 1)
    assert mcu.read32(IIR) == 0xC1
    mcu.kernel.run_until(ends[7])
    assert [t for t, _ in u.rx_log] == ends
    assert mcu.read32(IIR) == 0xC4 and mcu.irq.lines[IRQ]      # RDA
    assert mcu.read32(RBR) == 10                                # level 7: RDA gone
    assert mcu.read32(IIR) == 0xC1 and not mcu.irq.lines[IRQ]
    cti = ends[7] + math.ceil(4 * F115200)                      # activity: the RBR read at ends[7]
    mcu.kernel.run_until(cti - 1)
    assert mcu.read32(IIR) == 0xC1
    mcu.kernel.run_until(cti)
    assert mcu.read32(IIR) == 0xCC and mcu.irq.lines[IRQ]      # CTI
    assert [mcu.read32(RBR) for _ in range(7)] == list(range(11, 18))
    assert mcu.read32(IIR) == 0xC1 and mcu.read32(LSR) & 1 == 0


def test_rx_bytes_fed_while_receiving_queue_behind_the_current_frame():
    ep = BufferEndpoint()
    mcu, u = rig(endpoint=ep)
    lpcopen_init(mcu)
    mcu.kernel.at(300, ep.feed, b"ab")
    mcu.kernel.at(300 + math.ceil(F115200) + 5000, ep.feed, b"c")   # during frame 2
    mcu.kernel.run_until(300 + math.ceil(3 * F115200))
    assert u.rx_log == [(300 + math.ceil(k * F115200), b) for k, b in zip((1, 2, 3), b"abc", strict=True)]
    mcu.kernel.at(mcu.kernel.now + 7, ep.feed, b"d")                   # idle line: starts now
    t = mcu.kernel.now + 7
    mcu.kernel.run_until(t + math.ceil(F115200))
    assert u.rx_log[-1] == (t + math.ceil(F115200), ord("d"))


def test_rx_overrun_when_the_fifo_is_full_sets_oe_until_lsr_is_read():
    ep = BufferEndpoint()
    mcu, u = rig(endpoint=ep)
    lpcopen_init(mcu)
    mcu.write32(FCR, 0xC1)                              # trigger 14
    mcu.write32(IER, 0x05)                              # RBRIE | RXIE
    ep.feed(bytes(range(17)))
    mcu.kernel.run_until(math.ceil(17 * F115200))
    assert u.rx_overruns == 1
    assert mcu.read32(IIR) == 0xC6                      # RLS, the highest priority
    assert mcu.read32(LSR) == 0x63                      # RDR | OE | THRE | TEMT
    assert mcu.read32(LSR) == 0x61                      # OE cleared by the read
    assert mcu.read32(IIR) == 0xC4                      # 16 >= 14: RDA
    assert [mcu.read32(RBR) for _ in range(16)] == list(range(16))   # byte 16 was lost
    assert mcu.read32(RBR) == 0 and mcu.read32(LSR) & 1 == 0


def test_rx_without_fifos_is_a_one_byte_buffer():
    ep = BufferEndpoint()
    mcu, u = rig(endpoint=ep)
    lpcopen_init(mcu)
    mcu.write32(FCR, 0)
    mcu.write32(IER, 0x01)
    ep.feed(b"xy")
    mcu.kernel.run_until(math.ceil(F115200))
    assert mcu.read32(IIR) == 0x04
    mcu.kernel.run_until(math.ceil(2 * F115200))
    assert u.rx_overruns == 1 and mcu.read32(RBR) == ord("x")


def test_signals_fire_after_frames_for_polling_drivers():
    ep = BufferEndpoint()
    mcu, u = rig(endpoint=ep)
    lpcopen_init(mcu)
    seen = []
    u.tx_done._wait(lambda: seen.append(("tx", mcu.kernel.now, mcu.read32(LSR) & 0x40)))
    u.rx_ready._wait(lambda: seen.append(("rx", mcu.kernel.now, mcu.read32(LSR) & 1)))
    mcu.write32(THR, 1)
    ep.feed(b"z")
    mcu.kernel.run_until(math.ceil(F115200))
    assert sorted(seen) == [("rx", math.ceil(F115200), 1), ("tx", math.ceil(F115200), 0x40)]


def test_feed_at_replays_injections_deterministically():
    logs = []
    for _ in range(2):
        ep = BufferEndpoint()
        mcu, u = rig(endpoint=ep)
        lpcopen_init(mcu)
        for tick, data in [(10, b"\xfd\x09"), (30_000, b"\x00\x01\x02")]:
            ep.feed_at(tick, data)
        mcu.kernel.run_until(200_000)
        logs.append(list(u.rx_log))
    assert logs[0] == logs[1] and [b for _, b in logs[0]] == [0xFD, 0x09, 0, 1, 2]


@pytest.mark.parametrize("setup, match", [
    ([(LCR, 0x83), (DLL, 0), (DLM, 0), (LCR, 0x03)], r"USART2\.DLL\.DLLSB = 0x0"),
    ([(FDR, 0x00)], r"USART2\.FDR\.MULVAL = 0x0"),
    ([(FDR, 0x55)], r"USART2\.FDR\.DIVADDVAL = 0x5"),
    ([(LCR, 0x83), (DLL, 2), (DLM, 0), (LCR, 0x03), (FDR, 0x21)], r"USART2\.DLL\.DLLSB = 0x2"),
])
def test_unusable_divisors_raise_when_a_frame_needs_them(setup, match):
    ep = BufferEndpoint()
    mcu, u = rig(endpoint=ep)
    for addr, v in setup:
        mcu.write32(addr, v)                            # accepted: the divisor is written in steps
    with pytest.raises(UnsupportedConfiguration, match=match):
        mcu.write32(THR, 0x41)
    assert mcu.read32(LSR) == 0x60 and u.tx_log == []   # the refused write changed nothing
    with pytest.raises(UnsupportedConfiguration, match=match):
        ep.feed(b"A")


@pytest.mark.parametrize("addr, value, match", [
    (LCR, 0x43, r"USART2\.LCR\.BC = 0x1"),
    (OSR, 0x80, r"USART2\.OSR\.OSINT = 0x8"),
    (ACR, 0x01, r"USART2\.ACR\.START = 0x1"),
    (ICR, 0x01, r"USART2\.ICR\.IRDAEN = 0x1"),
    (HDEN, 0x01, r"USART2\.HDEN\.HDEN = 0x1"),
    (SCICTRL, 0x01, r"USART2\.SCICTRL\.SCIEN = 0x1"),
    (RS485CTRL, 0x01, r"USART2\.RS485CTRL\.NMMEN = 0x1"),
    (SYNCCTRL, 0x01, r"USART2\.SYNCCTRL\.SYNC = 0x1"),
])
def test_unmodelled_modes_raise_at_the_write(addr, value, match):
    mcu, _u = rig()
    with pytest.raises(UnsupportedConfiguration, match=match):
        mcu.write32(addr, value)


@pytest.mark.parametrize("offset", [0x10, 0x18, 0x30, 0x34, 0x38, 0x3C, 0x44, 0x60, 0xFFC])
def test_unmapped_offsets_are_bus_faults(offset):
    mcu, _u = rig()
    with pytest.raises(BusFault):
        mcu.read32(BASE + offset)


def test_dlab_selects_the_divisor_latches_and_scr_is_storage():
    mcu, u = rig()
    mcu.write32(IER, 0x01)
    mcu.write32(LCR, 0x80)
    mcu.write32(DLL, 0x53)
    mcu.write32(DLM, 0x01)
    assert mcu.read32(DLL) == 0x53 and mcu.read32(DLM) == 0x01 and u.divisor == 0x153
    mcu.write32(LCR, 0x03)
    assert mcu.read32(IER) == 0x01
    mcu.write32(SCR, 0xA5)
    assert mcu.read32(SCR) == 0xA5


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a POSIX pty")
def test_pty_round_trip_with_pyserial():
    serial = pytest.importorskip("serial")
    ep = PtyEndpoint(poll="1ms")
    try:
        mcu, _u = rig(endpoint=ep)
        lpcopen_init(mcu)
        assert ep.poll == CORE_HZ // 1000
        with serial.Serial(ep.path, 115200, timeout=2) as ser:
            for b in b"hello\x00\xfd\r\n":             # binary-safe: raw mode on both ends
                mcu.write32(THR, b)
            mcu.kernel.run_until(mcu.kernel.now + CORE_HZ // 1000)
            assert ser.read(9) == b"hello\x00\xfd\r\n"
            ser.write(b"world\r\n\x03")
            ser.flush()
            got = bytearray()
            deadline = time.monotonic() + 5
            while len(got) < 8 and time.monotonic() < deadline:
                ep.wait_input(0.05)
                mcu.kernel.run_until(mcu.kernel.now + CORE_HZ // 1000)   # one poll + frames
                while mcu.read32(LSR) & 1:
                    got.append(mcu.read32(RBR))
            assert bytes(got) == b"world\r\n\x03"
            assert b"".join(d for _, d in ep.injected) == b"world\r\n\x03"
            assert all(t % ep.poll == 0 for t, _ in ep.injected)      # injected only at poll ticks
    finally:
        ep.close()
    assert ep.closed


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 17), ier=st.sampled_from([0, 0x02]), start=st.integers(0, 5000))
def test_a_mid_burst_frame_end_is_inert_up_to_the_frame_end_that_empties_the_fifo(n, ier, start):
    """The fast engine's served runs pass over a frame end that changes nothing outside the USART
    (``Usart.served_inert``): its bound must be the tick of the first later frame end that does
    (the one loading the FIFO's last byte: THRE), None for that one, and no bound (inf) after it.
    Checked against the frame ends as they run: before the bound nothing but ``tx_log`` and the
    FIFO moves (LSR's THRE and the interrupt id stay as they were; the last frame sets TEMT, a
    bit firmware reads at its own tick, after every frame end before it has run)."""
    mcu, u = rig()
    lpcopen_init(mcu)
    mcu.write32(IER, ier)
    mcu.kernel.run_until(start)
    for b in range(n):
        mcu.write32(THR, 0x41 + b)
    bound = None
    while u._tx_ev is not None:
        ev = u._tx_ev
        got = u.served_inert(ev)
        mcu.kernel.run_until(ev.time - 1)               # what comes before it (a delayed THRE)
        before = (mcu.read32(LSR) & 0x60, u.interrupt_id())
        mcu.kernel.run_until(ev.time)
        after = (mcu.read32(LSR) & 0x60, u.interrupt_id())
        if bound is not None and ev.time < bound:
            assert got == bound                         # the same bound all along the burst
        if got is None:
            assert ev.time == bound or bound is None    # the frame end that empties the FIFO
            assert not u._txq and u._tsr is not None and after[0] & 0x20
            bound = None
        elif got == math.inf:
            # the last frame: nothing follows, and only TEMT moves (read by firmware when it reads)
            assert u._tx_ev is None and before[1] == after[1] and after[0] == 0x60
        else:
            assert before == after and u._txq          # inert: THRE and the interrupt id unchanged
            bound = got
    assert len(u.tx_log) == n


def test_a_frame_end_is_not_inert_where_someone_sees_it():
    """A far end, a task waiting on ``tx_done`` or a byte in the RX FIFO (the character time-out
    depends on the tick) make every frame end an event of its own."""
    for case in ("endpoint", "waiter", "rx"):
        mcu, u = rig(endpoint=BufferEndpoint() if case == "endpoint" else None)
        lpcopen_init(mcu)
        if case == "waiter":
            u.tx_done._wait(lambda: None)
        if case == "rx":
            u.receive(b"x")
            mcu.kernel.run_until(mcu.kernel.now + math.ceil(2 * F115200))
            assert u._rxq
        for b in range(6):
            mcu.write32(THR, b)
        assert u.served_inert(u._tx_ev) is None, case


@pytest.mark.parametrize("engine", ["reference", "fast"])
def test_threie_enabled_during_the_initialization_delay_waits_for_it(engine):
    """UM10503's THRE rule: a byte written to an idle transmitter with the FIFO never holding two
    sets the THRE interrupt one character time minus the stop bit later. Enabling THREIE right
    after the write (the common order) must not raise the interrupt at once."""
    import mcusim
    sim = mcusim.load("ciaa-edu", firmware=False, engine=engine)
    m = sim.mcu
    sim.connect_serial("USART3", "buffer")
    edges = []
    m.nvic.line_listeners.append(lambda irq, lv: edges.append((sim.kernel.now, irq, lv)))
    u3 = 0x400C2000
    m.write32(u3 + 0x0C, 0x80)      # DLAB
    m.write32(u3 + 0x00, 10)        # DLL 10: 160 PCLK cycles a bit
    m.write32(u3 + 0x0C, 3)         # 8N1
    m.write32(u3 + 0x08, 7)         # FIFOs on, reset
    sim.run(cycles=10000)
    t0 = sim.kernel.now
    m.write32(u3 + 0x00, 0x41)
    m.write32(u3 + 0x04, 2)         # THREIE
    sim.run(cycles=3000)
    ticks = sim.timebase.base_hz // 204_000_000
    assert [(t - t0) // ticks for t, irq, lv in edges if irq == 27 and lv] == [9 * 160]
    sim.close()


def test_fcr_dmamode_is_accepted_and_changes_nothing_without_a_dma_controller():
    """UM10503 FCR.DMAMODE selects the UART DMA request mode only; a firmware that sets it without
    programming the GPDMA (none is modelled) runs on the chip as without it. It had been refused."""
    mcu, u = rig()
    lpcopen_init(mcu)
    mcu.write32(FCR, 0x09)               # FIFOEN | DMAMODE
    mcu.write32(THR, 0x41)
    mcu.kernel.run_until(mcu.kernel.now + 10**6)
    assert [b for _, b in u.tx_log] == [0x41]
