"""Per-timer-clock reference model of the AVR 8/16-bit timers (sheet §1.7 order), the test oracle.

It steps every timer clock with a direct transcription of the rules pinned in the docstring of
``periph/avr/timer1.py`` (compare on the value being left, buffer load before the compare of an
update clock, fast-PWM BOTTOM action after the compare, dual-slope level forcing at TOP).  It shares
no code with the event-driven model.
"""

from __future__ import annotations

TOV, OCFA, OCFB, ICF = 1, 2, 4, 32

MODES16 = {
    0: ("normal", 0xFFFF), 1: ("pc", 0xFF), 2: ("pc", 0x1FF), 3: ("pc", 0x3FF), 4: ("ctc", "A"),
    5: ("fast", 0xFF), 6: ("fast", 0x1FF), 7: ("fast", 0x3FF), 8: ("pfc", "I"), 9: ("pfc", "A"),
    10: ("pc", "I"), 11: ("pc", "A"), 12: ("ctc", "I"), 14: ("fast", "I"), 15: ("fast", "A"),
}
MODES8 = {0: ("normal", 0xFF), 1: ("pc", 0xFF), 2: ("ctc", "A"), 3: ("fast", 0xFF), 5: ("pc", "A"),
          7: ("fast", "A")}


class Oracle:
    """One timer, one clock at a time.  ``clock()`` returns nothing; read ``edges``/``flag_log``."""

    def __init__(self, mode, ocr=(0, 0), icr=0, com=(0, 0), tcnt=0, max_=0xFFFF, modes=MODES16):
        self.kind, self.topsrc = modes[mode]
        self.max = max_
        self.dual = self.kind in ("pc", "pfc")
        self.ocr = {"A": ocr[0], "B": ocr[1]}
        self.buf = dict(self.ocr)
        self.icr = icr
        self.com = {"A": com[0], "B": com[1]}
        self.c, self.d = tcnt, 1
        self.latch = {"A": 0, "B": 0}
        self.k = 0                  # clocks done
        self.block = -1             # clock whose compare is blocked
        self.flags = 0
        self.flag_log = []          # (clock, flag bits newly set... all bits set this clock)
        self.edges = {"A": [], "B": []}   # (clock, level) output changes while connected

    def top(self):
        if self.topsrc == "A":
            return self.ocr["A"]
        if self.topsrc == "I":
            return self.icr
        return self.topsrc

    def output(self, ch):
        """'pwm', 'toggle', 'set', 'clear' or None (disconnected) per the §1.4 table."""
        com = self.com[ch]
        if com == 0:
            return None
        if self.kind in ("normal", "ctc"):
            return {1: "toggle", 2: "clear", 3: "set"}[com]
        if com == 1:
            if ch == "A" and (self.topsrc == "A" or (self.kind == "fast" and self.topsrc == "I")):
                return "toggle"
            return None
        return "pwm"

    def write_tcnt(self, v):
        self.c = v
        self.block = self.k + 1

    def write_ocr(self, ch, v):
        self.buf[ch] = v
        if self.kind in ("normal", "ctc"):
            self.ocr[ch] = v

    def clock(self):
        K = self.k + 1
        c, d, T = self.c, self.d, self.top()
        old = dict(self.latch)
        # a TCNT write blocks every compare of the next clock, TOP's too where TOP is OCRnA or
        # ICR1: "the Compare Match for the TOP will be ignored and the counter will continue to
        # 0xFFFF" (datasheet, TC1 "Using the Output Compare Unit")
        top_blocked = K == self.block and self.topsrc in ("A", "I") and T < self.max
        if self.dual:
            at_top = d > 0 and c == T and not top_blocked
            at_bottom = c == 0
            at_max = False
        else:
            at_top = c == T and not top_blocked
            at_bottom = False
            at_max = c == self.max and not at_top
        # 1. buffer load at the mode's update point
        if (self.kind == "pc" and at_top) or (self.kind == "pfc" and at_bottom) or \
                (self.kind == "fast" and at_top):
            self.ocr = dict(self.buf)
        newT = self.top()
        flags = 0
        # 2. compare matches on the value being left
        if K != self.block:
            up = (not self.dual) or c == 0 or (d > 0 and not at_top)
            for ch in "AB":
                if c == self.ocr[ch]:
                    flags |= OCFA if ch == "A" else OCFB
                    out = self.output(ch)
                    m = 0 if self.com[ch] == 2 else 1
                    if out == "pwm":
                        if self.kind == "fast":
                            self.latch[ch] = m
                        else:
                            self.latch[ch] = m if up else 1 - m
                    elif out == "toggle":
                        self.latch[ch] ^= 1
                    elif out == "clear":
                        self.latch[ch] = 0
                    elif out == "set":
                        self.latch[ch] = 1
        # 3. TOP
        if at_top:
            if self.topsrc == "I":
                flags |= ICF
            elif self.topsrc == "A":
                flags |= OCFA
            if self.kind == "fast" or (self.kind in ("normal", "ctc") and T == self.max):
                flags |= TOV
            for ch in "AB":
                if self.output(ch) == "pwm":
                    m = 0 if self.com[ch] == 2 else 1
                    if self.kind == "fast":
                        self.latch[ch] = 1 - m
                    else:
                        self.latch[ch] = 1 - m if self.ocr[ch] >= newT else m
        # 4. BOTTOM (dual) / MAX wrap (single)
        if at_bottom or at_max:
            flags |= TOV
        if flags:
            self.flags |= flags
            self.flag_log.append((K, flags))
        for ch in "AB":
            if self.output(ch) is not None and self.latch[ch] != old[ch]:
                self.edges[ch].append((K, self.latch[ch]))
        # advance (with the rules of the old TOP)
        if self.dual:
            if at_top:
                self.c, self.d = c - 1, -1
            elif c == 0:
                self.c, self.d = 1, 1
            elif d > 0:
                self.c = 0 if c == self.max else c + 1
            else:
                self.c = c - 1
        else:
            self.c = 0 if (at_top or c == self.max) else c + 1
        self.k = K

    def run(self, n):
        for _ in range(n):
            self.clock()
        return self
