"""A minimal GDB remote-serial-protocol client for the tests (no gdb needed)."""

from __future__ import annotations

import socket
import time


class Rsp:
    def __init__(self, port, timeout=30.0):
        deadline = time.monotonic() + timeout
        while True:
            try:
                self.sock = socket.create_connection(("127.0.0.1", port), timeout=timeout)
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.05)
        self.buf = b""

    def send(self, payload: str) -> None:
        data = payload.encode("latin-1")
        self.sock.sendall(b"$" + data + b"#" + b"%02x" % (sum(data) & 0xFF))

    def recv(self) -> str:
        while True:
            if b"#" in self.buf and b"$" in self.buf:
                start = self.buf.index(b"$")
                end = self.buf.find(b"#", start)
                if end >= 0 and len(self.buf) >= end + 3:
                    body, cs = self.buf[start + 1:end], self.buf[end + 1:end + 3]
                    self.buf = self.buf[end + 3:]
                    assert int(cs, 16) == sum(body) & 0xFF, "bad checksum"
                    self.sock.sendall(b"+")
                    return body.decode("latin-1")
            chunk = self.sock.recv(65536)
            if not chunk:
                raise ConnectionError("the server closed the connection")
            self.buf += chunk.replace(b"+", b"") if not self.buf else chunk

    def ask(self, payload: str) -> str:
        self.send(payload)
        return self.recv()

    def interrupt(self) -> None:
        self.sock.sendall(b"\x03")

    def close(self):
        self.sock.close()
