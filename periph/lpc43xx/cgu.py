"""LPC43xx clock generation unit (CGU) and clock control units (CCU1, CCU2), as far as LPCOpen's
start-up (SystemInit, Chip_SetupXtalClocking / Chip_SetupCoreClock) and drivers (Chip_Clock_*)
read and write them (UM10503 chapters 12 and 13; offsets and bit positions from the manual's
register tables).

The core clock is the board's (``[clocks] sysclk``, 204 MHz on ``ciaa-edu``): the time base is
fixed, so the CGU cannot change it. Register reset values are the state LPCOpen's
Chip_SetupCoreClock(CLKIN_CRYSTAL, 204 MHz, true) leaves, as if the start-up code had run (the
STM32 RCC model does the same): crystal on, PLL1 in direct mode at 204 MHz from the 12 MHz
crystal (M = 17, N = 1), BASE_M4_CLK and the peripheral base clocks on PLL1.

Rules:

* a status follows its enable at once (oscillator and PLL start-up and lock times are not
  modelled): PLL1_STAT.LOCK = not PLL1_CTRL.PD, PLL0USB/PLL0AUDIO_STAT read LOCK and FR while
  their PD bit is clear; a CCU branch's STAT follows its CFG;
* BASE_M4_CLK (the core clock) must give the board's core clock, through whatever chain feeds it
  (crystal, PLL1, an integer divider). Accepted besides, for at most ``TRANSIENT_S`` (2 ms): the
  IRC and the crystal (12 MHz), which LPCOpen selects for a few instructions while it reprograms
  PLL1, and PLL1 at half the core clock, the ramp step UM10503 requires before running above
  110 MHz (LPCOpen clears DIRECT, waits about 50 us, sets it). The core keeps running at the
  board's clock meanwhile; a core still on such a clock when the 2 ms are up is refused then.
  Anything else is refused at the write that makes it, naming the register and the frequency:
  a BASE_M4_CLK selection, and a write to any register of the chain feeding it (PLL1_CTRL,
  XTAL_OSC_CTRL: the crystal switched off under the core, an IDIVx_CTRL);
* PLL1's current-controlled oscillator runs only between 156 and 320 MHz (UM10503): a PLL1_CTRL
  that powers it up outside that range is refused (the chip would never lock);
* the CCU1 branch clock of the core (CLK_M4_M4CORE) cannot be stopped (the core would stop);
* everything else is stored: the other base clocks, the integer dividers, PLL0USB/PLL0AUDIO
  (their dividers are not decoded), the branch clocks. Gating is not modelled: a peripheral whose
  branch clock is off still responds. The modelled ADC, I2C and USART run at their profile's
  clock; one whose profile names its base clock (``base_clock = "BASE_APB3_CLK"``) checks, each
  time it starts a conversion, a transfer or a frame, that the base clock gives that frequency
  (:meth:`Cgu.check_base_clock`), and refuses to run otherwise (a base clock on the crystal, an
  integer divider, powered down).

FREQ_MON measures at once: writing MEAS = 1 counts the selected clock against RCNT cycles of the
12 MHz IRC and clears MEAS (a clock the model does not know, such as an Ethernet PHY clock,
counts 0).
"""

from __future__ import annotations

from fractions import Fraction
from functools import partialmethod
from typing import ClassVar

from mcusim.errors import ConfigError, UnsupportedConfiguration
from mcusim.registers import Field, Peripheral, Register

IRC_HZ = 12_000_000
#: how long the core may run on LPCOpen's transitional clocks (the IRC or crystal while PLL1 is
#: reprogrammed, PLL1's 102 MHz ramp step): its start-up leaves them within microseconds
TRANSIENT_S = Fraction(2, 1000)
#: PLL1's CCO range (UM10503, PLL1 description)
CCO_MIN, CCO_MAX = 156_000_000, 320_000_000
# clock source numbers of the CLK_SEL fields (UM10503 Table "Clock source selection")
SRC_32K, SRC_IRC, SRC_XTAL, SRC_PLL0USB, SRC_PLL0AUDIO, SRC_PLL1 = 0x00, 0x01, 0x06, 0x07, 0x08, 0x09
SRC_IDIV = {0x0C: "IDIVA_CTRL", 0x0D: "IDIVB_CTRL", 0x0E: "IDIVC_CTRL", 0x0F: "IDIVD_CTRL", 0x10: "IDIVE_CTRL"}
SOURCE_NAMES = {0x00: "32 kHz oscillator", 0x01: "IRC", 0x02: "ENET_RX_CLK", 0x03: "ENET_TX_CLK", 0x04: "GP_CLKIN",
                0x06: "crystal oscillator", 0x07: "PLL0USB", 0x08: "PLL0AUDIO", 0x09: "PLL1",
                0x0C: "IDIVA", 0x0D: "IDIVB", 0x0E: "IDIVC", 0x0F: "IDIVD", 0x10: "IDIVE"}

_SEL = Field("CLK_SEL", 24, 5)
_AUTOBLOCK = Field("AUTOBLOCK", 11)


def _pll0(prefix, base, frac=False):
    regs = [
        Register(f"{prefix}_STAT", base, access="r", on_read=f"_read_{prefix.lower()}_stat", fields=(
            Field("LOCK", 0, access="r"), Field("FR", 1, access="r"))),
        Register(f"{prefix}_CTRL", base + 4, reset=0x0100_0003, fields=(
            Field("PD", 0), Field("BYPASS", 1), Field("DIRECTI", 2), Field("DIRECTO", 3), Field("CLKEN", 4),
            Field("FRM", 6), _AUTOBLOCK, Field("PLLFRACT_REQ", 12), Field("SEL_EXT", 13),
            Field("MOD_PD", 14), _SEL)),
        Register(f"{prefix}_MDIV", base + 8),
        Register(f"{prefix}_NP_DIV", base + 12),
    ]
    if frac:
        regs.append(Register(f"{prefix}_FRAC", base + 16))
    return regs


def _idiv(letter, offset, bits):
    return Register(f"IDIV{letter}_CTRL", offset, reset=0x0100_0000, on_write=f"_write_idiv{letter}", fields=(
        Field("PD", 0), Field("IDIV", 2, bits), _AUTOBLOCK, _SEL))


# (name, offset, reset): the state InitClkStates of LPCOpen's sysinit leaves (PLL1 = 0x09 with
# AUTOBLOCK; USB0 and ADCHS on their source but powered down; the clock outputs powered down)
_PLL1_AB = 0x0900_0800
_BASES = (
    ("BASE_SAFE_CLK", 0x5C, 0x0100_0800), ("BASE_USB0_CLK", 0x60, 0x0700_0801),
    ("BASE_PERIPH_CLK", 0x64, _PLL1_AB), ("BASE_USB1_CLK", 0x68, 0x0100_0000),
    ("BASE_M4_CLK", 0x6C, _PLL1_AB), ("BASE_SPIFI_CLK", 0x70, 0x0100_0000),
    ("BASE_SPI_CLK", 0x74, _PLL1_AB), ("BASE_PHY_RX_CLK", 0x78, 0x0100_0000),
    ("BASE_PHY_TX_CLK", 0x7C, 0x0100_0000), ("BASE_APB1_CLK", 0x80, _PLL1_AB),
    ("BASE_APB3_CLK", 0x84, _PLL1_AB), ("BASE_LCD_CLK", 0x88, 0x0100_0000),
    ("BASE_ADCHS_CLK", 0x8C, _PLL1_AB | 1), ("BASE_SDIO_CLK", 0x90, _PLL1_AB),
    ("BASE_SSP0_CLK", 0x94, _PLL1_AB), ("BASE_SSP1_CLK", 0x98, _PLL1_AB),
    ("BASE_UART0_CLK", 0x9C, _PLL1_AB), ("BASE_UART1_CLK", 0xA0, _PLL1_AB),
    ("BASE_UART2_CLK", 0xA4, _PLL1_AB), ("BASE_UART3_CLK", 0xA8, _PLL1_AB),
    ("BASE_OUT_CLK", 0xAC, 0x0100_0801), ("BASE_AUDIO_CLK", 0xC0, 0x0100_0801),
    ("BASE_CGU_OUT0_CLK", 0xC4, 0x0100_0801), ("BASE_CGU_OUT1_CLK", 0xC8, 0x0100_0801),
)


def _base(name, offset, reset):
    sel = Field("CLK_SEL", 24, 5, access="r") if name == "BASE_SAFE_CLK" else _SEL   # the IRC only
    return Register(name, offset, reset=reset, fields=(Field("PD", 0), _AUTOBLOCK, sel),
                    on_write="_write_base_m4" if name == "BASE_M4_CLK" else None)


class Cgu(Peripheral):
    SIZE = 0x1000
    REGISTERS = (
        Register("FREQ_MON", 0x14, on_write="_write_freq_mon", fields=(
            Field("RCNT", 0, 9), Field("FCNT", 9, 14, access="r"), Field("MEAS", 23), _SEL)),
        # crystal on (ENABLE = 0 is "on"), no bypass; HF stays as at chip reset (LPCOpen only sets it
        # for a crystal of 20 MHz or more)
        Register("XTAL_OSC_CTRL", 0x18, reset=0x4, on_write="_write_xtal",
                 fields=(Field("ENABLE", 0), Field("BYPASS", 1), Field("HF", 2))),
        *_pll0("PLL0USB", 0x1C),
        *_pll0("PLL0AUDIO", 0x2C, frac=True),
        Register("PLL1_STAT", 0x40, access="r", on_read="_read_pll1_stat", fields=(Field("LOCK", 0, access="r"),)),
        # direct mode, M = 17, N = 1, from the crystal: 204 MHz
        Register("PLL1_CTRL", 0x44, reset=0x0610_0080, on_write="_write_pll1_ctrl", fields=(
            Field("PD", 0), Field("BYPASS", 1), Field("FBSEL", 6), Field("DIRECT", 7), Field("PSEL", 8, 2),
            _AUTOBLOCK, Field("NSEL", 12, 2), Field("MSEL", 16, 8), _SEL)),
        _idiv("A", 0x48, 2), _idiv("B", 0x4C, 4), _idiv("C", 0x50, 4), _idiv("D", 0x54, 4), _idiv("E", 0x58, 8),
        *(_base(*b) for b in _BASES),
    )

    def __init__(self, name, mcu, xtal_hz=12_000_000):
        super().__init__(name)
        self.mcu = mcu
        self.core_hz = Fraction(mcu.core_clock.hz)
        self.xtal_hz = Fraction(xtal_hz)
        self._transient_ev = None      # the check that the core left a transitional clock
        self.writes = 0                # register writes so far: base clock users re-check after one

    def write_register(self, reg, data, lanes=-1):
        self.writes += 1
        super().write_register(reg, data, lanes)

    # --- frequencies ---------------------------------------------------------------------------
    def source_hz(self, sel: int, depth: int = 0) -> Fraction | None:
        """The frequency of clock source ``sel`` as the registers set it; 0 when it is off; None
        when the model does not know it (an external clock, PLL0USB/PLL0AUDIO)."""
        if sel == SRC_32K:
            creg = self.mcu.periph.get("CREG")
            # CREG0: RESET32KHZ or PD32KHZ holds the 32 kHz oscillator off
            return Fraction(0) if creg is not None and creg.value["CREG0"] & 0b1100 else Fraction(32768)
        if sel == SRC_IRC:
            return Fraction(IRC_HZ)
        if sel == SRC_XTAL:
            return Fraction(0) if self.value["XTAL_OSC_CTRL"] & 1 else self.xtal_hz
        if sel == SRC_PLL1:
            return self.pll1_hz(self.value["PLL1_CTRL"])
        if sel in SRC_IDIV and depth < 3:
            reg = SRC_IDIV[sel]
            if self.value[reg] & 1:
                return Fraction(0)
            src = self.source_hz(self.field(reg, "CLK_SEL"), depth + 1)
            return None if src is None else src / (self.field(reg, "IDIV") + 1)
        return None

    def pll1_cco_hz(self, ctrl: int) -> Fraction | None:
        """PLL1's CCO frequency for a PLL1_CTRL value (UM10503): M·Fin/N in direct and non-integer
        mode, 2P times the output in integer mode; None when it does not run (powered down,
        bypassed) or its input is unknown."""
        if ctrl & 1 or ctrl >> 1 & 1:
            return None
        fin = self.source_hz((ctrl >> 24) & 0x1F)
        if fin is None:
            return None
        m, n, p = ((ctrl >> 16) & 0xFF) + 1, ((ctrl >> 12) & 3) + 1, 1 << ((ctrl >> 8) & 3)
        direct, fbsel = ctrl >> 7 & 1, ctrl >> 6 & 1
        return fin * m / n * (2 * p if fbsel and not direct else 1)

    def pll1_hz(self, ctrl: int) -> Fraction | None:
        """PLL1's output for a PLL1_CTRL value (UM10503, PLL1 modes): direct, M·Fin/N; integer
        (FBSEL = 1), M·Fin/N with the CCO at 2P times that; non-integer, M·Fin/(2P·N); bypass,
        Fin (direct) or Fin/(2P). 0 while powered down."""
        if ctrl & 1:
            return Fraction(0)
        fin = self.source_hz((ctrl >> 24) & 0x1F)
        if fin is None:
            return None
        m, n, p = ((ctrl >> 16) & 0xFF) + 1, ((ctrl >> 12) & 3) + 1, 1 << ((ctrl >> 8) & 3)
        direct, fbsel, bypass = ctrl >> 7 & 1, ctrl >> 6 & 1, ctrl >> 1 & 1
        if bypass:
            return fin if direct else fin / (2 * p)
        if direct or fbsel:
            return fin * m / n
        return fin * m / (n * 2 * p)

    def base_hz(self, base: str) -> Fraction | None:
        """The frequency base clock ``base`` (``"BASE_APB3_CLK"``) gives as the registers set it: 0
        when it is powered down or its source is off, None when the model does not know it."""
        v = self.value[base]
        return Fraction(0) if v & 1 else self.source_hz((v >> 24) & 0x1F)

    def check_base_clock(self, user) -> None:
        """For a peripheral model about to run (``user``: its ``name``, ``clock``, ``base_clock``):
        the base clock feeding it must give the clock it was built with, as the models do not follow
        a base clock's changes. Checked when it runs, not when the CGU is written: a firmware may
        move or power down the base clock of a peripheral it does not use. Else
        UnsupportedConfiguration naming the base clock and what it gives."""
        base = user.base_clock
        hz = self.base_hz(base)
        if hz == user.clock.hz:
            return
        got = ("is powered down" if self.value[base] & 1 else
               f"selects {SOURCE_NAMES.get((self.value[base] >> 24) & 0x1F, 'a reserved source')}"
               + ("" if not hz else f", {float(hz) / 1e6:g} MHz") + (" (off)" if hz == 0 else ""))
        raise UnsupportedConfiguration(
            self.name, base, None, self.value[base],
            f"{got}: {user.name} runs on it, and its model runs at the board's "
            f"{float(user.clock.hz) / 1e6:g} MHz (the peripherals do not follow a base clock's changes)")

    # --- the core clock ------------------------------------------------------------------------
    def _check_m4(self, reg: str, value: int) -> None:
        """After a write to ``reg`` (already stored; a refusal puts it back): the core's clock, as
        BASE_M4_CLK and the chain feeding it now give it, is the board's, or one of LPCOpen's
        transitional clocks (for TRANSIENT_S at most). Else UnsupportedConfiguration."""
        base = self.value["BASE_M4_CLK"]
        if base & 1:
            raise UnsupportedConfiguration(self.name, reg, None, value,
                                           "powers down BASE_M4_CLK, the core's clock: not modelled")
        sel = (base >> 24) & 0x1F
        hz = self.source_hz(sel)
        if hz == self.core_hz:
            self._transient(None)
            return
        if (sel in (SRC_IRC, SRC_XTAL) and hz) or (sel == SRC_PLL1 and hz == self.core_hz / 2):
            self._transient(sel)      # LPCOpen's clock while it reprograms PLL1, or the ramp step
            return
        what = SOURCE_NAMES.get(sel, f"clock source {sel:#x}")
        given = "a frequency the model does not know" if hz is None else f"{float(hz) / 1e6:g} MHz"
        raise UnsupportedConfiguration(self.name, reg, None, value,
                                       f"gives the core {given} from {what}; the board runs at "
                                       f"{float(self.core_hz) / 1e6:g} MHz ([clocks] sysclk)")

    def _transient(self, sel) -> None:
        """Start (``sel``: the transitional source) or end (None) the core's stay on a
        transitional clock; one that lasts TRANSIENT_S is refused then."""
        kernel = self.mcu.kernel
        if sel is None:
            if self._transient_ev is not None:
                self._transient_ev.cancel()
                self._transient_ev = None
            return
        if self._transient_ev is None:
            self._transient_ev = kernel.at(kernel.now + kernel.timebase.ticks(TRANSIENT_S), self._stayed)

    def _stayed(self) -> None:
        self._transient_ev = None
        sel = (self.value["BASE_M4_CLK"] >> 24) & 0x1F
        hz = self.source_hz(sel)
        raise UnsupportedConfiguration(
            self.name, "BASE_M4_CLK", None, self.value["BASE_M4_CLK"],
            f"has run the core on {float(hz or 0) / 1e6:g} MHz from {SOURCE_NAMES.get(sel, hex(sel))} for "
            f"{float(TRANSIENT_S) * 1e3:g} ms: a core clock other than the board's "
            f"{float(self.core_hz) / 1e6:g} MHz is accepted only as LPCOpen's transitional step while "
            "it reprograms PLL1 (the simulated core keeps the board's clock)")

    def _write_base_m4(self, old, new):
        self._check_m4("BASE_M4_CLK", new)

    def _write_pll1_ctrl(self, old, new):
        cco = self.pll1_cco_hz(new)
        if cco is not None and not CCO_MIN <= cco <= CCO_MAX:
            raise UnsupportedConfiguration(self.name, "PLL1_CTRL", None, new,
                                           f"runs PLL1's CCO at {float(cco) / 1e6:g} MHz, outside its "
                                           "156-320 MHz range (UM10503): the PLL would not lock")
        self._check_m4("PLL1_CTRL", new)

    # the core's clock may come through the crystal or an integer divider
    def _write_chain(self, reg, old, new):
        self._check_m4(reg, new)

    _write_xtal = partialmethod(_write_chain, "XTAL_OSC_CTRL")
    _write_idivA = partialmethod(_write_chain, "IDIVA_CTRL")
    _write_idivB = partialmethod(_write_chain, "IDIVB_CTRL")
    _write_idivC = partialmethod(_write_chain, "IDIVC_CTRL")
    _write_idivD = partialmethod(_write_chain, "IDIVD_CTRL")
    _write_idivE = partialmethod(_write_chain, "IDIVE_CTRL")

    # --- status ----------------------------------------------------------------------------------
    def _read_pll1_stat(self, stored):
        return 0 if self.value["PLL1_CTRL"] & 1 else 1

    def _read_pll0usb_stat(self, stored):
        return 0 if self.value["PLL0USB_CTRL"] & 1 else 0b11       # LOCK and FR once powered up

    def _read_pll0audio_stat(self, stored):
        return 0 if self.value["PLL0AUDIO_CTRL"] & 1 else 0b11

    def _write_freq_mon(self, old, new):
        if not new >> 23 & 1:
            return
        rcnt = new & 0x1FF
        hz = self.source_hz((new >> 24) & 0x1F) or Fraction(0)
        fcnt = int(rcnt * hz / IRC_HZ)
        left = 0
        if fcnt > 0x3FFF:           # FCNT full first: RCNT keeps what it had left to count
            fcnt = 0x3FFF
            left = max(0, rcnt - -(-0x3FFF * IRC_HZ // hz))
        self.value["FREQ_MON"] = (new & ~((1 << 23) | (0x3FFF << 9) | 0x1FF)) | fcnt << 9 | left


# --- CCU1 / CCU2 ---------------------------------------------------------------------------------
# branch clocks by CFG offset (UM10503 Tables "Register overview: CCU1/CCU2"); each STAT at +4
CCU1_BRANCHES = {
    0x100: "APB3_BUS", 0x108: "APB3_I2C1", 0x110: "APB3_DAC", 0x118: "APB3_ADC0", 0x120: "APB3_ADC1",
    0x128: "APB3_CAN0",
    0x200: "APB1_BUS", 0x208: "APB1_MOTOCON_PWM", 0x210: "APB1_I2C0", 0x218: "APB1_I2S", 0x220: "APB1_CAN1",
    0x300: "SPIFI",
    0x400: "M4_BUS", 0x408: "M4_SPIFI", 0x410: "M4_GPIO", 0x418: "M4_LCD", 0x420: "M4_ETHERNET",
    0x428: "M4_USB0", 0x430: "M4_EMC", 0x438: "M4_SDIO", 0x440: "M4_DMA", 0x448: "M4_M4CORE",
    0x468: "M4_SCT", 0x470: "M4_USB1", 0x478: "M4_EMCDIV", 0x480: "M4_FLASHA", 0x488: "M4_FLASHB",
    0x490: "M4_M0APP", 0x498: "M4_ADCHS", 0x4A0: "M4_EEPROM",
    0x500: "M4_WWDT", 0x508: "M4_USART0", 0x510: "M4_UART1", 0x518: "M4_SSP0", 0x520: "M4_TIMER0",
    0x528: "M4_TIMER1", 0x530: "M4_SCU", 0x538: "M4_CREG",
    0x600: "M4_RITIMER", 0x608: "M4_USART2", 0x610: "M4_USART3", 0x618: "M4_TIMER2", 0x620: "M4_TIMER3",
    0x628: "M4_SSP1", 0x630: "M4_QEI",
    0x700: "PERIPH_BUS", 0x710: "PERIPH_CORE", 0x718: "PERIPH_SGPIO",
    0x800: "USB0", 0x900: "USB1", 0xA00: "SPI", 0xB00: "ADCHS",
}
CCU2_BRANCHES = {
    0x100: "AUDIO", 0x200: "APB2_USART3", 0x300: "APB2_USART2", 0x400: "APB0_UART1",
    0x500: "APB0_USART0", 0x600: "APB2_SSP1", 0x700: "APB0_SSP0", 0x800: "SDIO",
}
# BASE_STAT bit of each 0x100 page of branches (the base clock feeding them)
_CCU1_BASE_BIT = {1: 0, 2: 1, 3: 2, 4: 3, 5: 3, 6: 3, 7: 6, 8: 7, 9: 8, 10: 9, 11: 10}
_CCU2_BASE_BIT = {1: 0, 2: 1, 3: 2, 4: 3, 5: 4, 6: 5, 7: 6, 8: 7}
_CFG_FIELDS = (Field("RUN", 0), Field("AUTO", 1), Field("WAKEUP", 2), Field("DIV", 5, 3),
               Field("DIVSTAT", 27, 3, access="r"))


def _ccu_registers(branches):
    regs = [Register("PM", 0x000, fields=(Field("PD", 0),)),
            Register("BASE_STAT", 0x004, access="r", on_read="_read_base_stat")]
    for off, name in branches.items():
        # every branch clock runs after reset (RUN = 1)
        regs.append(Register(f"CLK_{name}_CFG", off, reset=1, fields=_CFG_FIELDS))
        regs.append(Register(f"CLK_{name}_STAT", off + 4, reset=1, access="r", fields=(
            Field("RUN", 0, access="r"), Field("AUTO", 1, access="r"), Field("WAKEUP", 2, access="r"))))
    return tuple(regs)


class _Ccu(Peripheral):
    SIZE = 0x1000
    BRANCHES: ClassVar[dict] = {}
    BASE_BIT: ClassVar[dict] = {}

    def __init__(self, name, mcu):
        super().__init__(name)
        self.mcu = mcu

    def write_register(self, reg, data, lanes=-1):
        old = self.value[reg.name]
        super().write_register(reg, data, lanes)
        if reg.name == "CLK_M4_M4CORE_CFG" and not self.value[reg.name] & 1:
            self.value[reg.name] = old      # a refused write leaves the register as it was
            raise UnsupportedConfiguration(self.name, reg.name, "RUN", 0,
                                           "stops the core's own branch clock: the core would stop (not modelled)")
        if reg.name == "PM" or reg.name.endswith("_CFG"):
            self._sync()

    def _sync(self) -> None:
        """Hardware's side: each STAT follows its CFG (and PM) at once."""
        for name in self.BRANCHES.values():
            self.value[f"CLK_{name}_STAT"] = self._stat(self.value[f"CLK_{name}_CFG"])

    def _stat(self, cfg: int) -> int:
        """A branch's STAT: RUN follows CFG.RUN at once, but a branch with WAKEUP set stops while
        PM.PD is set (the power-down sequence); AUTO and WAKEUP as configured."""
        run = cfg & 1 and not (self.value["PM"] & 1 and cfg >> 2 & 1)
        return (1 if run else 0) | (cfg & 0b110)

    def _read_base_stat(self, stored):
        """Bit k set when every branch clock the base clock k feeds is disabled."""
        running = set()
        for off, name in self.BRANCHES.items():
            if self._stat(self.value[f"CLK_{name}_CFG"]) & 1:
                running.add(self.BASE_BIT[off >> 8])
        return sum(1 << b for b in set(self.BASE_BIT.values()) - running)


class Ccu1(_Ccu):
    BRANCHES, BASE_BIT = CCU1_BRANCHES, _CCU1_BASE_BIT
    REGISTERS = _ccu_registers(CCU1_BRANCHES)


class Ccu2(_Ccu):
    BRANCHES, BASE_BIT = CCU2_BRANCHES, _CCU2_BASE_BIT
    REGISTERS = _ccu_registers(CCU2_BRANCHES)


BASE_CLOCKS = tuple(b[0] for b in _BASES)


class BaseClockUser:
    """Mixin of a peripheral model fed by a CGU base clock: ``base_clock`` (a BASE_x_CLK name, or
    "" for none) is checked with :meth:`Cgu.check_base_clock` each time it starts to run, and
    again after any CGU write only (it costs a lookup otherwise)."""

    def _init_base_clock(self, base_clock: str) -> None:
        if base_clock and base_clock not in BASE_CLOCKS:
            raise ConfigError(f"{self.name}: base_clock {base_clock!r} is not one of the CGU's "
                              f"({', '.join(BASE_CLOCKS)})")
        self.base_clock = base_clock or None
        self._cgu = None
        self._cgu_seen = -1

    def _check_base_clock(self) -> None:
        if self.base_clock is None:
            return
        cgu = self._cgu
        if cgu is None:
            cgu = self._cgu = next((p for p in self.mcu.periph.values() if isinstance(p, Cgu)), False)
        if cgu and cgu.writes != self._cgu_seen:
            cgu.check_base_clock(self)
            self._cgu_seen = cgu.writes
