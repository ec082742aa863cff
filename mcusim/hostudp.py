"""A serial-to-UDP adapter as a host end of a simulated UART (the endpoint protocol of
:mod:`mcusim.hostserial`), and the ``--mavlink`` link specifications of the command line.

Like a hardware serial-to-UDP bridge (ser2net, a WiFi telemetry module), it carries a byte
stream: the bytes the USART transmitted since the previous poll go out as one datagram at each
poll event (every ``poll`` of simulated time, default 1 ms), and every datagram received is put on
the USART's RX line at the poll event that reads it, one USART frame per byte. MAVLink frames may
therefore be split across datagrams; ground stations and pymavlink parse UDP links as a stream.

* ``udpout:HOST:PORT``: sends to HOST:PORT from an ephemeral port and takes replies on it
  (QGroundControl listens on UDP 14550);
* ``udpin:HOST:PORT``: listens on HOST:PORT and sends to whoever sent the last datagram (nothing
  goes out, and ``dropped`` counts the bytes, until a peer has spoken).

HOST is a name or an IPv4 address, or an IPv6 address in brackets (``udpout:[::1]:14550``).

Sockets are non-blocking: the simulation never waits for the host. A datagram the host's stack
refuses (no listener: ECONNREFUSED, a full buffer) is dropped and counted in ``dropped``. Like the
bridge's own buffer, at most ``rx_buffer`` bytes (1024) wait for the USART's RX line; received
bytes beyond that are dropped and counted in ``rx_dropped`` (a host that sends faster than the
simulated line carries, e.g. when the simulation runs slower than real time).
Determinism: as for :class:`mcusim.hostserial.PtyEndpoint`, what arrives when depends on the host;
``injected`` logs every ``(tick, bytes)`` handed to the USART, and replaying it with
``BufferEndpoint.feed_at`` reproduces the run.
"""

from __future__ import annotations

import socket

from .errors import ConfigError
from .hostserial import RX_BUFFER, PolledEndpoint

MAX_DATAGRAM = 65507


class UdpEndpoint(PolledEndpoint):
    def __init__(self, mode: str, host: str, port: int, poll="1ms", rx_buffer: int = RX_BUFFER):
        if mode not in ("udpin", "udpout"):
            raise ConfigError(f"UDP link mode {mode!r}: expected udpin or udpout")
        self.mode, self.host, self.port = mode, host, port
        self.sock = None
        try:                                   # IPv4 or IPv6, as the host name resolves ("[::1]": IPv6)
            family, _, _, _, addr = socket.getaddrinfo(host.strip("[]"), port, socket.AF_UNSPEC,
                                                       socket.SOCK_DGRAM)[0]
            self.sock = socket.socket(family, socket.SOCK_DGRAM)
            if mode == "udpin":
                self.sock.bind(addr)
                self.peer = None
            else:
                self.sock.bind(("::", 0) if family == socket.AF_INET6 else ("0.0.0.0", 0))
                self.peer = addr
        except OSError as exc:
            if self.sock is not None:
                self.sock.close()
            raise ConfigError(f"--mavlink {mode}:{host}:{port}: {exc.strerror or exc}") from None
        self.sock.setblocking(False)
        self._init_poll(poll, rx_buffer)
        self.kind = f"UDP link {mode}:{host}:{port}"
        self._out = bytearray()

    @property
    def address(self) -> tuple:
        return self.sock.getsockname()

    # --- endpoint protocol ---------------------------------------------------------------------
    def transmit(self, byte: int, tick: int) -> None:
        if not self.closed:
            self._out.append(byte)

    # --- host side -----------------------------------------------------------------------------
    def _flush(self) -> None:
        if not self._out:
            return
        data, self._out = bytes(self._out), bytearray()
        if self.peer is None:
            self.dropped += len(data)
            return
        for i in range(0, len(data), MAX_DATAGRAM):
            try:
                self.sock.sendto(data[i:i + MAX_DATAGRAM], self.peer)
            except OSError:                 # no listener (ICMP refused), buffer full: the bytes are lost
                self.dropped += len(data[i:i + MAX_DATAGRAM])

    def _read(self) -> bytes:
        got = bytearray()
        while True:
            try:
                data, addr = self.sock.recvfrom(MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:                 # e.g. ECONNREFUSED reported for an earlier send
                continue
            if self.mode == "udpin":
                self.peer = addr
            got += data
        return bytes(got)

    def _close_host(self) -> None:
        self.sock.close()


def parse_link(spec: str, what: str = "--mavlink"):
    """``pty``, ``udpout:HOST:PORT`` or ``udpin:HOST:PORT`` (pymavlink's connection-string syntax):
    ``("pty",)`` or ``(mode, host, port)``; ConfigError for anything else."""
    text = spec.strip()
    if text == "pty":
        return ("pty",)
    mode, _, rest = text.partition(":")
    host, _, port = rest.rpartition(":")
    lowest = 0 if mode == "udpin" else 1          # udpin:HOST:0 listens on a free port (printed)
    if mode in ("udpout", "udpin") and host and port.isdigit() and lowest <= int(port) < 65536:
        return (mode, host, int(port))
    if mode in ("udpout", "udpin") and host and port.isdigit():
        raise ConfigError(f"{what} {spec!r}: port {int(port)} is out of range ({lowest} to 65535"
                          + (", 0 for udpin only: a free port" if mode == "udpout" else ": 0 takes a free port") + ")")
    raise ConfigError(f"{what} {spec!r}: expected pty, udpout:HOST:PORT or udpin:HOST:PORT "
                      "(udpout:127.0.0.1:14550 reaches QGroundControl)")


def open_link(spec: str, what: str = "--mavlink"):
    """The endpoint a link specification names (not yet attached to a UART)."""
    parsed = parse_link(spec, what)
    if parsed[0] == "pty":
        from .hostserial import PtyEndpoint
        return PtyEndpoint()
    return UdpEndpoint(*parsed)


def describe(endpoint) -> str:
    """One line for the user: where to connect."""
    if hasattr(endpoint, "path"):
        return f"{endpoint.path} (pty: mavproxy.py --master={endpoint.path}, mavros serial://{endpoint.path})"
    host, port = _host(endpoint.address[0]), endpoint.address[1]
    if endpoint.mode == "udpout":
        return f"UDP to {_host(endpoint.peer[0])}:{endpoint.peer[1]} from {host}:{port}"
    return f"UDP on {host}:{port} (connect with udpout:{host}:{port})"


def _host(addr: str) -> str:
    return f"[{addr}]" if ":" in addr else addr
