"""``mavlink`` task of ``rover_control``: the ground-station / companion-computer link on USART3.

Written like the C task on the MAVLink C headers, with pymavlink's generated ``common`` dialect in
their place (``mavlink_msg_*_pack`` + ``_mav_finalize_message_chan_send`` are ``<msg>_encode`` +
``MAVLink.send``; ``mavlink_parse_char`` is ``MAVLink.parse_buffer``): framing, CRC and field
packing are the library's. The task sends MAVLink 2 and parses MAVLink 1 and 2.

Loop (a NuttX task blocked in ``poll()`` on the serial device): wait until received bytes are
available or the next telemetry message is due, parse what arrived, handle each message, send
what is due. System 1, component 1 (MAV_COMP_ID_AUTOPILOT1), MAV_TYPE_GROUND_ROVER,
MAV_AUTOPILOT_GENERIC. Streams and their default intervals are in ``STREAMS`` (changed by
MAV_CMD_SET_MESSAGE_INTERVAL, sent once by MAV_CMD_REQUEST_MESSAGE).

Bytes that are not a valid frame (garbage, a bad CRC, a truncated frame) are counted in
``rx_errors`` and skipped. Unlike ``mavlink_parse_char``, which drops every byte of a frame whose
CRC fails, the task rescans such a frame from its second byte: a start byte in garbage followed by
a large length byte would otherwise swallow the valid frames behind it. A frame of an id outside
the dialect (a GCS speaking ``ardupilotmega``) cannot have its CRC checked (no CRC_EXTRA); like
``mavlink_parse_char`` the task drops it whole, counted in ``ignored``, when a start byte follows
it (the sender's next frame), and treats it as garbage to rescan otherwise.

Transmit: a message is written only if the serial transmit buffer has room for the whole frame
(``poll(POLLOUT)``); otherwise it is skipped and counted in ``tx_skipped`` (the sequence number
still advances, so the receiver sees the gap). Telemetry streams leave ``TX_RESERVE`` bytes free
for the ``PRIORITY`` messages (HEARTBEAT, COMMAND_ACK, PARAM_VALUE, STATUSTEXT); PARAM_VALUEs
(list items, read and set replies) wait in ``param_queue`` until they fit beside a smaller reserve.
SET_MESSAGE_INTERVAL refuses intervals whose streams would take more than ``STREAM_SHARE`` of the
line.

Cycle costs (declared, ``firmware.cycles_mavlink_*``): one wake-up, each received byte
(``mavlink_parse_char``), each message handled and each message packed and queued.
"""

from __future__ import annotations

import math
from typing import ClassVar

from mcusim.fw.openrover_rcm.mavlink_params import ParamProtocol

MAV_TYPE_GROUND_ROVER, MAV_AUTOPILOT_GENERIC = 10, 0
MAV_TYPE_GCS, MAV_TYPE_ONBOARD_CONTROLLER = 6, 18
MODE_CUSTOM, MODE_GUIDED, MODE_MANUAL_INPUT, MODE_ARMED = 1, 8, 64, 128
STATE_BOOT, STATE_STANDBY, STATE_ACTIVE, STATE_CRITICAL, STATE_EMERGENCY = 1, 3, 4, 5, 6
SEV_CRITICAL, SEV_ERROR, SEV_WARNING, SEV_NOTICE, SEV_INFO = 2, 3, 4, 5, 6
RESULT_ACCEPTED, RESULT_TEMP_REJECTED, RESULT_DENIED, RESULT_UNSUPPORTED, RESULT_FAILED = 0, 1, 2, 3, 4
RESULT_COMMAND_LONG_ONLY = 7
CMD_ARM_DISARM, CMD_SET_INTERVAL, CMD_REQUEST_MESSAGE, CMD_REQUEST_CAPS = 400, 511, 512, 520
COMMAND_LONG_ONLY = (CMD_ARM_DISARM, CMD_SET_INTERVAL, CMD_REQUEST_MESSAGE, CMD_REQUEST_CAPS)
SENSOR_MOTORS, SENSOR_BATTERY = 0x8000, 0x02000000
CAPS = 2 | 128 | 8192     # PARAM_FLOAT | SET_POSITION_TARGET_LOCAL_NED | MAVLINK2
FRAME_LOCAL_NED, FRAME_LOCAL_OFFSET_NED, FRAME_BODY_NED, FRAME_BODY_OFFSET_NED, FRAME_BODY_FRD = 1, 7, 8, 9, 12
IGNORE_VX, IGNORE_VY, IGNORE_YAW_RATE = 8, 16, 2048
AXIS_INVALID = 0x7FFF
START_BYTES = (0xFD, 0xFE)                 # MAVLink 2, MAVLink 1

# message id -> default interval in ms (0: only on request)
STREAMS = {0: 1000, 1: 1000, 147: 1000, 32: 100, 30: 100, 251: 200, 148: 0}
STREAM_NAMES = {0: "HEARTBEAT", 1: "SYS_STATUS", 147: "BATTERY_STATUS", 32: "LOCAL_POSITION_NED",
                30: "ATTITUDE", 251: "NAMED_VALUE_FLOAT", 148: "AUTOPILOT_VERSION"}
# never skipped for the streams' sake: the TX buffer keeps TX_RESERVE bytes free for them
PRIORITY = {0: "HEARTBEAT", 77: "COMMAND_ACK", 22: "PARAM_VALUE", 253: "STATUSTEXT"}
TX_RESERVE = 128
STREAM_SHARE = 0.75          # of the line's bytes per second, at most, for the streams
FRAME_OVERHEAD = 12          # MAVLink 2: 10-byte header, 2-byte CRC


def message_id(param: float) -> int | None:
    """A message id carried in a float command parameter: a whole, finite number, else None."""
    if not math.isfinite(param) or param != math.floor(param):
        return None
    return int(param)


class MavlinkLink(ParamProtocol):
    """The task's state and its handlers; ``rc`` is the RoverControl it serves."""

    def __init__(self, rc, serial):
        from pymavlink.dialects.v20 import common as mavlink

        self.rc, self.serial, self.p = rc, serial, rc.p
        self.ml = mavlink
        self.mav = mavlink.MAVLink(self, srcSystem=1, srcComponent=1)
        self.mav.robust_parsing = True
        self.intervals = dict(STREAMS)          # message id -> interval in ms (0: off)
        self.due = {mid: 0 for mid in STREAMS}
        self.once: list[int] = []               # REQUEST_MESSAGE: sent at the next pass
        self.statustext: list[tuple[int, str]] = []
        # poll() on the serial device and on the event queue: one wake-up for both
        self.wake = serial.rxavail
        self._text_id = 0
        self.param_queue: list[int] = []        # PARAM_VALUEs still to send, in order (list, reads, sets)
        self.gains = None                       # (KP, KI, KD) once every module holds the same
        self.armed = False
        self.source = 0                         # MODE_GUIDED or MODE_MANUAL_INPUT: what drives, armed
        self.gcs_tick = None                    # tick of the last GCS heartbeat
        self.gcs_lost = False
        self._cmd_key = None
        self._next_cmd_id = -1
        self._cost = 0
        self.rx_frames = self.rx_errors = self.tx_frames = self.tx_skipped = self.ignored = 0
        self.last_busy = (0, 0)                 # (tick, cpu busy ticks) for the load figure
        self._unknown = None                    # an unknown-id frame waiting for the byte after it
        self._priority = False                  # the frame being written is a PRIORITY one

    # --- file-like for pymavlink: write() is the serial device's write() -----------------------------
    def write(self, buf) -> int:
        buf = bytes(buf)
        self._cost += self.p["cycles_mavlink_tx"]
        if self.serial.txroom < len(buf) + (0 if self._priority else TX_RESERVE):
            self.tx_skipped += 1
            return 0
        self.tx_frames += 1
        return self.serial.write(buf)

    def send(self, msg) -> None:
        self._priority = msg.get_msgId() in PRIORITY
        self.mav.send(msg)

    # --- the task ---------------------------------------------------------------------------------
    async def run(self):
        rtos, cpu = self.rc.rtos, self.rc.cpu
        self.last_busy = (self.rc.mcu.kernel.now, cpu.busy_ticks)     # the first load figure starts here
        while True:
            now = rtos.tick_count
            self._cost += self.p["cycles_mavlink_wake"]
            self.check_gcs(now)
            self.send_due(now)
            await self.param_step()
            if self._cost:
                cost, self._cost = self._cost, 0
                await cpu.cycles(cost)
            now = rtos.tick_count
            nxt = min((t for mid, t in self.due.items() if self.intervals[mid] > 0), default=now + 1000)
            if self.param_queue or self.once or self.statustext:
                nxt = now + 1
            if not self.serial.recv:
                await rtos.wait_signal(self.wake, timeout=max(1, nxt - now))
            data = self.serial.read()
            if data:
                await cpu.cycles(self.p["cycles_mavlink_rx_byte"] * len(data))
                for msg in self.parse(data):
                    await self.handle(msg)
                    await cpu.cycles(self.p["cycles_mavlink_handle"])

    def parse(self, data: bytes) -> list:
        """Valid messages in ``data``, with every invalid stretch counted and rescanned."""
        out = []
        if self._unknown is not None and data:          # the byte after an unknown-id frame has come
            frame, self._unknown = self._unknown, None
            if data[0] in START_BYTES:
                self.ignored += 1
            else:
                self.rx_errors += 1
                data = frame[1:] + data
        queue = self._parse_buffer(data)
        i = 0
        while i < len(queue):
            m = queue[i]
            if m.get_type().startswith("UNKNOWN_"):     # an id outside the dialect: its CRC cannot be checked
                tail = self._tail(queue[i + 1:])
                if not tail:                            # decide when the next byte comes
                    self._unknown = bytes(m.get_msgbuf())
                    i += 1
                    continue
                if tail[0] in START_BYTES:              # another frame follows: skip this one whole
                    self.ignored += 1
                    i += 1
                    continue
                m = self.ml.MAVLink_bad_data(m.get_msgbuf(), "unknown message id, no frame after it")
            if m.get_type() != "BAD_DATA":
                self.rx_frames += 1
                out.append(m)
            else:
                self.rx_errors += 1
                if m.reason != "Bad prefix" and len(m.data) > 1:
                    tail = self._tail(queue[i + 1:])
                    self.mav.buf, self.mav.buf_index = bytearray(), 0
                    self.mav.expected_length = self.ml.HEADER_LEN_V1 + 2
                    queue = queue[: i + 1] + self._parse_buffer(bytes(m.data[1:]) + tail)
            i += 1
        return out

    def _tail(self, rest: list) -> bytes:
        """The bytes after a frame: the messages parsed behind it and what the parser still holds."""
        tail = b"".join(bytes(x.data) if x.get_type() == "BAD_DATA" else bytes(x.get_msgbuf()) for x in rest)
        return tail + bytes(self.mav.buf[self.mav.buf_index:])

    def _parse_buffer(self, data: bytes) -> list:
        try:
            return self.mav.parse_buffer(data) or []
        except self.ml.MAVError:        # not raised with robust_parsing; a guard for the link's sake
            self.rx_errors += 1
            self.mav.buf, self.mav.buf_index = bytearray(), 0
            return []

    # --- telemetry -----------------------------------------------------------------------------------
    def time_boot_ms(self) -> int:
        return self.rc.rtos.tick_count * 1000 // self.p["tick_hz"]

    def _ticks(self, ms: int) -> int:
        return max(1, round(ms * self.p["tick_hz"] / 1000))

    def send_due(self, now: int) -> None:
        for severity, text in self.statustext:
            raw = text.encode()
            if len(raw) <= 50:
                self.send(self.ml.MAVLink_statustext_message(severity, raw))
                continue
            self._text_id = self._text_id % 0xFFFF + 1     # a long text in chunks of 50 bytes
            chunks = [raw[i:i + 50] for i in range(0, len(raw), 50)]
            for seq, chunk in enumerate(chunks):
                self.send(self.ml.MAVLink_statustext_message(severity, chunk, self._text_id, seq))
        self.statustext.clear()
        for mid in self.once:
            self.send_stream(mid)
        self.once.clear()
        for mid, iv in self.intervals.items():
            if iv > 0 and now >= self.due[mid]:
                self.due[mid] = max(self.due[mid] + self._ticks(iv), now)
                self.send_stream(mid)

    def heartbeat_state(self) -> tuple[int, int]:
        rc = self.rc
        base = MODE_CUSTOM | ((MODE_ARMED | self.source) if self.armed else 0)
        if rc.estop_pressed or rc.estop_latched:
            status = STATE_EMERGENCY
        elif rc.battery_state == "critical" or rc.faults:
            status = STATE_CRITICAL
        elif not (rc.motors_enabled or rc.missing):
            status = STATE_BOOT
        else:
            status = STATE_ACTIVE if self.armed else STATE_STANDBY
        return base, status

    def body_velocity(self) -> tuple:
        return self.rc.layout.forward(self.rc.wheel_speeds)

    def send_stream(self, mid: int) -> None:
        rc, ml, t = self.rc, self.ml, self.time_boot_ms()
        if mid == 0:
            base, status = self.heartbeat_state()
            self.send(ml.MAVLink_heartbeat_message(MAV_TYPE_GROUND_ROVER, MAV_AUTOPILOT_GENERIC, base, 0, status, 3))
        elif mid == 1:
            health = SENSOR_MOTORS if not rc.faults else 0
            health |= SENSOR_BATTERY if rc.battery_state != "critical" else 0
            mv = 0xFFFF if rc.battery_v is None else min(0xFFFE, round(rc.battery_v * 1000))
            self.send(ml.MAVLink_sys_status_message(
                SENSOR_MOTORS | SENSOR_BATTERY, SENSOR_MOTORS | SENSOR_BATTERY, health, self.load_permille(),
                mv, -1, -1, 0, min(0xFFFF, self.rx_errors), 0, 0, 0, 0, 0, 0, 0))
        elif mid == 147:
            mv = 0xFFFF if rc.battery_v is None else min(0xFFFE, round(rc.battery_v * 1000))
            # MAV_BATTERY_CHARGE_STATE_UNDEFINED (0) until the monitor's first reading: OK would claim one
            charge = 0 if rc.battery_v is None else {"normal": 1, "low": 2, "critical": 3}[rc.battery_state]
            self.send(ml.MAVLink_battery_status_message(
                0, 2, 0, 0x7FFF, [mv] + [0xFFFF] * 9, -1, -1, -1, -1, 0, charge, [0, 0, 0, 0], 0, 0))
        elif mid == 32:
            x, y, yaw = rc.odometry.pose
            vx, vy, _ = self.body_velocity()
            c, s = math.cos(yaw), math.sin(yaw)      # odometry frame (x fwd, y left) -> NED (y right)
            self.send(ml.MAVLink_local_position_ned_message(t, x, -y, 0.0, c * vx - s * vy, -(s * vx + c * vy), 0.0))
        elif mid == 30:
            _, _, yaw = rc.odometry.pose
            wz = self.body_velocity()[2]
            self.send(ml.MAVLink_attitude_message(t, 0.0, 0.0, -yaw, 0.0, 0.0, -wz))
        elif mid == 251:
            k = 2 * math.pi / (self.p["gear_ratio"] * self.p["counts_per_motor_rev"])
            for i in range(len(rc.modules)):
                self.send(ml.MAVLink_named_value_float_message(t, f"W{i + 1}_VEL".encode(), rc.wheel_speeds[i]))
                self.send(ml.MAVLink_named_value_float_message(t, f"W{i + 1}_CMD".encode(),
                                                               rc.wheel_setpoints[i] * k))
        elif mid == 148:
            self.send(ml.MAVLink_autopilot_version_message(CAPS, 0, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0, 0,
                                                           [0] * 18))

    def stream_load(self, intervals: dict) -> float:
        """Bytes per second the streams take on the line at these intervals (frames at full length)."""
        total = 0.0
        for mid, iv in intervals.items():
            if iv > 0:
                per = 2 * len(self.rc.modules) if mid == 251 else 1
                total += per * (FRAME_OVERHEAD + self.ml.mavlink_map[mid].unpacker.size) * 1000 / iv
        return total

    def load_permille(self) -> int:
        """CPU load over the last SYS_STATUS interval, from the core's busy time (d%)."""
        now, busy = self.rc.mcu.kernel.now, self.rc.cpu.busy_ticks
        t0, b0 = self.last_busy
        self.last_busy = (now, busy)
        return 0 if now == t0 else min(1000, (busy - b0) * 1000 // (now - t0))

    def event(self, severity: int, text: str) -> None:
        """Queue a STATUSTEXT (sent at the task's next pass)."""
        self.statustext.append((severity, text))
        self.wake.fire()

    # --- failsafes -------------------------------------------------------------------------------------
    def gcs_silent(self, now: int) -> bool:
        """A ground station has been heard and its heartbeat is overdue."""
        return self.gcs_tick is not None and now - self.gcs_tick > self._ticks(self.p["gcs_timeout_ms"])

    def check_gcs(self, now: int) -> None:
        lost = self.gcs_silent(now)
        if lost and not self.gcs_lost:
            self.event(SEV_WARNING, f"GCS heartbeat lost for {self.p['gcs_timeout_ms']} ms: stopping")
            self.disarm()
        self.gcs_lost = lost

    def disarm(self) -> None:
        if self.armed:
            self.armed, self._cmd_key, self.source = False, None, 0
            self._next_cmd_id -= 1
            self.rc.cmd_vel_clear(self._next_cmd_id)     # stop, without starting the watchdog

    def _command(self, vx: float, vy: float, wz: float) -> None:
        """A velocity command into the controller's mailbox; a changed value is a new command."""
        key = (vx, vy, wz)
        if key != self._cmd_key:
            self._cmd_key, self._next_cmd_id = key, self._next_cmd_id - 1
        self.rc.cmd_vel_rx(vx, vy, wz, self._next_cmd_id)

    # --- received messages ------------------------------------------------------------------------------
    def _for_me(self, system: int, component: int | None = None) -> bool:
        return system in (0, 1) and (component is None or component in (0, 1))

    async def handle(self, m) -> None:
        kind = m.get_type()
        handler = getattr(self, "on_" + kind.lower(), None)
        if handler is None:
            self.ignored += 1
            return
        await handler(m)

    async def on_heartbeat(self, m) -> None:
        # a ground station (QGC: MAV_TYPE_GCS, 255.190) or a companion computer (mavros:
        # MAV_TYPE_ONBOARD_CONTROLLER, 1.191), not ourselves; another vehicle's does not count
        if m.type in (MAV_TYPE_GCS, MAV_TYPE_ONBOARD_CONTROLLER) and (m.get_srcSystem(), m.get_srcComponent()) != (1, 1):
            self.gcs_tick = self.rc.rtos.tick_count
        else:
            self.ignored += 1

    async def on_command_long(self, m) -> None:
        if not self._for_me(m.target_system, m.target_component):
            self.ignored += 1
            return
        result = self.command(m.command, (m.param1, m.param2, m.param3))
        self.send(self.ml.MAVLink_command_ack_message(m.command, result, 0, 0, m.get_srcSystem(),
                                                      m.get_srcComponent()))

    async def on_command_int(self, m) -> None:
        if not self._for_me(m.target_system, m.target_component):
            self.ignored += 1
            return
        result = RESULT_COMMAND_LONG_ONLY if m.command in COMMAND_LONG_ONLY else RESULT_UNSUPPORTED
        self.send(self.ml.MAVLink_command_ack_message(m.command, result, 0, 0, m.get_srcSystem(),
                                                      m.get_srcComponent()))

    def command(self, cmd: int, params) -> int:
        rc = self.rc
        if cmd == CMD_ARM_DISARM:
            if params[0] == 0.0:
                self.disarm()
                return RESULT_ACCEPTED
            if params[0] != 1.0:
                return RESULT_DENIED
            if rc.estop_pressed or self.gcs_silent(rc.rtos.tick_count):   # until it heartbeats again
                return RESULT_TEMP_REJECTED
            if rc.battery_state == "critical" or rc.faults or (rc.missing and not rc.motors_enabled):
                # a valid command that cannot be carried out (not DENIED: bad params): what the
                # HEARTBEAT shows as CRITICAL (a critical battery, a module fault, a module missing)
                return RESULT_FAILED
            if not rc.motors_enabled:
                return RESULT_TEMP_REJECTED     # booting (its modules not identified yet): waiting clears it
            if not self.armed:
                self.armed, self._cmd_key = True, None
            return RESULT_ACCEPTED
        if cmd == CMD_SET_INTERVAL:
            mid, us = message_id(params[0]), params[1]
            if mid not in STREAMS or not math.isfinite(us) or (us < 0 and us != -1):
                return RESULT_DENIED
            iv = STREAMS[mid] if us == 0 else (0 if us == -1 else max(1, round(us / 1000)))
            if self.stream_load({**self.intervals, mid: iv}) > STREAM_SHARE * self.p["mavlink_baud"] / 10:
                return RESULT_DENIED      # more than the line carries beside the replies
            self.intervals[mid] = iv
            self.due[mid] = rc.rtos.tick_count
            return RESULT_ACCEPTED
        if cmd == CMD_REQUEST_MESSAGE:
            mid = message_id(params[0])
            if mid not in STREAMS:
                return RESULT_DENIED
            self.once.append(mid)
            return RESULT_ACCEPTED
        if cmd == CMD_REQUEST_CAPS:
            self.once.append(148)
            return RESULT_ACCEPTED
        return RESULT_UNSUPPORTED

    async def on_set_position_target_local_ned(self, m) -> None:
        if not self._for_me(m.target_system, m.target_component):
            self.ignored += 1
            return
        used = ~m.type_mask & (IGNORE_VX | IGNORE_VY | IGNORE_YAW_RATE)
        if not self.armed or not used or m.coordinate_frame not in (
                FRAME_LOCAL_NED, FRAME_LOCAL_OFFSET_NED, FRAME_BODY_NED, FRAME_BODY_OFFSET_NED, FRAME_BODY_FRD):
            self.ignored += 1
            return
        vx = 0.0 if m.type_mask & IGNORE_VX else m.vx          # an ignored axis is zero
        vy = 0.0 if m.type_mask & IGNORE_VY else m.vy
        fwd, right = vx, vy
        if m.coordinate_frame in (FRAME_LOCAL_NED, FRAME_LOCAL_OFFSET_NED):   # for velocities the same frame
            psi = -self.rc.odometry.pose[2]                    # rotate by the heading (NED yaw = -odometry yaw)
            fwd, right = vx * math.cos(psi) + vy * math.sin(psi), -vx * math.sin(psi) + vy * math.cos(psi)
        wz = 0.0 if m.type_mask & IGNORE_YAW_RATE else -m.yaw_rate
        if not all(math.isfinite(v) for v in (fwd, right, wz)):
            self.ignored += 1
            return
        self.source = MODE_GUIDED
        self._command(fwd, -right if self.rc.layout.holonomic else 0.0, wz)

    async def on_manual_control(self, m) -> None:
        if m.target not in (0, 1) or not self.armed:
            self.ignored += 1
            return
        x = 0 if m.x == AXIS_INVALID else max(-1000, min(1000, m.x))
        r = 0 if m.r == AXIS_INVALID else max(-1000, min(1000, m.r))
        self.source = MODE_MANUAL_INPUT
        self._command(x / 1000 * self.p["manual_max_linear"], 0.0, -r / 1000 * self.p["manual_max_yaw"])

    async def on_mission_request_list(self, m) -> None:
        if not self._for_me(m.target_system, m.target_component):
            self.ignored += 1
            return
        self.send(self.ml.MAVLink_mission_count_message(m.get_srcSystem(), m.get_srcComponent(), 0,
                                                        m.mission_type))

    # --- summary ---------------------------------------------------------------------------------------
    #: the summary before the link is made (board_init, at the firmware's first step): nothing yet
    BEFORE: ClassVar[dict] = {"armed": False, "rx_frames": 0, "rx_errors": 0, "tx_frames": 0, "tx_skipped": 0,
                              "ignored": 0, "gcs_lost": False}

    def summary(self) -> dict:
        return {"armed": self.armed, "rx_frames": self.rx_frames, "rx_errors": self.rx_errors,
                "tx_frames": self.tx_frames, "tx_skipped": self.tx_skipped, "ignored": self.ignored,
                "gcs_lost": self.gcs_lost}
