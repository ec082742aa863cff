"""External interrupts INT0 (PD2) and INT1 (PD3) (datasheet §13): EICRA, EIMSK, EIFR.

ISCn1:0 = 00 low level, 01 any change, 10 falling edge, 11 rising edge. An edge sets INTFn on the
next CPU clock edge (the edge detector runs on the I/O clock); INTFn is cleared by writing 1 or on
vector entry. In level mode there is no flag: the request lasts while the pin is low, and INTFn
"is always cleared when INTn is configured as a level interrupt" (§13.2.3): switching ISCn to 00
clears a flag an earlier edge left set. An edge that arrives while INTFn is already set is lost, as
on the chip.
"""

from __future__ import annotations

from mcusim.registers import Field, Peripheral, Register


class _IntPin:
    """The listener ExtInt puts on INTn's net (callable per edge; the fast engine asks it what an
    edge would do, see :mod:`mcusim.engine.served`)."""

    __slots__ = ("ext", "n")

    def __init__(self, ext, n):
        self.ext, self.n = ext, n

    def __call__(self, net):
        self.ext._edge(self.n, net.level)

    def served_vector(self):
        return self.ext.served_vector(self.n)


class ExtInt(Peripheral):
    BUS_WIDTH = 1
    ACCESS_SIZES = (1,)          # the AVR data bus is 8 bits wide
    REGISTERS = (
        Register("EIFR", 0x3C, width=8, on_write="_update", fields=(Field("INTF0", 0, access="w1c"),
                                                                    Field("INTF1", 1, access="w1c"))),
        Register("EIMSK", 0x3D, width=8, on_write="_update", fields=(Field("INT0", 0), Field("INT1", 1))),
        Register("EICRA", 0x69, width=8, on_write="_update", fields=(Field("ISC00", 0), Field("ISC01", 1),
                                                                     Field("ISC10", 2), Field("ISC11", 3))),
    )

    def __init__(self, name, mcu, clock, pins=("PD2", "PD3"), vectors=(1, 2)):
        super().__init__(name)
        self.mcu, self.kernel, self.irq, self.clock = mcu, mcu.kernel, mcu.irq, clock
        self.nets = [mcu.add_pin(p) for p in pins]
        self.vectors = vectors
        self.edges_lost = [0, 0]
        for n, net in enumerate(self.nets):
            net.listen(_IntPin(self, n))
            mcu.irq.on_entry[vectors[n]] = lambda n=n: self._clear(n)

    def served_vector(self, n):
        """(clock, cpu, vector) when an edge on INTn's pin now would do nothing but set INTFn at
        the next clock edge and request the vector: any-change mode, INTn enabled, INTFn clear
        (a set flag would make the edge a lost one). Else None."""
        value = self.value
        if ((value["EICRA"] >> (2 * n)) & 3 != 1 or not value["EIMSK"] >> n & 1
                or value["EIFR"] >> n & 1 or self.irq.cpu is None):
            return None
        return self.clock, self.irq.cpu, self.vectors[n]

    def _sense(self, n):
        return (self.value["EICRA"] >> (2 * n)) & 3

    def _edge(self, n, level):
        isc = self._sense(n)
        if isc == 0:
            self._request(n)
        elif isc == 1 or (isc == 2 and not level) or (isc == 3 and level):
            t = self.clock.next_edge(self.kernel.now)
            if t == self.kernel.now:
                self._set_flag(n)
            else:
                self.kernel.at(t, self._set_flag, n)

    def _set_flag(self, n):
        if self._sense(n) == 0:     # switched to level mode since the edge: no flag there
            return
        if self.value["EIFR"] >> n & 1:
            self.edges_lost[n] += 1
        self.set_bits("EIFR", 1 << n)
        self._request(n)            # INTFn changed, nothing else

    def _clear(self, n):
        if self._sense(n) != 0:
            self.clear_bits("EIFR", 1 << n)
            self._request(n)

    def _update(self, old, new):
        for n in range(2):
            self._request(n)

    def _request(self, n):
        """Interrupt request of INTn: the pin low (level mode) or INTFn, AND INTn in EIMSK."""
        value = self.value
        if (value["EICRA"] >> (2 * n)) & 3 == 0:
            if value["EIFR"] >> n & 1:
                self.clear_bits("EIFR", 1 << n)     # always cleared in level mode
            req = not self.nets[n].level
        else:
            req = bool(value["EIFR"] >> n & 1)
        self.irq.set_line(self.vectors[n], req and bool(value["EIMSK"] >> n & 1))
