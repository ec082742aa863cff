"""SysTick rules from the Armv7-M ARM (B3.3) that the runtime tests in test_nvic_cpu.py do not pin.

The rig's processor clock is one base tick per cycle; its reference clock runs at 27 MHz, one
cycle every 8 base ticks (a clock's edges are at multiples of its period, mcusim.time.Clock).
"""

from cortexm_rig import rig

S = 0xE000E010                     # SYST_CSR; RVR +4, CVR +8, CALIB +0xC
ENABLE, CLKSOURCE = 1, 4


def _val_at(m, ticks):
    out = []
    for t in ticks:
        m.kernel.run_until(t)
        out.append(m.read32(S + 8))
    return out


def test_systick_clksource_change_while_running_counts_only_the_processor_clocks_after_it():
    # B3.3.3: the counter decrements once per clock of the source CLKSOURCE selects. Switching
    # from the reference clock to the processor clock must not count processor clocks that
    # elapsed before the switch.
    m = rig()
    m.write32(S + 4, 99)
    m.write32(S + 8, 0)
    m.write32(S, ENABLE)           # reference clock: the edge at tick 8 loads RELOAD
    m.kernel.run_until(13)
    assert m.read32(S + 8) == 99
    m.write32(S, ENABLE | CLKSOURCE)
    assert m.read32(S + 8) == 99   # the write itself does not decrement
    assert _val_at(m, (14, 15, 20)) == [98, 97, 92]


def test_systick_clksource_change_while_running_counts_on_the_reference_clocks_edges():
    m = rig()
    m.write32(S + 4, 99)
    m.write32(S + 8, 0)
    m.write32(S, ENABLE | CLKSOURCE)   # processor clock: tick 1 loads 99, tick 13 reads 87
    m.kernel.run_until(13)
    assert m.read32(S + 8) == 87
    m.write32(S, ENABLE)               # to the reference clock: its next edges are 16, 24, 32
    assert _val_at(m, (15, 16, 23, 24, 32)) == [87, 86, 86, 85, 84]
