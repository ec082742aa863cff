"""LPC4337 GPIO port block (UM10503 GPIO; register wording from NXP's SVD ``gpio_port``)."""

import pytest
from lpc_rig import bare_lpc4337
from mcusim.periph.lpc43xx.gpio import Gpio

from mcusim.errors import BusFault, McusimError

BASE = 0x400F4000


def B(port, pin):
    return BASE + 32 * port + pin


def W(port, pin):
    return BASE + 0x1000 + 4 * (32 * port + pin)


def DIR(p): return BASE + 0x2000 + 4 * p
def MASK(p): return BASE + 0x2080 + 4 * p
def PIN(p): return BASE + 0x2100 + 4 * p
def MPIN(p): return BASE + 0x2180 + 4 * p
def SET(p): return BASE + 0x2200 + 4 * p
def CLR(p): return BASE + 0x2280 + 4 * p
def NOT(p): return BASE + 0x2300 + 4 * p


@pytest.fixture
def m():
    mcu = bare_lpc4337()
    gpio = Gpio("GPIO", mcu)
    mcu.periph["GPIO"] = gpio
    mcu.bus.attach(BASE, gpio)
    return mcu


def test_every_pin_is_an_mcu_net_named_gpio_port_underscore_bit(m):
    assert len([n for n in m.pins if n.startswith("GPIO")]) == 8 * 32
    assert m.pin("GPIO3_0") is m.periph["GPIO"].pin(3, 0)
    assert m.pin("GPIO5_16").name == "GPIO5_16"


def test_set_clr_not_act_on_the_bits_written_one_and_set_reads_the_output_bits(m):
    m.write32(SET(3), 0b0101)
    assert m.read32(SET(3)) == 0b0101
    m.write32(SET(3), 0)                      # writing 0: no operation
    assert m.read32(SET(3)) == 0b0101
    m.write32(CLR(3), 0b0001)
    assert m.read32(SET(3)) == 0b0100
    m.write32(NOT(3), 0b0110)
    assert m.read32(SET(3)) == 0b0010
    assert m.read32(CLR(3)) == 0 and m.read32(NOT(3)) == 0   # write-only
    assert m.read32(SET(2)) == 0              # ports are independent


def test_dir_1_drives_the_output_bit_onto_the_net_and_dir_0_releases_it(m):
    net = m.pin("GPIO3_0")
    m.write32(SET(3), 1)
    assert net.level == 0                     # DIR = 0 at reset: the latch does not reach the pin
    m.write32(DIR(3), 1)
    assert net.level == 1
    with pytest.raises(McusimError, match="contention on net GPIO3_0"):
        net.set("other", 0)                   # the GPIO block is a named driver of the net
    net.set("other", None)
    m.write32(CLR(3), 1)
    assert net.level == 0
    m.write32(DIR(3), 0)                      # input: released
    net.set("other", 1)                       # another driver now owns it without contention
    assert net.level == 1 and m.read32(PIN(3)) & 1 == 1


def test_pin_reads_levels_regardless_of_direction_and_a_write_loads_all_output_bits(m):
    m.write32(PIN(1), 0xF0F0)
    assert m.read32(SET(1)) == 0xF0F0
    assert m.read32(PIN(1)) == 0              # nothing drives the pins (DIR = 0, no pulls)
    m.write32(DIR(1), 0x00FF)
    assert m.read32(PIN(1)) == 0x00F0
    m.pin("GPIO1_0").drive(1)                 # external stimulus beats the output driver
    assert m.read32(PIN(1)) == 0x00F1
    m.pin("GPIO1_12").drive(1)                # an input pin
    assert m.read32(PIN(1)) == 0x10F1


def test_mask_affects_mpin_only(m):
    m.write32(DIR(2), 0xFFFF)
    m.write32(MASK(2), 0xFF00)
    m.write32(MPIN(2), 0xFFFF)                # only unmasked bits 7:0 are loaded
    assert m.read32(SET(2)) == 0x00FF
    m.write32(PIN(2), 0x0F0F)                 # PIN ignores MASK
    assert m.read32(PIN(2)) == 0x0F0F
    assert m.read32(MPIN(2)) == 0x000F        # masked bits read 0
    m.write32(SET(2), 0xF000)                 # SET/CLR/NOT ignore MASK
    m.write32(NOT(2), 0x0100)
    m.write32(CLR(2), 0x0001)
    assert m.read32(SET(2)) == 0xFE0E
    m.write32(MPIN(2), 0)                     # clears only the unmasked bits
    assert m.read32(SET(2)) == 0xFE00


def test_byte_pin_register_reads_0_or_1_and_bit_0_of_a_write_loads_the_output(m):
    m.write32(DIR(5), 0b100)                  # LEDB = GPIO5[2]
    m.write8(B(5, 2), 0x01)
    assert m.pin("GPIO5_2").level == 1 and m.read8(B(5, 2)) == 0x01
    m.write8(B(5, 2), 0xFE)                   # bit 0 = 0: clears; bits 7:1 ignored
    assert m.pin("GPIO5_2").level == 0 and m.read8(B(5, 2)) == 0x00
    assert m.read32(SET(5)) == 0


def test_word_pin_register_reads_all_ones_when_high_and_any_nonzero_write_sets(m):
    m.write32(DIR(0), 1 << 14)                # LED1 = GPIO0[14]
    m.write32(W(0, 14), 0x80000000)
    assert m.pin("GPIO0_14").level == 1
    assert m.read32(W(0, 14)) == 0xFFFFFFFF
    m.write32(W(0, 14), 0)
    assert m.read32(W(0, 14)) == 0 and m.read32(SET(0)) == 0


def test_input_reads_a_pulled_up_net_and_the_net_driven_low_externally(m):
    fired = []
    net = m.pin("GPIO0_4")                    # TEC1: 10 kOhm board pull-up, switch to GND
    net.pull = 1                              # the board wiring
    net.release()
    assert m.read8(B(0, 4)) == 1 and m.read32(PIN(0)) >> 4 & 1 == 1
    m.periph["GPIO"].changed._wait(lambda: fired.append(m.read8(B(0, 4))))
    net.drive(0)                              # button pressed
    assert m.read8(B(0, 4)) == 0 and m.read32(PIN(0)) >> 4 & 1 == 0
    assert m.read32(W(0, 4)) == 0
    assert fired == [0]                       # ``changed`` fired after the level changed
    net.release()
    assert m.read8(B(0, 4)) == 1


@pytest.mark.parametrize("address, size", [
    (BASE + 0x100, 1),             # past B255
    (BASE + 0x0FFF, 1),
    (BASE + 0x1400, 4),            # past W255
    (BASE + 0x2020, 4),            # DIR8 does not exist
    (BASE + 0x2320, 4),            # past NOT7
    (BASE + 0x3FFC, 4),
    (BASE + 0x0000, 4),            # B registers are 8-bit
    (BASE + 0x1000, 1),            # W registers are 32-bit
    (BASE + 0x2000, 1),            # port registers are 32-bit
    (BASE + 0x2100, 2),
])
def test_bad_offsets_and_access_sizes_raise_bus_fault(m, address, size):
    with pytest.raises(BusFault):
        m.bus.read(address, size)
    with pytest.raises(BusFault):
        m.bus.write(address, 0, size)


def test_pins_beyond_the_instance_are_bus_faults_and_reserved_bits_read_0():
    mcu = bare_lpc4337()
    gpio = Gpio("GPIO", mcu, ports=2, pins_per_port=16)
    mcu.bus.attach(BASE, gpio)
    assert "GPIO1_15" in mcu.pins and "GPIO1_16" not in mcu.pins and "GPIO2_0" not in mcu.pins
    with pytest.raises(BusFault):
        mcu.read8(B(0, 16))
    with pytest.raises(BusFault):
        mcu.read32(DIR(2))
    mcu.write32(SET(0), 0xFFFFFFFF)
    assert mcu.read32(SET(0)) == 0xFFFF
    mcu.write32(DIR(0), 0xFFFFFFFF)
    assert mcu.read32(DIR(0)) == 0xFFFF and mcu.read32(PIN(0)) == 0xFFFF


def test_register_access_tracer_sees_pin_register_names(m):
    seen = []
    m.periph["GPIO"].access_log = lambda kind, p, reg, value, old: seen.append((kind, reg.name, value))
    m.write8(B(3, 5), 1)
    m.read32(W(3, 5))
    m.write32(DIR(3), 1 << 5)
    assert seen == [("write", "B101", 1), ("read", "W101", 0), ("write", "DIR3", 1 << 5)]


def test_reset_gives_the_reset_values_dir_0_releases_every_pin_and_clears_the_output_bits(m):
    # UM10503 GPIO register tables: DIR, MASK and the output bits (read in SET) reset to 0, so after a
    # reset every pin is an input (not driven by the block) and SET reads 0, whatever was set before
    gpio = m.periph["GPIO"]
    m.write32(DIR(3), 0b11)
    m.write32(SET(3), 0b01)
    m.write32(MASK(3), 0b10)
    net0 = gpio.pin(3, 0)
    assert net0.level == 1
    gpio.reset()
    assert m.read32(DIR(3)) == 0 and m.read32(SET(3)) == 0 and m.read32(MASK(3)) == 0
    net0.set("other", 0)                         # released: another driver owns it, no contention
    assert net0.level == 0 and m.read32(PIN(3)) & 1 == 0
    net0.set("other", None)
    m.write32(DIR(3), 0b01)                      # an output again: it drives the reset output bit 0
    assert net0.level == 0
    with pytest.raises(McusimError, match="contention on net GPIO3_0"):
        net0.set("other", 1)


def test_the_edu_ciaa_push_buttons_read_1_when_not_pressed():
    """EDU-CIAA-NXP: TEC1-TEC4 (GPIO0[4], GPIO0[8], GPIO0[9], GPIO1[9]) are active low with 10 kΩ
    pull-ups on the board, so sAPI's !gpioRead(TEC1) is false until a button is pressed; the
    profile had no pull-ups and every button read as pressed. Pressing one (driving its net to 0)
    reads 0."""
    import mcusim
    sim = mcusim.load("ciaa-edu", firmware=False)
    pin0, pin1 = 0x400F6100, 0x400F6104             # GPIO PIN0, PIN1
    assert sim.mcu.read32(pin0) & 0x310 == 0x310 and sim.mcu.read32(pin1) & 0x200 == 0x200
    sim.pin("GPIO0_8").drive(0)
    assert sim.mcu.read32(pin0) & 0x310 == 0x210
    sim.close()
