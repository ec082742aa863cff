"""LPC4337 USART0/2/3 in asynchronous mode (UM10503 "USART0_2_3"), 16550-style, event-driven.

Sources: NXP UM10503 and the EDU-CIAA-NXP schematic (instances and board use); register
layout, reset values and wording from NXP's SVD (svd2rust ``usart0``) and LPCOpen's
``uart_18xx_43xx.h``/``.c`` (``LPC_USART_T``, ``Chip_UART_Init``, ``Chip_UART_SetBaudFDR``).

Instances (the board builder attaches them; ``irq`` is the NVIC line): USART0 0x40081000 IRQ 24,
USART2 0x400C1000 IRQ 26, USART3 0x400C2000 IRQ 27 (UART1, with modem lines, is a different block
and is not routed on the EDU-CIAA). ``clock`` is the USART's PCLK (BASE_UARTn_CLK; 204 MHz under
LPCOpen). ``endpoint`` is the far end of the TX/RX lines (:mod:`mcusim.hostserial`).

Registers (4 KB slot, 8/16/32-bit accesses)
-------------------------------------------
=======  ======  ===========================================================================
0x00     RBR     (read, DLAB = 0) pops the RX FIFO; reads 0 when it is empty
0x00     THR     (write, DLAB = 0) pushes the TX FIFO
0x00     DLL     (DLAB = 1) DLLSB 7:0, reset 0x01
0x04     DLM     (DLAB = 1) DLMSB 7:0, reset 0
0x04     IER     (DLAB = 0) RBRIE 0, THREIE 1, RXIE 2, ABEOINTEN 8, ABTOINTEN 9
0x08     IIR     (read) INTSTATUS 0 (active low), INTID 3:1, FIFOENABLE 7:6, reset 0x01
0x08     FCR     (write) FIFOEN 0, RXFIFORES 1, TXFIFORES 2, DMAMODE 3, RXTRIGLVL 7:6
0x0C     LCR     WLS 1:0, SBS 2, PE 3, PS 5:4, BC 6, DLAB 7
0x14     LSR     (read) RDR 0, OE 1, PE 2, FE 3, BI 4, THRE 5, TEMT 6, RXFE 7, TXERR 8; reset 0x60
0x1C     SCR     PAD 7:0, plain storage
0x20     ACR     auto-baud: START/MODE/AUTORESTART unmodelled; ABEOINTCLR/ABTOINTCLR no effect
0x24     ICR     IrDA: unmodelled
0x28     FDR     DIVADDVAL 3:0, MULVAL 7:4, reset 0x10
0x2C     OSR     oversampling: unmodelled (reset 0xF0 = 16 clocks per bit)
0x40     HDEN    half duplex: unmodelled
0x48     SCICTRL smart card: unmodelled
0x4C     RS485CTRL, 0x50 RS485ADRMATCH, 0x54 RS485DLY: unmodelled
0x58     SYNCCTRL synchronous mode: unmodelled
0x5C     TER     TXEN 0, reset 1
=======  ======  ===========================================================================

"Unmodelled" fields take their reset value (LPCOpen's ``Chip_UART_Init`` writes 0 to ACR and the
RS485 registers, which is accepted); anything else raises UnsupportedConfiguration. Offsets 0x10,
0x18, 0x30-0x3C, 0x44 and everything above 0x5C are bus faults (UART1's MCR/MSR do not exist here).

Timing (exact, integer)
-----------------------
The baud16 clock is PCLK / (256*DLM + DLL) / (1 + DIVADDVAL/MULVAL); a bit is 16 baud16 periods
(OSR at reset); a frame is 1 start + 5..8 data + parity (if PE) + stop bits (1; 2 with SBS; 1.5 with
SBS and 5-bit words). A frame therefore lasts exactly::

    F = bits * 16 * DL * (MULVAL + DIVADDVAL) / MULVAL     PCLK cycles   (a Fraction)

**Rounding rule (choice):** the model keeps frame boundaries as exact Fractions of PCLK cycles and
schedules each frame-end event at the first PCLK edge at or after its exact time (ceiling). A frame
that starts while the line is idle starts at the first PCLK edge at or after the tick the byte
reaches the shift register (or, for RX, the tick ``receive`` is called); back-to-back frames start at
the previous frame's *exact* end, so the n-th back-to-back frame ends at
``t0 + ceil(n * F)`` PCLK cycles: within one PCLK cycle of the exact rate and never drifting. (The
chip's fractional divider swallows PCLK pulses, so its baud16 edges also fall on PCLK edges with
the same long-run rate; the exact pulse pattern is not modelled.) The frame length is taken from the
registers when the frame starts; a change of DLL/DLM/FDR/LCR applies from the next frame.

Checked when a frame's timing is needed (a THR write or TER enable that starts a frame, a chained
frame, an RX frame) and raising UnsupportedConfiguration: divisor DLM:DLL = 0 (``USARTn.DLL.DLLSB``),
MULVAL = 0 (``USARTn.FDR.MULVAL``), DIVADDVAL >= MULVAL (``USARTn.FDR.DIVADDVAL``), DIVADDVAL > 0
with a divisor below 3 (``USARTn.DLL.DLLSB``; UM rule, also in LPCOpen's search). Break (LCR.BC = 1)
raises at the LCR write (``USARTn.LCR.BC``). Parity is only a bit of frame length: an endpoint
delivers clean bytes, so PE/FE/BI never set.

Transmitter
-----------
* TX FIFO of 16 bytes when FCR.FIFOEN = 1, a 1-byte holding register when FIFOEN = 0 (the UM asks
  for FIFOEN = 1; the 16450-like mode is modelled as the brief asks). A byte written while the
  transmitter is idle moves to the shift register (TSR) at once, so 1 + 16 bytes can be in flight.
  A THR write to a full FIFO is lost (counted in ``tx_overflows``), as on the chip.
* At each frame end the byte (masked to the word length) is appended to ``tx_log`` as
  ``(tick, byte)`` (the recent ones: :mod:`mcusim.recent`, at least the last 10 000) and handed to ``endpoint.transmit(byte, tick)``; then the next FIFO byte, if
  any and TER.TXEN = 1, starts at once.
* LSR.THRE = TX FIFO empty; LSR.TEMT = FIFO and TSR empty.
* TER.TXEN = 0 stops the transmitter after the frame in progress; bytes wait in the FIFO until
  TXEN = 1 (LPCOpen's ``Chip_UART_Init`` clears it; ``Chip_UART_TXEnable`` sets it).
* THRE interrupt source (UM wording [I]): set when the FIFO becomes empty because its last byte
  moves to the TSR, if the FIFO held at least two bytes at one time since the previous THRE = 1
  event; otherwise it is set one character time minus the stop bit(s) after that moment (the
  "initialization delay"; for a byte written to an idle transmitter that is from the frame's start),
  unless THR is written meanwhile. A TX FIFO reset that empties the FIFO sets it at once (choice). A THR write clears it, and so does an
  IIR read that reports THRE. Enabling IER.THREIE while THRE = 1 sets it at once (16550 behaviour
  [I]; NuttX does not rely on it, it calls its xmit routine itself), except during the
  initialization delay, which still decides (the common "write the first byte, then enable
  THREIE" gets its interrupt a character time later, not at once).

Receiver
--------
* ``receive(data)`` puts bytes on the RX line: the first starts at the first PCLK edge at or after
  the call if the line is idle, each following byte (also from later calls while the line is busy)
  starts at the exact end of the previous one; each takes one frame of the USART's own current
  format (the host's baud rate and framing are assumed to match; a mismatch is not simulated).
* At a frame's end the byte (masked to the word length) enters the RX FIFO (16 bytes with FIFOEN,
  else 1) and ``rx_log`` gets ``(tick, byte)``; with the FIFO full the byte is lost and LSR.OE is
  set (``rx_overruns`` counts them); reading LSR clears OE. LSR.RDR = FIFO not empty.
* Interrupts, by the UM's priorities: RLS (IIR 0x6; IER.RXIE and LSR.OE), RDA (0x4; RBRIE and
  FIFO level >= RXTRIGLVL 1/4/8/14, any byte without FIFOs), CTI (0xC; RBRIE, FIFOs on, at least one
  byte and no RX FIFO activity (byte received or RBR read) for **4 character times** (choice in the
  UM's 3.5-4.5), using the frame length at the last activity), THRE (0x2). The NVIC line is the OR of
  the enabled sources (``mcu.irq.set_line``); IIR bits 7:6 read 11 when FIFOs are on.
* FCR: a change of FIFOEN clears both FIFOs; RXFIFORES/TXFIFORES clear the FIFO (not the shift
  register: a frame in progress completes); bits 7:1 are ignored when FIFOEN is written 0 (UM).

``tx_done`` fires after every TX frame end and ``rx_ready`` after every RX frame end (byte stored or
lost), once the registers are updated, so polling drivers can ``await rtos.wait_signal(...)``.

Not modelled: auto-baud, IrDA, smart card, RS-485, synchronous mode, half duplex, DMA (FCR.DMAMODE
is accepted and changes nothing: it only shapes the DMA requests, which reach no DMA controller
here), oversampling other than 16, line errors and break, the TXD/RXD pins as nets.
"""

from __future__ import annotations

import math
from collections import deque
from fractions import Fraction

from mcusim.errors import BusFault, UnsupportedConfiguration
from mcusim.firmware import Signal
from mcusim.recent import RecentLog
from mcusim.registers import Field, Peripheral, Register

from .cgu import BaseClockUser

# instance -> (base address, NVIC IRQ) [V: LO-MAP, SVD, reference §2.3]
INSTANCES = {"USART0": (0x40081000, 24), "USART2": (0x400C1000, 26), "USART3": (0x400C2000, 27)}
# IIR interrupt identifications
INT_RLS, INT_RDA, INT_CTI, INT_THRE = 0b011, 0b010, 0b110, 0b001
RX_TRIGGER = (1, 4, 8, 14)
FIFO_DEPTH = 16
CTI_CHARS = 4

RBRIE, THREIE, RXIE = 1, 2, 4
# offsets shared by several registers: (read, write, with DLAB = 1)
SHARED = {0x00: ("RBR", "THR", "DLL"), 0x04: ("IER", "IER", "DLM"), 0x08: ("IIR", "FCR", None)}
DLAB = 0x80


def _unmodelled(*spec):
    return tuple(Field(name, lsb, width, modelled=False) for name, lsb, width in spec)


class Usart(BaseClockUser, Peripheral):
    SIZE = 0x1000
    #: the VCD draws this USART's TXD line bit by bit from its frames (mcusim.tracebus.UartWaveform)
    traced_txd = True
    REGISTERS = (
        Register("RBR", 0x00, access="r", on_read="_read_rbr", fields=(Field("RBR", 0, 8, access="r"),)),
        Register("THR", 0x00, on_write="_write_thr", fields=(Field("THR", 0, 8, access="w"),)),
        Register("DLL", 0x00, reset=0x01, fields=(Field("DLLSB", 0, 8),)),
        Register("DLM", 0x04, fields=(Field("DLMSB", 0, 8),)),
        Register("IER", 0x04, on_write="_write_ier",
                 fields=(Field("RBRIE", 0), Field("THREIE", 1), Field("RXIE", 2),
                         Field("ABEOINTEN", 8, doc="auto-baud never runs: no effect"),
                         Field("ABTOINTEN", 9, doc="auto-baud never runs: no effect"))),
        Register("IIR", 0x08, reset=0x01, on_read="_read_iir",
                 fields=(Field("INTSTATUS", 0, access="r"), Field("INTID", 1, 3, access="r"),
                         Field("FIFOENABLE", 6, 2, access="r"), Field("ABEOINT", 8, access="r"),
                         Field("ABTOINT", 9, access="r"))),
        Register("FCR", 0x08, on_write="_write_fcr",
                 fields=(Field("FIFOEN", 0, access="w"), Field("RXFIFORES", 1, access="w"),
                         Field("TXFIFORES", 2, access="w"), Field("DMAMODE", 3, access="w"),
                         Field("RXTRIGLVL", 6, 2, access="w"))),
        Register("LCR", 0x0C,
                 fields=(Field("WLS", 0, 2), Field("SBS", 2), Field("PE", 3), Field("PS", 4, 2),
                         Field("BC", 6, modelled=False), Field("DLAB", 7))),
        Register("LSR", 0x14, reset=0x60, on_read="_read_lsr",
                 fields=(Field("RDR", 0, access="r"), Field("OE", 1, access="r"), Field("PE", 2, access="r"),
                         Field("FE", 3, access="r"), Field("BI", 4, access="r"), Field("THRE", 5, access="r"),
                         Field("TEMT", 6, access="r"), Field("RXFE", 7, access="r"),
                         Field("TXERR", 8, access="r"))),
        Register("SCR", 0x1C, fields=(Field("PAD", 0, 8),)),
        Register("ACR", 0x20, fields=_unmodelled(("START", 0, 1), ("MODE", 1, 1), ("AUTORESTART", 2, 1))
                 + (Field("ABEOINTCLR", 8, access="w"), Field("ABTOINTCLR", 9, access="w"))),
        Register("ICR", 0x24, fields=_unmodelled(("IRDAEN", 0, 1), ("IRDAINV", 1, 1), ("FIXPULSEEN", 2, 1),
                                                 ("PULSEDIV", 3, 3))),
        Register("FDR", 0x28, reset=0x10, fields=(Field("DIVADDVAL", 0, 4), Field("MULVAL", 4, 4))),
        Register("OSR", 0x2C, reset=0xF0, fields=_unmodelled(("OSFRAC", 1, 3), ("OSINT", 4, 4), ("FDINT", 8, 7))),
        Register("HDEN", 0x40, fields=_unmodelled(("HDEN", 0, 1))),
        Register("SCICTRL", 0x48, fields=_unmodelled(("SCIEN", 0, 1), ("NACKDIS", 1, 1), ("PROTSEL", 2, 1),
                                                     ("TXRETRY", 5, 3), ("GUARDTIME", 8, 8))),
        Register("RS485CTRL", 0x4C, fields=_unmodelled(("NMMEN", 0, 1), ("RXDIS", 1, 1), ("AADEN", 2, 1),
                                                       ("DCTRL", 4, 1), ("OINV", 5, 1))),
        Register("RS485ADRMATCH", 0x50, fields=_unmodelled(("ADRMATCH", 0, 8))),
        Register("RS485DLY", 0x54, fields=_unmodelled(("DLY", 0, 8))),
        Register("SYNCCTRL", 0x58, fields=_unmodelled(("SYNC", 0, 1), ("CSRC", 1, 1), ("FES", 2, 1),
                                                      ("TSBYPASS", 3, 1), ("CSCEN", 4, 1), ("SSSDIS", 5, 1),
                                                      ("CCCLR", 6, 1))),
        Register("TER", 0x5C, reset=0x01, on_write="_write_ter", fields=(Field("TXEN", 0),)),
    )

    def __init__(self, name, mcu, clock, irq: int, endpoint=None, base_clock=""):
        super().__init__(name)
        self._plain = {r.offset: r for r in self.REGISTERS if r.offset not in SHARED}
        self.mcu, self.kernel, self.clock, self.irqn = mcu, mcu.kernel, clock, irq
        self._init_base_clock(base_clock)
        self._writing = False
        # transmitter
        self._fifoen = False
        self._trigger = 1
        self._txq: deque[int] = deque()
        self._tsr: int | None = None
        self._tx_end = Fraction(0)           # exact end of the frame in the TSR (PCLK cycles)
        self._tx_ev = None
        self._thr_peak = 0                   # most bytes held in the FIFO since the last THRE = 1 event
        self._thre_int = False
        self._thre_ev = None
        # receiver
        self._line: deque[int] = deque()     # bytes on the RX wire, the first one being received
        self._rx_end = Fraction(0)
        self._rx_ev = None
        self._rxq: deque[int] = deque()
        self._oe = False
        self._cti_at = None                  # tick at which the character time-out fires
        self._cti_ev = None
        # observers
        self.tx_log: RecentLog = RecentLog()    # (tick, byte): the recent ones (mcusim.recent)
        self.rx_log: RecentLog = RecentLog()
        self.tx_overflows = 0
        self.rx_overruns = 0
        self.tx_done = Signal()
        self.rx_ready = Signal()
        self.endpoint = None
        if endpoint is not None:
            self.connect(endpoint)

    def connect(self, endpoint) -> None:
        """Connect the far end: it gets ``transmit(byte, tick)`` calls and may call ``receive``."""
        self.endpoint = endpoint
        attach = getattr(endpoint, "attach", None)
        if attach is not None:
            attach(self)

    # --- timing ----------------------------------------------------------------------------------
    @property
    def divisor(self) -> int:
        return (self.value["DLM"] & 0xFF) << 8 | (self.value["DLL"] & 0xFF)

    def frame_format(self):
        """(frame length, bit time, stop bits) in PCLK cycles/bits, exact; raises if unsupported."""
        dl = self.divisor
        fdr = self.value["FDR"]
        add, mul = fdr & 0xF, fdr >> 4 & 0xF
        if dl == 0:
            raise UnsupportedConfiguration(self.name, "DLL", "DLLSB", 0,
                                           "with DLM = 0 (divisor 0 stops the baud generator) is not modelled")
        if mul == 0:
            raise UnsupportedConfiguration(self.name, "FDR", "MULVAL", 0, "is not allowed (1..15)")
        if add >= mul:
            raise UnsupportedConfiguration(self.name, "FDR", "DIVADDVAL", add,
                                           f"is not allowed: it must be less than MULVAL = {mul}")
        if add and dl < 3:
            raise UnsupportedConfiguration(self.name, "DLL", "DLLSB", dl,
                                           f"(divisor {dl}) is not allowed with DIVADDVAL = {add}: "
                                           "the divisor must be at least 3")
        lcr = self.value["LCR"]
        data = 5 + (lcr & 3)
        stop = (Fraction(3, 2) if data == 5 else Fraction(2)) if lcr & 4 else Fraction(1)
        bit = Fraction(16 * dl * (mul + add), mul)
        bits = 1 + data + (1 if lcr & 8 else 0) + stop
        return bits * bit, bit, stop

    @property
    def frame_cycles(self) -> Fraction:
        """PCLK cycles per frame at the current configuration (exact)."""
        return self.frame_format()[0]

    def _now_cycle(self) -> int:
        """The first PCLK edge at or after now, in PCLK cycles."""
        return -(-self.kernel.now // self.clock.period)

    def _tick(self, cycles: Fraction) -> int:
        """Base tick of the first PCLK edge at or after ``cycles``."""
        return math.ceil(cycles) * self.clock.period

    @property
    def _wmask(self) -> int:
        return (1 << (5 + (self.value["LCR"] & 3))) - 1

    # --- interrupts --------------------------------------------------------------------------------
    def _cti(self) -> bool:
        return self._fifoen and bool(self._rxq) and self._cti_at is not None and self.kernel.now >= self._cti_at

    def _rda(self) -> bool:
        return len(self._rxq) >= (self._trigger if self._fifoen else 1)

    def interrupt_id(self) -> int | None:
        """The IIR INTID the chip would report now, None if no enabled source is pending."""
        ier = self.value["IER"]
        if ier & RXIE and self._oe:
            return INT_RLS
        if ier & RBRIE and self._rda():
            return INT_RDA
        if ier & RBRIE and self._cti():
            return INT_CTI
        if ier & THREIE and self._thre_int:
            return INT_THRE
        return None

    def _update_irq(self) -> None:
        self.mcu.irq.set_line(self.irqn, self.interrupt_id() is not None)

    # --- transmitter -------------------------------------------------------------------------------
    @property
    def _tx_capacity(self) -> int:
        return FIFO_DEPTH if self._fifoen else 1

    def _write_thr(self, old, new):
        byte = new & 0xFF
        start = self._tsr is None and not self._txq and self.value["TER"] & 1
        if start:
            self._check_base_clock()                      # may raise, as may the format:
        fmt = self.frame_format() if start else None      # nothing has changed yet
        self._cancel_thre()
        self._thre_int = False
        if len(self._txq) >= self._tx_capacity:
            self.tx_overflows += 1
        else:
            self._txq.append(byte)
            self._thr_peak = max(self._thr_peak, len(self._txq))
            if start:
                self._load_tsr(Fraction(self._now_cycle()), fmt)
        self._update_irq()

    def _load_tsr(self, start: Fraction, fmt) -> None:
        self._check_base_clock()
        frame, bit, stop = fmt
        self._tsr = self._txq.popleft() & self._wmask
        self._tx_end = start + frame
        self._tx_ev = self.kernel.at(self._tick(self._tx_end), self._tx_frame_end)
        if not self._txq:
            self._thre_event(start, frame - stop * bit)

    def _thre_event(self, at: Fraction, delay: Fraction) -> None:
        """THR became empty at exact cycle ``at``: the UM's THRE interrupt rule."""
        self._cancel_thre()
        if self._thr_peak >= 2:
            self._thre_int = True
        else:
            self._thre_ev = self.kernel.at(max(self.kernel.now, self._tick(at + delay)), self._thre_delayed)
        self._thr_peak = 0

    def _thre_delayed(self):
        self._thre_ev = None
        if not self._txq:
            self._thre_int = True
            self._update_irq()

    def _cancel_thre(self):
        if self._thre_ev is not None:
            self._thre_ev.cancel()
            self._thre_ev = None

    def _tx_frame_end(self):
        self._tx_ev = None
        byte, self._tsr = self._tsr, None
        now = self.kernel.now
        self.tx_log.append((now, byte))
        if self.endpoint is not None:
            self.endpoint.transmit(byte, now)
        if self._txq and self.value["TER"] & 1:
            self._load_tsr(self._tx_end, self.frame_format())
        self._update_irq()
        self.tx_done.fire()

    def served_inert(self, ev):
        """Fast engine (:func:`mcusim.engine.served.inert_until`): where the queued event ``ev`` is
        a frame end in the middle of a burst, the tick before which it and the frame ends it chains
        change nothing outside this USART, else None. Such a frame end logs its byte and loads the
        next one from a FIFO that keeps at least one more: THRE, the interrupt line and every
        register stay as they are. It must have no far end and no one waiting on ``tx_done``, an
        untraced ``tx_log`` and an empty RX FIFO (the character time-out is the one source that
        depends on the tick). The first frame end that does more loads the FIFO's last byte."""
        if (ev is not self._tx_ev or self.endpoint is not None or self.tx_done._waiters or self._rxq
                or type(self.tx_log) is not RecentLog):
            return None
        # (with two bytes or more in the FIFO no delayed THRE is pending and the THRE flag is clear:
        # every THR write cancels and clears them; a delayed THRE would be an event of its own anyway)
        q = len(self._txq)
        if q == 0 or not self.value["TER"] & 1:
            return math.inf             # nothing follows it
        if q == 1:
            return None                 # it empties the FIFO: THRE
        try:
            frame = self.frame_format()[0]
        except UnsupportedConfiguration:
            return None                 # the next frame raises
        return self._tick(self._tx_end + (q - 1) * frame)

    def _write_ter(self, old, new):
        if new & 1 and not old & 1 and self._tsr is None and self._txq:
            fmt = self.frame_format()
            self._load_tsr(Fraction(self._now_cycle()), fmt)
            self._update_irq()

    # --- receiver ----------------------------------------------------------------------------------
    @property
    def rx_pending(self) -> int:
        """Bytes handed to ``receive`` whose frames have not yet ended on the RX line (the far end's
        backlog: a host end that must not fall behind caps it)."""
        return len(self._line)

    def receive(self, data: bytes) -> None:
        """Bytes from the far end arrive on the RX line, one frame each, from now on."""
        data = bytes(data)
        if not data:
            return
        if self._rx_ev is None:
            self._check_base_clock()
            frame = self.frame_format()[0]               # may raise: nothing has changed yet
            self._line.extend(data)
            self._rx_end = self._now_cycle() + frame
            self._rx_ev = self.kernel.at(self._tick(self._rx_end), self._rx_frame_end)
        else:
            self._line.extend(data)

    def _rx_frame_end(self):
        self._rx_ev = None
        byte = self._line.popleft() & self._wmask
        now = self.kernel.now
        if len(self._rxq) >= (FIFO_DEPTH if self._fifoen else 1):
            self._oe = True
            self.rx_overruns += 1
        else:
            self._rxq.append(byte)
            self.rx_log.append((now, byte))
            self._rx_activity()
        if self._line:
            self._rx_end += self.frame_format()[0]
            self._rx_ev = self.kernel.at(self._tick(self._rx_end), self._rx_frame_end)
        self._update_irq()
        self.rx_ready.fire()

    def _rx_activity(self):
        """A byte entered or left the RX FIFO: restart the character time-out."""
        if self._cti_ev is not None:
            self._cti_ev.cancel()
        self._cti_at = self._cti_ev = None
        if not (self._fifoen and self._rxq):
            return
        try:
            frame = self.frame_format()[0]
        except UnsupportedConfiguration:
            return                                       # baud generator stopped: the timer does not run
        self._cti_at = self._tick(self._now_cycle() + CTI_CHARS * frame)
        self._cti_ev = self.kernel.at(self._cti_at, self._cti_fire)

    def _cti_fire(self):
        self._cti_ev = None
        self._update_irq()

    def _read_rbr(self, stored):
        if not self._rxq:
            return 0
        byte = self._rxq.popleft()
        self._rx_activity()
        self._update_irq()
        return byte

    # --- other registers ---------------------------------------------------------------------------
    def _read_lsr(self, stored):
        v = (1 if self._rxq else 0) | (2 if self._oe else 0)
        if not self._txq:
            v |= 0x20
            if self._tsr is None:
                v |= 0x40
        if self._oe:
            self._oe = False
            self._update_irq()
        return v

    def _read_iir(self, stored):
        intid = self.interrupt_id()
        v = 0xC0 if self._fifoen else 0
        if intid is None:
            return v | 1
        if intid == INT_THRE:
            self._thre_int = False
            self._update_irq()
        return v | intid << 1

    def _write_ier(self, old, new):
        if new & THREIE and not old & THREIE and not self._txq and self._thre_ev is None:
            self._thre_int = True       # (during the initialization delay its own event sets it)
        self._update_irq()

    def _write_fcr(self, old, new):
        fifoen = bool(new & 1)
        if fifoen != self._fifoen:
            self._fifoen = fifoen
            self._reset_tx_fifo()
            self._rxq.clear()
            self._rx_activity()
        if fifoen:
            self._trigger = RX_TRIGGER[new >> 6 & 3]
            if new & 2:
                self._rxq.clear()
                self._rx_activity()
            if new & 4:
                self._reset_tx_fifo()
        self._update_irq()

    def _reset_tx_fifo(self):
        if self._txq:                                    # THR becomes empty: THRE source at once (choice)
            self._txq.clear()
            self._cancel_thre()
            self._thre_int, self._thr_peak = True, 0

    # --- bus: RBR/THR/DLL, IER/DLM and IIR/FCR share offsets ----------------------------------------
    def _reg_at(self, offset, size, address):
        if size not in self.ACCESS_SIZES:
            raise BusFault(address, size, f"{self.name} accepts only 8/16/32-bit accesses")
        slot = offset - offset % self.BUS_WIDTH
        shared = SHARED.get(slot)
        if shared is not None:
            read_name, write_name, dlab_name = shared
            if self.value["LCR"] & DLAB and dlab_name is not None:
                return self.regs[dlab_name]
            return self.regs[write_name if self._writing else read_name]
        reg = self._plain.get(slot)
        if reg is None:
            raise BusFault(address, size, f"no register of {self.name} at offset {offset:#x}")
        return reg

    def bus_read(self, offset, size, address):
        self._writing = False
        return super().bus_read(offset, size, address)

    def bus_write(self, offset, data, size, address):
        self._writing = True
        try:
            super().bus_write(offset, data, size, address)
        finally:
            self._writing = False
