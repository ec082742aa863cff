"""The board's memories (flash, SRAM, TCM) as byte buffers shared by the CPU core and the bus.

A profile declares them in ``[[memory]]`` tables (``docs/boards.md``)::

    [[memory]]
    name = "FLASH"
    base = 0x08000000
    size = 0x100000
    kind = "flash"              # flash: read and execute (a firmware write faults); ram: read/write
    aliases = [0x00200000]      # the same bytes seen at other addresses (ITCM interface, boot shadow)

One buffer per region: the core maps it (and each alias) with ``mem_map_ptr``, and the bus maps
a :class:`Memory` view of it, so ``mcu.read32``/``write32`` reach RAM and flash as the firmware
sees them.
"""

from __future__ import annotations

import ctypes

from ..errors import BusFault
from ..registers import Peripheral

PAGE = 0x1000


class Memory(Peripheral):
    """A memory region on the bus: plain bytes, little-endian, any aligned 8/16/32-bit access."""

    REGISTERS = ()

    def __init__(self, name: str, base: int, size: int, kind: str, aliases=()):
        super().__init__(name)
        self.base, self.size, self.kind, self.aliases = base, size, kind, tuple(aliases)
        self.SIZE = size
        self.buffer = (ctypes.c_ubyte * size)()
        self.view = memoryview(self.buffer).cast("B")

    def bus_read(self, offset, size, address):
        return int.from_bytes(self.view[offset:offset + size], "little")

    def bus_write(self, offset, data, size, address):
        if self.kind == "flash":
            raise BusFault(address, size, f"{self.name} is flash: it is programmed through the flash "
                                          "interface, not written by a store")
        self.view[offset:offset + size] = data.to_bytes(size, "little")

    def contains(self, address: int, length: int = 1):
        """The offset of [address, address+length) in this region (base or an alias), or None."""
        for base in (self.base, *self.aliases):
            if base <= address and address + length <= base + self.size:
                return address - base
        return None


def build_memories(specs: list) -> list[Memory]:
    return [Memory(s["name"], s["base"], s["size"], s.get("kind", "ram"), s.get("aliases", ()))
            for s in specs]
