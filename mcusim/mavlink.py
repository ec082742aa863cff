"""A MAVLink ground station in simulated time: pymavlink's own packing and parsing over an
in-memory serial endpoint on a simulated UART.

::

    from mcusim.mavlink import MavlinkClient

    gcs = MavlinkClient(sim, "USART3", member="rcm")          # connects the UART
    hb = gcs.recv_match("HEARTBEAT", timeout="1.5s")          # runs the simulation until it comes
    gcs.mav.command_long_send(1, 0, 400, 0, 1, 0, 0, 0, 0, 0, 0)   # pymavlink's generated sender
    ack = gcs.recv_match("COMMAND_ACK", timeout="0.2s")

``mav`` is a ``pymavlink.dialects.v20.common.MAVLink`` whose file is the UART's RX line: each
``*_send`` puts the frame on the line now, one USART frame per byte. Received frames are parsed
byte by byte as the USART's TX frames end; ``log`` holds ``(tick, message)`` for the valid
messages, in order (the recent ones, :class:`mcusim.recent.RecentLog`). Waits run the simulation
(simulated time; the host clock plays no part) and raise :class:`mcusim.testing.SimTimeout` when
nothing matching arrives in time.

``heartbeat_hz`` (default 1; 0 for none) sends a GCS HEARTBEAT (MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID)
at that rate of simulated time from the first tick on, as QGroundControl and mavros do.
"""

from __future__ import annotations

from .errors import ConfigError
from .hostserial import BufferEndpoint
from .kernel import PRIO_INPUT
from .recent import RecentLog
from .testing import SimTimeout

MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID = 6, 8


def _dialect():
    try:
        from pymavlink.dialects.v20 import common
    except ImportError as exc:          # a dependency of mcusim; a broken install says so plainly
        raise ConfigError(f"MAVLink needs pymavlink (pip install pymavlink): {exc}") from None
    return common


def mavlink_port(sim) -> tuple:
    """``(uart, member)`` of the simulation's MAVLink firmware (its ``MAVLINK_UART``; ``member`` is
    the system member running it, None for a single board); ConfigError when there is none."""
    fw = sim.firmware
    uart = getattr(fw, "MAVLINK_UART", None)
    if fw is None:
        raise ConfigError(f"{sim.board_name} runs without firmware (--no-firmware): a MAVLink link needs "
                          "the rover controller's firmware")
    if uart is None:
        raise ConfigError(f"{sim.board_name} runs no firmware with a MAVLink link (the rover controller "
                          "has one: elementall, ciaa-edu)")
    member = next((n for n, m in sim.members.items() if m.get("firmware") is fw), None)
    return uart, (member if len(sim.members) > 1 else None)


class _ParsingEndpoint(BufferEndpoint):
    label = "a MAVLink ground station (mcusim.mavlink.MavlinkClient, e.g. a scenario's)"

    def __init__(self, client):
        super().__init__()
        self.client = client

    def transmit(self, byte: int, tick: int) -> None:
        super().transmit(byte, tick)
        self.client._byte(byte, tick)


class MavlinkClient:
    def __init__(self, sim, uart: str = "USART3", member: str | None = None, *, system: int = 255,
                 component: int = 190, heartbeat_hz: float = 1.0):
        ml = _dialect()
        self.ml, self.sim = ml, sim
        self.endpoint = sim.connect_serial(uart, _ParsingEndpoint(self), member=member)
        self.mav = ml.MAVLink(self, srcSystem=system, srcComponent=component)
        self.mav.robust_parsing = True
        self._rx = ml.MAVLink(None, srcSystem=system, srcComponent=component)
        self._rx.robust_parsing = True
        # (tick, message) of the messages received, the recent ones (mcusim.recent): a rover sends
        # about 60 a second for as long as the client stays attached
        self.log: RecentLog = RecentLog()
        # called with (tick, message) for each valid message as it arrives: whoever needs every
        # message of a long run (a scenario's expectations) watches instead of reading the log
        self.watchers: list = []
        self.errors = 0
        self._read = 0          # messages received before the next one a wait looks at (log.total)
        self._hb_period = None
        if heartbeat_hz:
            self._hb_period = sim.timebase.ticks(1 / heartbeat_hz, rounding=True)
            sim.kernel.at(max(1, sim.kernel.now), self._heartbeat, prio=PRIO_INPUT)

    # --- file-like of pymavlink ----------------------------------------------------------------------
    def write(self, buf) -> int:
        self.endpoint.feed(bytes(buf))
        return len(buf)

    def _heartbeat(self) -> None:
        if self._hb_period is None:
            return
        self.mav.heartbeat_send(MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID, 0, 0, 0)
        self.sim.kernel.after(self._hb_period, self._heartbeat, prio=PRIO_INPUT)

    def stop_heartbeat(self) -> None:
        """The ground station goes away: no more heartbeats."""
        self._hb_period = None

    def _byte(self, byte: int, tick: int) -> None:
        m = self._rx.parse_char(bytes([byte]))
        while m is not None:
            if m.get_type() == "BAD_DATA":
                self.errors += 1
            else:
                self.log.append((tick, m))
                for watch in self.watchers:
                    watch(tick, m)
            m = self._rx.parse_char(b"")

    # --- waits (simulated time) ----------------------------------------------------------------------
    def messages(self, type: str | None = None) -> list:
        """The valid messages received so far (of ``type``): the recent ones ``log`` holds."""
        return [m for _, m in self.log if type is None or m.get_type() == type]

    def flush(self) -> None:
        """Forget the messages received so far: the next wait sees only newer ones."""
        self._read = self.log.total

    def recv_match(self, type: str | None = None, condition=None, timeout="1s"):
        """The next message not returned before (of ``type``, with ``condition(msg)`` true),
        running the simulation up to ``timeout`` of simulated time for it. While it waits it sees
        every message; one that arrived between waits and has since left ``log`` (more than
        :data:`mcusim.recent.KEEP` messages came after it) is passed over."""
        __tracebackhide__ = True
        start = self.sim.kernel.now
        from .sim import unitless
        if unitless(timeout):
            raise ConfigError(f"recv_match(timeout={timeout!r:.40}): expected a number of seconds or a "
                              "duration with a unit (\"500ms\"), as run() takes it")
        end = start + self.sim.timebase.ticks(timeout, rounding=True)
        found = []

        def scan():
            log = self.log
            # a message trimmed from the log before any wait looked at it is passed over
            self._read = max(self._read, log.dropped)
            while self._read < log.total:
                _, m = log[self._read - log.dropped]
                self._read += 1
                if (type is None or m.get_type() == type) and (condition is None or condition(m)):
                    found.append(m)
                    return True
            return False

        if not scan():
            self.sim.run(until_tick=end, stop=scan)
        if found:
            return found[0]
        raise SimTimeout(f"a MAVLink {type or 'message'}" + (" matching the condition" if condition else ""),
                         timeout, self.sim.time_s, start / self.sim.timebase.base_hz)

    def tick_of(self, msg) -> int:
        """The base tick at which ``msg`` (one from ``log``) was received."""
        for tick, m in self.log:
            if m is msg:
                return tick
        raise ValueError("not a message the log holds (received, and among the recent ones)")
