"""Bit-level I2C and UART waveforms in the VCD (mcusim.tracebus): the exact SCL/SDA edges of a
scripted transfer, and the VCD of ciaa-edu and elementall read back by sigrok-cli's ``i2c`` and
``uart`` decoders (skipped without sigrok-cli)."""

import itertools
import re
import shutil
import subprocess
from fractions import Fraction

import pytest

import mcusim
from mcusim.i2c import I2cBus, I2cMaster, MemorySlave
from mcusim.kernel import Kernel
from mcusim.time import TimeBase
from mcusim.tracebus import I2cWaveform, horizon_ticks

DOWNSAMPLE = 100_000            # sigrok: 100 ns samples (the VCD is in ps)
SAMPLE_HZ = 10**12 // DOWNSAMPLE


# --- a stand-in for VcdTrace and a small I2C decoder ------------------------------------------------

class EdgeLog:
    """Records what a bus tracer draws (the trace interface of mcusim.tracebus)."""

    def __init__(self, kernel):
        self.kernel, self.lag, self.init, self.changes = kernel, 0, {}, []
        self.too_old = []       # changes older than now - lag when drawn (must stay empty)

    def add_wire(self, scope, name, init=0):
        self.init[name] = init
        return name

    def request_lag(self, ticks):
        self.lag = max(self.lag, ticks)

    def change(self, var, tick, value):
        if tick < self.kernel.now - self.lag:
            self.too_old.append((tick, var, value))
        self.changes.append((tick, len(self.changes), var, value))

    def merged(self):
        """(tick, wire, level) in time order, equal ticks in the order drawn."""
        return [(t, v, x) for t, _, v, x in sorted(self.changes)]


def decode_i2c(events, scl_name, sda_name):
    """START/Sr/STOP and 9-bit bytes from (tick, wire, level) changes (both lines idle high).
    Returns [("start"|"restart"|"stop", tick)] and ("byte", value, ack, first rise, last fall)."""
    scl = sda = 1
    out, bits, rises, busy = [], [], [], False
    for t, wire, level in events:
        if wire == sda_name and level != sda:
            sda = level
            if scl:                          # SDA moving while SCL is high: a condition
                assert len(bits) <= 1, f"START/STOP inside a byte at {t}"   # Sr/STOP: the SCL rise
                bits, rises = [], []
                if level == 0:
                    out.append(("restart" if busy else "start", t))
                    busy = True
                else:
                    out.append(("stop", t))
                    busy = False
        elif wire == scl_name and level != scl:
            scl = level
            if level:
                bits.append(sda)
                rises.append(t)
            elif len(bits) == 9:
                value = int("".join(map(str, bits[:8])), 2)
                out.append(("byte", value, bits[8] == 0, rises[0], t))
                bits, rises = [], []
    return out


def expected_from_log(log, H, L):
    out = []
    for t, kind, value in log:
        if kind in ("start", "restart", "stop"):
            out.append((kind, t))
        else:
            out.append(("byte", value[0], value[1], t - 9 * H - 8 * L, t))
    return out


# --- (a) the edges of scripted transfers, exactly -------------------------------------------------------

@pytest.mark.parametrize("low,high,stretch", [(80, 80, 0), (7, 5, 0), (80, 80, 333)])
def test_i2c_edges_of_scripted_transfers_are_exact(low, high, stretch):
    k = Kernel(TimeBase([16_000_000]))
    bus = I2cBus(k, "i2c0")
    slave = MemorySlave(bus, 0x50, stretch_ticks=stretch)
    slave.mem[0x20:0x23] = b"\x5A\xC3\x01"
    master = I2cMaster(k, bus, scl_low_ticks=low, scl_high_ticks=high)
    bus.log = []                                          # a log set before: still filled
    edges = EdgeLog(k)
    wave = I2cWaveform(edges, bus, "board.i2c0", k.timebase.base_hz)
    assert edges.init == {"i2c0_SCL": 1, "i2c0_SDA": 1} and wave.names == ("i2c0_SCL", "i2c0_SDA")
    k.run_until(1000)
    w = master.write(0x50, b"\x20\xA5")                   # ACKed address and data
    nack = master.write(0x51, b"\x01")                    # nobody at 0x51: NACK, then STOP
    wr = master.write_read(0x50, b"\x20", 3)              # Sr, reads, the master NACKs the last
    k.run_until(10**6)
    assert w.ok and not nack.ok and wr.ok and wr.data == b"\xA5\xC3\x01"   # 0xA5 written at 0x20
    H, L = high, low
    assert edges.lag >= max(horizon_ticks(16_000_000), 9 * (H + L) + L) and edges.too_old == []

    got = decode_i2c(edges.merged(), "i2c0_SCL", "i2c0_SDA")
    assert got == expected_from_log(bus.log, H, L)
    assert [g[0] for g in got] == (["start", "byte", "byte", "byte", "stop", "start", "byte", "stop", "start"]
                                   + ["byte"] * 2 + ["restart"] + ["byte"] * 4 + ["stop"])
    # START at the transfer's t_start with SCL falling H later; STOP at t_stop
    for tr in (w, nack, wr):
        assert ("start", tr.t_start) in got and ("stop", tr.t_stop) in got
        assert (tr.t_start + H, "i2c0_SCL", 0) in edges.merged()
    # every byte: 9 SCL pulses of H from r = e - 9H - 8L, H + L apart, the last fall at e
    for tr in (w, nack, wr):
        for e, _kind, byte, ack in tr.byte_ends:
            r = e - 9 * H - 8 * L
            assert ("byte", byte, ack, r, e) in got
            scl = [(t, x) for t, v, x in edges.merged() if v == "i2c0_SCL" and r <= t <= e]
            assert scl == [(r + n * (H + L) + h, 1 - h // H) for n in range(9) for h in (0, H)]
            # SDA carries the bit from mid-low before each rise (MSB first, then the ACK bit)
            sda = [(t, x) for t, v, x in edges.merged() if v == "i2c0_SDA" and r - L // 2 - 1 < t <= e]
            bits = [(byte >> (7 - n)) & 1 for n in range(8)] + [0 if ack else 1]
            assert sda == [(r + n * (H + L) - max(1, L // 2), bits[n]) for n in range(9)]
    # the NACKed address byte has SDA high on its 9th clock, an ACKed one low
    addr_nack = next(b for b in got if b[0] == "byte" and b[1] == 0x51 << 1)
    assert addr_nack[2] is False
    # the repeated START: SDA high during the low phase, SCL up at Sr - H, SDA down at Sr
    sr = next(t for t, kind, _ in bus.log if kind == "restart")
    around = [(t, v, x) for t, v, x in edges.merged() if sr - H - L < t <= sr + H]
    assert around == [(sr - H - max(1, L // 2), "i2c0_SDA", 1), (sr - H, "i2c0_SCL", 1),
                      (sr, "i2c0_SDA", 0), (sr + H, "i2c0_SCL", 0)]
    # clock stretching only lengthens the low phase before a byte
    if stretch:
        gaps = [b[3] - prev[4] for prev, b in itertools.pairwise(got) if prev[0] == "byte" and b[0] == "byte"]
        assert max(gaps) == stretch and min(gaps) == L


# --- VCD helpers ---------------------------------------------------------------------------------------

def vcd_changes(path):
    """{variable name: [(ps, level)]} of the 1-bit wires, checking timestamps never go back."""
    from vcd.reader import TokenKind, tokenize
    names, out, t = {}, {}, 0
    with open(path, "rb") as f:
        for tok in tokenize(f):
            if tok.kind is TokenKind.VAR:
                names[tok.var.id_code] = tok.var.reference
                out.setdefault(tok.var.reference, [])
            elif tok.kind is TokenKind.CHANGE_TIME:
                assert tok.time_change >= t
                t = tok.time_change
            elif tok.kind is TokenKind.CHANGE_SCALAR:
                out[names[tok.scalar_change.id_code]].append((t, int(tok.scalar_change.value)))
    return out


def traced(board, seconds, tmp_path, **load_kw):
    sim = mcusim.load(board, **load_kw)
    bus = sim.mcu.periph["I2C0"].bus
    bus.log = []
    path = tmp_path / f"{board}.vcd"
    tr = sim.trace_vcd(path)
    sim.run(seconds=seconds)
    sim.close()
    assert tr.late_edges == 0
    return sim, tr, bus, path


def sigrok(path, *args):
    if shutil.which("sigrok-cli") is None:
        pytest.skip("sigrok-cli is not installed")
    return subprocess.run(["sigrok-cli", "-I", f"vcd:downsample={DOWNSAMPLE}", "-i", str(path), *args,
                           "--protocol-decoder-samplenum"],
                          capture_output=True, text=True, timeout=60, check=True).stdout


def annotations(out, decoder):
    return [(int(a), int(b), text) for a, b, text in
            re.findall(rf"^(\d+)-(\d+) {decoder}-1: (.*)$", out, re.MULTILINE)]


def sample(tick, base_hz):
    ps = (tick * 2 * 10**12 + base_hz) // (2 * base_hz)     # VcdTrace's rounding to ps
    return ps // DOWNSAMPLE


def sigrok_i2c(path):
    """The decoder's conditions, address and data bytes and ACK bits (not the R/W bit's own
    "Read"/"Write", which the address classes also carry)."""
    ann = annotations(sigrok(path, "-P", "i2c:scl=i2c0_SCL:sda=i2c0_SDA", "-A",
                             "i2c=start:repeat-start:stop:ack:nack:address-read:address-write:"
                             "data-read:data-write"), "i2c")
    return [a for a in ann if a[2] not in ("Read", "Write")]


def expected_i2c_annotations(log, H, L, base_hz):
    """What sigrok's i2c decoder reports for each bus.log entry, with its start sample."""
    out = []
    for t, kind, value in log:
        if kind in ("start", "restart", "stop"):
            out.append((sample(t, base_hz), {"start": "Start", "restart": "Start repeat", "stop": "Stop"}[kind]))
            continue
        byte, ack = value
        r = t - 9 * H - 8 * L
        if kind == "addr":
            text = f"Address {'read' if byte & 1 else 'write'}: {byte >> 1:02X}"
        else:
            text = f"Data {kind}: {byte:02X}"
        out.append((sample(r, base_hz), text))
        out.append((sample(r + 8 * (H + L), base_hz), "ACK" if ack else "NACK"))
    return out


# --- (b) I2C: ciaa-edu probing absent modules, elementall talking to them ---------------------------------

def test_vcd_of_ciaa_edu_has_exact_bus_waveforms(tmp_path):
    """Without sigrok: the VCD is in time order and its SCL/SDA/TXD decode to bus.log and tx_log."""
    sim, tr, bus, path = traced("ciaa-edu", 0.25, tmp_path)
    hz = sim.timebase.base_hz
    i2c = sim.mcu.periph["I2C0"]
    H, L = i2c.scl_high_ticks, i2c.scl_low_ticks
    assert (H, L) == (1020, 1020)                   # 100 kHz at 204 MHz
    assert tr.lag == max(horizon_ticks(hz), 9 * (H + L) + L)
    waves = vcd_changes(path)
    events = sorted([(round(ps * hz / 10**12), n, lv) for n in ("i2c0_SCL", "i2c0_SDA")
                     for ps, lv in waves[n][1:]], key=lambda e: e[0])   # [0]: the $dumpvars value
    assert waves["i2c0_SCL"][0] == (0, 1) and waves["i2c0_SDA"][0] == (0, 1)
    got = decode_i2c(events, "i2c0_SCL", "i2c0_SDA")
    assert got == expected_from_log(bus.log, H, L) and len(got) >= 15
    assert {b[1:3] for b in got if b[0] == "byte"} == {(0x10, False), (0x12, False), (0x14, False),
                                                       (0x16, False)}      # 0x08..0x0B, nobody answers
    # TXD: every frame of USART2 from its exact edges (8N1: start, 8 data LSB first, stop)
    u = sim.mcu.periph["USART2"]
    frame, bit, _ = u.frame_format()
    assert u.value["LCR"] & 0x3F == 3 and u.clock.period == 1 and hz / bit == Fraction(9_562_500, 83)
    txd = [(Fraction(ps * hz, 10**12), lv) for ps, lv in waves["USART2_TXD"]]

    def level(t):
        return next(lv for tt, lv in reversed(txd) if tt <= t)
    for e, byte in u.tx_log:
        s = e - frame                                # frame start, to within one PCLK cycle
        levels = [level(s + (n + Fraction(1, 2)) * bit) for n in range(10)]
        assert levels == [0] + [(byte >> n) & 1 for n in range(8)] + [1]
        start_edge = max(tt for tt, lv in txd if lv == 0 and tt <= s + bit / 2)
        assert abs(start_edge - s) < 1.001 or s < 1  # the first frame starts at tick 0 (no edge)
    assert bytes(b for _, b in u.tx_log).startswith(b"rover_control: layout skid_steer")


def test_running_in_steps_gives_the_same_waveforms(tmp_path):
    """flush() after every run() writes only what is older than now - lag: bytes that straddle a
    step are drawn as in one long run (the VCD differs only by the flush timestamps)."""
    _, _, _, one = traced("ciaa-edu", 0.25, tmp_path)
    sim = mcusim.load("ciaa-edu")
    tr = sim.trace_vcd(tmp_path / "steps.vcd")
    for _ in range(250):
        sim.run(seconds="1ms")         # shorter than the 2 ms lag
    sim.close()
    assert tr.late_edges == 0 and tr.lag > sim.timebase.ticks("1ms")
    assert vcd_changes(tmp_path / "steps.vcd") == vcd_changes(one)


def test_sigrok_i2c_decoder_reads_the_nacked_probes_of_ciaa_edu(tmp_path):
    sim, _tr, bus, path = traced("ciaa-edu", 0.25, tmp_path)   # 3 tries at each of 0x08..0x0B
    i2c = sim.mcu.periph["I2C0"]
    ann = sigrok_i2c(path)
    got = [(ss, text) for ss, _es, text in ann]
    want = expected_i2c_annotations(bus.log, i2c.scl_high_ticks, i2c.scl_low_ticks, sim.timebase.base_hz)
    assert [text for _, text in got] == [text for _, text in want]
    assert all(abs(a - b) <= 1 for (a, _), (b, _) in zip(got, want))
    assert [text for _, text in got[:4]] == ["Start", "Address write: 08", "NACK", "Stop"]
    assert {text for _, text in got if text.startswith("Address")} == {f"Address write: {a:02X}"
                                                                       for a in (8, 9, 10, 11)}


def test_sigrok_i2c_decoder_reads_who_am_i_of_the_motor_modules(tmp_path):
    sim, _tr, bus, path = traced("elementall", 0.13, tmp_path, overrides={"cmd_vel.linear": 0})
    i2c = sim.mcu.periph["I2C0"]
    ann = sigrok_i2c(path)
    got = [(ss, text) for ss, _es, text in ann]
    want = expected_i2c_annotations(bus.log, i2c.scl_high_ticks, i2c.scl_low_ticks, sim.timebase.base_hz)
    assert [text for _, text in got] == [text for _, text in want] and len(got) > 100
    assert all(abs(a - b) <= 1 for (a, _), (b, _) in zip(got, want))
    # the WHO_AM_I read of the module at 0x08: register 0 written, Sr, 0x4D read and NACKed
    assert [text for _, text in got[:12]] == [
        "Start", "Address write: 08", "ACK", "Data write: 00", "ACK", "Start repeat",
        "Address read: 08", "ACK", "Data read: 4D", "NACK", "Stop", "Start"]
    who = [got[i + 2][1] for i in range(len(got) - 2)
           if got[i][1].startswith("Address read") and got[i + 1][1] == "ACK"]
    assert who[:4] == ["Data read: 4D"] * 4


# --- (c) UART: the console of ciaa-edu --------------------------------------------------------------------

def test_sigrok_uart_decoder_reads_the_console_of_ciaa_edu(tmp_path):
    """USART2 at 115210.8 Bd (204 MHz / (16 * 83 * (1 + 1/3)), LPCOpen's DLL = 83, FDR 1/3) read by
    the decoder at 115200 Bd: every byte of the console, from the first (written 1 ms after reset,
    after an idle line), at the sample where its data bits begin."""
    sim, _tr, _bus, path = traced("ciaa-edu", 0.25, tmp_path)
    hz = sim.timebase.base_hz
    u = sim.mcu.periph["USART2"]
    frame, bit, _ = u.frame_format()
    assert u.clock.period == 1 and float(hz / bit) == pytest.approx(115210.84, abs=0.01)
    out = sigrok(path, "-P", "uart:tx=USART2_TXD:baudrate=115200", "-A", "uart=tx-data")
    ann = [(ss, int(text, 16)) for ss, _es, text in annotations(out, "uart")]
    assert [b for _, b in ann] == [b for _, b in u.tx_log]
    # each frame's data bits begin within one decoder sample drift of the model's
    starts = [round((e - frame + bit) * SAMPLE_HZ / hz) for e, _ in u.tx_log]
    assert all(abs(ss - s0) <= 2 for (ss, _), s0 in zip(ann, starts))
    lines = bytes(b for _, b in u.tx_log).split(b"\r\n")
    assert lines[0] == b"rover_control: layout skid_steer, 4 motor modules on I2C0"
    assert lines[1] == b"rover_control: motors disabled: no answer from 0x08 0x09 0x0a 0x0b"


# --- GTKWave -------------------------------------------------------------------------------------------

def test_gtkw_shows_the_bus_wires(tmp_path):
    sim = mcusim.load("ciaa-edu", firmware=False)
    tr = sim.trace_vcd(tmp_path / "c.vcd")
    sim.run(seconds="1ms")
    sim.close()
    with open(tr.write_gtkw()) as f:
        lines = f.read().splitlines()
    groups = [lines[i + 1][1:] for i, x in enumerate(lines) if x == "@800200"]
    assert groups == ["ciaa-edu", "ciaa-edu.i2c0", "interrupts"]      # no plant on the bench
    for name in ("ciaa-edu.USART2_TXD", "ciaa-edu.USART3_TXD", "ciaa-edu.i2c0.i2c0_SCL",
                 "ciaa-edu.i2c0.i2c0_SDA"):
        assert name in lines
    i = lines.index("-ciaa-edu.i2c0")
    assert lines[i + 1:i + 4] == ["@28", "ciaa-edu.i2c0.i2c0_SCL", "ciaa-edu.i2c0.i2c0_SDA"]
