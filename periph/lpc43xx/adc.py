"""LPC4337 ADC0/ADC1 (10-bit SAR, UM10503 "ADC0/1"), event-driven.

Sources: NXP UM10503 and the LPC4337 data sheet (instances and IRQs, register map, timing, modes
and flags, transfer function). Tags: [V] read in a source, [I] our inference.

Instances: ADC0 at 0x400E3000 (NVIC IRQ 17), ADC1 at 0x400E4000 (IRQ 21); the board builder attaches
them. 32-bit accesses only. ``clock`` is PCLK_ADC (BASE_APB3: 204 MHz under LPCOpen/sAPI, 12 MHz
under NuttX lpc4337-ws, §1.1).

Registers (§1.2): CR 0x000 (SEL, CLKDIV, BURST, CLKS, PDN, START, EDGE; reset 0), GDR 0x004 (RESULT
15:6, CHN 26:24, OVERRUN 30, DONE 31), INTEN 0x00C (ADINTEN 7:0, ADGINTEN 8; reset 0x100), DR0..DR7
0x010..0x02C (RESULT, OVERRUN, DONE), STAT 0x030 (DONE 7:0, OVERRUN 15:8, ADINT 16). Offset 0x008 and
everything above 0x030 in the 4 KB slot is a bus fault. GDR, DRn and STAT reset to 0 (the sheet's
suggestion; the chip leaves them undefined).

Modelled
--------
* ADC clock = PCLK_ADC / (CLKDIV + 1). Every event is at ``t_start + k * (CLKDIV + 1) * period`` with
  ``period`` the PCLK period in base ticks, so it is a whole number of PCLK cycles; nothing is
  computed in floats.
* **ADC clock phase (choice):** the divider restarts on the CR write that starts a conversion. The
  conversion starts on the first PCLK edge at or after the write (on a 204 MHz board that is the
  write tick itself) and ends exactly 11 (software) or 11 - CLKS (burst) ADC clocks later.
* **Sampling instant (choice):** the input is sampled (``AnalogNet.voltage(t)`` is called with that
  tick) one ADC clock after the start, i.e. at the end of the first ADC clock. Reason: the datasheet's
  source-impedance rule Rs < 1/(7 fclk Cia) - 2 kOhm (§1.3) is "7 time constants in one ADC clock",
  i.e. the hold capacitor tracks during one ADC clock; and in burst mode, where conversions follow
  each other without a gap, that tracking must lie inside the conversion. The sheet does not give the
  instant [I]. This costs one kernel event for the sample and one for the completion.
* Transfer function (§1.5 [I]): code = min(1023, floor(Vin * 1024 / VREF)), computed exactly with
  Fractions on the shortest decimal form of the float voltages (so 1.65 V at 3.3 V is 512); negative
  inputs give 0. ``vref`` is VDDA (3.3 V).
* Software mode (BURST = 0): every CR write with START = 001 (and PDN = 1) starts one conversion of the
  SEL channel (SEL = 0 converts channel 0, "all zeros behaves like 0x01"); START does not clear itself
  (§1.4 [I]). More than one SEL bit raises UnsupportedConfiguration (ADCn.CR.SEL). CLKS is ignored
  (11 clocks, 10 bits).
* Burst mode (BURST = 1, START = 000): continuous conversions of the SEL channels, lowest first, then
  upwards, wrapping to the lowest (§1.4 [I]); each takes 11 - CLKS ADC clocks and keeps 10 - CLKS
  result bits, the low CLKS bits of RESULT read 0 (§1.4 [I]). The next conversion starts at the
  completion tick of the previous one. A CR write that keeps BURST = 1 does not disturb the running
  conversion; the SEL, CLKS and CLKDIV it writes apply from the next conversion (the next channel is
  the next selected one above the channel just converted, wrapping). Clearing BURST lets the running
  conversion complete, then the converter stops.
* **CR write during a conversion (choice, the usual reading of §1.2 GDR.DONE "If CR is written while a
  conversion is in progress, DONE is set and a new conversion starts"):** a write that requests a new
  conversion (START = 001 with BURST = 0, or BURST 0 -> 1) aborts the running conversion (its channel's
  DRn is not written), sets GDR.DONE (GDR.RESULT/CHN keep the previous result) and starts the new
  conversion. A write that requests nothing new (START = 000, BURST left at 1, or BURST 1 -> 0) lets
  the running conversion complete. A write with PDN = 0 aborts it (no result, no DONE).
* **PDN = 0 (choice):** a write that requests a conversion (START = 001 or BURST = 1) with PDN = 0
  raises UnsupportedConfiguration (ADCn.CR.PDN): on the chip nothing starts and a polling loop hangs
  silently; failing loudly shows the bug at the write.
* ADC clock above 4.5 MHz (§1.3, DS Table 37): checked when a write starts conversions (the burst
  configuration is checked at every CR write while BURST = 1). With ``strict=True`` it raises
  McusimError naming ADCn, CLKDIV, the clock in MHz and the 4.5 MHz limit; otherwise it warns
  (:class:`AdcClockWarning`, a UserWarning) once per (PCLK, CLKDIV) pair, appends the message to
  ``self.warnings``, and converts at the programmed clock anyway. Exactly 4.5 MHz is allowed ("must be
  <= 4.5 MHz").
* An input outside 0 V .. VDDA (the absolute maximum of a pin in analog mode, DS Table 37 VIA):
  the code saturates (0 or 1023), and the sample warns (:class:`AdcInputWarning`) once per channel
  and side, or raises McusimError with ``strict=True``: a battery wired without its divider.
* Flags (§1.2, §1.4): at completion RESULT is written to DRn and GDR (with CHN) and both DONE bits are
  set. In burst mode OVERRUN is set in DRn (GDR) when the result overwrites one whose DONE is still set
  (DONE stays set); OVERRUN stays set until the register is read. In software mode an unread result is
  overwritten without OVERRUN ("burst mode only", §1.2). Reading DRn clears DRn.DONE and
  DRn.OVERRUN; reading GDR clears GDR.DONE and GDR.OVERRUN; any CR write clears GDR.DONE. GDR.DONE and
  DRn.DONE are independent (§1.4 [I]). STAT is a pure mirror; reading it clears nothing.
* **Read-only registers (choice):** writes to GDR, DRn and STAT are ignored (as the APB slave does);
  they change no flag.
* Interrupt (§1.4 [V/I]): STAT.ADINT = (DONE[7:0] & ADINTEN) != 0 or (GDR.DONE and ADGINTEN), driven
  level-sensitively on ``mcu.irq.set_line(irq, ADINT)`` whenever it can change. The sheet's "ADGINTEN
  must be 0 in burst mode" [I] is not enforced: the formula is applied as it stands.
* A conversion of a channel without an AnalogNet raises UnsupportedConfiguration (ADCn.CR.SEL, naming
  the channel) at the CR write that requests it. A channel whose net nothing drives (declared in
  ``inputs`` but not wired in ``[analog]``, never set from Python) converts 0 V and warns once
  (AdcInputWarning; an error with ``strict``): on the chip an open pin reads an undefined value.
* ``adc.done`` (a :class:`mcusim.firmware.Signal`) fires after every completion, once the registers
  and the interrupt line are updated, so a busy-wait on STAT/GDR/DRn can block. ``conversions``
  counts completions; ``history`` holds (t_start, t_sample, t_done, channel, RESULT) per conversion.

Not modelled: hardware start triggers START = 010..110 (CTOUT_15, CTOUT_8, ADCTRIG0/1, MCOA2: they
need the SCT / timers / GIMA) raise UnsupportedConfiguration, as does the reserved START = 111 and a
START other than 000 with BURST = 1; EDGE is stored and has no effect. DMA requests, the CCU1 branch
clock enable, PCLK changes while a conversion runs, the power-up settling time after PDN, INL/DNL/
offset/gain errors, the source impedance and the sample-and-hold charge sharing (§1.3), the 1.2 kOhm
board resistor (§2) are not modelled.
"""

from __future__ import annotations

import math
import warnings
from fractions import Fraction
from functools import partialmethod

from mcusim.errors import ConfigError, McusimError, UnsupportedConfiguration
from mcusim.firmware import Signal
from mcusim.kernel import PRIO_HW
from mcusim.recent import RecentLog
from mcusim.registers import Field, Peripheral, Register
from mcusim.signals import exact_voltage as _exact

from .cgu import BaseClockUser

DONE = 1 << 31
OVERRUN = 1 << 30
ADGINTEN = 1 << 8
MAX_ADC_HZ = Fraction(4_500_000)    # DS Table 37 fclk(ADC) max, §1.3
SOFTWARE_CLOCKS = 11                # §1.3: 11 ADC clocks per software-mode conversion
TRIGGERS = {2: "edge on CTOUT_15", 3: "edge on CTOUT_8", 4: "edge on ADCTRIG0",
            5: "edge on ADCTRIG1", 6: "edge on motor-control PWM output MCOA2"}


class AdcClockWarning(UserWarning):
    """The ADC clock PCLK_ADC / (CLKDIV + 1) is above the 4.5 MHz maximum of the data sheet."""


class AdcInputWarning(UserWarning):
    """A sampled input is outside 0 V .. VDDA, the range of a pin in analog mode."""




def _mhz(hz: Fraction) -> str:
    return f"{float(hz) / 1e6:.5g}"  # for messages only


def _result_fields():
    return (Field("RESULT", 6, 10, access="r"), Field("OVERRUN", 30, access="rc_r"),
            Field("DONE", 31, access="rc_r"))


class _Conversion:
    __slots__ = ("bits", "burst", "channel", "result", "t_done", "t_sample", "t_start")

    def __init__(self, channel, t_start, t_sample, t_done, bits, burst):
        self.channel, self.t_start, self.t_sample, self.t_done = channel, t_start, t_sample, t_done
        self.bits, self.burst, self.result = bits, burst, None


class Adc(BaseClockUser, Peripheral):
    RGU_RESET = True  # the RGU may call reset() (periph/lpc43xx/rgu.py)
    SIZE = 0x1000     # one 4 KB APB3 slot (ADC1 follows ADC0 at +0x1000)
    BUS_WIDTH = 4
    ACCESS_SIZES = (4,)
    REGISTERS = (
        Register("CR", 0x000, on_write="_write_cr", fields=(
            Field("SEL", 0, 8), Field("CLKDIV", 8, 8), Field("BURST", 16), Field("CLKS", 17, 3),
            Field("PDN", 21), Field("START", 24, 3), Field("EDGE", 27))),
        Register("GDR", 0x004, on_read="_read_gdr", fields=(
            Field("RESULT", 6, 10, access="r"), Field("CHN", 24, 3, access="r"),
            Field("OVERRUN", 30, access="rc_r"), Field("DONE", 31, access="rc_r"))),
        Register("INTEN", 0x00C, reset=0x100, on_write="_write_inten", fields=(
            Field("ADINTEN", 0, 8), Field("ADGINTEN", 8))),
        *(Register(f"DR{n}", 0x010 + 4 * n, on_read=f"_read_dr{n}", fields=_result_fields())
          for n in range(8)),
        Register("STAT", 0x030, fields=(
            Field("DONE", 0, 8, access="r"), Field("OVERRUN", 8, 8, access="r"),
            Field("ADINT", 16, access="r"))),
    )

    def __init__(self, name, mcu, clock, inputs=None, irq=17, vref=3.3, strict=False, base_clock=""):
        super().__init__(name)
        self.mcu, self.kernel, self.clock = mcu, mcu.kernel, clock
        self._init_base_clock(base_clock)
        self.irq = irq
        self.inputs = dict(inputs or {})
        for ch in self.inputs:
            if not (isinstance(ch, int) and 0 <= ch <= 7):
                raise ConfigError(f"{name}: input channel {ch!r} is not one of 0..7")
        self.vref = _exact(vref)
        if self.vref <= 0:
            raise ConfigError(f"{name}: vref {vref} V must be positive")
        self.strict = strict
        self.conversions = 0
        self.warnings: list[str] = []
        self.history = RecentLog()   # (t_start, t_sample, t_done, channel, result): the recent ones
        self.done = Signal()
        self._warned: set[tuple[Fraction, int]] = set()
        self._conv: _Conversion | None = None
        self._ev_sample = self._ev_done = None

    # --- helpers -------------------------------------------------------------------------------
    def _cr(self, name: str, cr: int | None = None) -> int:
        return self.regs["CR"].by_name[name].get(self.value["CR"] if cr is None else cr)

    @property
    def adc_clock_hz(self) -> Fraction:
        return Fraction(self.clock.hz) / (self._cr("CLKDIV") + 1)

    @property
    def busy(self) -> bool:
        return self._conv is not None

    @staticmethod
    def code(vin: Fraction, vref: Fraction, bits: int = 10) -> int:
        """RESULT (10-bit scale) for ``vin``: floor(Vin * 2^bits / VREF) clamped, low 10 - bits zero."""
        n = int((vin * (1 << bits)) // vref)
        return max(0, min((1 << bits) - 1, n)) << (10 - bits)

    @staticmethod
    def _channels(sel: int) -> list[int]:
        sel = sel or 1  # "all zeros behaves like 0x01" (§1.2 CR.SEL)
        return [n for n in range(8) if sel >> n & 1]

    def _refresh(self) -> None:
        """Recompute the STAT mirror and ADINT, and drive the interrupt line (level)."""
        done = ovr = 0
        for n in range(8):
            v = self.value[f"DR{n}"]
            done |= (v >> 31 & 1) << n
            ovr |= (v >> 30 & 1) << n
        inten = self.value["INTEN"]
        adint = bool(done & inten & 0xFF) or bool(self.value["GDR"] & DONE and inten & ADGINTEN)
        self.value["STAT"] = done | ovr << 8 | int(adint) << 16
        self.mcu.irq.set_line(self.irq, adint)

    def _check(self, cr: int) -> bool:
        """Validate a CR value before anything changes. True if it requests conversions."""
        sel, clkdiv, burst = self._cr("SEL", cr), self._cr("CLKDIV", cr), self._cr("BURST", cr)
        pdn, start = self._cr("PDN", cr), self._cr("START", cr)
        if start == 7:
            raise UnsupportedConfiguration(self.name, "CR", "START", start, "is reserved")
        if start in TRIGGERS:
            raise UnsupportedConfiguration(
                self.name, "CR", "START", start,
                f"({TRIGGERS[start]}) is not modelled: hardware start triggers need the SCT/timers")
        if burst and start:
            raise UnsupportedConfiguration(self.name, "CR", "START", start,
                                           "with BURST = 1: START must be 000 in burst mode")
        wants = bool(burst or start == 1)
        if not wants:
            return False
        if not pdn:
            raise UnsupportedConfiguration(
                self.name, "CR", "PDN", 0,
                "(power-down) while START = 001 or BURST = 1 asks for a conversion: the converter "
                "does not run; set PDN = 1 first")
        if not burst and sel.bit_count() > 1:
            raise UnsupportedConfiguration(
                self.name, "CR", "SEL", sel,
                "selects more than one channel with BURST = 0 (software mode converts one channel)")
        for ch in self._channels(sel):
            if ch not in self.inputs:
                raise UnsupportedConfiguration(
                    self.name, "CR", "SEL", sel,
                    f"selects channel {ch} ({self.name}_{ch}), which has no AnalogNet connected")
        self._check_clock(clkdiv)
        return True

    def _check_clock(self, clkdiv: int) -> None:
        hz = Fraction(self.clock.hz)
        f = hz / (clkdiv + 1)
        if f <= MAX_ADC_HZ:
            return
        min_div = math.ceil(hz / MAX_ADC_HZ) - 1
        msg = (f"{self.name}: ADC clock {_mhz(f)} MHz = PCLK_ADC {_mhz(hz)} MHz / (CLKDIV {clkdiv} + 1) "
               f"is above the 4.5 MHz maximum (data sheet Table 37); CLKDIV >= {min_div} keeps it "
               f"at or below 4.5 MHz")
        self._limit(msg, (hz, clkdiv), AdcClockWarning)

    def _limit(self, msg: str, key, category) -> None:
        """A specification limit exceeded: McusimError with ``strict``, else one warning per
        ``key`` (appended to ``self.warnings`` as well)."""
        if self.strict:
            raise McusimError(msg)
        if key not in self._warned:
            self._warned.add(key)
            self.warnings.append(msg)
            warnings.warn(msg, category, stacklevel=3)

    # --- register hooks ------------------------------------------------------------------------
    def _write_cr(self, old: int, new: int) -> None:
        try:
            wants = self._check(new)
            if wants and self._cr("PDN", new):
                self._check_base_clock()
        except McusimError:
            self.value["CR"] = old  # a refused write leaves CR as it was (also for the strict clock error)
            raise
        self.clear_bits("GDR", DONE)  # "cleared ... when CR is written" (§1.2 GDR.DONE)
        burst = self._cr("BURST", new)
        if not self._cr("PDN", new):
            self._abort()  # power-down: the running conversion is lost
        elif wants and (not burst or not self._cr("BURST", old) or not self.busy):
            if self.busy:
                # choice: abort and restart; "DONE is set and a new conversion starts" (§1.2)
                self._abort()
                self.set_bits("GDR", DONE)
            self._begin(self.clock.next_edge(self.kernel.now), self._channels(self._cr("SEL", new))[0])
        self._refresh()

    def _write_inten(self, old: int, new: int) -> None:
        self._refresh()

    def _read_gdr(self, stored: int) -> int:
        self.clear_bits("GDR", DONE | OVERRUN)
        self._refresh()
        return stored

    def _read_dr(self, n: int, stored: int) -> int:
        self.clear_bits(f"DR{n}", DONE | OVERRUN)
        self._refresh()
        return stored

    _read_dr0 = partialmethod(_read_dr, 0)
    _read_dr1 = partialmethod(_read_dr, 1)
    _read_dr2 = partialmethod(_read_dr, 2)
    _read_dr3 = partialmethod(_read_dr, 3)
    _read_dr4 = partialmethod(_read_dr, 4)
    _read_dr5 = partialmethod(_read_dr, 5)
    _read_dr6 = partialmethod(_read_dr, 6)
    _read_dr7 = partialmethod(_read_dr, 7)

    def reset(self) -> None:
        self._abort()
        super().reset()
        self._refresh()

    # --- conversion ----------------------------------------------------------------------------
    def _begin(self, t_start: int, channel: int) -> None:
        self._check_base_clock()
        burst = bool(self._cr("BURST"))
        clks = self._cr("CLKS") if burst else 0
        pt = self.clock.period * (self._cr("CLKDIV") + 1)  # base ticks per ADC clock
        c = _Conversion(channel, t_start, t_start + pt, t_start + (SOFTWARE_CLOCKS - clks) * pt,
                        10 - clks, burst)
        self._conv = c
        self._ev_sample = self.kernel.at(c.t_sample, self._sample, prio=PRIO_HW)
        self._ev_done = self.kernel.at(c.t_done, self._complete, prio=PRIO_HW)

    def _abort(self) -> None:
        for ev in (self._ev_sample, self._ev_done):
            if ev is not None:
                ev.cancel()
        self._ev_sample = self._ev_done = None
        self._conv = None

    def _sample(self) -> None:
        self._ev_sample = None
        c = self._conv
        net = self.inputs[c.channel]
        if net.floating:
            self._limit(f"{self.name}: channel {c.channel} ({net.name}) is converted but nothing drives it (no "
                        "part's output is wired to it in [analog], and nothing set it): it reads 0 V here, an "
                        "undefined value on an open pin of the chip", ("floating", c.channel), AdcInputWarning)
        vin = _exact(net.voltage(self.kernel.now))
        if not 0 <= vin <= self.vref:
            self._check_input(c.channel, vin)
        c.result = self.code(vin, self.vref, c.bits)

    def _check_input(self, channel: int, vin: Fraction) -> None:
        """An input outside 0 V .. VDDA: beyond the absolute maximum of a pin in analog mode (data
        sheet Table 37, VIA). The code saturates as the transfer function says; warned once per
        channel and side (an error with ``strict``): a source wired without its divider."""
        side = "above VDDA" if vin > self.vref else "below 0 V"
        msg = (f"{self.name}: channel {channel} samples {float(vin):.4g} V, {side} ({float(self.vref):g} V): "
               f"outside the input range of a pin in analog mode, 0 V .. VDDA (its absolute maximum, data "
               f"sheet Table 37); the result saturates at {0 if vin < 0 else 1023}")
        self._limit(msg, ("input", channel, side), AdcInputWarning)

    def _complete(self) -> None:
        c, now = self._conv, self.kernel.now
        self._conv = self._ev_done = None
        self.conversions += 1
        self.history.append((c.t_start, c.t_sample, now, c.channel, c.result))
        word = c.result << 6
        dr = f"DR{c.channel}"
        for reg, extra in ((dr, 0), ("GDR", c.channel << 24)):
            old = self.value[reg]
            lost = OVERRUN if (old & OVERRUN or (c.burst and old & DONE)) else 0
            self.value[reg] = word | extra | DONE | lost
        if self._cr("BURST") and self._cr("PDN"):
            chans = self._channels(self._cr("SEL"))
            nxt = next((ch for ch in chans if ch > c.channel), chans[0])
            self._begin(now, nxt)
        self._refresh()
        self.done.fire()
