"""ATmega328P ports, INT0/INT1 and the AVR interrupt model (fixed priority, I flag, lost edges)."""

import pytest
from avr_rig import bare_atmega328p
from mcusim.periph.avr.extint import ExtInt
from mcusim.periph.avr.port import AvrPort

from mcusim.signals import Port

PINB, DDRB, PORTB, PIND, DDRD, PORTD = 0x23, 0x24, 0x25, 0x29, 0x2A, 0x2B
EIFR, EIMSK, EICRA, SREG = 0x3C, 0x3D, 0x69, 0x5F


@pytest.fixture
def m():
    mcu = bare_atmega328p(cpu=True)
    bus, clock = mcu.bus, mcu.core_clock
    for name, base in (("PORTB", 0x23), ("PORTC", 0x26), ("PORTD", 0x29)):
        p = AvrPort(name, mcu, name[-1])
        mcu.periph[name] = p
        bus.attach_registers(base, p)
    mcu.periph["EXINT"] = ExtInt("EXINT", mcu, clock)
    bus.attach_registers(0, mcu.periph["EXINT"])
    return mcu


def test_output_pin_follows_port_and_pin_write_toggles(m):
    m.write8(DDRB, 0b10)
    m.write8(PORTB, 0b10)
    assert m.pin("PB1").level == 1 and m.read8(PINB) & 0b10
    m.write8(PINB, 0b10)                     # writing 1 to PINxn toggles PORTxn
    assert m.pin("PB1").level == 0 and m.read8(PORTB) == 0


def test_input_pull_up_and_external_drive(m):
    m.write8(PORTD, 1 << 2)                  # DDRD2 = 0, PORTD2 = 1: pull-up
    assert m.read8(PIND) >> 2 & 1 == 1
    m.pin("PD2").drive(0)
    assert m.read8(PIND) >> 2 & 1 == 0


def test_alternate_function_drives_pin_only_when_ddr_is_output(m):
    oc = Port("OC1A")
    m.periph["PORTB"].connect_override(1, oc)
    oc.set(1)
    m.write8(PORTB, 0)
    assert m.pin("PB1").level == 0           # DDRB1 = 0: not an output, OC1A does not reach it
    m.write8(DDRB, 0b10)
    assert m.pin("PB1").level == 1
    oc.set(0)
    assert m.pin("PB1").level == 0
    oc.set(None)                             # COM1A = 00: the port bit drives again
    m.write8(PORTB, 0b10)
    assert m.pin("PB1").level == 1


def test_int0_rising_edge_enters_vector_1_four_cycles_later_and_clears_intf0(m):
    seen = []
    m.cpu.vector(1, lambda: seen.append((m.kernel.now, m.read8(EIFR), m.read8(SREG) >> 7)), cost=100)
    m.irq.set_i(True)
    m.write8(EICRA, 0b11)                    # ISC01:00 = 11 rising edge
    m.write8(EIMSK, 1)
    m.kernel.at(1000, m.pin("PD2").drive, 1)
    m.kernel.run_until(5000)
    # one CPU cycle is one base tick at 16 MHz; the flag is cleared and I is 0 inside the handler
    assert seen == [(1004, 0, 0)]
    assert m.read8(SREG) >> 7 == 1            # RETI set I again


def test_lower_vector_number_wins_and_no_nesting_while_i_is_clear(m):
    order = []
    m.cpu.vector(1, lambda: order.append(("INT0", m.kernel.now)), cost=50)
    m.cpu.vector(2, lambda: order.append(("INT1", m.kernel.now)), cost=50)
    m.irq.set_i(True)
    m.write8(EICRA, 0b0101)                  # any change on both
    m.write8(EIMSK, 0b11)
    m.kernel.at(100, m.pin("PD3").drive, 1)  # INT1 first
    m.kernel.at(110, m.pin("PD2").drive, 1)  # INT0 arrives while INT1's handler runs: waits
    m.kernel.run_until(1000)
    assert order == [("INT1", 104), ("INT0", 104 + 50 + 4)]


def test_int1_and_int0_at_one_tick_enter_int0_first_whichever_edge_came_first(m):
    """ATmega328P datasheet, Reset and Interrupt Handling: the lower the vector address, the higher the priority;
    INT1's and INT0's edges at the same tick, INT1's event first: INT0 is taken first."""
    order = []
    m.cpu.vector(1, lambda: order.append(("INT0", m.kernel.now)), cost=50)
    m.cpu.vector(2, lambda: order.append(("INT1", m.kernel.now)), cost=50)
    m.irq.set_i(True)
    m.write8(EICRA, 0b0101)
    m.write8(EIMSK, 0b11)
    m.kernel.at(100, m.pin("PD3").drive, 1)
    m.kernel.at(100, m.pin("PD2").drive, 1)
    m.kernel.run_until(1000)
    assert order == [("INT0", 104), ("INT1", 104 + 50 + 4)]


def test_edge_arriving_while_flag_pending_is_lost(m):
    hits = []
    m.cpu.vector(1, lambda: hits.append(m.kernel.now), cost=200)
    m.irq.set_i(True)
    m.write8(EICRA, 0b01)                    # any change
    m.write8(EIMSK, 1)
    pin = m.pin("PD2")
    for t, lv in ((100, 1), (150, 0), (180, 1), (190, 0)):  # 4 edges; handler busy 104..304
        m.kernel.at(t, pin.drive, lv)
    m.kernel.run_until(2000)
    # edge 1 enters at 104 (flag cleared); edges 2-4 during the handler: the flag holds one of them
    assert len(hits) == 2
    assert m.periph["EXINT"].edges_lost[0] == 2


# (an edge at the entry tick itself is taken before it: inputs settle before the core acts)
@pytest.mark.parametrize("second, runs", [(102, 1), (103, 1), (104, 1), (105, 2), (110, 2)])
def test_an_edge_during_the_four_cycle_response_is_lost_as_intf0_clears_only_at_the_vector(m, second, runs):
    """ATmega328P datasheet: INTF0 'is cleared when the interrupt routine is executed', after 'four
    clock cycles minimum' of response. An edge of the same pin inside those cycles finds the flag
    still set and is lost; one at or after the vector (entry at 104) sets it again and runs the
    handler a second time. The flag had been cleared when the request was accepted (at 100)."""
    hits = []
    m.cpu.vector(1, lambda: hits.append(m.kernel.now), cost=20)
    m.irq.set_i(True)
    m.write8(EICRA, 0b01)                    # any change
    m.write8(EIMSK, 1)
    pin = m.pin("PD2")
    m.kernel.at(100, pin.drive, 1)
    m.kernel.at(second, pin.drive, 0)
    seen = []
    m.irq.line_listeners.append(lambda v, lv: v == 1 and seen.append((m.kernel.now, lv)))
    m.kernel.run_until(1000)
    assert len(hits) == runs and hits[0] == 104
    assert seen[:2] == [(100, True), (104, False)]    # the request line: high through the response


def test_intf_is_always_cleared_when_int_is_configured_as_level_interrupt(m):
    # datasheet §13.2.3 EIFR: "This flag is always cleared when INT0 is configured as a level
    # interrupt." A flag set by an edge while INT0 was masked does not survive the switch to level
    # mode, and an edge whose flag would be set on the next clock after the switch sets none.
    m.write8(EICRA, 0b01)                    # any change, INT0 masked: the flag just collects
    m.pin("PD2").drive(1)
    m.kernel.run_until(10)
    assert m.read8(EIFR) & 1
    m.write8(EICRA, 0b00)                    # low level
    assert m.read8(EIFR) & 1 == 0
    m.pin("PD2").drive(0)
    m.kernel.run_until(20)
    assert m.read8(EIFR) & 1 == 0
    m.write8(EICRA, 0b01)
    m.pin("PD2").drive(1)                    # an edge, then level mode before its clock edge
    m.write8(EICRA, 0b00)
    m.kernel.run_until(30)
    assert m.read8(EIFR) & 1 == 0


def test_low_level_interrupt_lasts_while_pin_low(m):
    hits = []
    m.cpu.vector(1, lambda: hits.append(m.kernel.now), cost=96)
    m.irq.set_i(True)
    m.pin("PD2").drive(1)
    m.write8(EICRA, 0b00)                    # low level
    m.write8(EIMSK, 1)
    m.kernel.at(1000, m.pin("PD2").drive, 0)
    m.kernel.at(1300, m.pin("PD2").drive, 1)
    m.kernel.run_until(3000)
    # entered 4 cycles after the request; on RETI the pin is still low, so it is entered again; at
    # 1300 the pin goes high in the same tick as the third return, before it (hardware first)
    assert hits == [1004, 1104, 1204]


def test_wait_for_interrupt_resumes_a_polling_loop_after_each_isr(m):
    passes = []

    async def loop():
        while True:
            passes.append(m.kernel.now)
            await m.cpu.cycles(10)
            await m.rtos.wait_for_interrupt()
    m.cpu.vector(1, lambda: None, cost=20)
    m.rtos.create_task("loop", loop(), 1)
    m.irq.set_i(True)
    m.write8(EICRA, 0b01)
    m.write8(EIMSK, 1)
    for t in (500, 900):
        m.kernel.at(t, m.pin("PD2").drive, t == 500)
    m.kernel.run_until(2000)
    assert passes == [0, 500 + 4 + 20, 900 + 4 + 20]


def test_the_chips_unmodelled_io_registers_are_named_when_written_and_read_their_reset_value():
    """ATmega328P registers of units without a model (Timer2, USART0, PRR, ...) are declared at
    their data-space addresses (datasheet "Register Summary"): a read gives the reset value, a
    write of anything else is refused naming the register (it was a bus fault at a bare
    address); GPIOR0-2 are plain storage."""
    import mcusim
    from mcusim.errors import UnsupportedConfiguration
    sim = mcusim.load("pro-mini", firmware=False)
    m = sim.mcu
    assert m.read8(0xC0) == 0x20 and m.read8(0xC2) == 0x06     # UCSR0A (UDRE0), UCSR0C (8N1)
    assert m.read8(0x5D) == 0xFF and m.read8(0x5E) == 0x08     # SP = RAMEND 0x08FF
    m.write8(0x3E, 0xA5)
    assert m.read8(0x3E) == 0xA5                                 # GPIOR0
    m.write8(0x64, 0x00)                                         # PRR at its reset value: accepted
    for addr, name in ((0x64, "PRR"), (0xB1, "TCCR2B"), (0xC1, "UCSR0B")):
        with pytest.raises(UnsupportedConfiguration, match=rf"ATmega328P\.{name} = 0x1 is not supported"):
            m.write8(addr, 1)
    sim.close()


def test_mcusr_holds_the_reset_flags_cleared_by_writing_0_and_wdt_disable_is_accepted():
    """MCUSR after a power-on reset holds PORF, and firmware clears the flags by writing 0
    (datasheet, MCUSR); wdt_disable()'s timed sequence (WDCE|WDE, then 0) leaves the watchdog
    off and is accepted, while enabling the watchdog (WDE without WDCE, or WDIE) is refused."""
    import mcusim
    from mcusim.errors import UnsupportedConfiguration
    sim = mcusim.load("pro-mini", firmware=False)
    m = sim.mcu
    assert m.read8(0x54) == 0x01
    m.write8(0x54, 0x0F)                 # writing 1 leaves a flag as it is
    assert m.read8(0x54) == 0x01
    m.write8(0x54, 0x00)
    assert m.read8(0x54) == 0x00
    m.write8(0x60, 0x18)
    m.write8(0x60, 0x00)
    for v in (0x08, 0x40):
        with pytest.raises(UnsupportedConfiguration, match="WDTCSR"):
            m.write8(0x60, v)
    sim.close()


def test_a_watchdog_left_on_after_the_timed_sequence_is_refused():
    """Datasheet WDTCSR (safety level 1, the Arduino fuses): writing WDE = 1 enables the watchdog;
    WDCE opens 4 cycles in which wdt_disable() writes WDE = 0. WDCE|WDE alone (or with a
    prescaler, 0x1F) leaves the watchdog on, which had been accepted as off."""
    import mcusim
    from mcusim.errors import UnsupportedConfiguration
    sim = mcusim.load("pro-mini", firmware=False)
    m = sim.mcu
    m.write8(0x60, 0x18)
    sim.run(cycles=3)
    m.write8(0x60, 0x00)                 # within the window: off, accepted
    sim.run(cycles=20)
    m.write8(0x60, 0x1F)
    sim.run(cycles=3)
    with pytest.raises(UnsupportedConfiguration, match=r"WDTCSR\.WDE = 0x1 \(written 0x1f with WDCE"):
        sim.run(cycles=2)
    sim.close()
