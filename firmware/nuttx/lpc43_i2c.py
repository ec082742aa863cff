"""NuttX's LPC43xx I2C master driver (``arch/arm/src/lpc43xx/lpc43_i2c.c``), over the I2C registers.

The structure and names follow the C driver: a device structure (:class:`Lpc43I2cDev`, the C's
``struct lpc43_i2cdev_s``), ``lpc43_i2c_setfrequency``, ``lpc43_i2c_start`` (START, then wait on a
semaphore with a watchdog), ``lpc43_i2c_stop``, ``lpc43_i2c_nextmsg`` and the interrupt handler
``lpc43_i2c_interrupt``, a state machine on STAT that walks the message list: repeated START between
messages, STOP after the last one or on any other status. The driver touches the peripheral only
through its registers on ``mcu.bus`` (``getreg32``/``putreg32``) and is entered through IRQ
``irq`` (bound with a declared cycle cost, enabled by an NVIC ISER write).

What ``setfrequency`` does (as the C): above 100 kHz an asymmetric 47:83 high:low split "per the
400 kHz I2C spec", ``SCLH = base_freq / 130 * 47 / f`` and ``SCLL = base_freq / 130 * 83 / f``; at
or below 100 kHz a 50:50 split, ``SCLH = SCLL = base_freq / 100 * 50 / f`` (C integer arithmetic,
left to right). At 204 MHz: 100 kHz gives 1020/1020 (exactly 100 kHz), 400 kHz gives 184/325 (509
cycles, 400.79 kHz). ``base_freq`` is the board's APB1 clock (``BOARD_ABP1_FREQUENCY``, 204 MHz on
the EDU-CIAA), a constant of the firmware, not read from the model.

Deviations from the C, on purpose
---------------------------------
* ``transfer`` returns 0 or a negated errno: ``-ENXIO`` when an address byte is NACKed (0x20,
  0x48), ``-EIO`` when a data byte is NACKed (0x30) or on any unexpected status, ``-ETIMEDOUT``
  when the 20 ms watchdog expires, ``-EINVAL`` for messages the driver cannot express. (The C
  returns ``priv->nmsg``, the number of messages not completed, which is positive on failure.)
* On a timeout the C only posts the semaphore; here the driver also asks for a STOP (CONSET.STO,
  then CONCLR.STAC|SIC): at once if SI is set, else after the byte under way (see
  :mod:`mcusim.periph.lpc43xx.i2c`), so a later transfer finds the bus released.
* A zero-length write (an address probe) goes straight to the next message at 0x18; the C would
  send ``buffer[0]``.
* ``I2C_M_NOSTART`` (``I2C_M_NORESTART`` in older headers) is supported on a write message that
  follows a write message to the same address: its bytes continue the previous one without a
  repeated START (register address and data in separate buffers). The C ignores the flag. Any other
  use, 10-bit addresses (``I2C_M_TEN``) and zero-length reads give ``-EINVAL`` before the bus is
  touched.
* ``msg.frequency`` of the first message sets the rate as in the C, but 0/None keeps the current
  rate (the C would divide by zero).
* No SCU/CCU set-up (pin mode, branch clock): those blocks are not modelled.

Timing: the handler body runs at handler entry (12 cycles after SI rises); its register writes,
including the CONCLR.SIC that lets the next byte go, happen there, and the declared cost
(``LPC43_I2C_ISR_CYCLES``) is CPU time after it.
"""

from __future__ import annotations

from dataclasses import dataclass

from mcusim.firmware import Signal

# include/errno.h (NuttX uses the Linux numbering)
EIO, ENXIO, EAGAIN, EINVAL, ETIMEDOUT = 5, 6, 11, 22, 110
OK = 0

# include/nuttx/i2c/i2c_master.h
I2C_M_READ = 0x0001
I2C_M_TEN = 0x0002
I2C_M_NOSTOP = 0x0040
I2C_M_NOSTART = 0x0080
I2C_M_NORESTART = I2C_M_NOSTART
I2C_READBIT = 0x01


def I2C_WRITEADDR8(a):
    return (a << 1) & 0xFF


def I2C_READADDR8(a):
    return I2C_WRITEADDR8(a) | I2C_READBIT


# chip/lpc43_i2c.h: register offsets and bits
LPC43_I2C0_BASE = 0x400A1000
LPC43M4_IRQ_I2C0 = 18
LPC43_I2C_CONSET_OFFSET = 0x00
LPC43_I2C_STAT_OFFSET = 0x04
LPC43_I2C_DAT_OFFSET = 0x08
LPC43_I2C_ADR0_OFFSET = 0x0C
LPC43_I2C_SCLH_OFFSET = 0x10
LPC43_I2C_SCLL_OFFSET = 0x14
LPC43_I2C_CONCLR_OFFSET = 0x18
LPC43_I2C_MMCTRL_OFFSET = 0x1C
LPC43_I2C_BUFR_OFFSET = 0x2C
I2C_CONSET_AA, I2C_CONSET_SI, I2C_CONSET_STO, I2C_CONSET_STA, I2C_CONSET_I2EN = 0x04, 0x08, 0x10, 0x20, 0x40
I2C_CONCLR_AAC, I2C_CONCLR_SIC, I2C_CONCLR_STAC, I2C_CONCLR_I2ENC = 0x04, 0x08, 0x20, 0x40

NVIC_ISER0 = 0xE000E100

BOARD_ABP1_FREQUENCY = 204_000_000   # EDU-CIAA: PLL1 at 204 MHz feeds BASE_APB1_CLK
I2C0_DEFAULT_FREQUENCY = 400_000     # CONFIG_LPC43_I2C0_SUPERFAST unset
I2C_TIMEOUT_MS = 20                  # I2C_TIMEOUT = 20*1000/CONFIG_USEC_PER_TICK

# declared costs in core cycles [I]: the handler (status dispatch, a few register accesses, the
# message bookkeeping) and the transfer set-up before the START (mutex, setfrequency, registers)
LPC43_I2C_ISR_CYCLES = 150
LPC43_I2C_TRANSFER_CYCLES = 200


@dataclass
class I2cMsg:
    """``struct i2c_msg_s``: ``buffer`` holds the bytes to write, or receives the bytes read (give a
    bytearray, or an int to have one of that length allocated); ``length`` defaults to its size."""

    addr: int
    flags: int = 0
    buffer: bytearray | bytes | int = b""
    length: int | None = None
    frequency: int | None = None

    def __post_init__(self):
        if isinstance(self.buffer, int) or (self.flags & I2C_M_READ and not isinstance(self.buffer, bytearray)):
            self.buffer = bytearray(self.buffer)   # a buffer the driver can fill
        if self.length is None:
            self.length = len(self.buffer)


class Lpc43I2cDev:
    """``struct lpc43_i2cdev_s`` plus the driver's operations."""

    def __init__(self, mcu, base: int, irqid: int, base_freq: int = BOARD_ABP1_FREQUENCY,
                 isr_cycles: int = LPC43_I2C_ISR_CYCLES):
        self.mcu, self.bus, self.cpu, self.rtos = mcu, mcu.bus, mcu.cpu, mcu.rtos
        self.base, self.irqid, self.base_freq = base, irqid, base_freq
        self.isr_cycles = isr_cycles
        self.wait = Signal()        # sem_t wait: the state machine is done
        self.state = 0              # last STAT seen (0xFF after a timeout)
        self.frequency = 0
        self.msgs: list[I2cMsg] | None = None
        self.nmsg = 0
        self.msgi = 0               # index of the message in progress (the C advances a pointer)
        self.wrcnt = 0
        self.rdcnt = 0
        self.result = OK
        self._locked = False        # sem_t mutex
        self._unlocked = Signal()
        self.timeout_ticks = max(1, I2C_TIMEOUT_MS * self.rtos.tick_hz // 1000)

    # --- register access ------------------------------------------------------------------------
    def getreg32(self, offset: int) -> int:
        return self.bus.read32(self.base + offset)

    def putreg32(self, value: int, offset: int) -> None:
        self.bus.write32(self.base + offset, value)

    # --- driver -----------------------------------------------------------------------------------
    def lpc43_i2c_setfrequency(self, frequency: int) -> None:
        if frequency != self.frequency:
            if frequency > 100_000:
                # asymmetric per the 400 kHz I2C spec
                self.putreg32(self.base_freq // (83 + 47) * 47 // frequency, LPC43_I2C_SCLH_OFFSET)
                self.putreg32(self.base_freq // (83 + 47) * 83 // frequency, LPC43_I2C_SCLL_OFFSET)
            else:
                # 50/50 mark-space ratio
                self.putreg32(self.base_freq // 100 * 50 // frequency, LPC43_I2C_SCLH_OFFSET)
                self.putreg32(self.base_freq // 100 * 50 // frequency, LPC43_I2C_SCLL_OFFSET)
            self.frequency = frequency

    setfrequency = lpc43_i2c_setfrequency

    async def lpc43_i2c_start(self) -> int:
        self.putreg32(I2C_CONCLR_STAC | I2C_CONCLR_SIC, LPC43_I2C_CONCLR_OFFSET)
        self.putreg32(I2C_CONSET_STA, LPC43_I2C_CONSET_OFFSET)
        # wd_start(timeout) + nxsem_wait(wait)
        posted = await self.rtos.wait_signal(self.wait, timeout=self.timeout_ticks)
        if not posted:
            self.lpc43_i2c_timeout()
        return self.result

    def lpc43_i2c_timeout(self) -> None:
        """The watchdog expired: give up and ask for a STOP (see the module notes)."""
        self.state = 0xFF
        self.result = -ETIMEDOUT
        self.msgs = None
        self.putreg32(I2C_CONSET_STO, LPC43_I2C_CONSET_OFFSET)
        self.putreg32(I2C_CONCLR_STAC | I2C_CONCLR_SIC, LPC43_I2C_CONCLR_OFFSET)

    def lpc43_i2c_stop(self) -> None:
        if self.state != 0x38:
            self.putreg32(I2C_CONSET_STO | I2C_CONSET_AA, LPC43_I2C_CONSET_OFFSET)
        self.wait.fire()            # nxsem_post(&priv->wait)

    def lpc43_i2c_nextmsg(self) -> None:
        """Set up the next message (``lpc32_i2c_nextmsg`` in the C)."""
        self.nmsg -= 1
        if self.nmsg > 0:
            self.msgi += 1
            msg = self.msgs[self.msgi]
            if msg.flags & I2C_M_NOSTART:
                self._put_first_byte(msg)           # continue the write, no repeated START
            else:
                self.putreg32(I2C_CONSET_STA, LPC43_I2C_CONSET_OFFSET)
        else:
            self.result = OK
            self.lpc43_i2c_stop()

    def _put_first_byte(self, msg: I2cMsg) -> None:
        self.wrcnt = 0
        if msg.length > 0:
            self.putreg32(msg.buffer[0], LPC43_I2C_DAT_OFFSET)
        else:
            self.lpc43_i2c_nextmsg()

    def lpc43_i2c_interrupt(self) -> None:
        """The I2C interrupt handler (UM10503 master state tables)."""
        state = self.getreg32(LPC43_I2C_STAT_OFFSET)
        self.state = state
        state &= 0xF8
        if self.msgs is None:                       # nothing in progress (after a timeout)
            self.putreg32(I2C_CONSET_STO, LPC43_I2C_CONSET_OFFSET)
            self.putreg32(I2C_CONCLR_SIC, LPC43_I2C_CONCLR_OFFSET)
            return
        msg = self.msgs[self.msgi]
        if state in (0x08, 0x10):                   # (repeated) START sent: address
            addr = I2C_READADDR8(msg.addr) if msg.flags & I2C_M_READ else I2C_WRITEADDR8(msg.addr)
            self.putreg32(addr, LPC43_I2C_DAT_OFFSET)
            self.putreg32(I2C_CONCLR_STAC, LPC43_I2C_CONCLR_OFFSET)
        elif state == 0x18:                         # SLA+W sent, ACK
            self._put_first_byte(msg)
        elif state == 0x28:                         # data sent, ACK
            self.wrcnt += 1
            if self.wrcnt < msg.length:
                self.putreg32(msg.buffer[self.wrcnt], LPC43_I2C_DAT_OFFSET)
            else:
                self.lpc43_i2c_nextmsg()
        elif state == 0x40:                         # SLA+R sent, ACK
            self.rdcnt = 0
            if msg.length > 1:
                self.putreg32(I2C_CONSET_AA, LPC43_I2C_CONSET_OFFSET)     # ACK the next byte
            else:
                self.putreg32(I2C_CONCLR_AAC, LPC43_I2C_CONCLR_OFFSET)    # one byte: NACK it
        elif state == 0x50:                         # data received, ACK returned
            self.rdcnt += 1
            msg.buffer[self.rdcnt - 1] = self.getreg32(LPC43_I2C_BUFR_OFFSET) & 0xFF
            if self.rdcnt >= msg.length - 1:
                self.putreg32(I2C_CONCLR_AAC, LPC43_I2C_CONCLR_OFFSET)    # NACK the last one
        elif state == 0x58:                         # data received, NACK returned
            msg.buffer[self.rdcnt] = self.getreg32(LPC43_I2C_BUFR_OFFSET) & 0xFF
            self.lpc43_i2c_nextmsg()
        else:                                       # 0x20, 0x30, 0x48, 0x38, anything else
            self.result = -ENXIO if state in (0x20, 0x48) else -EIO
            self.lpc43_i2c_stop()
        self.putreg32(I2C_CONCLR_SIC, LPC43_I2C_CONCLR_OFFSET)           # let the bus go on

    @staticmethod
    def _check(msgs) -> int:
        if not msgs:
            return -EINVAL
        for k, m in enumerate(msgs):
            if not 0 <= m.addr <= 0x7F or m.flags & I2C_M_TEN:
                return -EINVAL
            if m.length < 0 or m.length > len(m.buffer):
                return -EINVAL
            if m.flags & I2C_M_READ and m.length == 0:
                return -EINVAL
            if m.flags & I2C_M_NOSTART:
                prev = msgs[k - 1] if k else None
                if (prev is None or m.flags & I2C_M_READ or prev.flags & I2C_M_READ
                        or prev.addr != m.addr):
                    return -EINVAL
        return OK

    async def transfer(self, msgs) -> int:
        """``lpc43_i2c_transfer``: perform the messages; 0 or a negated errno."""
        msgs = list(msgs)
        ret = self._check(msgs)
        if ret != OK:
            return ret
        while self._locked:                         # nxsem_wait(&priv->mutex)
            await self.rtos.wait_signal(self._unlocked)
        self._locked = True
        try:
            self.wrcnt = self.rdcnt = 0
            self.msgs, self.msgi, self.nmsg = msgs, 0, len(msgs)
            self.result = -EIO
            if msgs[0].frequency:
                self.lpc43_i2c_setfrequency(msgs[0].frequency)
            await self.cpu.cycles(LPC43_I2C_TRANSFER_CYCLES)
            ret = await self.lpc43_i2c_start()
            self.msgs = None
        finally:
            self._locked = False
            self._unlocked.fire()
        return ret

    # --- conveniences (i2c_write / i2c_read / i2c_writeread of drivers/i2c/i2c_writeread.c) ---------
    async def write(self, addr: int, data) -> int:
        return await self.transfer([I2cMsg(addr, 0, bytes(data))])

    async def read(self, addr: int, nread: int) -> tuple[int, bytes]:
        msg = I2cMsg(addr, I2C_M_READ, nread)
        ret = await self.transfer([msg])
        return ret, bytes(msg.buffer) if ret == OK else b""

    async def write_read(self, addr: int, wbytes, nread: int) -> tuple[int, bytes]:
        """Write ``wbytes``, repeated START, read ``nread`` bytes, STOP. Returns ``(ret, data)``:
        ret 0 and the bytes read, or a negated errno and b""."""
        rd = I2cMsg(addr, I2C_M_READ, nread)
        ret = await self.transfer([I2cMsg(addr, 0, bytes(wbytes)), rd])
        return ret, bytes(rd.buffer) if ret == OK else b""


def lpc43_i2c_init(mcu, base: int = LPC43_I2C0_BASE, irq: int = LPC43M4_IRQ_I2C0,
                   frequency: int = I2C0_DEFAULT_FREQUENCY, base_freq: int = BOARD_ABP1_FREQUENCY,
                   isr_cycles: int = LPC43_I2C_ISR_CYCLES) -> Lpc43I2cDev:
    """``lpc43_i2cbus_initialize``: rate, I2EN, attach and enable the interrupt."""
    priv = Lpc43I2cDev(mcu, base, irq, base_freq, isr_cycles)
    priv.lpc43_i2c_setfrequency(frequency)
    priv.putreg32(I2C_CONSET_I2EN, LPC43_I2C_CONSET_OFFSET)
    mcu.cpu.vector(irq, priv.lpc43_i2c_interrupt, cost=isr_cycles)      # irq_attach
    mcu.bus.write32(NVIC_ISER0 + 4 * (irq // 32), 1 << (irq % 32))       # up_enable_irq
    return priv
