"""NuttX's LPC43xx serial lower half (``arch/arm/src/lpc43xx/lpc43_serial.c`` with the divisor search
of ``lpc43_uart.c``), over the USART registers: the console that ``syslog``/``printf`` write to.

Structure as in the C: ``up_setup`` (FIFOs reset and on, the receive interrupt at 8 bytes or a
character timeout, 8N1, the baud divisor),
``up_txint`` (THRE interrupt on while the transmit buffer holds data), ``up_interrupt`` (on THRE,
move up to 16 bytes from the buffer to the FIFO; on received data, read RBR into the receive
buffer) and the upper half's circular ``xmit`` buffer that ``write`` fills. The driver touches the
USART only through its registers and is entered through its interrupt.

Deviations: the divisor search (``lpc43_setbaud``) tries every MULVAL 1..15 and DIVADDVAL
0..MULVAL-1 and keeps the divisor with the smallest rate error, which finds the same setting as
LPCOpen's ``Chip_UART_SetBaudFDR`` for 115200 at 204 MHz (DL 83, DIVADDVAL 5, MULVAL 15: +0.0094 %);
a full transmit buffer drops the rest of a write (the upper half would block the caller; callers
that must not lose bytes check ``txroom`` first, as a C task would poll for POLLOUT); a full
receive buffer (``rxbufsize``, CONFIG_USARTn_RXBUFSIZE, 256 by default) drops the byte read from
RBR and counts it in ``rx_dropped``. ``rxavail`` is fired when received bytes enter the buffer
(the upper half's ``recvsem`` post that wakes a reader blocked in ``read``/``poll``).
"""

from __future__ import annotations

from collections import deque

from mcusim.firmware import Signal

UART_RBR_THR_DLL, UART_DLM_IER, UART_IIR_FCR, UART_LCR, UART_LSR = 0x00, 0x04, 0x08, 0x0C, 0x14
UART_FDR = 0x28
IER_RBRIE, IER_THREIE = 0x01, 0x02
LCR_8N1, LCR_DLAB = 0x03, 0x80
FCR_FIFOEN, FCR_RXRST, FCR_TXRST, FCR_RXTRIGGER_8 = 0x01, 0x02, 0x04, 0x80
LSR_RDR, LSR_THRE = 0x01, 0x20
IIR_INTID_MASK, IIR_THRE, IIR_RDA, IIR_CTI = 0x0E, 0x02, 0x04, 0x0C
NVIC_ISER0 = 0xE000E100
UART_SERIAL_ISR_CYCLES = 180      # declared: the handler moving up to 16 bytes


def lpc43_setbaud(pclk: int, baud: int) -> tuple[int, int, int]:
    """(divisor, DIVADDVAL, MULVAL) with the smallest error: baud = pclk / (16·DL·(1 + DA/MUL))."""
    best = None
    for mul in range(1, 16):
        for div in range(mul):
            dl = round(pclk * mul / (16 * baud * (mul + div)))
            if not 0 < dl < 1 << 16 or (div and dl < 3):
                continue
            err = abs(pclk * mul / (16 * dl * (mul + div)) - baud)
            if best is None or err < best[0]:
                best = (err, dl, div, mul)
    if best is None:
        raise ValueError(f"no divisor gives {baud} baud from {pclk} Hz")
    return best[1], best[2], best[3]


class Lpc43SerialDev:
    def __init__(self, mcu, base: int, irq: int, baud: int, pclk: int, txbufsize: int = 512,
                 isr_cycles: int = UART_SERIAL_ISR_CYCLES, rxbufsize: int = 256):
        self.mcu, self.base, self.irq, self.baud, self.pclk = mcu, base, irq, baud, pclk
        self.xmit: deque[int] = deque()
        self.recv = bytearray()
        self.txbufsize, self.rxbufsize = txbufsize, rxbufsize
        self.rx_dropped = 0
        self.rxavail = Signal()
        self.dropped = 0
        self.ier = 0
        self.isr_cycles = isr_cycles

    def getreg(self, off: int) -> int:
        return self.mcu.bus.read32(self.base + off)

    def putreg(self, off: int, value: int) -> None:
        self.mcu.bus.write32(self.base + off, value)

    def up_setup(self) -> None:
        """up_setup (FIFOs reset and on, the receive trigger at 8 bytes, 8N1, the divisors), then
        what the upper half's open does next: up_attach (the vector, the NVIC line) and
        up_rxint(true) (RBRIE)."""
        self.putreg(UART_IIR_FCR, FCR_RXRST | FCR_TXRST)        # clear fifos
        self.putreg(UART_IIR_FCR, FCR_FIFOEN | FCR_RXTRIGGER_8)  # set trigger
        self.ier = self.getreg(UART_DLM_IER)
        self.putreg(UART_LCR, LCR_8N1)
        self.lpc43_setbaud()
        self.putreg(UART_IIR_FCR, FCR_RXTRIGGER_8 | FCR_TXRST | FCR_RXRST | FCR_FIFOEN)
        self.mcu.cpu.vector(self.irq, self.up_interrupt, cost=self.isr_cycles)       # up_attach
        self.mcu.bus.write32(NVIC_ISER0 + 4 * (self.irq // 32), 1 << (self.irq % 32))
        self.ier |= IER_RBRIE                                                         # up_rxint
        self.putreg(UART_DLM_IER, self.ier)

    def lpc43_setbaud(self) -> None:
        """lpc43_uart.c: DLAB set on the LCR as read, DLM, DLL, DLAB cleared, then FDR."""
        dl, divadd, mul = lpc43_setbaud(self.pclk, self.baud)
        lcr = self.getreg(UART_LCR)
        self.putreg(UART_LCR, lcr | LCR_DLAB)
        self.putreg(UART_DLM_IER, dl >> 8)
        self.putreg(UART_RBR_THR_DLL, dl & 0xFF)
        self.putreg(UART_LCR, lcr & ~LCR_DLAB)
        self.putreg(UART_FDR, mul << 4 | divadd)

    def up_txint(self, enable: bool) -> None:
        ier = (self.ier | IER_THREIE) if enable else (self.ier & ~IER_THREIE)
        if ier != self.ier:
            self.ier = ier
            self.putreg(UART_DLM_IER, ier)

    def _fill_fifo(self) -> None:
        for _ in range(16):
            if not self.xmit:
                break
            self.putreg(UART_RBR_THR_DLL, self.xmit.popleft())
        self.up_txint(bool(self.xmit))

    def up_interrupt(self) -> None:
        while True:
            iir = self.getreg(UART_IIR_FCR)
            if iir & 1:                         # no interrupt pending
                return
            intid = iir & IIR_INTID_MASK
            if intid in (IIR_RDA, IIR_CTI):
                while self.getreg(UART_LSR) & LSR_RDR:
                    byte = self.getreg(UART_RBR_THR_DLL) & 0xFF
                    if len(self.recv) < self.rxbufsize:
                        self.recv.append(byte)
                    else:
                        self.rx_dropped += 1
                self.rxavail.fire()
            elif intid == IIR_THRE:
                self._fill_fifo()
                if not self.xmit:
                    return
            else:                               # line status: reading LSR clears it
                self.getreg(UART_LSR)

    @property
    def txroom(self) -> int:
        """Free bytes in the transmit buffer (what a write can queue without dropping)."""
        return self.txbufsize - len(self.xmit)

    def read(self) -> bytes:
        """The upper half's non-blocking read(): every byte in the receive buffer."""
        data, self.recv = bytes(self.recv), bytearray()
        return data

    def write(self, data: bytes) -> int:
        """The upper half's write(): queue the bytes; start the transmitter if it is idle."""
        room = self.txbufsize - len(self.xmit)
        if len(data) > room:
            self.dropped += len(data) - room
            data = data[:room]
        self.xmit.extend(data)
        if self.getreg(UART_LSR) & LSR_THRE:
            self._fill_fifo()
        else:
            self.up_txint(True)
        return len(data)
