"""Declarative registers on a memory-mapped bus.

A peripheral lists its registers once, as data::

    REGISTERS = (
        Register("SR", 0x10, fields=(Field("UIF", 0, access="rc_w0"), ...)),
        Register("CNT", 0x24, on_read="_read_cnt", on_write="_write_cnt"),
    )

Access kinds (per field, the names of the reference manuals):

=========  =================================================================
``rw``     read/write
``r``      read-only; writes ignored
``w``      write-only; reads 0 (the written value reaches the write hook)
``rc_w0``  read, cleared by writing 0; writing 1 has no effect
``rc_w1``  read, cleared by writing 1 (also spelt ``w1c``)
``rc_r``   read, cleared by the read
=========  =================================================================

A field declared with ``modelled=False`` exists on the chip but not in the model: writing anything
but its reset value raises :class:`UnsupportedConfiguration`. Bits in no field are reserved: they
read 0 and ignore writes.

Hooks are method names on the peripheral. ``on_write(old, new)`` runs after the stored value has
been updated by the access rules (``new`` holds the bits of ``w`` fields as written; they are
cleared from storage after the hook). ``on_read(stored) -> value`` computes what a read returns.
Hardware sets and clears bits with :meth:`Peripheral.set_bits` / :meth:`Peripheral.clear_bits`,
which bypass the access rules.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass
from dataclasses import field as dc_field

from .errors import BusFault, UnsupportedConfiguration
from .params import a_or_an

ACCESS_KINDS = ("rw", "r", "w", "rc_w0", "rc_w1", "w1c", "rc_r")


@dataclass(frozen=True)
class Field:
    name: str
    lsb: int
    width: int = 1
    access: str = "rw"
    modelled: bool = True
    doc: str = ""

    @property
    def mask(self) -> int:
        return ((1 << self.width) - 1) << self.lsb

    def get(self, value: int) -> int:
        return (value >> self.lsb) & ((1 << self.width) - 1)


@dataclass
class Register:
    name: str
    offset: int
    reset: int = 0
    width: int = 32
    fields: tuple = ()
    on_read: str | None = None
    on_write: str | None = None
    access: str = "rw"  # access of the whole register when it declares no fields
    doc: str = ""
    # derived masks
    _masks: dict = dc_field(default_factory=dict, repr=False)

    def __post_init__(self):
        fields = self.fields or (Field(self.name, 0, self.width, self.access),)
        self.fields = tuple(fields)
        masks = {k: 0 for k in ACCESS_KINDS}
        owner: dict[int, str] = {}
        for f in self.fields:
            if f.access not in ACCESS_KINDS:
                raise ValueError(f"{self.name}.{f.name}: unknown access kind {f.access!r}")
            kind = "rc_w1" if f.access == "w1c" else f.access
            for bit in range(f.lsb, f.lsb + f.width):
                if owner.get(bit, kind) != kind:
                    raise ValueError(f"{self.name}: bit {bit} declared with two access kinds")
                owner[bit] = kind
            masks[kind] |= f.mask
        self._masks = masks
        # the masks write_register applies, as attributes (one lookup each on the write path)
        self.m_rw, self.m_w, self.m_rc_w0, self.m_rc_w1, self.m_rc_r = (
            masks["rw"], masks["w"], masks["rc_w0"], masks["rc_w1"], masks["rc_r"])
        self.unmodelled = tuple(f for f in self.fields if not f.modelled)
        self.by_name = {f.name: f for f in self.fields}
        self.readable = masks["rw"] | masks["r"] | masks["rc_w0"] | masks["rc_w1"] | masks["rc_r"]

    def field(self, name: str) -> Field:
        return self.by_name[name]


class Peripheral:
    """Base of every memory-mapped peripheral model. Subclasses set ``REGISTERS``."""

    REGISTERS: tuple = ()
    SIZE = 0x400  # bytes of address space the instance occupies
    BUS_WIDTH = 4  # bytes per register slot (4 on Cortex-M, 1 on AVR)
    ACCESS_SIZES = (1, 2, 4)  # access widths in bytes the peripheral accepts

    def __init__(self, name: str):
        self.name = name
        self._by_offset = {r.offset: r for r in self.REGISTERS}
        self.regs = {r.name: r for r in self.REGISTERS}
        self.value = {r.name: r.reset for r in self.REGISTERS}
        self.access_log = None  # callable(kind, periph, reg, value, old) set by a register-access tracer

    def register_names(self) -> list[str]:
        """The names of every register the bus can reach (a register log filter is matched
        against them); a model that decodes registers from the offset lists those too."""
        return [r.name for r in self.REGISTERS]

    # --- hardware-side access (no access rules) ---------------------------------------------
    def set_bits(self, reg: str, mask: int) -> None:
        self.value[reg] |= mask

    def clear_bits(self, reg: str, mask: int) -> None:
        self.value[reg] &= ~mask

    def field(self, reg: str, name: str) -> int:
        return self.regs[reg].by_name[name].get(self.value[reg])

    def reset(self) -> None:
        for r in self.REGISTERS:
            self.value[r.name] = r.reset

    # --- bus-side access ----------------------------------------------------------------
    def _reg_at(self, offset: int, size: int, address: int) -> Register:
        if size not in self.ACCESS_SIZES:
            raise BusFault(address, size, f"{self.name} accepts only "
                                          f"{'/'.join(str(8 * n) for n in self.ACCESS_SIZES)}-bit accesses")
        slot = offset - offset % self.BUS_WIDTH
        reg = self._by_offset.get(slot)
        if reg is None:
            raise BusFault(address, size, f"no register of {self.name} at offset {offset:#x}")
        return reg

    def bus_read(self, offset: int, size: int, address: int) -> int:
        reg = self._reg_at(offset, size, address)
        stored = self.value[reg.name]
        value = getattr(self, reg.on_read)(stored) if reg.on_read else stored
        value &= reg.readable if not reg.on_read else (1 << reg.width) - 1
        if reg._masks["rc_r"]:
            self.value[reg.name] = stored & ~reg._masks["rc_r"]
        if self.access_log is not None:
            self.access_log("read", self, reg, value, stored)
        shift = (offset % self.BUS_WIDTH) * 8
        return (value >> shift) & ((1 << (8 * size)) - 1)

    def bus_write(self, offset: int, data: int, size: int, address: int) -> None:
        reg = self._reg_at(offset, size, address)
        shift = (offset % self.BUS_WIDTH) * 8
        lanes = (((1 << (8 * size)) - 1) << shift) & ((1 << (8 * self.BUS_WIDTH)) - 1)
        data = (data << shift) & lanes
        self.write_register(reg, data, lanes)

    def write_register(self, reg: Register, data: int, lanes: int = -1) -> None:
        """Apply a write of ``data`` to the byte lanes in ``lanes`` under the access rules."""
        values, name, m_rw, m_w = self.value, reg.name, reg.m_rw, reg.m_w
        old = values[name]
        new = (old & ~m_rw) | (data & m_rw)
        new &= ~(reg.m_rc_w0 & ~data)         # rc_w0: a written 0 clears
        new &= ~(reg.m_rc_w1 & data)          # rc_w1 / w1c: a written 1 clears
        new = (new & ~m_w) | (data & m_w)
        new = (new & lanes) | (old & ~lanes)  # lanes not written keep their value
        for f in reg.unmodelled:
            v = f.get(new)
            if v != f.get(reg.reset):
                raise UnsupportedConfiguration(self.name, name, f.name, v,
                                               f"is not modelled ({f.doc})" if f.doc else "is not modelled")
        values[name] = new
        if reg.on_write:
            try:
                getattr(self, reg.on_write)(old, new)
            except UnsupportedConfiguration:
                values[name] = old  # a refused write leaves the register as it was
                raise
        if m_w:
            values[name] &= ~m_w
        if self.access_log is not None:
            self.access_log("write", self, reg, data, old)

    # --- accessors resolved once per (address, size), used by Bus -------------------------------
    def bus_reader(self, offset: int, size: int, address: int):
        """A function of no argument doing ``bus_read(offset, size, address)``. Resolved once: the
        register, its masks, hook and byte lane; a subclass that overrides ``bus_read`` gets a
        plain call of it. Raises what ``bus_read`` would raise for a bad access."""
        if type(self).bus_read is not Peripheral.bus_read:
            bus_read = self.bus_read
            return lambda: bus_read(offset, size, address)
        reg = self._reg_at(offset, size, address)
        values, name, rc_r = self.value, reg.name, reg.m_rc_r
        hook = getattr(self, reg.on_read) if reg.on_read else None
        keep = (1 << reg.width) - 1 if hook is not None else reg.readable
        shift = (offset % self.BUS_WIDTH) * 8
        lane = (1 << (8 * size)) - 1

        def read():
            stored = values[name]
            value = (hook(stored) if hook is not None else stored) & keep
            if rc_r:
                values[name] = stored & ~rc_r
            if self.access_log is not None:
                self.access_log("read", self, reg, value, stored)
            return (value >> shift) & lane
        return read

    def bus_writer(self, offset: int, size: int, address: int):
        """A function of the data doing ``bus_write(offset, data, size, address)``, resolved once
        (see :meth:`bus_reader`)."""
        if type(self).bus_write is not Peripheral.bus_write:
            bus_write = self.bus_write
            return lambda data: bus_write(offset, data, size, address)
        reg = self._reg_at(offset, size, address)
        shift = (offset % self.BUS_WIDTH) * 8
        lanes = (((1 << (8 * size)) - 1) << shift) & ((1 << (8 * self.BUS_WIDTH)) - 1)
        write_register = self.write_register
        return lambda data: write_register(reg, (data << shift) & lanes, lanes)


class Bus:
    """A memory map of peripherals. 8/16/32-bit accesses; misaligned or unmapped -> BusFault."""

    def __init__(self, name: str = "bus"):
        self.name = name
        self._bases: list[int] = []
        self._entries: list[tuple[int, int, Peripheral]] = []
        self._cache: dict[int, tuple[Peripheral, int]] = {}
        self._single: dict[int, tuple[Peripheral, int]] = {}
        # accessors resolved at the first access, keyed by 8 * address + size
        self._readers: dict[int, object] = {}
        self._writers: dict[int, object] = {}

    def _clear(self):
        self._cache.clear()
        self._readers.clear()
        self._writers.clear()

    def ranges(self) -> list:
        """(base, size, peripheral) of every attached peripheral, by address."""
        return list(self._entries)

    def attach(self, base: int, periph: Peripheral, size: int | None = None) -> None:
        size = periph.SIZE if size is None else size
        if base + size > 1 << 32:
            raise ValueError(f"{periph.name} at {base:#x} (size {size:#x}) runs past the end of the 4 GiB "
                             "address space")
        i = bisect.bisect(self._bases, base)
        if (i > 0 and self._entries[i - 1][0] + self._entries[i - 1][1] > base) or \
                (i < len(self._entries) and base + size > self._entries[i][0]):
            raise ValueError(f"{periph.name} at {base:#x} overlaps another peripheral")
        self._bases.insert(i, base)
        self._entries.insert(i, (base, size, periph))
        self._clear()

    def attach_registers(self, base: int, periph: Peripheral) -> None:
        """Map each register of ``periph`` at ``base + offset`` individually (AVR I/O space, where
        one peripheral's registers are scattered: TIFR1 at 0x36, TIMSK1 at 0x6F, TCCR1A at 0x80)."""
        for reg in periph.REGISTERS:
            for k in range(max(1, reg.width // (8 * periph.BUS_WIDTH))):
                addr = base + reg.offset + k * periph.BUS_WIDTH
                if addr in self._single or self.peripheral_at(addr) is not None:
                    raise ValueError(f"{periph.name}.{reg.name} at {addr:#x} overlaps another register")
                self._single[addr] = (periph, reg.offset + k * periph.BUS_WIDTH)
        self._clear()

    def peripheral_at(self, address: int) -> tuple[Peripheral, int] | None:
        hit = self._single.get(address)
        if hit is not None:
            return hit
        i = bisect.bisect(self._bases, address) - 1
        if i >= 0:
            base, size, p = self._entries[i]
            if address < base + size:
                return p, address - base
        return None

    def _lookup(self, address: int, size: int) -> tuple[Peripheral, int]:
        if address % size:
            raise BusFault(address, size, "misaligned access to device memory")
        hit = self._cache.get(address)
        if hit is None:
            hit = self.peripheral_at(address)
            if hit is None:
                raise BusFault(address, size)
            self._cache[address] = hit
        return hit

    def reader(self, address: int, size: int):
        """The function of no argument that reads ``size`` bytes at ``address`` (resolved once)."""
        fn = self._readers.get(8 * address + size)
        if fn is None:
            p, off = self._lookup(address, size)
            fn = self._readers[8 * address + size] = p.bus_reader(off, size, address)
        return fn

    def writer(self, address: int, size: int):
        """The function of the value that writes ``size`` bytes at ``address`` (resolved once)."""
        fn = self._writers.get(8 * address + size)
        if fn is None:
            p, off = self._lookup(address, size)
            fn = self._writers[8 * address + size] = p.bus_writer(off, size, address)
        return fn

    def read(self, address: int, size: int) -> int:
        fn = self._readers.get(8 * address + size)
        if fn is None:
            fn = self.reader(address, size)
        return fn()

    def write(self, address: int, value: int, size: int) -> None:
        if not 0 <= value < (1 << (8 * size)):
            raise ValueError(f"value {value:#x} does not fit {a_or_an(f'{8 * size}-bit')} write")
        fn = self._writers.get(8 * address + size)
        if fn is None:
            fn = self.writer(address, size)
        fn(value)

    def read8(self, a): return self.read(a, 1)
    def read16(self, a): return self.read(a, 2)
    def read32(self, a): return self.read(a, 4)
    def write8(self, a, v): self.write(a, v, 1)
    def write16(self, a, v): self.write(a, v, 2)
    def write32(self, a, v): self.write(a, v, 4)
