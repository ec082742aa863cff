"""Host ends of a simulated serial port (UART/USART TX and RX lines).

The endpoint protocol (duck-typed; the kernel imports no peripheral model):

* the USART model calls ``endpoint.attach(usart)`` when it is connected (``Usart(..., endpoint=ep)``
  or ``usart.connect(ep)``);
* it calls ``endpoint.transmit(byte, tick)`` at the end of every TX frame (``tick`` = base tick of
  the frame's end, ``byte`` already masked to the word length);
* the endpoint delivers host -> MCU bytes by calling ``usart.receive(data: bytes)``, which puts them
  on the RX line from the current simulated time on, one frame each, queued behind any byte still
  being received.

:class:`BufferEndpoint` is in memory and fully deterministic. :class:`PtyEndpoint` is a pseudo
terminal that host programs (pyserial, pymavlink ``mavlink_connection(ep.path)``, a ground station)
open like a serial port.

**Determinism.** What a pty delivers, and at which simulated instant, depends on the host: on when
the other program writes, on the kernel's pty buffering and on how fast the simulation runs compared
with the wall clock. The pty is read only at the poll events, at fixed simulated ticks, and every
injection is recorded in ``PtyEndpoint.injected`` as ``(tick, bytes)``; everything after an injection
is deterministic, and feeding the same log to a :class:`BufferEndpoint` with :meth:`feed_at`
replays the run exactly. Output to the host never influences the simulation (it is buffered, never
blocks, and is dropped only when the host does not read, see ``PtyEndpoint.max_backlog``).
"""

from __future__ import annotations

import errno
import numbers
import os
import select

from .errors import ConfigError, McusimError
from .kernel import PRIO_INPUT
from .recent import RecentBytes, RecentLog

RX_BUFFER = 1024     # bytes a host end holds for the USART's RX line; the rest is dropped


def inject(endpoint, data: bytes) -> None:
    """Host -> MCU bytes from a live host end (pty, UDP): what fits in ``endpoint.rx_buffer``
    beside the bytes still waiting on the RX line is put on the line; the rest is dropped and
    counted in ``endpoint.rx_dropped``. This is the receive buffer of a serial bridge or of a tty
    driver: a host that sends faster than the line carries (a simulation slower than real time)
    loses bytes instead of piling up seconds of delay."""
    usart = endpoint.usart
    room = max(0, endpoint.rx_buffer - getattr(usart, "rx_pending", 0))
    if len(data) > room:
        endpoint.rx_dropped += len(data) - room
        data = data[:room]
    if data:
        endpoint.injected.append((usart.kernel.now, data))
        usart.receive(data)


class BufferEndpoint:
    """In-memory endpoint: ``sent`` collects what the MCU transmitted, ``feed`` injects bytes.

    ``sent`` (the bytes) and ``log`` (``(tick, byte)`` pairs) hold the recent past only, at least
    the last :data:`mcusim.recent.KEEP` bytes (:mod:`mcusim.recent`; ``.total`` counts them all),
    so an endpoint left attached to a rover's telemetry keeps memory flat."""

    def __init__(self):
        self.usart = None
        self.sent = RecentBytes()
        self.log: RecentLog = RecentLog()   # (tick, byte) of the bytes the MCU sent, the recent ones

    def attach(self, usart) -> None:
        self.usart = usart

    def transmit(self, byte: int, tick: int) -> None:
        self.sent.append(byte)
        self.log.append((tick, byte))

    def _need_usart(self):
        if self.usart is None:
            raise McusimError("serial endpoint is not connected to a USART")
        return self.usart

    def feed(self, data) -> None:
        """Bytes from the host: they start arriving on the RX line now."""
        self._need_usart().receive(_as_bytes(data))

    def feed_at(self, tick: int, data) -> None:
        """Schedule ``feed(data)`` at base tick ``tick`` (e.g. to replay ``PtyEndpoint.injected``)."""
        usart = self._need_usart()
        if isinstance(tick, bool) or not isinstance(tick, numbers.Integral) or tick < usart.kernel.now:
            raise McusimError(f"feed_at({tick!r}): a base tick, an int not before now ({usart.kernel.now})")
        usart.kernel.at(int(tick), usart.receive, _as_bytes(data), prio=PRIO_INPUT)


def _as_bytes(data) -> bytes:
    """Bytes given to ``feed``: anything with the buffer protocol (bytes, bytearray, a numpy uint8
    array, array('B')) or a list of 0..255; not an int, which ``bytes()`` would take as a count
    of zero bytes, nor text, which has no one encoding."""
    if isinstance(data, (list, tuple)):
        if all(isinstance(b, numbers.Integral) and not isinstance(b, bool) and 0 <= b <= 255 for b in data):
            return bytes(data)
    elif not isinstance(data, (str, numbers.Number)) and data is not None:
        try:
            return memoryview(data).cast("B").tobytes()
        except TypeError:
            pass
    raise McusimError(f"feed({data!r:.60}): give bytes (b\"...\"), a bytearray or a list of ints 0..255")


class PolledEndpoint:
    """What the live host ends (pty, UDP) share: every ``poll`` of simulated time (base ticks, or a
    duration string rounded to the nearest tick) they flush what the MCU sent to the host and
    :func:`inject` what the host sent. Subclasses give ``_flush()``, ``_read() -> bytes`` and
    ``_close_host()``."""

    kind = "host link"

    def _init_poll(self, poll, rx_buffer: int) -> None:
        self.poll_spec, self.poll, self._ev = poll, None, None
        self.usart = None
        self.rx_buffer, self.rx_dropped = rx_buffer, 0  # host -> MCU bytes lost: the RX buffer was full
        self.dropped = 0                               # MCU -> host bytes lost
        self.injected: list[tuple[int, bytes]] = []    # (tick, bytes) handed to the USART
        self.closed = False

    def attach(self, usart) -> None:
        if self.closed:
            raise McusimError(f"{self.kind} is closed")
        self.usart = usart
        kernel = usart.kernel
        spec = self.poll_spec
        poll = spec if isinstance(spec, int) else kernel.timebase.ticks(spec, rounding=True)
        if poll <= 0:
            raise ConfigError(f"{self.kind} poll interval {spec!r} must be at least one base tick")
        self.poll = poll
        if self._ev is not None:
            self._ev.cancel()
        self._ev = kernel.after(poll, self._poll, prio=PRIO_INPUT)

    def _poll(self) -> None:
        self._ev = None
        if self.closed:
            return
        self._flush()
        data = self._read()
        if data:
            inject(self, data)
        self._ev = self.usart.kernel.after(self.poll, self._poll, prio=PRIO_INPUT)

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        if self._ev is not None:
            self._ev.cancel()
            self._ev = None
        self._close_host()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __del__(self):
        if not getattr(self, "closed", True):
            self.close()


class PtyEndpoint(PolledEndpoint):
    """A pseudo terminal: the host program opens ``path`` (the slave side); the simulation uses the master.

    Both ends are set to raw mode (no echo, no CR/LF translation: binary MAVLink frames pass
    unchanged). ``poll`` is the simulated interval between reads of the host's input, in base ticks
    (int) or a duration string ("1ms", rounded to the nearest base tick); default 1 ms. The baud rate
    the host program sets on the pty is ignored: bytes take the USART's frame time on the RX line.
    At most ``rx_buffer`` bytes wait for the RX line; what the host writes beyond that is dropped and
    counted in ``rx_dropped`` (see :func:`inject`).
    """

    def __init__(self, poll="1ms", chunk: int = 4096, max_backlog: int = 1 << 20, rx_buffer: int = RX_BUFFER):
        import tty

        self._init_poll(poll, rx_buffer)
        self.chunk, self.max_backlog = chunk, max_backlog
        self.master, self.slave = os.openpty()
        tty.setraw(self.master)
        tty.setraw(self.slave)   # kept open, so the master never sees a hang-up between host sessions
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self.slave)
        self.kind = f"pty {self.path}"
        self._backlog = bytearray()

    # --- endpoint protocol ---------------------------------------------------------------------
    def transmit(self, byte: int, tick: int) -> None:
        if self.closed:
            return
        self._backlog.append(byte)
        self._flush()

    # --- host side -----------------------------------------------------------------------------
    def _flush(self) -> None:
        while self._backlog:
            try:
                n = os.write(self.master, self._backlog)
            except BlockingIOError:
                break
            except OSError as e:                       # EIO: no slave open; keep the bytes
                if e.errno != errno.EIO:
                    raise
                break
            del self._backlog[:n]
        excess = len(self._backlog) - self.max_backlog
        if excess > 0:
            del self._backlog[:excess]
            self.dropped += excess

    def _read(self) -> bytes:
        try:
            return os.read(self.master, self.chunk)
        except BlockingIOError:
            return b""
        except OSError as e:
            if e.errno == errno.EIO:                   # no slave side open at the moment
                return b""
            raise

    def wait_input(self, timeout: float) -> bool:
        """Block the *host* (not the simulation) up to ``timeout`` seconds until the host program has
        written something; for tools and tests that pace the simulation on host input."""
        if self.closed:
            return False
        ready, _, _ = select.select([self.master], [], [], timeout)
        return bool(ready)

    def _close_host(self) -> None:
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass
