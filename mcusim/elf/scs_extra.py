"""The rest of the System Control Space that CMSIS start-up and HAL code touch, for a compiled
image: the Cortex-M7 cache maintenance registers (their identification registers are the SCB's,
:mod:`.scb`), the MPU, ICTR and ACTLR,
and the ITM's control registers (Armv7-M ARM B3.2.3, B3.5, B4.8, C1.7; Cortex-M7 TRM for the
cache geometry).

What they do here. The model has no caches and does not enforce the MPU: memory is always
coherent, every access runs at the core's one cycle model, and an access a region would forbid
runs as if the MPU were off. So cache maintenance operations (``SCB_EnableDCache``'s set/way
loop, ``SCB_CleanDCache_by_Addr``) are accepted and do nothing, the cache geometry reads as the
chip's (so that loop runs its real count of steps), and the MPU's regions are stored and read
back as written: a correct image behaves as on the chip; an image that relies on an MPU fault
(a stack guard region) is not caught. The ITM has no trace port: writes to its stimulus ports go
nowhere and a port always reads as ready.
"""

from __future__ import annotations

from ..errors import UnsupportedConfiguration
from ..registers import Field, Peripheral, Register


class CacheMaintenance(Peripheral):
    """The cache and branch predictor maintenance operations (0xE000EF50, Cortex-M7): each is a
    write-only register whose write is the operation. Memory is coherent here: they do nothing."""
    SIZE = 0x2C
    REGISTERS = tuple(Register(n, off, access="w") for n, off in (
        ("ICIALLU", 0x00), ("ICIMVAU", 0x08), ("DCIMVAC", 0x0C), ("DCISW", 0x10), ("DCCMVAU", 0x14),
        ("DCCMVAC", 0x18), ("DCCSW", 0x1C), ("DCCIMVAC", 0x20), ("DCCISW", 0x24), ("BPIALL", 0x28)))


class Mpu(Peripheral):
    """MPU_TYPE, MPU_CTRL, MPU_RNR, MPU_RBAR, MPU_RASR and their aliases A1-A3 (0xE000ED90): the
    regions are stored and read back, not enforced (module docstring). A write to RBAR with VALID
    set selects the region its REGION field names, as on the chip (B3.5.9)."""
    SIZE = 0x2C
    REGISTERS = (
        Register("TYPE", 0x00, access="r", fields=(Field("SEPARATE", 0, access="r"),
                                                   Field("DREGION", 8, 8, access="r"),
                                                   Field("IREGION", 16, 8, access="r"))),
        Register("CTRL", 0x04, fields=(Field("ENABLE", 0), Field("HFNMIENA", 1), Field("PRIVDEFENA", 2))),
        Register("RNR", 0x08, on_write="_write_rnr", fields=(Field("REGION", 0, 8),)),
    ) + tuple(r for k, suffix in enumerate(("", "_A1", "_A2", "_A3")) for r in (
        Register("RBAR" + suffix, 0x0C + 8 * k, on_read="_read_rbar", on_write="_write_rbar"),
        Register("RASR" + suffix, 0x10 + 8 * k, on_read="_read_rasr", on_write="_write_rasr")))

    def __init__(self, regions: int = 8, name="MPU"):
        super().__init__(name)
        self.regions = regions
        self.value["TYPE"] = regions << 8
        self._rbar = [0] * regions
        self._rasr = [0] * regions

    def _write_rnr(self, old, new):
        if new & 0xFF >= self.regions:
            raise UnsupportedConfiguration(self.name, "RNR", "REGION", new & 0xFF,
                                           f"(the MPU has regions 0 to {self.regions - 1})")

    def _read_rbar(self, stored):
        r = self.value["RNR"] & 0xFF
        return self._rbar[r] | r

    def _write_rbar(self, old, new):
        if new & 0x10:                        # VALID: REGION selects the region, and RNR follows
            region = new & 0xF
            if region >= self.regions:
                raise UnsupportedConfiguration(self.name, "RBAR", "REGION", region,
                                               f"(the MPU has regions 0 to {self.regions - 1})")
            self.value["RNR"] = region
        self._rbar[self.value["RNR"] & 0xFF] = new & 0xFFFFFFE0

    def _read_rasr(self, stored):
        return self._rasr[self.value["RNR"] & 0xFF]

    def _write_rasr(self, old, new):
        self._rasr[self.value["RNR"] & 0xFF] = new


class ScnScb(Peripheral):
    """ICTR and ACTLR (0xE000E000, B3.2.2): ICTR gives the number of interrupt lines in groups of
    32; ACTLR's implementation-defined bits (folding, write buffer) are stored."""
    SIZE = 0x10
    REGISTERS = (Register("ICTR", 0x4, access="r", fields=(Field("INTLINESNUM", 0, 4, access="r"),)),
                 Register("ACTLR", 0x8))

    def __init__(self, irqs: int, name="SCnSCB"):
        super().__init__(name)
        self.value["ICTR"] = max(0, (irqs + 31) // 32 - 1)


class Itm(Peripheral):
    """The ITM (0xE0000000, C1.7): stimulus ports 0-31, TER, TPR, TCR, LAR. Without a trace port
    a port's write goes nowhere and its read says the FIFO is ready (bit 0), so CMSIS's
    ``ITM_SendChar`` never waits; TER, TPR and TCR are stored."""
    SIZE = 0x1000
    REGISTERS = tuple(Register(f"PORT{k}", 4 * k, on_read="_read_port") for k in range(32)) + (
        Register("TER", 0xE00), Register("TPR", 0xE40), Register("TCR", 0xE80), Register("LAR", 0xFB0, access="w"))

    def _read_port(self, stored):
        return 1
