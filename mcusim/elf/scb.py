"""The Cortex-M system registers startup and HAL code touch, for a compiled image: SCB (CPUID,
ICSR, VTOR, AIRCR, SCR, CCR, SHPR1-3, SHCSR, fault status, the cache identification registers,
CPACR), the FPU's FPCCR, STIR,
CoreDebug DEMCR and the DWT cycle counter (Armv7-M ARM B3.2, C1.8; the Cortex-M7 and -M4 TRMs
for the reset values).

Modelled: what these bits do to the exception model (:mod:`mcusim.elf.exceptions`): VTOR moves
the vector table, AIRCR.PRIGROUP splits priorities, SHPRx set the system handlers' priorities,
ICSR pends and clears PendSV and SysTick and reports the active and pending exception,
SCR.SLEEPONEXIT sleeps on return to thread mode, CCR.STKALIGN aligns frames. Stored but without
effect (the core cannot honour them, see docs/firmware.md): CPACR (unicorn runs FP instructions
whatever it says), the caches' enable bits in CCR, FPCCR's lazy stacking (frames are stacked
eagerly). AIRCR.SYSRESETREQ and the fault-trap bits are refused as not modelled.
"""

from __future__ import annotations

from ..irq import PENDSV, SYSTICK
from ..registers import Field, Peripheral, Register

#: CPUID: the STM32F74x/75x carry Cortex-M7 r0p1 (ST errata sheet ES0290; FreeRTOS ships an
#: ARM_CM7/r0p1 port for these parts and its portCORTEX_M7_r0p1_ID = 0x410FC271 is what a
#: port built for the M4 asserts against); the LPC4337's Cortex-M4 is r0p1 (0x410FC241)
CPUID = {"cortex-m7": 0x410FC271, "cortex-m4": 0x410FC241}
#: Cortex-M7 with 4 KB two-way instruction and 4 KB four-way data caches of 32-byte lines (the
#: STM32F74x/75x configuration, RM0385 §2.1): CLIDR (level 1 separate instruction and data caches,
#: LoUU = LoC = 1) and CTR (32-byte lines) as the Cortex-M7 TRM gives them. A Cortex-M4 has no
#: caches: they read 0 there.
CACHES = {"cortex-m7": (0x09000003, 0x8303C003, (4096, 2), (4096, 4))}


def ccsidr(size_bytes: int, ways: int, line_bytes: int = 32) -> int:
    """CCSIDR of a cache of ``size_bytes`` in ``ways`` ways of ``line_bytes`` lines: WT, WB, RA and
    WA set (the TRM's values for the data cache; for the instruction cache an inference: CMSIS
    reads only the sets, ways and line size), sets − 1, ways − 1, log2(words per line) − 2."""
    sets = size_bytes // (ways * line_bytes)
    return (0xF << 28) | ((sets - 1) << 13) | ((ways - 1) << 3) | ((line_bytes // 4).bit_length() - 3)
_SHCSR_ACT = {4: 0, 5: 1, 6: 3, 11: 7, 12: 8, 14: 10, 15: 11}        # exception number: xxxACT bit
_SHCSR_PENDED = {6: 12, 4: 13, 5: 14, 11: 15}


class CoreScb(Peripheral):
    SIZE = 0x90
    REGISTERS = (
        Register("CPUID", 0x00, access="r"),
        Register("ICSR", 0x04, on_read="_read_icsr", on_write="_write_icsr", fields=(
            Field("VECTACTIVE", 0, 9, access="r"), Field("RETTOBASE", 11, access="r"),
            Field("VECTPENDING", 12, 9, access="r"), Field("ISRPENDING", 22, access="r"),
            Field("PENDSTCLR", 25, access="w"), Field("PENDSTSET", 26, access="w"),
            Field("PENDSVCLR", 27, access="w"), Field("PENDSVSET", 28, access="w"),
            Field("NMIPENDSET", 31, modelled=False, doc="no NMI source or NMI handling is modelled"))),
        Register("VTOR", 0x08, on_write="_write_vtor", fields=(Field("TBLOFF", 7, 25),)),
        Register("AIRCR", 0x0C, on_read="_read_aircr", on_write="_write_aircr", fields=(
            Field("VECTRESET", 0, modelled=False), Field("VECTCLRACTIVE", 1, modelled=False),
            Field("SYSRESETREQ", 2, modelled=False), Field("PRIGROUP", 8, 3),
            Field("ENDIANNESS", 15, access="r"), Field("VECTKEY", 16, 16, access="w"))),
        Register("SCR", 0x10, on_write="_write_scr", fields=(
            Field("SLEEPONEXIT", 1), Field("SLEEPDEEP", 2), Field("SEVONPEND", 4))),
        Register("CCR", 0x14, reset=0x200, on_write="_write_ccr", fields=(
            Field("NONBASETHRDENA", 0, modelled=False), Field("USERSETMPEND", 1, modelled=False),
            Field("UNALIGN_TRP", 3, modelled=False,
                  doc="the core cannot trap unaligned accesses without a hook on every access"),
            Field("DIV_0_TRP", 4, modelled=False,
                  doc="the core cannot trap a division by zero: SDIV/UDIV give 0, as with DIV_0_TRP = 0"),
            Field("BFHFNMIGN", 8, modelled=False), Field("STKALIGN", 9), Field("DC", 16), Field("IC", 17),
            Field("BP", 18))),
        Register("SHPR1", 0x18, on_write="_write_shpr"),
        Register("SHPR2", 0x1C, on_write="_write_shpr"),
        Register("SHPR3", 0x20, on_write="_write_shpr"),
        Register("SHCSR", 0x24, on_read="_read_shcsr", on_write="_write_shcsr", fields=(
            Field("MEMFAULTACT", 0), Field("BUSFAULTACT", 1), Field("USGFAULTACT", 3), Field("SVCALLACT", 7),
            Field("MONITORACT", 8), Field("PENDSVACT", 10), Field("SYSTICKACT", 11),
            Field("USGFAULTPENDED", 12), Field("MEMFAULTPENDED", 13), Field("BUSFAULTPENDED", 14),
            Field("SVCALLPENDED", 15), Field("MEMFAULTENA", 16), Field("BUSFAULTENA", 17),
            Field("USGFAULTENA", 18))),
        Register("CFSR", 0x28, access="rc_w1"),
        Register("HFSR", 0x2C, access="rc_w1"),
        Register("DFSR", 0x30, access="rc_w1"),
        Register("MMFAR", 0x34),
        Register("BFAR", 0x38),
        Register("AFSR", 0x3C),
        # which cache CCSIDR describes: CSSELR.InD = 1 the instruction cache; only level 1 exists
        Register("CLIDR", 0x78, access="r"),
        Register("CTR", 0x7C, access="r"),
        Register("CCSIDR", 0x80, access="r", on_read="_read_ccsidr"),
        Register("CSSELR", 0x84, fields=(Field("InD", 0), Field("Level", 1, 3))),
        Register("CPACR", 0x88, fields=(Field("CP10", 20, 2), Field("CP11", 22, 2))),
    )

    def __init__(self, nvic, exc_model, kind="cortex-m7", name="SCB"):
        super().__init__(name)
        self.nvic, self.exc = nvic, exc_model
        self.value["CPUID"] = CPUID.get(kind, CPUID["cortex-m4"])
        self.value["VTOR"] = exc_model.vtor
        clidr, ctr, icache, dcache = CACHES.get(kind, (0, 0, None, None))
        self.value["CLIDR"], self.value["CTR"] = clidr, ctr
        self._ccsidr = {1: ccsidr(*icache), 0: ccsidr(*dcache)} if icache else {1: 0, 0: 0}

    def _read_ccsidr(self, stored):
        sel = self.value["CSSELR"]
        return self._ccsidr[sel & 1] if (sel >> 1) & 7 == 0 else 0

    def _read_icsr(self, stored):
        exc = self.exc
        active = exc.active[-1] if exc.active else 0
        pend = exc.pending_exception() or 0
        v = active | (pend << 12)
        if len(exc.active) <= 1:
            v |= 1 << 11
        if any(n >= 0 for n in self.nvic.pending):
            v |= 1 << 22
        if PENDSV in self.nvic.pending:
            v |= 1 << 28
        if SYSTICK in self.nvic.pending:
            v |= 1 << 26
        return v

    def _status(self):
        """SHCSR's active and pending bits as the exception model has them (B3.2.13)."""
        v = 0
        for exc in self.exc.active:
            v |= 1 << _SHCSR_ACT.get(exc, 32)
        for exc, bit in _SHCSR_PENDED.items():
            if exc - 16 in self.nvic.pending:
                v |= 1 << bit
        return v & 0xFFFF

    def _read_shcsr(self, stored):
        return (stored & 0x70000) | self._status()

    def _write_shcsr(self, old, new):
        from ..errors import UnsupportedConfiguration
        if (new ^ self._status()) & 0xFFFF:     # (a read-modify-write leaves them as they are)
            raise UnsupportedConfiguration(self.name, "SHCSR", "active/pending bits", new & 0xFFFF,
                                           "(changing an exception's state through SHCSR) is not modelled")
        self.value["SHCSR"] = new & 0x70000

    def _write_icsr(self, old, new):
        for bit, irqn, setting in ((28, PENDSV, True), (27, PENDSV, False), (26, SYSTICK, True),
                                   (25, SYSTICK, False)):
            if new >> bit & 1:
                if setting:
                    self.nvic.set_pending(irqn)
                else:
                    self.nvic.pending.discard(irqn)

    def _write_vtor(self, old, new):
        self.exc.vtor = new

    def _read_aircr(self, stored):
        return (0xFA05 << 16) | (stored & 0x700)

    def _write_aircr(self, old, new):
        from ..errors import UnsupportedConfiguration
        if new >> 16 != 0x05FA:
            self.value["AIRCR"] = old         # a write without the key is ignored
            return
        if new & 0x7:
            raise UnsupportedConfiguration(self.name, "AIRCR", "SYSRESETREQ", new & 7, "(a reset request) is not modelled")
        self.exc.prigroup = (new >> 8) & 7
        self.nvic._changed()                  # a new group split may let a pending one preempt now

    def _write_scr(self, old, new):
        self.exc.sleeponexit = bool(new & 2)

    def _write_ccr(self, old, new):
        self.exc.stkalign = bool(new & 0x200)

    def _write_shpr(self, old, new):
        # SHPR1: MemManage(4) BusFault(5) UsageFault(6); SHPR2: SVCall(11); SHPR3: PendSV(14) SysTick(15)
        shift = 8 - self.nvic.prio_bits
        keep = (0xFF << shift) & 0xFF
        # bytes of reserved priorities read 0: SHPR1's 7th, SHPR2's 8-10, SHPR3's 13
        for reg, first, used in (("SHPR1", 4, 0x00FFFFFF), ("SHPR2", 8, 0xFF000000), ("SHPR3", 12, 0xFFFF00FF)):
            v = self.value[reg] & (keep * 0x01010101) & used
            self.value[reg] = v
            for b in range(4):
                exc = first + b
                if exc in (4, 5, 6, 11, 12, 14, 15):
                    self.nvic.priority[exc - 16] = ((v >> (8 * b)) & 0xFF) >> shift
        self.nvic._changed()


class Fpu(Peripheral):
    """FPCCR, FPCAR, FPDSCR at 0xE000EF34 (base 0xE000EF30). FPCCR.ASPEN = 0: exceptions stack no
    FP state (the frame follows ASPEN and CONTROL.FPCA); LSPEN is stored: stacking is eager."""
    SIZE = 0x10
    REGISTERS = (Register("FPCCR", 0x4, reset=0xC0000000, on_write="_write_fpccr"), Register("FPCAR", 0x8),
                 Register("FPDSCR", 0xC))
    exc = None                                # the exception model, once the core exists

    def _write_fpccr(self, old, new):
        if self.exc is not None:
            self.exc.aspen = bool(new >> 31)


class Stir(Peripheral):
    """Software Trigger Interrupt Register (0xE000EF00): writing n pends interrupt n."""
    SIZE = 0x4
    REGISTERS = (Register("STIR", 0x0, access="w", on_write="_write"),)

    def __init__(self, nvic, name="STIR"):
        super().__init__(name)
        self.nvic = nvic

    def _write(self, old, new):
        if (new & 0x1FF) < self.nvic.num_irqs:
            self.nvic.set_pending(new & 0x1FF)


class CoreDebug(Peripheral):
    """DHCSR, DCRSR, DCRDR, DEMCR at 0xE000EDF0: DEMCR.TRCENA (bit 24) powers the DWT: its cycle
    counter stands still while TRCENA = 0 (Armv7-M ARM C1.6.5, C1.8.8)."""
    SIZE = 0x10
    REGISTERS = (Register("DHCSR", 0x0, access="r"), Register("DCRSR", 0x4, access="w"), Register("DCRDR", 0x8),
                 Register("DEMCR", 0xC, on_write="_write_demcr"))

    def __init__(self, dwt, name="CoreDebug"):
        super().__init__(name)
        self.dwt = dwt

    def _write_demcr(self, old, new):
        self.dwt.set_gates(trcena=bool(new >> 24 & 1))


class Dwt(Peripheral):
    """DWT_CTRL and DWT_CYCCNT (0xE0001000): CYCCNT counts core cycles while CYCCNTENA = 1 and
    DEMCR.TRCENA = 1."""
    SIZE = 0x1000
    REGISTERS = (
        Register("CTRL", 0x0, reset=0x40000000, on_write="_write_ctrl", fields=(
            Field("CYCCNTENA", 0), Field("NUMCOMP", 28, 4, access="r"))),
        Register("CYCCNT", 0x4, on_read="_read_cyccnt", on_write="_write_cyccnt"),
        Register("LAR", 0xFB0, access="w"),
    )

    def __init__(self, mcu, name="DWT"):
        super().__init__(name)
        self.kernel, self.period = mcu.kernel, mcu.core_clock.period
        self._base = None          # (cycle at which CYCCNT held _val)
        self._val = 0
        self._ena = self._trc = False

    def _cycles(self):
        return self.kernel.now // self.period

    def _read_cyccnt(self, stored):
        if self._base is None:
            return self._val
        return (self._val + self._cycles() - self._base) & 0xFFFFFFFF

    def _write_cyccnt(self, old, new):
        self._val = new
        self._base = self._cycles() if self._base is not None else None

    def _write_ctrl(self, old, new):
        self.set_gates(ena=bool(new & 1))

    def set_gates(self, ena=None, trcena=None):
        self._ena = self._ena if ena is None else ena
        self._trc = self._trc if trcena is None else trcena
        on = self._ena and self._trc
        if on and self._base is None:
            self._base = self._cycles()
        elif not on and self._base is not None:
            self._val = self._read_cyccnt(0)
            self._base = None
