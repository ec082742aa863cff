"""STM32F746 general-purpose and advanced timers TIM1-TIM5, TIM8 (time base, PWM, encoder).

Sources: ST RM0385, the TIM1/TIM8 and TIM2-TIM5 chapters ("the sheet" below; § marks are the
project's timer notes).

Modelled
--------
* Time base (§2): 16-bit PSC, always buffered (loaded at UEV); ARR with ARPE; 16-bit CNT (32-bit on
  TIM2/TIM5); up, down and centre-aligned counting (CMS=01/10/11, DIR read-only there); update event
  (UEV) on overflow and underflow; EGR.UG; URS; UDIS; OPM; repetition counter (TIM1/TIM8, 16 bits);
  CR1.UIFREMAP / CNT bit 31 = UIFCPY.
* Output compare (§3): CCR1-4 with OCxPE preload; OCxM frozen, force inactive/active, PWM1, PWM2;
  OCx = OCxREF xor CCxP when CCxE=1 (and BDTR.MOE=1 on TIM1/TIM8), else the port is not driven;
  CCxIF on compare match; DIER.UIE/CC1IE..CC4IE drive the NVIC lines as levels.
* Encoder mode SMS=001/010/011 (§4) with the direction table of §4.2, CCxP inversion, the ICxF filter
  with CKD, DIR, wrap in both directions with UEV, the up-only prescaler counter of §4.3, and the capture
  of CNT into CCR1/CCR2 on the active edge when CC1S/CC2S=01 and CCxE=1 (HAL_TIM_Encoder_Start sets
  CCxE). Input stage: :mod:`mcusim.periph.stm32.tim_input`.
* Everything else raises UnsupportedConfiguration when set to a non-reset value (invariant 7): other
  OCxM/SMS values, OCxCE, TS/ECE/ETR, CR2 (MMS, CCDS, OIS...), DMA enables, TIE/COMIE/BIE, CCxG/TG/COMG/
  BG, BDTR dead time/break/lock/OSSx/AOE, complementary outputs, channels 5/6, DCR/DMAR/OR, input capture
  outside encoder mode (CCxS!=00 with CCxE=1), CCxS=11 (TRC).

Choices where the sheet says [INF]/[UNVERIFIED]
-----------------------------------------------
* ARR reset value: constructor parameter ``arr_reset``, default 0 as RM0090/RM0390 (RM0385 value is
  [UNVERIFIED], §1.2). ARR=0 blocks the counter.
* CEN start latency (§2.1): the prescaler sees its first CK_INT edge one CK_INT cycle after the CEN
  write (the first edge at or after t_write + 1 cycle). With PSC=0, CEN written on a CK_INT edge t
  gives CNT+1 at t + 1 cycle.
* Any register write takes effect at its base tick; UG clears the prescaler counter at the first
  CK_INT edge at or after the write, so the next CK_CNT tick is (PSC+1) cycles after that edge; UIF from
  UG is set at once (no APB/kernel-domain delay modelled, §2.5).
* Centre-aligned UEV (§2.3 [INF]): overflow on the CK_CNT tick where CNT reaches ARR, underflow on the
  tick where CNT reaches 0. DIR reads 1 from CNT=ARR down to 1, 0 from CNT=0 up to ARR-1.
* CCxIF (§3.1): set on the CK_CNT tick on which CNT becomes equal to CCRx (not by CCR or CNT writes).
  In centre-aligned mode the tick's counting direction decides: CMS=01 flags only down-counting ticks
  (the tick into 0 included), CMS=10 only up-counting ticks (the tick into ARR included), 11 both.
* OCxREF is a continuous comparison (§3.1): PWM1 is 1 while CNT < CCR counting up and while CNT <= CCR
  counting down (PWM2 the complement); a CCR/mode write changes the output at once.
* OPM (§2.7): CEN is cleared by every UEV (UG included).
* UEV from UG sets UIF when URS=0 (old-HAL behaviour, §2.5/#30).
* Up-counting with CNT > ARR (ARR lowered, ARPE=0; open question 6): the counter runs to its maximum
  and wraps to 0 with an overflow [UNVERIFIED]. In centre-aligned mode the direction is not updated
  by a CNT above ARR: counting up, the counter goes on up ("Hints on using center-aligned mode",
  RM0008/RM0016: "if the counter was counting up, it continues to count up"), runs to its maximum
  and rolls over to 0 without an update event [INF: neither an overflow, reached at ARR, nor an
  underflow], then counts up to ARR as usual. Writing ARR or 0 into CNT updates the direction
  (down from ARR, up from 0) without a UEV, as the hint says.
* Encoder (§4): SMS=001 counts TI1 edges, 010 TI2 edges (HAL reading). DIR is updated on every decoded
  transition of TI1FP1/TI2FP2 while CEN=1. Input latency: see :mod:`mcusim.periph.stm32.tim_input` (sampled at
  the first CK_INT/f_SAMPLING edge strictly after the pin edge, +2 CK_INT resynchronisation). If TI1 and
  TI2 take effect on the same CK_INT edge (same sample) nothing is counted and DIR is unchanged (the RM
  calls it undefined, §4.3). Encoder counting with ARR=0 is blocked.
* set_kernel_clock: the counter and prescaler count are kept; the prescaler phase restarts on the new
  clock's next edge.

Performance: CNT is computed from (now - base) when read; the only scheduled events are the next wrap
(overflow/underflow, at which UEV/shadow loads happen) and, per channel, the next compare match when it
changes a driven output or sets a flag with its interrupt enabled (other CCxIF flags are set lazily when
SR is read). A steady 50 kHz PWM costs one wrap event plus one match event per driven channel per period.
"""

from __future__ import annotations

from mcusim.errors import UnsupportedConfiguration
from mcusim.registers import Field, Peripheral, Register
from mcusim.signals import Net, Port

from .tim_input import EncoderStage, TiInput
from .tim_lazy import EXIT_FIRST, LazyEncoderStage
from .tim_steady import SteadyStage

# CR1 bits (§1.2)
CEN, UDIS, URS, OPM, DIR, ARPE, UIFREMAP = 1 << 0, 1 << 1, 1 << 2, 1 << 3, 1 << 4, 1 << 7, 1 << 11
UIF = 1
CCIF = (0, 1 << 1, 1 << 2, 1 << 3, 1 << 4)
CCOF = (0, 1 << 9, 1 << 10, 1 << 11, 1 << 12)
CHANNELS = (1, 2, 3, 4)
OCM_SUPPORTED = {0b0000: "frozen", 0b0100: "force inactive", 0b0101: "force active",
                 0b0110: "PWM1", 0b0111: "PWM2"}
PWM1, PWM2, FORCE_INACTIVE, FORCE_ACTIVE = 0b0110, 0b0111, 0b0100, 0b0101
# registers whose writes may only reach a preload (the shadow changes at the next update event)
_PRELOADED = frozenset(("CCR1", "CCR2", "CCR3", "CCR4", "ARR", "PSC"))
INPUT = -1  # _mode value of a channel with CCxS != 00


def _u(name, lsb, width=1, access="rw"):
    """A field that exists on the chip but is not modelled: a non-reset value raises."""
    return Field(name, lsb, width, access=access, modelled=False)


def _ccmr(name, offset, a, b):
    return Register(name, offset, on_write=f"_write_{name.lower()}", fields=(
        Field(f"CC{a}S", 0, 2), Field(f"OC{a}FE", 2), Field(f"OC{a}PE", 3), Field(f"OC{a}M", 4, 3),
        Field(f"OC{a}CE", 7), Field(f"CC{b}S", 8, 2), Field(f"OC{b}FE", 10), Field(f"OC{b}PE", 11),
        Field(f"OC{b}M", 12, 3), Field(f"OC{b}CE", 15), Field(f"OC{a}M_3", 16), Field(f"OC{b}M_3", 24)),
        doc="output view; input view: ICxPSC = bits 3:2, ICxF = bits 7:4 (decoded in _write_ccmr)")


def _registers(bits: int, arr_reset: int) -> tuple:
    """The register map of §1.2; CNT/ARR/CCRx are ``bits`` wide."""
    cnt_fields = (Field("CNT", 0, bits),) + ((Field("UIFCPY", 31, access="r"),) if bits < 32 else ())
    return (
        Register("CR1", 0x00, on_write="_write_cr1", on_read="_read_cr1", fields=(
            Field("CEN", 0), Field("UDIS", 1), Field("URS", 2), Field("OPM", 3), Field("DIR", 4),
            Field("CMS", 5, 2), Field("ARPE", 7), Field("CKD", 8, 2), Field("UIFREMAP", 11))),
        Register("CR2", 0x04, fields=(
            _u("CCPC", 0), _u("CCUS", 2), _u("CCDS", 3), _u("MMS", 4, 3), _u("TI1S", 7), _u("OIS1", 8),
            _u("OIS1N", 9), _u("OIS2", 10), _u("OIS2N", 11), _u("OIS3", 12), _u("OIS3N", 13),
            _u("OIS4", 14), _u("OIS5", 16), _u("OIS6", 18), _u("MMS2", 20, 4))),
        Register("SMCR", 0x08, on_write="_write_smcr", fields=(
            Field("SMS", 0, 3), _u("TS", 4, 3), _u("MSM", 7), _u("ETF", 8, 4), _u("ETPS", 12, 2),
            _u("ECE", 14), _u("ETP", 15), Field("SMS_3", 16))),
        Register("DIER", 0x0C, on_write="_write_dier", fields=(
            Field("UIE", 0), Field("CC1IE", 1), Field("CC2IE", 2), Field("CC3IE", 3), Field("CC4IE", 4),
            _u("COMIE", 5), _u("TIE", 6), _u("BIE", 7), _u("UDE", 8), _u("CC1DE", 9), _u("CC2DE", 10),
            _u("CC3DE", 11), _u("CC4DE", 12), _u("COMDE", 13), _u("TDE", 14))),
        Register("SR", 0x10, on_write="_write_sr", on_read="_read_sr", fields=tuple(
            Field(n, b, access="rc_w0") for n, b in (
                ("UIF", 0), ("CC1IF", 1), ("CC2IF", 2), ("CC3IF", 3), ("CC4IF", 4), ("COMIF", 5),
                ("TIF", 6), ("BIF", 7), ("B2IF", 8), ("CC1OF", 9), ("CC2OF", 10), ("CC3OF", 11),
                ("CC4OF", 12), ("SBIF", 13), ("CC5IF", 16), ("CC6IF", 17)))),
        Register("EGR", 0x14, on_write="_write_egr", fields=(
            Field("UG", 0, access="w"),) + tuple(_u(n, b, access="w") for n, b in (
                ("CC1G", 1), ("CC2G", 2), ("CC3G", 3), ("CC4G", 4), ("COMG", 5), ("TG", 6), ("BG", 7),
                ("B2G", 8)))),
        _ccmr("CCMR1", 0x18, 1, 2),
        _ccmr("CCMR2", 0x1C, 3, 4),
        Register("CCER", 0x20, on_write="_write_ccer", fields=(
            Field("CC1E", 0), Field("CC1P", 1), _u("CC1NE", 2), _u("CC1NP", 3),
            Field("CC2E", 4), Field("CC2P", 5), _u("CC2NE", 6), _u("CC2NP", 7),
            Field("CC3E", 8), Field("CC3P", 9), _u("CC3NE", 10), _u("CC3NP", 11),
            Field("CC4E", 12), Field("CC4P", 13), _u("CC4NP", 15),
            _u("CC5E", 16), _u("CC5P", 17), _u("CC6E", 20), _u("CC6P", 21))),
        Register("CNT", 0x24, on_write="_write_cnt", on_read="_read_cnt", fields=cnt_fields),
        Register("PSC", 0x28, fields=(Field("PSC", 0, 16),)),  # preload; active copy loads at UEV
        Register("ARR", 0x2C, reset=arr_reset, on_write="_write_arr", fields=(Field("ARR", 0, bits),)),
        Register("RCR", 0x30, on_write="_write_rcr", fields=(Field("REP", 0, 16),)),
        Register("CCR1", 0x34, on_write="_write_ccr1", on_read="_read_ccr1", fields=(Field("CCR1", 0, bits),)),
        Register("CCR2", 0x38, on_write="_write_ccr2", on_read="_read_ccr2", fields=(Field("CCR2", 0, bits),)),
        Register("CCR3", 0x3C, on_write="_write_ccr3", fields=(Field("CCR3", 0, bits),)),
        Register("CCR4", 0x40, on_write="_write_ccr4", fields=(Field("CCR4", 0, bits),)),
        Register("BDTR", 0x44, on_write="_write_bdtr", fields=(
            _u("DTG", 0, 8), _u("LOCK", 8, 2), _u("OSSI", 10), _u("OSSR", 11), _u("BKE", 12),
            Field("BKP", 13), _u("AOE", 14), Field("MOE", 15), _u("BKF", 16, 4), _u("BK2F", 20, 4),
            _u("BK2E", 24), Field("BK2P", 25))),  # BKP/BK2P have no effect while BKE/BK2E=0
        Register("DCR", 0x48, fields=(_u("DBA", 0, 5), _u("DBL", 8, 5))),
        Register("DMAR", 0x4C, fields=(_u("DMAB", 0, 32),)),
        Register("OR", 0x50, fields=(_u("RMP", 0, 32),)),
        Register("CCMR3", 0x54, fields=(_u("CCMR3", 0, 32),)),
        Register("CCR5", 0x58, fields=(_u("CCR5", 0, 32),)),
        Register("CCR6", 0x5C, fields=(_u("CCR6", 0, 16),)),
    )


class Tim(EncoderStage, LazyEncoderStage, SteadyStage, Peripheral):
    SIZE = 0x400
    ACCESS_SIZES = (2, 4)  # RM: timer registers take half-word or word accesses

    def __init__(self, name: str, mcu, clock, irqs: dict, counter_bits: int = 16,
                 advanced: bool = False, arr_reset: int = 0):
        # ARR reset: RM0090/RM0390 say 0, RM0367 says all-ones; RM0385 is [UNVERIFIED] (§1.2)
        self.REGISTERS = _registers(counter_bits, arr_reset)
        super().__init__(name)
        self.mcu, self.kernel, self.nvic = mcu, mcu.kernel, mcu.nvic
        self.bits, self.mask, self.advanced = counter_bits, (1 << counter_bits) - 1, advanced
        self._irq_up = irqs["update"]
        self._irq_cc = irqs.get("cc", self._irq_up)
        self.oc: dict[int, Port] = {ch: Port(f"{name}_CH{ch}") for ch in CHANNELS}
        self.ti: dict[int, Net] = {ch: Net(f"{name}_TI{ch}") for ch in CHANNELS}
        self._P = clock.period          # base ticks per CK_INT cycle
        # counter state: CNT=_cnt at base tick _tb, where the prescaler counter was 0 (when _run)
        self._cnt, self._up, self._pscc, self._tb, self._run = 0, True, 0, 0, False
        self._psc = 0                   # active prescaler (shadow of PSC)
        self._tick = self._P            # base ticks per CK_CNT tick = (PSC_active+1) * P
        self._arr = arr_reset           # active auto-reload
        self._ccr = [0] * 5             # active compare registers (index = channel)
        self._rep = 0                   # repetition down-counter (TIM1/TIM8)
        self._t_wrap, self._ev_wrap = None, None
        self._ev_steady = None      # fast engine: the waveforms wait for the counter's first clock
        # decoded configuration (cached on register writes)
        self._cms, self._sms = 0, 0
        self._flag_up = self._flag_down = True
        self._mode = [0] * 5            # OCxM, or INPUT
        self._ocpe = [False] * 5
        self._icf = [0] * 5
        self._icpsc = [0] * 5
        self._pol = [0] * 5             # CCxP
        self._en = [False] * 5          # OCx driven: output mode, CCxE=1, (MOE=1 on TIM1/TIM8)
        self._cap = [False] * 5         # encoder-mode capture of CNT into CCRx on the active edge
        self._capn = [0] * 5            # ICxPSC event counters
        self._ccie = [False] * 5
        self._ref = [0] * 5             # OCxREF
        self._ev_cc = [None] * 5
        self._lazy = [None] * 5         # time of a CCxIF set not scheduled as an event
        self._inp = {1: TiInput(self.kernel, 1, self._ti_apply), 2: TiInput(self.kernel, 2, self._ti_apply)}
        self._steady, self._uif_lazy = False, None   # fast engine (tim_steady)
        self._enc_lazy = None           # fast engine: a lazy encoder stretch (tim_lazy)
        for ch in (1, 2):
            # outside encoder mode the inputs are ignored, so a waveform on them needs no edges;
            # an encoder's level descriptors are read lazily when lazy_enter takes them
            self.ti[ch].listen(self._ti_net, waves=lambda: not self._sms or self._enc_lazy is not None,
                               sinks=lambda desc, ch=ch: [(self, ch)])
        for ch in (3, 4):       # not modelled as inputs: never read
            self.ti[ch].listen(self._ti_net, waves=True, sinks=lambda desc: [])

    # ------------------------------------------------------------------ public helpers
    @property
    def counter(self) -> int:
        """CNT now, without side effects."""
        if self._enc_lazy is not None:
            self._lazy_sync()
        return self._cnt_at(self.kernel.now)

    def set_kernel_clock(self, clock) -> None:
        if self._enc_lazy is not None:   # the input stage's timing changes: edge by edge
            self._lazy_sync()
            self._enc_lazy.enc.materialize()
        self._sync()
        if self._run:
            self._pscc = max(0, (self.kernel.now - self._tb) // self._P)
            self._run = False  # _plan restarts the prescaler phase on the new clock
        self._P = clock.period
        self._tick = (self._psc + 1) * self._P
        self._plan()

    def pwm_waveform(self, ch: int):
        """(high base ticks, period base ticks) of OCx per counter period when steady in PWM, else None.

        §3.2 rules: edge-aligned up: CCR ticks high (clamped to ARR+1); down: CCR+1; centre: 2*CCR of
        2*ARR. PWM2 and CCxP=1 take the complement. Meant for fast-forwarding a steady configuration.
        """
        m = self._mode[ch]
        if not (self._run and self._en[ch] and m in (PWM1, PWM2)):
            return None
        arr, ccr = self._arr, self._ccr[ch]
        if self._cms:
            period, high = 2 * arr, 2 * min(ccr, arr)
        elif self._up:
            period, high = arr + 1, min(ccr, arr + 1)
        else:
            period, high = arr + 1, min(ccr + 1, arr + 1)
        if (m == PWM2) ^ bool(self._pol[ch]):
            high = period - high
        return high * self._tick, period * self._tick

    # ------------------------------------------------------------------ lazy counter
    def _cnt_at(self, t: int) -> int:
        if not self._run:
            return self._cnt
        if self._steady and self._ev_wrap is None:
            return self._steady_cnt_at(t)
        if t >= self._t_wrap:  # a wrap due now whose event has not run yet
            if self._cms:
                return self._arr if self._up and self._cnt <= self._arr else 0
            if self._up:
                return 0
            uev = self._rep == 0 and not self.value["CR1"] & UDIS
            return self.value["ARR"] if uev and self.value["CR1"] & ARPE else self._arr
        k = (t - self._tb) // self._tick
        if k <= 0:
            return self._cnt
        return self._cnt + k if self._up else self._cnt - k

    def _sync(self) -> None:
        """Bring _cnt/_tb to kernel.now (a whole number of CK_CNT ticks)."""
        if not self._run:
            return
        if self._steady and self._ev_wrap is None:
            self._steady_sync()
            return
        now = self.kernel.now
        if now >= self._t_wrap:
            self._wrap()
            return
        k = (now - self._tb) // self._tick
        if k > 0:
            self._cnt += k if self._up else -k
            self._tb += k * self._tick

    def _on_wrap(self) -> None:
        self._ev_wrap = None
        self._wrap()

    def _wrap(self) -> None:
        """Overflow/underflow at _t_wrap (§2.3); UEV unless UDIS or the repetition count is not 0."""
        self._tb = self._t_wrap
        up, arr_reached = self._up, self._arr
        if self._cms and up and self._cnt > arr_reached:
            # centre-aligned, counting up from above ARR: the roll-over from the counter's maximum
            # to 0 is no overflow (module doc); it goes on up to ARR
            self._cnt = 0
            self._plan(tick_up=True)
            return
        self._count_wrap()
        if self._cms == 0:
            self._cnt = 0 if up else self._arr  # down: ARR reloads before the counter (§2.4)
        elif up:  # centre-aligned: CNT reached ARR -> overflow, count down from there
            self._cnt, self._up = arr_reached, False
        else:     # CNT reached 0 -> underflow, count up
            self._cnt, self._up = 0, True
        self._plan(tick_up=up)

    def _count_wrap(self) -> None:
        """§2.6: the repetition counter decrements at each wrap; a UEV when it is 0 (unless UDIS)."""
        if self._rep:
            self._rep -= 1
        elif not self.value["CR1"] & UDIS:
            self._update_event(False)

    def _update_event(self, ug: bool) -> None:
        """§2.4: shadow loads (PSC, ARR if ARPE, CCRx if OCxPE, REP), UIF (not for UG with URS), OPM."""
        v = self.value
        cr1 = v["CR1"]
        psc = v["PSC"]
        if psc != self._psc:
            self._psc, self._tick = psc, (psc + 1) * self._P
        if cr1 & ARPE:
            self._arr = v["ARR"]
        ocpe, ccr = self._ocpe, self._ccr
        if ocpe[1]: ccr[1] = v["CCR1"]
        if ocpe[2]: ccr[2] = v["CCR2"]
        if ocpe[3]: ccr[3] = v["CCR3"]
        if ocpe[4]: ccr[4] = v["CCR4"]
        self._rep = v["RCR"]
        if not (ug and cr1 & URS):
            v["SR"] |= UIF
            self._irq()
        if cr1 & OPM:  # §2.7: the counter stops at the UEV
            v["CR1"] = cr1 & ~CEN

    def _plan(self, tick_up=None) -> None:
        """Re-derive outputs and schedule the next wrap and compare matches from the state at now.

        ``tick_up`` is not None when a CK_CNT tick (in that direction) happened at now: a compare match
        on the new CNT value then sets CCxIF.
        """
        now, kernel = self.kernel.now, self.kernel
        if self._ev_wrap is not None:
            self._ev_wrap.cancel()
            self._ev_wrap = None
        if self._ev_steady is not None:
            self._ev_steady.cancel()
            self._ev_steady = None
        lazy, ev_cc, mode, ccr = self._lazy, self._ev_cc, self._mode, self._ccr
        sr_before = self.value["SR"]
        if self._steady:
            self._steady_flush(now)
            self._steady = False
        self._uif_lazy = None
        sr = self.value["SR"]
        for ch in CHANNELS:
            if ev_cc[ch] is not None:
                ev_cc[ch].cancel()
                ev_cc[ch] = None
            t = lazy[ch]
            if t is not None:
                if t <= now:
                    sr |= CCIF[ch]
                lazy[ch] = None
        cnt, up = self._cnt, self._up
        if tick_up is not None and (self._flag_up if tick_up else self._flag_down):
            for ch in CHANNELS:
                if mode[ch] >= 0 and ccr[ch] == cnt:
                    sr |= CCIF[ch]
        if sr != sr_before:   # (flags set lazily above count too: an interrupt just enabled sees them)
            self.value["SR"] = sr
            self._irq()
        run = bool(self.value["CR1"] & CEN) and not self._sms and self._arr != 0
        if run != self._run:
            if run:  # §2.1: first prescaler clock one CK_INT cycle after the CEN write (module doc)
                P = self._P
                e1 = -(-(now + P) // P) * P
                self._tb = e1 - (self._pscc + 1) * P
            else:
                self._pscc = max(0, (now - self._tb) // self._P)
            self._run = run
        if run and self._cms:  # centre-aligned turning points reached by a write (module doc)
            if up and cnt == self._arr:
                up = self._up = False
            elif not up and cnt == 0:
                up = self._up = True
        steady = self._steady_possible()
        if steady and self._tb > now:
            # the counter starts (CEN, UG, ARR from 0) at the next CK_INT edge: until then the
            # outputs hold the levels of its present value, which a waveform anchored at that
            # edge would not give (it would show the tail of a period before it); the waveforms
            # are published there, edge by edge's outputs not having changed in between
            steady = False
            self._ev_steady = kernel.at(self._tb, self._plan)
        self._refresh_outputs(keep_waves=steady)
        if not run:
            self._t_wrap = None
            return
        arr, tick, tb = self._arr, self._tick, self._tb
        if self._cms == 0:
            if up:
                jw = arr - cnt + 1 if cnt <= arr else self.mask - cnt + 1
            else:
                jw = cnt + 1
        elif up:
            jw = arr - cnt if cnt <= arr else self.mask - cnt + 1   # (above ARR: to the roll-over)
        else:
            jw = cnt
        self._t_wrap = tb + jw * tick
        if steady:  # fast engine: waveforms, lazy flags, a wrap event only when it matters
            if self._wrap_needed():
                self._ev_wrap = kernel.at(self._t_wrap, self._on_wrap)
            self._steady = True
            self._publish_waves()
            self._steady_lazy(now)
            return
        self._ev_wrap = kernel.at(self._t_wrap, self._on_wrap)
        flag = self._flag_up if up else self._flag_down
        for ch in CHANNELS:
            m = mode[ch]
            if m < 0:
                continue
            j = ccr[ch] - cnt if up else cnt - ccr[ch]
            if 0 < j < jw:
                t = tb + j * tick
                if (self._en[ch] and m >= PWM1) or (flag and self._ccie[ch]):
                    ev_cc[ch] = kernel.at(t, self._on_match, ch, flag)
                elif flag:
                    lazy[ch] = t

    def _on_match(self, ch: int, flag: bool) -> None:
        """CNT == CCRx inside a segment (§3.1): CCxIF and the OCxREF change."""
        self._ev_cc[ch] = None
        if flag:
            self.value["SR"] |= CCIF[ch]
            if self._ccie[ch]:
                self._irq()
        m = self._mode[ch]
        if m >= PWM1:
            r = 0 if self._up else 1  # CNT == CCR: PWM1 goes low counting up, high counting down
            if m == PWM2:
                r ^= 1
            self._ref[ch] = r
            if self._en[ch]:
                self.oc[ch].set(r ^ self._pol[ch])

    def _pwm_ref(self, ch: int) -> bool:
        """OCxREF of PWM channel ``ch`` now (§3.1): PWM1 is active while CNT < CCRx counting up and
        while CNT <= CCRx counting down; PWM2 the complement."""
        c, cnt = self._ccr[ch], self._cnt
        r = (cnt < c) if self._up else (cnt <= c)
        return r ^ (self._mode[ch] == PWM2)

    def _refresh_outputs(self, keep_waves: bool = False) -> None:
        """OCxREF from the continuous comparison (§3.1), OCx = OCxREF xor CCxP when driven.
        ``keep_waves``: a port's waveform stays (the fast engine republishes it if it changed)."""
        ref = self._ref
        for ch in CHANNELS:
            m = self._mode[ch]
            if m >= PWM1:
                ref[ch] = self._pwm_ref(ch)
            elif m == FORCE_ACTIVE:
                ref[ch] = 1
            elif m == FORCE_INACTIVE:
                ref[ch] = 0
            # frozen (0000): OCxREF keeps its level; input: no output
            v = (int(ref[ch]) ^ self._pol[ch]) if self._en[ch] else None
            port = self.oc[ch]
            if port.wave is not None:
                if not (keep_waves and m >= PWM1 and self._en[ch]):
                    port.set(v)
            elif port.value != v and not (keep_waves and self._wave_coming(ch)):
                # (a constant output that becomes a waveform now goes to it in one step, one
                # change for whoever listens: _publish_waves follows)
                port.set(v)

    def _flush_lazy(self) -> None:
        now, lazy = self.kernel.now, self._lazy
        for ch in CHANNELS:
            t = lazy[ch]
            if t is not None and t <= now:
                self.value["SR"] |= CCIF[ch]
                lazy[ch] = None

    def _irq(self) -> None:
        sr, ie = self.value["SR"], self.value["DIER"]
        u, c = sr & ie & 1, sr & ie & 0x1E
        if self._irq_up == self._irq_cc:
            self.nvic.set_line(self._irq_up, bool(u or c))
        else:
            self.nvic.set_line(self._irq_up, bool(u))
            self.nvic.set_line(self._irq_cc, bool(c))

    # ------------------------------------------------------------------ register hooks
    def _refuse(self, reg: str, old: int, fld: str, value: int, why: str = "is not modelled"):
        self.value[reg] = old  # a refused write leaves the model unchanged (invariant 7)
        raise UnsupportedConfiguration(self.name, reg, fld, value, why)

    def _read_cr1(self, stored: int) -> int:
        if self._enc_lazy is not None:
            self._lazy_sync()
        return (stored & ~DIR) | (0 if self._up else DIR)  # DIR is the hardware direction

    def _write_cr1(self, old: int, new: int) -> None:
        ckd = (new >> 8) & 3
        if ckd == 3:
            self._refuse("CR1", old, "CKD", ckd, "is reserved")
        cms = (new >> 5) & 3
        if cms and old & CEN and not (old >> 5) & 3:
            # RM0385 (CMS): "It is not allowed to switch from edge-aligned mode to center-aligned
            # mode as long as the counter is enabled (CEN=1)"
            self._refuse("CR1", old, "CMS", cms, "set while the counter runs edge-aligned (CEN = 1) is "
                         "not allowed: stop the counter first")
        if cms and self._sms:
            self._refuse("CR1", old, "CMS", cms, "in encoder mode (SMS = 1-3) is not modelled")
        self._sync()
        self._cms = cms
        self._flag_up = cms != 1
        self._flag_down = cms != 2
        if cms == 0 and not self._sms:
            self._up = not new & DIR  # DIR is read-only in centre-aligned and encoder modes (§2.7)
        if old & ARPE and not new & ARPE:
            # [INF] RM: preload contents reach the shadow "permanently" while ARPE=0, so clearing
            # ARPE with a preload pending makes it effective at once
            self._arr = self.value["ARR"]
        self._plan()

    def _write_smcr(self, old: int, new: int) -> None:
        sms = (new & 7) | ((new >> 13) & 8)
        if sms > 3:
            self._refuse("SMCR", old, "SMS", sms)
        if sms and self._cms:
            self._refuse("SMCR", old, "SMS", sms, "with a centre-aligned counter (CMS != 00) is not modelled")
        self._sync()
        self._sms = sms
        if not self._check_inputs():
            self._sms = (old & 7) | ((old >> 13) & 8)
            self._refuse("SMCR", old, "SMS", sms, "with a channel in input mode and CCxE=1 (input "
                         "capture) is not modelled outside encoder mode")
        if sms and not (old & 0x10007):
            for ch in (1, 2):
                self._inp[ch].reset(self.ti[ch].level ^ self._pol[ch])
        if not sms and (old & 0x10007) and self._cms == 0:
            self._up = not self.value["CR1"] & DIR
        self._plan()
        for ch in CHANNELS:     # encoder mode needs every edge of TI1/TI2 (a waveform no longer does)
            self.ti[ch].refresh()

    def _write_dier(self, old: int, new: int) -> None:
        self._sync()
        for ch in CHANNELS:
            self._ccie[ch] = bool(new & CCIF[ch])
        if self._steady:      # flags due by now are set before the enable is looked at
            self._steady_flush(self.kernel.now)
        self._irq()
        self._plan()

    def write_register(self, reg, data, lanes=-1):
        lazy = self._enc_lazy
        if lazy is not None:
            self._lazy_sync()
            if reg.name in EXIT_FIRST:
                lazy.enc.materialize()
        if reg.name == "SR":
            if self._steady:
                self._steady_flush(self.kernel.now)
            self._flush_lazy()  # a flag set before this write must be seen by it (rc_w0)
        super().write_register(reg, data, lanes)
        if self._steady:
            if reg.name == "SR":
                self._steady_lazy(self.kernel.now)
            elif self._ev_wrap is None and self._wrap_needed():
                # a preload now waits for the next update event: it needs its wrap
                self._sync()
                if reg.name in _PRELOADED:
                    self._await_update()
                else:
                    self._plan()
        if self._enc_lazy is not None:
            self._lazy_after_write()

    def _read_sr(self, stored: int) -> int:
        if self._enc_lazy is not None:
            self._lazy_sync()
        if self._steady:
            self._steady_flush(self.kernel.now)
        if self._lazy.count(None) != 5:
            self._flush_lazy()
        return self.value["SR"]

    def _write_sr(self, old: int, new: int) -> None:
        self._irq()

    def _write_egr(self, old: int, new: int) -> None:
        if new & 1:
            self._ug()

    def _ug(self) -> None:
        """§2.5: counter to 0 (ARR counting down), prescaler counter cleared, UEV unless UDIS."""
        self._sync()
        if not self.value["CR1"] & UDIS:
            self._update_event(True)
        if self._cms:
            self._cnt, self._up = 0, True
        else:
            self._cnt = 0 if self._up else self._arr
        self._pscc = 0
        if self._run:
            self._tb = -(-self.kernel.now // self._P) * self._P  # cleared at the next CK_INT edge
        self._plan()

    def _write_cnt(self, old: int, new: int) -> None:
        self._sync()
        # with UIFREMAP bit 31 reads as UIFCPY, but a write still reaches the counter (§1.2)
        self._cnt = new & self.mask
        self._plan()

    def _read_cnt(self, stored: int) -> int:
        if self._enc_lazy is not None:
            self._lazy_sync()
        cnt = self._cnt_at(self.kernel.now)
        if self.value["CR1"] & UIFREMAP:  # §1.2: bit 31 = UIFCPY
            if self._steady:
                self._steady_flush(self.kernel.now)
            cnt = (cnt & 0x7FFFFFFF) | ((self.value["SR"] & UIF) << 31)
        return cnt

    def _write_arr(self, old: int, new: int) -> None:
        if not self.value["CR1"] & ARPE:  # ARPE=0: takes effect at once (§2.4)
            self._sync()
            self._arr = new
            self._plan()

    def _write_rcr(self, old: int, new: int) -> None:
        if not self.advanced and new:
            self._refuse("RCR", old, "REP", new, "does not exist on this timer")

    def _write_ccr(self, ch: int, old: int, new: int) -> None:
        reg = f"CCR{ch}"
        if self._mode[ch] == INPUT:
            self.value[reg] = old  # read-only in input mode
            return
        if not self._ocpe[ch]:  # OCxPE=0: the comparator sees the write at once (§3.3)
            self._sync()
            self._ccr[ch] = new
            self._plan()

    def _read_captured(self, reg: str, stored: int) -> int:
        if self._enc_lazy is not None:    # a capture may have happened lazily
            self._lazy_sync()
            stored = self.value[reg]
        ch = int(reg[-1])
        if self._cap[ch] and self.value["SR"] & CCIF[ch]:
            # RM0385 (CCxIF, channel as input): "cleared by software or by reading TIMx_CCRx"
            self.value["SR"] &= ~CCIF[ch]
            self._irq()
        return stored

    def _read_ccr1(self, stored): return self._read_captured("CCR1", stored)
    def _read_ccr2(self, stored): return self._read_captured("CCR2", stored)

    def _write_ccr1(self, old, new): self._write_ccr(1, old, new)
    def _write_ccr2(self, old, new): self._write_ccr(2, old, new)
    def _write_ccr3(self, old, new): self._write_ccr(3, old, new)
    def _write_ccr4(self, old, new): self._write_ccr(4, old, new)

    def _write_ccmr1(self, old, new): self._write_ccmr("CCMR1", 1, old, new)
    def _write_ccmr2(self, old, new): self._write_ccmr("CCMR2", 3, old, new)

    def _write_ccmr(self, reg: str, first: int, old: int, new: int) -> None:
        """CCxS=00: output view (OCxM, OCxPE, OCxCE); else input view (ICxPSC, ICxF)."""
        decoded = []
        for i, ch in enumerate((first, first + 1)):
            lo = (new >> (8 * i)) & 0xFF
            ccs = lo & 3
            if ccs == 0:
                m = ((lo >> 4) & 7) | (((new >> (16 + 8 * i)) & 1) << 3)
                if m not in OCM_SUPPORTED:
                    self._refuse(reg, old, f"OC{ch}M", m)
                if lo & 0x80:
                    self._refuse(reg, old, f"OC{ch}CE", 1)
                # OCxFE only acts with a trigger input, which is not modelled: accepted, no effect
                decoded.append((ch, m, bool(lo & 8), 0, 0))
            else:
                if ccs == 3:
                    self._refuse(reg, old, f"CC{ch}S", ccs)
                decoded.append((ch, INPUT, False, lo >> 4, (lo >> 2) & 3))
        saved = [(self._mode[ch], self._ocpe[ch], self._icf[ch], self._icpsc[ch]) for ch, *_ in decoded]
        # the counter up to now under the old modes (a wrap the fast engine passes here without its
        # event leaves OCxREF as the old mode's comparison, as the wrap event does edge by edge)
        self._sync()
        for ch, *_ in decoded:
            if self._mode[ch] >= PWM1:
                # OCxREF is the comparison's whatever CCxE (and MOE) say, but only a driven output
                # or an enabled interrupt keeps match events: the level now, which frozen keeps
                self._ref[ch] = self._pwm_ref(ch)
        for ch, m, pe, icf, icpsc in decoded:
            self._mode[ch], self._ocpe[ch], self._icf[ch], self._icpsc[ch] = m, pe, icf, icpsc
        if not self._check_inputs():
            for (ch, *_), s in zip(decoded, saved):
                self._mode[ch], self._ocpe[ch], self._icf[ch], self._icpsc[ch] = s
            self._refuse(reg, old, "CCxS", new & 0x303, "(input capture) is not modelled outside encoder mode")
        for (ch, *_), (_, pe_was, *_r) in zip(decoded, saved):
            if pe_was and not self._ocpe[ch]:  # [INF] as ARPE: OCxPE=0 transfers permanently
                self._ccr[ch] = self.value[f"CCR{ch}"]
        self._decode_enables()
        self._plan()

    def _write_ccer(self, old: int, new: int) -> None:
        pol = [0] + [(new >> (4 * (ch - 1) + 1)) & 1 for ch in CHANNELS]
        saved = self._pol
        self._pol = pol
        if not self._check_inputs():
            self._pol = saved
            self._refuse("CCER", old, "CCxE", new, "with CCxS!=00 (input capture) is not modelled "
                         "outside encoder mode")
        self._sync()
        self._decode_enables()
        for ch in (1, 2):   # RM0385 (ICxPSC): "the prescaler is reset as soon as CCxE=0"
            if not new >> (4 * (ch - 1)) & 1:
                self._capn[ch] = 0
        if self._sms:
            for ch in (1, 2):
                if pol[ch] != saved[ch]:  # TIxFPx = TIx xor CCxP changes at once
                    self._inp[ch].edge(self.ti[ch].level ^ pol[ch], self.kernel.now,
                                       *self._filter(ch), self._P)
        self._plan()

    def _write_bdtr(self, old: int, new: int) -> None:
        if not self.advanced and new:
            self._refuse("BDTR", old, None, new, "does not exist on this timer")
        self._sync()
        self._decode_enables()
        self._plan()

    def _check_inputs(self) -> bool:
        """Input capture is modelled only for CH1/CH2 with CCxS=01 in encoder mode."""
        ccer = self.value["CCER"]
        for ch in CHANNELS:
            if self._mode[ch] == INPUT and ccer >> (4 * (ch - 1)) & 1:
                ccs = (self.value["CCMR1" if ch < 3 else "CCMR2"] >> (8 * ((ch - 1) & 1))) & 3
                if not (self._sms and ch in (1, 2) and ccs == 1):
                    return False
        return True

    def _decode_enables(self) -> None:
        ccer = self.value["CCER"]
        moe = (not self.advanced) or bool(self.value["BDTR"] & (1 << 15))
        for ch in CHANNELS:
            e = bool(ccer >> (4 * (ch - 1)) & 1)
            self._en[ch] = e and moe and self._mode[ch] != INPUT
            self._cap[ch] = e and self._mode[ch] == INPUT
