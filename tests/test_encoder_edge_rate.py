"""The PJRC Encoder on INT0/INT1 of the simulated ATmega328P: the ISR-bound edge-rate limit.

Each edge costs 4 cycles of interrupt response plus the library's measured 148-cycle ISR
(reference sheet §3), 152 cycles in all: about 105 k edges/s at 16 MHz. Below that every edge is
served (two edges between reads are still right, through the table's ±2 rows); above it, edges
pile up, a flag that is already pending absorbs the next edge on its pin, and counts are lost.
"""

from mcusim.fw.arduino.core import ArduinoCore
from mcusim.fw.arduino.encoder import Encoder

import mcusim

QUAD = [(0, 0), (0, 1), (1, 1), (1, 0)]  # (pin1, pin2): pin2 leading counts positive (§3)


def run_quadrature(edges_per_s: int, n_edges: int = 4000):
    sim = mcusim.load("pro-mini", firmware=False)
    core = ArduinoCore(sim.mcu)
    core.init()
    enc = Encoder(core, 2, 3)
    for n in (0, 1):
        core.set_isr_cycles(n, Encoder.ISR_CYCLES)
    d2, d3 = sim.pin("PD2"), sim.pin("PD3")
    d2.drive(0)
    d3.drive(0)
    sim.run(cycles=1000)
    enc.write(0)
    spacing = 16_000_000 // edges_per_s
    t0 = sim.now + 100
    for k in range(1, n_edges + 1):
        a, b = QUAD[k % 4]
        sim.kernel.at(t0 + k * spacing, (d2.drive if a != QUAD[(k - 1) % 4][0] else d3.drive), a if a != QUAD[(k - 1) % 4][0] else b)
    sim.run(cycles=(n_edges + 10) * spacing + 1000)
    return enc.read()


def test_counts_exact_at_60k_edges_per_second():
    assert run_quadrature(60_000) == 4000


def test_counts_exact_just_below_isr_capacity():
    assert run_quadrature(100_000) == 4000  # 160 cycles per edge > 152


def test_counts_lost_above_isr_capacity():
    assert run_quadrature(130_000) != 4000  # 123 cycles per edge < 152
