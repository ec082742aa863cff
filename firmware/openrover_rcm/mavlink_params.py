"""The MAVLink parameter protocol of the ``mavlink`` task (:mod:`.mavlink_task`): PARAM_REQUEST_LIST,
PARAM_REQUEST_READ and PARAM_SET, each answered with PARAM_VALUE (MAV_PARAM_TYPE_REAL32).

Parameters: the wheel PID gains ``WHL_KP/KI/KD``, written to the KP/KI/KD registers of every motor
module over I2C and read back from all of them (NaN, plus a STATUSTEXT, when they do not all hold
the same value), and the battery monitor's thresholds ``BATT_LOW_V``, ``BATT_CRIT_V``,
``BATT_HYST_V``. A refused value (out of range, inconsistent thresholds) is echoed unchanged.
PARAM_VALUEs wait in ``param_queue`` until the transmit buffer has room for them beside a reserve
for a HEARTBEAT and a COMMAND_ACK.
"""

from __future__ import annotations

import math

PARAM_REAL32 = 9
GAIN_PARAMS = {"WHL_KP": "KP", "WHL_KI": "KI", "WHL_KD": "KD"}
GAIN_MAX = 1e4                             # the modules' own range for kp, ki, kd
BATTERY_PARAMS = {"BATT_LOW_V": "low_v", "BATT_CRIT_V": "critical_v", "BATT_HYST_V": "hysteresis_v"}
PARAM_IDS = tuple(GAIN_PARAMS) + tuple(BATTERY_PARAMS)
PARAM_VALUE_LEN, PARAM_RESERVE, PARAM_QUEUE = 37, 48, 64     # framed bytes; bytes kept free; entries
SEV_WARNING = 4                            # MAV_SEVERITY_WARNING


class ParamProtocol:
    """Mixin of :class:`.mavlink_task.MavlinkLink` (uses its ``rc``, ``p``, ``serial``, ``ml``,
    ``send``, ``event``, ``_for_me``, ``ignored``, ``param_queue`` and ``gains``)."""

    async def on_param_request_list(self, m) -> None:
        if not self._for_me(m.target_system, m.target_component):
            self.ignored += 1
            return
        self.queue_param(*range(len(PARAM_IDS)))

    async def on_param_request_read(self, m) -> None:
        if not self._for_me(m.target_system, m.target_component):
            self.ignored += 1
            return
        idx = m.param_index if m.param_index >= 0 else self._index(m.param_id)
        if idx is None or not 0 <= idx < len(PARAM_IDS):
            self.ignored += 1
            return
        self.queue_param(idx)

    async def on_param_set(self, m) -> None:
        if not self._for_me(m.target_system, m.target_component):
            self.ignored += 1
            return
        idx = self._index(m.param_id)
        if idx is None:
            self.ignored += 1
            return
        name, v = PARAM_IDS[idx], float(m.param_value)
        if name in GAIN_PARAMS:
            if self.rc.motors_enabled and 0 <= v <= GAIN_MAX:      # refused values are echoed unchanged
                failed = []
                for addr in self.rc.modules:
                    if await self.rc._write_reg(addr, GAIN_PARAMS[name], v) != 0:
                        failed.append(addr)
                self.gains = None            # read back what the modules took
                if failed:
                    self.event(SEV_WARNING, f"{name} not written to " + " ".join(f"{a:#04x}" for a in failed))
                elif math.isnan(await self.param_value(idx)):
                    self.event(SEV_WARNING, f"{name}: the modules do not all hold the same value")
        elif math.isfinite(v) and 0 <= v <= 100:
            key = BATTERY_PARAMS[name]
            trial = {**self.p, key: v}
            if trial["critical_v"] < trial["low_v"] and trial["hysteresis_v"] <= 10:
                self.p[key] = v            # refused values are echoed unchanged
        self.queue_param(idx)

    def _index(self, param_id) -> int | None:
        pid = param_id if isinstance(param_id, str) else bytes(param_id).decode("ascii", "replace")
        pid = pid.split("\x00")[0]
        return PARAM_IDS.index(pid) if pid in PARAM_IDS else None

    async def read_gains(self) -> tuple:
        """(KP, KI, KD) as every module holds them, NaN where a module does not answer or they
        differ; cached once they agree, until the next PARAM_SET of a gain."""
        if self.gains is not None:
            return self.gains
        if not self.rc.motors_enabled:
            return (math.nan,) * 3
        gains = []
        for reg in ("KP", "KI", "KD"):
            got = [await self.rc._read_reg(addr, reg) for addr in self.rc.modules]
            gains.append(got[0] if None not in got and len(set(got)) == 1 else math.nan)
        if not any(math.isnan(g) for g in gains):
            self.gains = tuple(gains)
        return tuple(gains)

    async def param_value(self, idx: int) -> float:
        name = PARAM_IDS[idx]
        if name in GAIN_PARAMS:
            return (await self.read_gains())[list(GAIN_PARAMS).index(name)]
        return float(self.p[BATTERY_PARAMS[name]])

    def queue_param(self, *idx: int) -> None:
        """PARAM_VALUEs to send, never dropped while the queue (PARAM_QUEUE entries) has room."""
        room = PARAM_QUEUE - len(self.param_queue)
        self.param_queue.extend(idx[:room])
        self.ignored += max(0, len(idx) - room)

    async def param_step(self) -> None:
        """Send queued PARAM_VALUEs while the transmit buffer has room for them beside PARAM_RESERVE
        bytes (a HEARTBEAT and a COMMAND_ACK); the streams keep the larger TX_RESERVE free."""
        while self.param_queue and self.serial.txroom >= PARAM_VALUE_LEN + PARAM_RESERVE:
            idx = self.param_queue.pop(0)
            value = await self.param_value(idx)
            self.send(self.ml.MAVLink_param_value_message(PARAM_IDS[idx].encode(), value, PARAM_REAL32,
                                                          len(PARAM_IDS), idx))

