"""Cross-check against simavr where simavr is right (reference sheet §5): Timer1 CTC.

simavr runs events at instruction boundaries, so its edges are late by up to one instruction;
the model's are exact. The check is therefore: same period, and simavr never earlier and at most
one instruction later.

Runs only when avr-gcc and simavr (with its avr_mcu_section.h) are installed (`.ci/run` installs
Debian's packages when it can). The same register sequence runs in simavr and in our model; the
comparison uses times relative to the TCCR1B write that starts the timer, so instruction timing
before it does not matter. Debian ships simavr 1.6, which predates the Timer1 mode-14 fix
(c744120, issue #579); for the plain ICR1-as-TOP waveform below it is already right.
"""

import shutil
import subprocess
from pathlib import Path

import pytest

import mcusim

HEADERS = Path("/usr/include/simavr/avr")
pytestmark = pytest.mark.skipif(
    not (shutil.which("avr-gcc") and shutil.which("simavr") and (HEADERS / "avr_mcu_section.h").exists()),
    reason="avr-gcc and simavr are not installed")


def _run_simavr(tmp_path, name):
    src = Path(__file__).parent / "simavr" / f"{name}.c"
    elf = tmp_path / f"{name}.elf"
    subprocess.run(["avr-gcc", "-mmcu=atmega328p", "-Os", f"-I{HEADERS}", "-o", str(elf), str(src)], check=True)
    # simavr exits non-zero when the firmware sleeps with interrupts off, which is how it ends
    subprocess.run(["simavr", str(elf)], cwd=tmp_path, capture_output=True, timeout=60, check=False)
    return _vcd_changes(tmp_path / f"{name}.vcd")


def _cycles_of(scale):
    # simavr writes floor(cycle · 62.5 ns / unit); with units shorter than a cycle the exact inverse
    # is the ceiling (rounding would give ±1-cycle jitter)
    per_unit = round(scale * 1e12) * 16  # cycles per unit, times 1e6: 10 ns -> 160000
    return lambda units: -(-units * per_unit // 1_000_000)


def _level_changes(changes, name):
    """(time, level) of the real level changes of a 1-bit signal (simavr repeats values)."""
    out, prev = [], None
    for t, v in changes[name]:
        if v in "01" and v != prev:
            if prev is not None:
                out.append((t, v))
            prev = v
    return out


def _vcd_changes(path):
    """{signal: [(time_units, value)]} and the timescale in seconds from a small VCD."""
    ids, changes, t, scale = {}, {}, 0, None
    for line in Path(path).read_text().splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "$timescale":
            num = "".join(c for c in parts[1] if c.isdigit())
            unit = parts[1][len(num):] or parts[2]
            scale = int(num) * {"s": 1, "ms": 1e-3, "us": 1e-6, "ns": 1e-9, "ps": 1e-12}[unit]
        elif parts[0] == "$var":
            ids[parts[3]] = parts[4]
            changes[parts[4]] = []
        elif line[0] == "#":
            t = int(line[1:])
        elif line[0] in "01xz" and line[1:] in ids:
            changes[ids[line[1:]]].append((t, line[0]))
        elif line[0] == "b" and len(parts) == 2 and parts[1] in ids:
            changes[ids[parts[1]]].append((t, parts[0][1:]))
    return changes, scale


def test_timer1_ctc_toggle_times_match_simavr(tmp_path):
    changes, scale = _run_simavr(tmp_path, "ctc")
    cycles = _cycles_of(scale)
    start = cycles(next(t for t, v in changes["TCCR1B"] if v.isdigit() and int(v, 2) & 1))
    sim_toggles = [cycles(t) - start for t, _ in _level_changes(changes, "OC1A")]
    sim_toggles = sim_toggles[:8]

    sim = mcusim.load("pro-mini", firmware=False)
    m = sim.mcu
    m.write8(0x24, 1 << 1)        # DDRB
    m.write8(0x89, 0)             # OCR1AH (TEMP), then OCR1AL
    m.write8(0x88, 99)
    m.write8(0x80, 1 << 6)        # TCCR1A: COM1A0
    t0 = sim.cycles
    m.write8(0x81, (1 << 3) | 1)  # TCCR1B: WGM12 | CS10
    ours = []
    sim.pin("PB1").listen(lambda n: ours.append(sim.cycles - t0))
    sim.run(cycles=1000)
    assert len(sim_toggles) == 8, "simavr produced no OC1A edges"
    # our toggles: exactly every OCR1A + 1 = 100 clocks from the timer start
    assert ours[:8] == [100 * k for k in range(1, 9)]
    # simavr delivers a timer event after the instruction that crosses its cycle (reference sheet
    # §5), so its edges land on instruction boundaries: never early, at most one instruction of the
    # wait loop (<= 2 cycles) late
    assert all(0 <= s_ - o <= 2 for s_, o in zip(sim_toggles, ours)), (sim_toggles, ours[:8])


def test_int0_flag_is_set_in_the_cycle_of_the_pin_edge_as_in_simavr(tmp_path):
    """INT0 on rising edges of PD2 driven by the firmware's own PORTD stores.

    simavr: INT0 becomes pending at the same instant as the store that raises PD2, and is taken
    within about one instruction (its 'pending' trace falls when the vector is accepted). simavr 1.6
    also raises one INT0 at start-up, before any store (the pin goes from undefined to 0 when DDRD
    is written); that one is not compared. The model: INTF0 is set at the store's tick (the edge
    detector runs on the 16 MHz clock, whose edges are every base tick) and the handler runs 4
    cycles later; each of the four edges is served once."""
    changes, _ = _run_simavr(tmp_path, "int0")
    stores, prev = [], None
    for t, v in changes["PORTD"]:  # real changes only: simavr repeats each value one unit later
        if v.isdigit() and v != prev:
            if int(v, 2) & 4:
                stores.append(t)
            prev = v
    pend = [t for t, v in changes["INT0_pend"] if v == "1"]
    assert len(stores) >= 4
    for t in stores[:4]:
        assert t in pend, f"simavr: no INT0 pending at the PD2 store at {t}"

    sim = mcusim.load("pro-mini", firmware=False)
    sim.pin("PD2").set("encoder", None)  # unplug the encoder output (motor at rest): PD2 is the MCU's
    m = sim.mcu
    entries = []
    m.cpu.vector(1, lambda: entries.append(sim.cycles), cost=20)
    m.write8(0x2A, 1 << 2)          # DDRD
    m.write8(0x69, 0b11)            # EICRA: rising
    m.write8(0x3D, 1)               # EIMSK
    m.write8(0x2B, 1 << 2)          # with I = 0: INTF0 is set in the cycle of the edge
    assert m.read8(0x3C) & 1
    m.write8(0x3C, 1)               # clear it (write 1)
    m.write8(0x2B, 0)
    m.irq.set_i(True)
    stores_ours = []
    for _ in range(4):
        m.write8(0x2B, 1 << 2)      # PORTD: rising edge on PD2
        stores_ours.append(sim.cycles)
        sim.run(cycles=200)
        m.write8(0x2B, 0)
        sim.run(cycles=200)
    # accepted at once (INTF0 cleared by the acceptance), handler 4 cycles later, once per edge
    assert entries == [t + 4 for t in stores_ours]


def test_timer1_mode14_waveform_matches_simavr_from_the_first_bottom(tmp_path):
    """Fast PWM, TOP = ICR1 = 799, OCR1A = 200, COM1A = 10: period 800, high OCR+1 = 201 clocks
    (reference sheet §7 #9, measured on simavr HEAD). simavr 1.6 agrees edge for edge from the
    first TOP -> BOTTOM wrap on. In the first period it also sets OC1A at the timer start, where
    no wrap to BOTTOM has happened; the model follows the datasheet's "set at BOTTOM" and keeps
    the pin low until the first wrap [unverified on silicon; not compared]."""
    changes, scale = _run_simavr(tmp_path, "mode14")
    cycles = _cycles_of(scale)
    start = cycles(next(t for t, v in changes["TCCR1B"] if v.isdigit() and int(v, 2) & 1))
    sim_edges = [(cycles(t) - start, int(v)) for t, v in _level_changes(changes, "OC1A")]
    sim_edges = [e for e in sim_edges if e[0] >= 800][:6]

    sim = mcusim.load("pro-mini", firmware=False)
    m = sim.mcu
    m.write8(0x24, 1 << 1)                               # DDRB1
    m.write8(0x87, 799 >> 8)                             # ICR1H (TEMP), ICR1L
    m.write8(0x86, 799 & 0xFF)
    m.write8(0x89, 0)                                    # OCR1A = 200
    m.write8(0x88, 200)
    m.write8(0x80, (1 << 7) | (1 << 1))                  # COM1A1 | WGM11
    t0 = sim.cycles
    ours = []
    sim.pin("PB1").listen(lambda n: ours.append((sim.cycles - t0, n.level)))
    m.write8(0x81, (1 << 4) | (1 << 3) | 1)              # WGM13 | WGM12 | CS10
    sim.run(cycles=4000)
    assert ours[:6] == [(800, 1), (1001, 0), (1600, 1), (1801, 0), (2400, 1), (2601, 0)]
    assert len(sim_edges) == 6
    assert all(lv == lo and 0 <= ts - to <= 2 for (ts, lv), (to, lo) in zip(sim_edges, ours))
