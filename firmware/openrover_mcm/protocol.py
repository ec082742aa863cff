"""The module's I2C protocol: a small register map (documented in docs/openrover_mcm_i2c.md).

A master writes ``[register, data...]`` to set registers, or ``[register]`` then reads N bytes
(repeated START or a separate transaction) to read from that register on, the pointer advancing
byte by byte. Multi-byte values are little-endian. Shared by the module firmware (slave) and the
robot controller (master).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

WHO_AM_I_VALUE = 0x4D          # 'M'
FW_VERSION = (1, 0)
DEFAULT_ADDRESS = 0x08


@dataclass(frozen=True)
class Reg:
    name: str
    addr: int
    fmt: str          # struct format, little-endian
    writable: bool

    @property
    def size(self) -> int:
        return struct.calcsize("<" + self.fmt)


REGISTERS = (
    Reg("WHO_AM_I", 0x00, "B", False),
    Reg("VERSION", 0x01, "BB", False),
    Reg("STATUS", 0x03, "B", False),
    Reg("CONTROL", 0x04, "B", True),
    Reg("SETPOINT", 0x08, "i", True),     # velocity set point, encoder counts per second
    Reg("POSITION", 0x0C, "H", False),    # encoder count, 16 bits, wrapping
    Reg("CURRENT", 0x0E, "h", False),     # motor current, mA, signed by drive direction
    Reg("CHARGE", 0x10, "I", False),      # accumulated |current|, mA·s (millicoulombs)
    Reg("KP", 0x14, "f", True),
    Reg("KI", 0x18, "f", True),
    Reg("KD", 0x1C, "f", True),
    Reg("VELOCITY", 0x20, "i", False),    # measured velocity, counts per second
    Reg("ERROR", 0x24, "B", False),       # last error code (cleared by CONTROL.CLEAR)
)
BY_NAME = {r.name: r for r in REGISTERS}
BY_ADDR = {r.addr: r for r in REGISTERS}
MAP_SIZE = max(r.addr + r.size for r in REGISTERS)

# STATUS bits
ST_PID_ENABLED, ST_STALL, ST_OVERCURRENT, ST_ERROR, ST_MOVING = 0x01, 0x02, 0x04, 0x08, 0x10
# CONTROL bits
CTL_PID_ENABLE, CTL_CLEAR_FAULTS = 0x01, 0x02
# ERROR codes
ERR_NONE, ERR_UNKNOWN_REGISTER, ERR_SHORT_WRITE, ERR_READ_ONLY = 0, 1, 2, 3


def encode(name: str, *values) -> bytes:
    r = BY_NAME[name]
    return struct.pack("<" + r.fmt, *values)


def decode(name: str, data: bytes):
    r = BY_NAME[name]
    v = struct.unpack("<" + r.fmt, bytes(data[: r.size]))
    return v[0] if len(v) == 1 else v
