"""Per-tick reference model of the STM32 timer time base and PWM (test oracle only).

It steps one CK_INT cycle at a time, written straight from the rules of
ST RM0385 (project timer notes) §2-§3 with no closed forms, so that the event-driven model in
periph/stm32/tim.py can be compared with it edge for edge. Conventions shared with the model (they are
the model's documented choices): the counter was started by CEN at cycle 0 with the prescaler counter
at 0; CCxIF is set on the tick on which CNT becomes CCRx (centre-aligned: direction of that tick per
CMS); centre-aligned overflow on the tick into ARR, underflow on the tick into 0.
"""

from __future__ import annotations

PWM1, PWM2 = 0b0110, 0b0111


class TimOracle:
    def __init__(self, *, psc, arr, ccr, mode, pol, cms=0, down=False, rcr=0, arpe=False, ocpe=False,
                 udis=False, opm=False, bits=16):
        # preload registers
        self.PSC, self.ARR, self.CCR, self.RCR = psc, arr, ccr, rcr
        self.arpe, self.ocpe, self.udis, self.opm = arpe, ocpe, udis, opm
        self.mode, self.pol, self.cms, self.mask = mode, pol, cms, (1 << bits) - 1
        # state after UG (EGR.UG done before CEN, URS=0): shadows loaded, counter reset
        self.psc_a, self.arr_a, self.ccr_a, self.rep = psc, arr, ccr, rcr
        self.up = (not down) or cms != 0
        self.cnt = 0 if self.up else arr
        self.pscc = 0
        self.cen = True
        self.uif_cycles, self.ccif_cycles = [], []
        self.cycle = 0

    def ref(self):
        if self.mode not in (PWM1, PWM2):
            return 0
        r = self.cnt < self.ccr_a if self.up else self.cnt <= self.ccr_a
        return int(r) ^ (self.mode == PWM2)

    def pin(self):
        return self.ref() ^ self.pol

    def uev(self):
        self.psc_a = self.PSC
        if self.arpe:
            self.arr_a = self.ARR
        if self.ocpe:
            self.ccr_a = self.CCR
        self.rep = self.RCR
        self.uif_cycles.append(self.cycle)
        if self.opm:
            self.cen = False

    def wrap(self):
        if self.rep:
            self.rep -= 1
        elif not self.udis:
            self.uev()

    def step(self):
        """One CK_INT cycle."""
        self.cycle += 1
        if not self.cen or self.arr_a == 0:
            return
        if self.pscc < self.psc_a:
            self.pscc += 1
            return
        self.pscc = 0
        tick_up = self.up
        if self.cms == 0:
            if self.up:
                if self.cnt == self.arr_a or self.cnt == self.mask:
                    self.cnt = 0
                    self.wrap()
                else:
                    self.cnt += 1
            else:
                if self.cnt == 0:
                    self.wrap()
                    self.cnt = self.arr_a
                else:
                    self.cnt -= 1
        elif self.up:
            self.cnt += 1
            if self.cnt == self.arr_a:
                self.up = False
                self.wrap()
        else:
            self.cnt -= 1
            if self.cnt == 0:
                self.up = True
                self.wrap()
        flag = self.cms == 0 or self.cms == 3 or (self.cms == 2) == tick_up
        if flag and self.cnt == self.ccr_a:
            self.ccif_cycles.append(self.cycle)

    # register writes between cycles (as the CPU does after the hardware at the same tick)
    def write_ccr(self, v):
        self.CCR = v
        if not self.ocpe:
            self.ccr_a = v

    def write_arr(self, v):
        self.ARR = v
        if not self.arpe:
            self.arr_a = v

    def write_psc(self, v):
        self.PSC = v


# ---------------------------------------------------------------------------- fixture helpers
BASES = {"TIM1": 0x4001_0000, "TIM8": 0x4001_0400, "TIM2": 0x4000_0000, "TIM3": 0x4000_0400,
         "TIM4": 0x4000_0800, "TIM5": 0x4000_0C00}
IRQS = {"TIM1": {"update": 25, "cc": 27, "brk": 24, "trg_com": 26}, "TIM8": {"update": 44, "cc": 46},
        "TIM2": {"update": 28, "cc": 28}, "TIM3": {"update": 29, "cc": 29},
        "TIM4": {"update": 30, "cc": 30}, "TIM5": {"update": 50, "cc": 50}}
OFF = {"CR1": 0x00, "CR2": 0x04, "SMCR": 0x08, "DIER": 0x0C, "SR": 0x10, "EGR": 0x14, "CCMR1": 0x18,
       "CCMR2": 0x1C, "CCER": 0x20, "CNT": 0x24, "PSC": 0x28, "ARR": 0x2C, "RCR": 0x30, "CCR1": 0x34,
       "CCR2": 0x38, "CCR3": 0x3C, "CCR4": 0x40, "BDTR": 0x44, "DCR": 0x48, "DMAR": 0x4C, "OR": 0x50, "CCMR3": 0x54, "CCR5": 0x58, "CCR6": 0x5C}


class Rig:
    """A Mcu with one timer on its bus, at ``mhz`` timer clock over a 216 MHz base."""

    def __init__(self, name="TIM1", mhz=216, arr_reset=0, engine="reference"):
        from mcusim.periph.stm32.tim import Tim

        from mcusim.irq import Nvic
        from mcusim.kernel import Kernel
        from mcusim.mcu import Mcu
        from mcusim.registers import Bus
        from mcusim.time import TimeBase

        self.tb = TimeBase([216_000_000])
        self.kernel = Kernel(self.tb, engine)
        self.bus = Bus()
        self.nvic = Nvic()
        core = self.tb.clock("HCLK", 216_000_000)
        self.mcu = Mcu("stm32f746", self.kernel, self.bus, core)
        self.mcu.nvic = self.nvic
        self.bus.attach(0xE000_E100, self.nvic)
        self.clock = self.tb.clock(f"{name}CLK", mhz * 1_000_000)
        self.P = self.clock.period
        self.base = BASES[name]
        self.tim = Tim(name, self.mcu, self.clock, IRQS[name], counter_bits=32 if name in ("TIM2", "TIM5") else 16,
                       advanced=name in ("TIM1", "TIM8"), arr_reset=arr_reset)
        self.bus.attach(self.base, self.tim)

    def w(self, reg, v):
        self.bus.write32(self.base + OFF[reg], v)

    def r(self, reg):
        return self.bus.read32(self.base + OFF[reg])

    def run(self, cycles):
        """Advance ``cycles`` timer-clock cycles."""
        self.kernel.run_until(self.kernel.now + cycles * self.P)

    def record(self, ch=1):
        edges = []
        self.tim.oc[ch].listen(lambda p: edges.append((self.kernel.now, p.value)))
        return edges
