"""Declarative registers: access kinds, byte lanes, hooks, unmodelled fields, bus faults."""

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mcusim.errors import BusFault, UnsupportedConfiguration
from mcusim.registers import Bus, Field, Peripheral, Register


class Dev(Peripheral):
    REGISTERS = (
        Register("CTRL", 0x00, reset=0x10, on_write="_w", fields=(Field("EN", 0), Field("MODE", 1, 3),
                                                                  Field("RO", 4, access="r"),
                                                                  Field("DMA", 8, modelled=False))),
        Register("SR", 0x04, fields=(Field("F0", 0, access="rc_w0"), Field("F1", 1, access="rc_w0"),
                                     Field("W1C", 8, access="w1c"), Field("RCR", 16, access="rc_r"))),
        Register("CMD", 0x08, fields=(Field("GO", 0, access="w"),), on_write="_cmd"),
        Register("CNT", 0x0C, on_read="_cnt"),
    )

    def __init__(self):
        super().__init__("DEV")
        self.writes, self.commands = [], []

    def _w(self, old, new):
        self.writes.append((old, new))

    def _cmd(self, old, new):
        self.commands.append(new)

    def _cnt(self, stored):
        return 1234


@pytest.fixture
def bus():
    b = Bus()
    b.attach(0x4000_0000, Dev())
    return b


def test_reset_values_and_read_only_field(bus):
    assert bus.read32(0x4000_0000) == 0x10
    bus.write32(0x4000_0000, 0x0000_0003)  # RO bit 4 written 0: keeps its value
    assert bus.read32(0x4000_0000) == 0x13


def test_rc_w0_writing_one_keeps_and_zero_clears(bus):
    dev = bus.peripheral_at(0x4000_0000)[0]
    dev.set_bits("SR", 0b11)
    bus.write32(0x4000_0004, 0x0000_0001)  # as reference sheet §6 #18
    assert bus.read32(0x4000_0004) & 0b11 == 0b01
    bus.write32(0x4000_0004, 0xFFFF_FFFE)
    assert bus.read32(0x4000_0004) & 0b11 == 0


def test_w1c_and_clear_on_read(bus):
    dev = bus.peripheral_at(0x4000_0000)[0]
    dev.set_bits("SR", (1 << 8) | (1 << 16))
    bus.write32(0x4000_0004, 0x0000_0003)     # 0s at bit 8 do nothing for w1c; 1s on rc_w0 keep
    assert bus.read32(0x4000_0004) & (1 << 8)
    assert not bus.read32(0x4000_0004) & (1 << 16)  # the previous read cleared it
    bus.write32(0x4000_0004, 1 << 8 | 0b11)
    assert not bus.read32(0x4000_0004) & (1 << 8)


def test_write_only_field_reaches_hook_and_reads_zero(bus):
    dev = bus.peripheral_at(0x4000_0000)[0]
    bus.write32(0x4000_0008, 1)
    assert dev.commands == [1]
    assert bus.read32(0x4000_0008) == 0


def test_read_hook_computes_value(bus):
    assert bus.read32(0x4000_000C) == 1234
    assert bus.read16(0x4000_000C) == 1234 & 0xFFFF
    assert bus.read8(0x4000_000D) == (1234 >> 8) & 0xFF


def test_unmodelled_field_raises_naming_it(bus):
    with pytest.raises(UnsupportedConfiguration, match=r"DEV\.CTRL\.DMA = 0x1"):
        bus.write32(0x4000_0000, 1 << 8)


def test_byte_write_touches_only_its_lane(bus):
    bus.write32(0x4000_0000, 0x0000_000F)
    bus.write8(0x4000_0001, 0x00)  # lane 1 (DMA field) unchanged value 0: allowed
    assert bus.read32(0x4000_0000) & 0xF == 0xF
    dev = bus.peripheral_at(0x4000_0000)[0]
    dev.set_bits("SR", 0b11)
    bus.write8(0x4000_0005, 0x00)  # writing 0s to lane 1 must not clear the rc_w0 flags in lane 0
    assert bus.read32(0x4000_0004) & 0b11 == 0b11


def test_unmapped_address_is_a_bus_fault_naming_it(bus):
    with pytest.raises(BusFault, match="0x50000000"):
        bus.read32(0x5000_0000)
    with pytest.raises(BusFault, match="no register of DEV at offset 0x20"):
        bus.write32(0x4000_0020, 1)


def test_misaligned_access_faults(bus):
    with pytest.raises(BusFault, match="misaligned"):
        bus.read32(0x4000_0002)


@given(st.integers(0, 0xFFFF_FFFF), st.integers(0, 3))
def test_rc_w0_flags_only_ever_clear_by_software(value, flags):
    b = Bus()
    dev = Dev()
    b.attach(0, dev)
    dev.set_bits("SR", flags)
    b.write32(4, value)
    assert b.read32(4) & 0b11 == flags & value & 0b11
