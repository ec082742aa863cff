"""A GDB remote-serial-protocol server for the compiled-image core (``mcusim run --gdb PORT``).

gdb connects with ``target extended-remote :PORT`` (or ``target remote``). The target is halted at
reset until gdb continues. While it is halted the whole simulation stands still: the server is
served from inside the core's kernel event, so simulated time advances only while the target
runs. What it offers:

* registers ``r0``-``r12``, ``sp``, ``lr``, ``pc``, ``xpsr`` (an ``org.gnu.gdb.arm.m-profile``
  target description), ``msp``, ``psp``, ``primask``, ``basepri``, ``faultmask``, ``control``
  and the FPU's ``d0``-``d15`` and ``fpscr`` (``org.gnu.gdb.arm.vfp``: gdb shows ``s0``-``s31``
  and float arguments and locals), read and written;
* memory: flash and RAM directly; a peripheral address goes through the register models, with
  their side effects, as on a real probe (reading a clear-on-read flag clears it);
* breakpoints (``Z0``/``Z1``) and watchpoints on RAM and peripherals (``Z2`` write, ``Z3`` read,
  ``Z4`` access), reported at the accessing instruction before it retires (gdb steps it);
* ``stepi``, ``continue``, Ctrl-C (polled once per simulated millisecond and at each quantum),
  ``detach`` (the run goes on without the debugger), ``kill`` (the run ends with an error).
"""

from __future__ import annotations

import os
import select
import socket
import sys

from unicorn import arm_const as A
from unicorn.unicorn_const import UC_HOOK_CODE, UC_HOOK_MEM_READ, UC_HOOK_MEM_WRITE

from ..errors import BusFault, ConfigError, McusimError
from ..kernel import PRIO_OBSERVE

SIGINT, SIGTRAP = 2, 5
CORE_REGS = tuple(f"r{i}" for i in range(13)) + ("sp", "lr", "pc", "xpsr")
SYSTEM_REGS = ("msp", "psp", "primask", "basepri", "faultmask", "control")
FP_REGS = tuple(f"d{i}" for i in range(16)) + ("fpscr",)     # gdb shows s0-s31 as halves of d0-d15
REGS = CORE_REGS + SYSTEM_REGS + FP_REGS


def _size(name):
    return 8 if name[0] == "d" else 4


def _reg_xml(names, first):
    return "".join(f'<reg name="{r}" bitsize="{8 * _size(r)}" regnum="{first + i}"'
                   + (' type="data_ptr"' if r in ("sp", "msp", "psp") else ' type="code_ptr"' if r == "pc"
                      else ' type="ieee_double"' if r[0] == "d" else "")
                   + "/>" for i, r in enumerate(names))


TARGET_XML = ('<?xml version="1.0"?><!DOCTYPE target SYSTEM "gdb-target.dtd"><target version="1.0">'
              "<architecture>arm</architecture>"
              '<feature name="org.gnu.gdb.arm.m-profile">' + _reg_xml(CORE_REGS, 0) + "</feature>"
              '<feature name="org.mcusim.cortex-m.system">' + _reg_xml(SYSTEM_REGS, len(CORE_REGS))
              + "</feature>"
              '<feature name="org.gnu.gdb.arm.vfp">' + _reg_xml(FP_REGS, len(CORE_REGS) + len(SYSTEM_REGS))
              + "</feature></target>")


class DebuggerKill(McusimError):
    """gdb killed the target: the run ends."""


def _checksum(data: bytes) -> bytes:
    return b"%02x" % (sum(data) & 0xFF)


_HEX = "0123456789abcdefABCDEF"


class _Malformed(Exception):
    """A packet whose fields do not parse (answered ``E01``)."""


def _hex_ints(text: str, n: int):
    """``n`` comma-separated hexadecimal numbers (the fields of ``m``, ``M``, ``Z`` ... packets)."""
    parts = text.split(",")
    if len(parts) != n or not all(x and x.strip(_HEX) == "" for x in parts):
        raise _Malformed(text)
    return tuple(int(x, 16) for x in parts)


def _hex_bytes(text: str) -> bytes:
    try:
        return bytes.fromhex(text)
    except ValueError:
        raise _Malformed(text) from None


class GdbServer:
    def __init__(self, sim, port: int, host: str = "127.0.0.1"):
        core = sim.mcu.cpu
        if not hasattr(core, "uc"):
            raise ConfigError("--gdb debugs a compiled image: give --firmware APP.ELF")
        self.sim, self.core, self.kernel = sim, core, sim.kernel
        self.listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self.listener.bind((host, port))
        except OSError as exc:
            self.listener.close()
            raise ConfigError(f"--gdb {port}: cannot listen on {host}:{port}: {exc.strerror or exc}") from None
        self.listener.listen(1)
        self.port = self.listener.getsockname()[1]
        self.conn = None
        self.breakpoints: dict[int, int] = {}       # address -> unicorn hook
        self.watchpoints: dict[tuple, int] = {}     # (kind, addr, len) -> hook
        self.halted = True                          # at reset, until gdb continues
        self.reason = f"T{SIGTRAP:02x}"
        self.stepping = False
        self._buf = b""
        core.debug = self
        self._poll_ev = None

    # --- connection ----------------------------------------------------------------------------
    def wait_for_client(self, quiet: bool = False) -> None:
        if not quiet:
            print(f"mcusim: waiting for gdb on port {self.port} (target extended-remote :{self.port})",
                  file=sys.stderr, flush=True)
        self.conn, _ = self.listener.accept()
        self.conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._schedule_poll()

    def close(self) -> None:
        if self.conn is not None:
            try:
                self.conn.close()
            except OSError:
                pass
            self.conn = None
        self.listener.close()

    def finish(self) -> None:
        """The run has ended: tell a gdb waiting for the target that it exited."""
        if self.conn is not None and not self.halted:
            try:
                self._send(b"W00")
            except OSError:
                pass
        self.detach()
        self.close()

    def _schedule_poll(self):
        period = self.kernel.timebase.ticks("1ms", rounding=True)
        self._poll_ev = self.kernel.after(period, self._poll_event, prio=PRIO_OBSERVE)

    def _poll_event(self):
        if self.core.debug is not self:
            return
        self._check_interrupt()
        if self.halted and self.core.state != "run":       # asleep (WFI): serve at this instant
            self.serve()
        self._schedule_poll()

    # --- the core's side -------------------------------------------------------------------------
    def before_quantum(self) -> None:
        if self.halted:
            self.serve()

    def budget(self, n: int) -> int:
        return 1 if self.stepping else n

    def entered(self) -> None:
        """An exception was taken: a step ends at the handler's first instruction."""
        if self.stepping:
            self._halt(f"T{SIGTRAP:02x}")

    def after_quantum(self, stop) -> None:
        if stop is not None:
            self._halt(stop)
        elif self.stepping:
            self._halt(f"T{SIGTRAP:02x}")
        else:
            self._check_interrupt()

    def _halt(self, reason: str) -> None:
        self.stepping = False
        self.halted = True
        self.reason = reason

    def _check_interrupt(self) -> None:
        if self.conn is None or self.halted:
            return
        if self._interrupted:
            self._interrupted = False
            self._halt(f"T{SIGINT:02x}")
            return
        r, _, _ = select.select([self.conn], [], [], 0)
        if r:
            data = self.conn.recv(4096)
            if not data:
                self.detach()
                return
            if b"\x03" in data:
                self._halt(f"T{SIGINT:02x}")
            self._buf += data.replace(b"\x03", b"")

    # --- hooks ---------------------------------------------------------------------------------
    def _on_breakpoint(self, uc, address, size, _):
        core = self.core
        if not core._in_emu or core._stop is not None or core._replaying:
            return
        if address == self._skip_bp and core._q_base == 0:
            self._skip_bp = None
            return                      # resuming from this breakpoint: execute it
        core._stop = ("debug", f"T{SIGTRAP:02x}swbreak:;")
        uc.emu_stop()

    def _on_watch(self, kind):
        def hook(uc, access, address, size, value, _):
            core = self.core
            if not core._in_emu or core._stop is not None or core._replaying:
                return
            pc = uc.reg_read(A.UC_ARM_REG_PC)
            if pc == self._skip_bp and core._retired_to(pc) == 0:
                return                  # resuming from this watchpoint's stop: its instruction runs
            # gdb takes an ARM watchpoint as firing before the access completes and steps the
            # instruction itself: the stop comes with it not retired, PC at it, as at a breakpoint
            # (a RAM access is made again when it runs: the same value, no side effect)
            core._stop = ("debug", f"T{SIGTRAP:02x}{kind}:{address:x};")
            uc.emu_stop()
        return hook

    def watch_hit(self, address: int, size: int, write: bool):
        """A peripheral access the core made: the stop reply if a watchpoint covers it."""
        for (kind, addr, length) in self.watchpoints:
            if address < addr + length and addr < address + size and (
                    kind == "awatch" or (kind == "watch") == write):
                return f"T{SIGTRAP:02x}{kind}:{address:x};"
        return None

    # --- packets -------------------------------------------------------------------------------
    def _send(self, payload: bytes) -> None:
        self.conn.sendall(b"$" + payload + b"#" + _checksum(payload))

    def _read_packet(self):
        while True:
            while b"$" in self._buf:
                start = self._buf.index(b"$")
                end = self._buf.find(b"#", start)
                if end < 0 or len(self._buf) < end + 3:
                    break
                payload = self._buf[start + 1:end]
                self._buf = self._buf[end + 3:]
                self.conn.sendall(b"+")
                return payload
            data = self.conn.recv(65536)
            if not data:
                return None
            if b"\x03" in data:          # Ctrl-C right behind a continue: halt once it runs
                self._interrupted = True
                data = data.replace(b"\x03", b"")
            self._buf += data.replace(b"+", b"") if b"$" not in data else data

    def serve(self) -> None:
        """Answer gdb until it resumes the target (continue, step, detach) or kills it."""
        if self.conn is None:
            return
        if self.reason is not None and self._reply_pending:
            self._send(self.reason.encode())
            self._reply_pending = False
        while True:
            try:
                pkt = self._read_packet()
            except OSError:
                pkt = None
            if pkt is None:               # gdb went away: the run goes on
                self.detach()
                return
            if _TRACE:
                print(f"gdb> {pkt.decode('latin-1')[:80]}", file=sys.stderr)
            try:
                reply = self._handle(pkt.decode("latin-1"))
            except _Malformed:
                reply = "E01"         # a packet that does not parse: an error reply, the session goes on
            if reply is _RESUME:
                self._skip_bp = self.core.reg("pc")
                self.halted = False
                self._reply_pending = True
                return
            if reply is _DETACHED:
                return
            self._send(reply.encode("latin-1"))

    _reply_pending = False
    _interrupted = False
    _skip_bp = None

    def _handle(self, p: str):
        if p == "?":
            return self.reason or f"S{SIGTRAP:02x}"
        if p.startswith("qSupported"):
            return "PacketSize=4000;qXfer:features:read+;swbreak+;vContSupported+"
        if p.startswith("qXfer:features:read:target.xml:"):
            off, length = _hex_ints(p.rsplit(":", 1)[1], 2)
            chunk = TARGET_XML[off:off + length]
            return ("l" if off + length >= len(TARGET_XML) else "m") + chunk
        if p == "qAttached":
            return "1"
        if p == "qC":
            return "QC1"
        if p == "qfThreadInfo":
            return "m1"
        if p == "qsThreadInfo":
            return "l"
        if p.startswith(("Hg", "Hc", "!", "QStart")) or p == "qSymbol::":
            return "OK" if not p.startswith("QStart") else ""
        if p == "g":
            return "".join(self._reg_hex(r) for r in REGS)
        if p.startswith("G"):
            data, pos = _hex_bytes(p[1:]), 0
            for r in REGS:
                if pos + _size(r) <= len(data):
                    self._set_reg(r, int.from_bytes(data[pos:pos + _size(r)], "little"))
                pos += _size(r)
            return "OK"
        if p.startswith("p"):
            n, = _hex_ints(p[1:], 1)
            return self._reg_hex(REGS[n]) if n < len(REGS) else "E00"
        if p.startswith("P"):
            n, _, v = p[1:].partition("=")
            n, = _hex_ints(n, 1)
            if n >= len(REGS):
                return "E00"
            self._set_reg(REGS[n], int.from_bytes(_hex_bytes(v), "little"))
            return "OK"
        if p.startswith("m"):
            addr, length = _hex_ints(p[1:], 2)
            try:
                return self._read_mem(addr, length).hex()
            except (BusFault, McusimError, OSError):
                return "E01"
        if p.startswith("M"):
            head, colon, data = p[1:].partition(":")
            addr, length = _hex_ints(head, 2)
            data = _hex_bytes(data)
            if not colon or len(data) != length:
                raise _Malformed(p)
            try:
                self._write_mem(addr, data)
            except (BusFault, McusimError, OSError):
                return "E01"
            return "OK"
        if p[:1] in "Zz" and len(p) > 3:
            kind, addr, length = _hex_ints(p[1:], 3)
            return self._point(p[0] == "Z", kind, addr, length)
        if p == "vCont?":
            return "vCont;c;C;s;S"
        if p.startswith("vCont;"):
            action = p[6:].split(";")[0].split(":")[0]
            if action[:1] in "sS":
                self.stepping = True
            return _RESUME
        if p.startswith("c"):
            if len(p) > 1:
                self._set_reg("pc", _hex_ints(p[1:], 1)[0])
            return _RESUME
        if p.startswith("s"):
            if len(p) > 1:
                self._set_reg("pc", _hex_ints(p[1:], 1)[0])
            self.stepping = True
            return _RESUME
        if p.startswith("D"):
            self._send(b"OK")
            self.detach()
            return _DETACHED
        if p in ("k", "vKill;1") or p.startswith("vKill"):
            if p.startswith("vKill"):
                self._send(b"OK")
            self.detach()
            self.close()
            raise DebuggerKill("the debugger killed the target (gdb kill): the run ends")
        return ""                 # not supported: gdb falls back or does without

    def _reg_hex(self, name):
        return (self.core.reg(name) & ((1 << (8 * _size(name))) - 1)).to_bytes(_size(name), "little").hex()

    def _set_reg(self, name, value):
        if name == "pc":
            value &= ~1
        self.core.set_reg(name, value)

    def _in_memory(self, addr, length):
        return self.core._region(addr, length)[0] is not None

    def _read_mem(self, addr, length) -> bytes:
        if self._in_memory(addr, length):
            return self.core.read(addr, length)
        out = bytearray()
        bus = self.core.bus
        a = addr
        while a < addr + length:            # a peripheral: through the models (side effects)
            size = 4 if a % 4 == 0 and addr + length - a >= 4 else 2 if a % 2 == 0 and addr + length - a >= 2 else 1
            try:
                v = bus.read(a, size)
            except BusFault:
                if size == 1:
                    raise
                v = bus.read(a - a % 4, 4) >> (8 * (a % 4)) if size != 4 else None
                if v is None:
                    raise
            out += (v & ((1 << (8 * size)) - 1)).to_bytes(size, "little")
            a += size
        return bytes(out)

    def _write_mem(self, addr, data):
        if self._in_memory(addr, len(data)):
            self.core.write(addr, data)          # flash too: gdb's load programs it
            return
        a = 0
        while a < len(data):
            size = 4 if (addr + a) % 4 == 0 and len(data) - a >= 4 else 2 if (addr + a) % 2 == 0 and len(data) - a >= 2 else 1
            self.core.bus.write(addr + a, int.from_bytes(data[a:a + size], "little"), size)
            a += size

    def _point(self, insert, kind, addr, length):
        uc = self.core.uc
        if kind in (0, 1):
            if insert and addr not in self.breakpoints:
                self.breakpoints[addr] = uc.hook_add(UC_HOOK_CODE, self._on_breakpoint, begin=addr, end=addr)
            elif not insert and addr in self.breakpoints:
                uc.hook_del(self.breakpoints.pop(addr))
            uc.ctl_remove_cache(addr, addr + 4)
            return "OK"
        if kind in (2, 3, 4):
            if length < 1:
                return "E01"          # (unicorn would take an empty range for every address)
            name = {2: "watch", 3: "rwatch", 4: "awatch"}[kind]
            key = (name, addr, length)
            if insert and key not in self.watchpoints:
                hooks = {2: UC_HOOK_MEM_WRITE, 3: UC_HOOK_MEM_READ, 4: UC_HOOK_MEM_WRITE | UC_HOOK_MEM_READ}
                self.watchpoints[key] = (uc.hook_add(hooks[kind], self._on_watch(name), begin=addr,
                                                     end=addr + length - 1)
                                         if self._in_memory(addr, length) else None)
            elif not insert and key in self.watchpoints:
                h = self.watchpoints.pop(key)
                if h is not None:
                    uc.hook_del(h)
            uc.ctl_flush_tb()         # memory hooks are compiled into the translated code
            return "OK"
        return ""

    def detach(self) -> None:
        """The run goes on without the debugger."""
        core = self.core
        if core.debug is not self:
            return
        for h in self.breakpoints.values():
            core.uc.hook_del(h)
        for h in self.watchpoints.values():
            if h is not None:
                core.uc.hook_del(h)
        for addr in self.breakpoints:
            core.uc.ctl_remove_cache(addr, addr + 4)
        self.breakpoints.clear()
        self.watchpoints.clear()
        self.halted = self.stepping = False
        core.debug = None
        if core.state == "run" and core._ev is None:
            core._schedule(core._aligned(self.kernel.now))


_RESUME, _DETACHED = object(), object()
_TRACE = bool(os.environ.get("MCUSIM_GDB_TRACE"))     # print each packet gdb sends (debugging the server)
