"""LPC4337 GPIO port block (UM10503 "GPIO"), base 0x400F4000, 16 KB of address space.

Sources: NXP UM10503 and the EDU-CIAA-NXP schematic (base address, the buttons,
LEDs and free header pins); register layout and wording from NXP's SVD (svd2rust ``gpio_port``) and
LPCOpen's ``LPC_GPIO_T``.

Registers (port ``p`` = 0..7, pin ``n`` = 0..31, reset 0 everywhere):

=======  ===============================  ==========================================================
name     offset                           semantics
=======  ===============================  ==========================================================
B<k>     0x0000 + k, k = 32*p + n         byte pin register, **8-bit accesses only**. Read: 0x01 if the
                                          pin is high, 0x00 if low, whatever its direction. Write:
                                          bit 0 loads the pin's output bit (bits 7:1 are ignored).
W<k>     0x1000 + 4*k                     word pin register. Read: 0xFFFFFFFF if the pin is high,
                                          0 if low. Write: 0 clears the output bit, any other value
                                          sets it.
DIR<p>   0x2000 + 4*p                     1 = output, 0 = input.
MASK<p>  0x2080 + 4*p                     1 = the pin is masked in MPIN (and only there).
PIN<p>   0x2100 + 4*p                     read: the pin levels (regardless of direction and MASK);
                                          write: loads all the output bits.
MPIN<p>  0x2180 + 4*p                     read: pin levels with the MASK = 1 bits reading 0; write:
                                          loads the output bits whose MASK bit is 0, leaves the others.
SET<p>   0x2200 + 4*p                     read: the output bits; write 1: set the output bit, 0: no
                                          operation.
CLR<p>   0x2280 + 4*p                     write-only (reads 0); 1: clear the output bit.
NOT<p>   0x2300 + 4*p                     write-only (reads 0); 1: toggle the output bit.
=======  ===============================  ==========================================================

The word registers (everything from 0x1000 up) take **32-bit accesses only**, as LPCOpen's
``LPC_GPIO_T`` (``uint32_t`` members) and NuttX's ``getreg32``/``putreg32`` use them; a narrower
access, an offset between the decoded ranges (0x0100-0x0FFF, 0x1400-0x1FFF, the gaps after each
8-entry port array, anything above 0x231C), a byte register or a bit of a pin the instance does not
have (``pins_per_port``, ``ports``) raises :class:`BusFault`. The port registers are declared as data
(``REGISTERS``, one per port); the 512 pin registers B/W are decoded from the offset and get a
``Register`` object only when first touched (so a register-access tracer sees their names).

Pins
----
Every pin is an mcu net ``GPIO<p>_<n>`` (``GPIO3_0``), created with ``mcu.add_pin`` for every pin of
the instance, so a board profile can refer to any of them by name. A pin with DIR = 1 drives its
output bit onto the net, the driver being named after this peripheral (``"GPIO"``); DIR = 0 releases
the net. A read returns the net's resolved level, so an external stimulus (``net.drive(0)``) on an
output pin is what PIN/B/W read, as on the chip ("regardless of direction").

Not modelled (stated): the SCU pin multiplexer. The model assumes every pin it drives or reads is
muxed to its GPIO function; nothing checks the SCU, so a firmware that forgets ``Chip_SCU_PinMux``
still works here. The SCU's pull-up/pull-down/repeater settings are not modelled either: a pull-up is
a property of the board wiring, the net's ``pull`` (the EDU-CIAA buttons have 10 kOhm external
pull-ups, §2.4). Analog-mode pins (which read 0 on the chip) and the pin-interrupt block (PIN_INT,
GPIO group interrupts) are not modelled.

``changed`` (a :class:`mcusim.firmware.Signal`) fires after any pin of the block changes level (from
an external stimulus or from the block's own outputs), so a task polling a pin can
``await rtos.wait_signal(gpio.changed)`` between reads instead of spinning.
"""

from __future__ import annotations

from mcusim.errors import BusFault
from mcusim.firmware import Signal
from mcusim.registers import Field, Peripheral, Register

GPIO_BASE = 0x400F4000          # [V: LO-MAP], reference §2.4
B_BASE, W_BASE = 0x0000, 0x1000
PORT_REGS = ("DIR", "MASK", "PIN", "MPIN", "SET", "CLR", "NOT")
PORT_BASE = {name: 0x2000 + 0x80 * i for i, name in enumerate(PORT_REGS)}


def _port_registers(ports: int, pins: int) -> tuple:
    def bits(prefix, access="rw"):
        return tuple(Field(f"{prefix}{n}", n, access=access) for n in range(pins))

    hooks = {  # name -> (field prefix, access, on_read, on_write)
        "DIR": ("DIRP", "rw", None, "_write_dir"),
        "MASK": ("MASKP", "rw", None, None),
        "PIN": ("PORT", "rw", "_read_pin", "_write_pin"),
        "MPIN": ("MPORTP", "rw", "_read_mpin", "_write_mpin"),
        "SET": ("SETP", "w", "_read_out", "_write_set"),     # write-1 actions; SET reads the output bits
        "CLR": ("CLRP", "w", None, "_write_clr"),
        "NOT": ("NOTP", "w", None, "_write_not"),
    }
    regs = []
    for name in PORT_REGS:
        prefix, access, on_read, on_write = hooks[name]
        for p in range(ports):
            regs.append(Register(f"{name}{p}", PORT_BASE[name] + 4 * p, on_read=on_read, on_write=on_write,
                                 fields=bits(prefix, access)))
    return tuple(regs)


class Gpio(Peripheral):
    """The GPIO port block: ``ports`` ports of ``pins_per_port`` pins (LPC4337: 8 ports, GPIO0..7)."""

    RGU_RESET = True  # the RGU may call reset() (periph/lpc43xx/rgu.py)
    SIZE = 0x4000
    BUS_WIDTH = 4
    ACCESS_SIZES = (1, 4)

    def __init__(self, name, mcu, ports: int = 8, pins_per_port: int = 32):
        if not 1 <= ports <= 8 or not 1 <= pins_per_port <= 32:
            raise ValueError(f"{name}: 1..8 ports of 1..32 pins, not {ports} x {pins_per_port}")
        self.REGISTERS = _port_registers(ports, pins_per_port)
        super().__init__(name)
        self.mcu, self.ports, self.npins = mcu, ports, pins_per_port
        self.pinmask = (1 << pins_per_port) - 1
        self.out = [0] * ports                  # output latches (what SET reads)
        self._driving = [0] * ports             # DIR as last applied to the nets
        self._driven = [0] * ports              # output bits as last applied to the nets
        self.pins = [[mcu.add_pin(f"GPIO{p}_{n}") for n in range(pins_per_port)] for p in range(ports)]
        self.changed = Signal()
        self._pin_regs: dict[int, Register] = {}
        for row in self.pins:
            for net in row:
                net.listen(self._net_changed)

    def pin(self, port: int, n: int):
        """The net of GPIO<port>[n]."""
        return self.pins[port][n]

    # --- pins ----------------------------------------------------------------------------------
    def _net_changed(self, net) -> None:
        self.changed.fire()

    def levels(self, p: int) -> int:
        return sum(1 << n for n, net in enumerate(self.pins[p]) if net.level)

    def _apply(self, p: int) -> None:
        """Drive or release the nets of port ``p`` whose direction or driven level changed."""
        d, o = self.value[f"DIR{p}"] & self.pinmask, self.out[p]
        diff = (d ^ self._driving[p]) | ((o ^ self._driven[p]) & d)
        self._driving[p], self._driven[p] = d, o
        n = 0
        while diff:
            if diff & 1:
                self.pins[p][n].set(self.name, (o >> n) & 1 if (d >> n) & 1 else None)
            diff >>= 1
            n += 1

    def _load(self, p: int, out: int) -> None:
        self.out[p] = out & self.pinmask
        self._apply(p)

    def reset(self) -> None:
        """Reset values (0 everywhere): the output latches too, and every pin is released (DIR = 0)."""
        super().reset()
        for p in range(self.ports):
            self._load(p, 0)

    # --- port registers --------------------------------------------------------------------------
    @staticmethod
    def _port(reg_name: str) -> int:
        return int(reg_name.lstrip("ABCDEFGHIJKLMNOPQRSTUVWXYZ"))

    def write_register(self, reg, data, lanes=-1):
        self._cur = self._port(reg.name) if reg.offset >= 0x2000 else None
        super().write_register(reg, data, lanes)

    def _write_dir(self, old, new):
        self._apply(self._cur)

    def _write_pin(self, old, new):
        self._load(self._cur, new)

    def _write_mpin(self, old, new):
        p = self._cur
        mask = self.value[f"MASK{p}"]
        self._load(p, (self.out[p] & mask) | (new & ~mask))

    def _write_set(self, old, new):
        self._load(self._cur, self.out[self._cur] | new)

    def _write_clr(self, old, new):
        self._load(self._cur, self.out[self._cur] & ~new)

    def _write_not(self, old, new):
        self._load(self._cur, self.out[self._cur] ^ new)

    def _read_pin(self, stored):
        return self.levels(self._cur)

    def _read_mpin(self, stored):
        return self.levels(self._cur) & ~self.value[f"MASK{self._cur}"] & self.pinmask

    def _read_out(self, stored):
        return self.out[self._cur]

    def register_names(self) -> list[str]:
        """The port registers and the pin registers B<k>/W<k> (k = 32·port + pin), which are
        decoded from the offset and made when first accessed."""
        pins = [32 * p + n for p in range(self.ports) for n in range(self.npins)]
        return super().register_names() + [f"B{k}" for k in pins] + [f"W{k}" for k in pins]

    # --- bus ---------------------------------------------------------------------------------------
    def _decode(self, offset: int, size: int, address: int):
        """-> (Register, port, pin or None); BusFault for anything that is not a register."""
        if offset < 0x1000:
            if size != 1:
                raise BusFault(address, size, f"{self.name} byte pin registers B take 8-bit accesses only")
            k = offset - B_BASE
        elif size != 4:
            raise BusFault(address, size, f"{self.name} word registers take 32-bit accesses only")
        elif offset < 0x2000:
            k = (offset - W_BASE) // 4
        else:
            reg = self._by_offset.get(offset)
            if reg is None:
                raise BusFault(address, size, f"no register of {self.name} at offset {offset:#x}")
            return reg, self._port(reg.name), None
        p, n = divmod(k, 32)
        if p >= self.ports or n >= self.npins:
            raise BusFault(address, size, f"no register of {self.name} at offset {offset:#x} "
                                          f"(GPIO{p}[{n}] does not exist)")
        reg = self._pin_regs.get(offset)
        if reg is None:
            kind = "B" if offset < 0x1000 else "W"
            reg = self._pin_regs[offset] = Register(f"{kind}{k}", offset, width=8 if kind == "B" else 32)
        return reg, p, n

    def bus_read(self, offset, size, address):
        reg, p, n = self._decode(offset, size, address)
        if n is None:
            self._cur = p
            return super().bus_read(offset, size, address)
        level = self.pins[p][n].level
        value = (0x01 if reg.width == 8 else 0xFFFFFFFF) if level else 0
        if self.access_log is not None:
            self.access_log("read", self, reg, value, value)
        return value

    def bus_write(self, offset, data, size, address):
        reg, p, n = self._decode(offset, size, address)
        if n is None:
            super().bus_write(offset, data, size, address)
            return
        bit = data & 1 if reg.width == 8 else int(data != 0)
        old = (self.out[p] >> n) & 1
        self._load(p, (self.out[p] & ~(1 << n)) | (bit << n))
        if self.access_log is not None:
            self.access_log("write", self, reg, data, old)

    def _reg_at(self, offset, size, address):
        # only reached from Peripheral.bus_read/bus_write for the port registers (decoded above)
        return self._by_offset[offset]
