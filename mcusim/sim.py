"""The Python API: ``mcusim.load(board)`` returns a :class:`Simulation`."""

from __future__ import annotations

import math
import numbers
import os
import time as _wall
from collections.abc import Mapping

from .board import build, parse_value, read_profile, split_overrides
from .engine import DEFAULT_ENGINE, check_engine
from .errors import ConfigError, McusimError, with_member
from .system import build_system, close_firmware_tasks, is_system
from .time import parse_duration

#: the last base tick a run may end at (a signed 64-bit count: what VCD and numpy time columns hold)
MAX_TICK = 2**63 - 1


class Simulation:
    def __init__(self, board: str, firmware: bool = True, overrides: dict | None = None, strict: bool = False,
                 engine: str | None = DEFAULT_ENGINE):
        engine = check_engine(DEFAULT_ENGINE if engine is None else engine)
        firmware = False if firmware is None else firmware
        if not isinstance(firmware, (bool, str, os.PathLike)):
            raise ConfigError(f"firmware={firmware!r}: expected True (the profile's firmware), False (none) "
                              "or the path of an ELF image")
        bad = [k for k in (overrides or {}) if not isinstance(k, str)]
        if bad:
            raise ConfigError(f"overrides: key {bad[0]!r} is not text; keys are --set keys such as "
                              '"motor1.R" or "/motor1/set_pos"')
        parsed = {}
        for k, v in (overrides or {}).items():
            try:
                parsed[k] = parse_value(v) if isinstance(v, str) else v
            except ConfigError as exc:
                raise ConfigError(f"{k} = {exc}") from None
        overrides = parsed
        profile, where = read_profile(board)
        if is_system(profile) and not isinstance(firmware, bool):
            raise ConfigError(f"{where}: a system runs its boards' own firmware; give an ELF to one board "
                              "profile (mcusim run nucleo-f746 --firmware app.elf)")
        if is_system(profile):
            ns = build_system(profile, where, overrides, firmware, engine)
            topics = ns["topics"]
            self.members = ns["members"]
        else:
            part_params, fw_params, topics = split_overrides(profile, overrides)
            ns = build(profile, where, part_params, firmware, fw_params, engine=engine)
            ns["topics"], ns["present"] = [], True
            self.members = {ns["board"]["name"]: ns}
        self.board_name = ns["board"]["name"]
        self.timebase, self.kernel, self.mcu = ns["timebase"], ns["kernel"], ns["mcu"]
        self.parts, self.firmware = ns["parts"], ns["firmware"]
        self.profile = profile
        self.wall_s = 0.0
        self._traces = []
        self._closers = []
        self._over = None       # why the simulation cannot run on (close, discard), or None
        if strict:      # specification limits become errors (the LPC4337 ADC's 4.5 MHz clock, ...)
            for p in self.peripherals():
                if hasattr(p, "strict"):
                    p.strict = True
        try:
            if topics and self.firmware is None:
                raise ConfigError(f"--set {', '.join(k for k, _ in topics)}: a message or input for the firmware, "
                                  "but this simulation runs without firmware (--no-firmware)")
            for mname, member in self.members.items():   # a system's per-board inputs (mcm1.velocity=10)
                for name, value in member["topics"]:
                    try:
                        member["firmware"].publish(name, value)
                    except ConfigError as exc:
                        if len(self.members) > 1:
                            named = with_member(exc, mname, [name])
                            if str(named) == str(exc):      # a message that does not start with the key
                                named = ConfigError(f"--set {mname}.{name}: {exc}")
                            raise named from None
                        raise
            for name, value in topics:
                self.publish(name, value)
        except BaseException:
            self.discard()
            raise

    # --- time ---------------------------------------------------------------------------------
    @property
    def now(self) -> int:
        """Simulated time in base ticks."""
        return self.kernel.now

    @property
    def time_s(self) -> float:
        return self.kernel.now / self.timebase.base_hz

    @property
    def cycles(self) -> int:
        """Core clock cycles since reset."""
        return self.kernel.now // self.mcu.core_clock.period

    def run(self, *, cycles: int | None = None, seconds=None, until=None, until_tick: int | None = None,
            stop=None) -> Simulation:
        """Advance by core ``cycles``, by ``seconds`` (number or "2ms"), to absolute ``until`` seconds
        or to base tick ``until_tick``. ``seconds`` is rounded to the nearest base tick at each call,
        so steps that are not whole ticks add up their roundings; ``until`` is an absolute end.
        ``stop()``, if given, is checked after every event; the run ends at the event that makes it
        true (``mcusim.testing.wait_until`` is built on it)."""
        self._going("run()")
        if stop is not None and not callable(stop):
            raise McusimError(f"run(stop={stop!r:.60}): stop is a function called after every event "
                              "(the run ends when it returns true)")
        given = [x is not None for x in (cycles, seconds, until, until_tick)]
        if sum(given) != 1:
            raise McusimError("run() takes exactly one of cycles=, seconds=, until=, until_tick=")
        if cycles is not None:
            if isinstance(cycles, bool) or not (isinstance(cycles, numbers.Integral) or (
                    isinstance(cycles, float) and cycles.is_integer())) or cycles < 0:
                raise McusimError(f"run(cycles={cycles!r}): expected a whole number of cycles >= 0")
            end = self.kernel.now + self.mcu.core_clock.cycles(int(cycles))
        elif seconds is not None:
            end = self.kernel.now + self._ticks_of("seconds", seconds)
        elif until is not None:
            end = self._ticks_of("until", until)
        else:
            if isinstance(until_tick, bool) or not isinstance(until_tick, int) and (
                    not isinstance(until_tick, float) or not until_tick.is_integer()):
                raise McusimError(f"run(until_tick={until_tick!r}): expected a whole number of base ticks")
            end = int(until_tick)
        if end > MAX_TICK:
            raise McusimError(f"run(): the end asked for ({end / self.timebase.base_hz:.3g} s) is "
                              f"beyond the last tick a simulation counts (2**63 - 1, "
                              f"{MAX_TICK / self.timebase.base_hz:.3g} s at this board's time base)")
        if end < self.kernel.now:
            raise McusimError(f"run(): the end asked for (tick {end}) is before now (tick {self.kernel.now}, "
                              f"{self.time_s:.9g} s); until= and until_tick= are absolute")
        t0 = _wall.perf_counter()
        try:
            self.kernel.run_until(end, stop=stop)
        except McusimError as exc:
            # a fault of the firmware or a refused register configuration stops the run inside an
            # event: the core and the models are left where it happened, not at a state a later
            # run could go on from (a faulted core would run on as if dead)
            self._over = self._over or f"stopped at t = {self.time_s:.9f} s on an error ({exc})"
            raise
        finally:
            self.wall_s += _wall.perf_counter() - t0
        for tr in self._traces:
            tr.flush(self.kernel.now)
        return self

    def _ticks_of(self, arg: str, value) -> int:
        """``run(seconds=...)`` or ``run(until=...)`` in base ticks, rounded to the nearest one; a
        positive time shorter than half a tick (which would round to no time at all) is refused."""
        if unitless(value):
            raise McusimError(f"run({arg}={value!r}): expected a number of seconds or a duration with a "
                              "unit (\"2ms\"), as the command line and scenarios take it")
        ticks = self.timebase.ticks(value, rounding=True)
        if ticks == 0 and parse_duration(value) > 0:
            raise McusimError(f"run({arg}={value!r}): shorter than half a base tick "
                              f"(1/{self.timebase.base_hz} s), which would run no time at all")
        return ticks

    # --- pins, topics -------------------------------------------------------------------------------
    def pin(self, name: str):
        """A pin of the board (``"PB1"``), in a system of any of its boards (``"mcm1.PB1"``; the
        main board's without a prefix too)."""
        head, dot, rest = name.partition(".") if isinstance(name, str) else ("", "", "")
        if dot and len(self.members) > 1 and head in self.members:
            return self.members[head]["mcu"].pin(rest)
        return self.mcu.pin(name)

    def firmware_for(self, topic: str):
        """(firmware, name) of a topic or input: ``"/motor1/set_pos"``, ``"velocity"``, or in a
        system ``"<board>.<input>"`` (``"mcm2.velocity"``) for a member board's firmware, as
        ``--set`` and scenarios name it."""
        head, dot, rest = topic.partition(".") if isinstance(topic, str) else ("", "", "")
        if dot and len(self.members) > 1 and head in self.members:
            fw = self.members[head]["firmware"]
            if fw is None:
                raise ConfigError(f"{topic!r:.60}: board {head!r} runs no firmware (present = false?)")
            return fw, rest
        return self._fw(), topic

    def _fw(self):
        if self.firmware is None:
            raise ConfigError("this simulation runs without firmware (--no-firmware, or load(..., firmware=False)): "
                              "it takes no topics or inputs")
        return self.firmware

    def _going(self, what: str) -> None:
        """McusimError naming ``what`` where the simulation cannot run on (closed, discarded or
        stopped on an error): a command, a trace or a link added then would never be seen."""
        if self._over is None:
            return
        if self._over.startswith("stopped"):
            raise McusimError(f"{what}: this simulation {self._over}, so it cannot run on (load the "
                              "board again)")
        raise McusimError(f"{what}: this simulation was {self._over}: its firmware's tasks are ended, "
                          "so it cannot run on (load the board again)")

    def publish(self, topic: str, value) -> None:
        """A message or input for the firmware (in a system, ``"mcm2.velocity"`` for a board's own)."""
        self._going(f"publish({topic!r:.60})")
        fw, name = self.firmware_for(topic)
        try:
            fw.publish(name, value)
        except ConfigError as exc:
            if name == topic:
                raise
            raise ConfigError(f"{topic.partition('.')[0]}: {exc}") from None

    def topic(self, name: str):
        """The firmware's last value of a topic (in a system, ``"mcm2.velocity"`` for a board's own)."""
        fw, rest = self.firmware_for(name)
        return fw.topic(rest)

    def connect_serial(self, uart: str, endpoint="pty", member: str | None = None):
        """Connect a UART (``"USART2"``) to a host endpoint: ``"pty"`` (a pseudo terminal; its
        ``path`` is what pyserial or pymavlink opens), ``"buffer"`` (in memory: ``.sent``, the recent
        bytes sent, and ``.feed()``), or an endpoint object. Returns the endpoint."""
        self._going(f"connect_serial({uart!r:.40})")
        from .hostserial import BufferEndpoint, PtyEndpoint
        if member is not None and member not in self.members:
            raise ConfigError(f"connect_serial(member={member!r}): no such board; boards: "
                              f"{', '.join(self.members)}")
        if not (isinstance(endpoint, str) and endpoint in ("pty", "buffer")) and not (
                hasattr(endpoint, "attach") and hasattr(endpoint, "transmit")):
            raise ConfigError(f"connect_serial({uart!r}, {endpoint!r}): the endpoint is \"pty\", "
                              "\"buffer\" or an object with attach(usart) and transmit(byte, tick)")
        mcu = self.members[member]["mcu"] if member else self.mcu
        periph = mcu.periph.get(uart)
        if periph is None or not hasattr(periph, "connect"):
            uarts = [n for n, p in mcu.periph.items() if hasattr(p, "connect") and hasattr(p, "receive")]
            raise ConfigError(f"no UART {uart!r} on {mcu.name}; UARTs: {', '.join(uarts) or 'none'}")
        held = getattr(periph, "endpoint", None)
        if held is not None:        # one far end per line: a second would silently take it over
            where = f"{uart} of {member}" if member else uart
            raise ConfigError(f"{where} is already connected to {_endpoint_name(held)}: a UART line has "
                              "one far end")
        if endpoint == "pty":
            endpoint = PtyEndpoint()
            self._closers.append(endpoint.close)
        elif endpoint == "buffer":
            endpoint = BufferEndpoint()
        periph.connect(endpoint)
        return endpoint

    def part(self, name: str):
        try:
            return self.parts[name]
        except KeyError:
            raise ConfigError(f"no part {name!r}; parts: {', '.join(self.parts)}") from None

    @property
    def motors(self) -> dict:
        return {n: p for n, p in self.parts.items() if type(p).__name__ == "DcMotor"}

    def peripherals(self):
        """Every peripheral model of every board."""
        for member in self.members.values():
            yield from member["mcu"].periph.values()

    # --- traces -------------------------------------------------------------------------------------
    def _sample_of(self, what: str, sample):
        """A trace's ``sample``: a number of seconds or a duration with a unit (a string without
        one, ``"50"``, is refused as run(seconds=...) refuses it, not taken as 50 s)."""
        if unitless(sample):
            raise ConfigError(f"{what}(sample={sample!r}): expected a number of seconds or a duration "
                              "with a unit (\"50us\"), as the command line and scenarios take it")
        return sample

    def trace_vcd(self, path, sample="50us"):
        self._going("trace_vcd()")
        from .trace import VcdTrace
        tr = VcdTrace(self, path, sample=self._sample_of("trace_vcd", sample))
        self._traces.append(tr)
        return tr

    def trace_csv(self, path=None, sample="1ms", keep: bool = False):
        """Plant and firmware variables on a uniform grid (:class:`mcusim.csvtrace.CsvTrace`)."""
        self._going("trace_csv()")
        from .csvtrace import CsvTrace
        tr = CsvTrace(self, path, sample=self._sample_of("trace_csv", sample), keep=keep)
        self._traces.append(tr)
        return tr

    def trace_registers(self, path_or_file, filter=None):
        """Log every firmware register access from now on as JSON lines (:mod:`mcusim.reglog`;
        ``mcusim.reglog.load_logged`` also catches the accesses made while the firmware starts)."""
        self._going("trace_registers()")
        from .reglog import RegisterLog
        log = RegisterLog(self, path_or_file, filter=filter)
        self._traces.append(log)
        return log

    def discard(self) -> None:
        """Drop the firmware's task coroutines (a simulation that will not run on)."""
        self._over = self._over or "discarded"
        close_firmware_tasks(self.members)

    def close(self) -> None:
        """End the run: traces flushed and closed, links closed, the firmware's tasks ended. The
        state stays readable; ``run()`` refuses to go on."""
        self._over = "closed"
        for tr in self._traces:
            tr.close(self.kernel.now)
        self._traces.clear()
        for fn in self._closers:
            fn()
        self._closers.clear()
        self.discard()      # the run is over: end the firmware's tasks (some may never have started)

    # --- summary ------------------------------------------------------------------------------------
    def summary(self) -> dict:
        sim_s = self.time_s
        motors = {}
        for i, (name, m) in enumerate(sorted(self.motors.items()), start=1):
            entry = {"angle_rad": m.output_angle, "speed_rpm": m.output_speed * 60 / (2 * math.pi),
                     "peak_current_a": m.peak_current}
            if self.firmware is not None and hasattr(self.firmware, "set_point"):
                entry["setpoint_rad"] = self.firmware.set_point(i)
            motors[name] = entry
        out = {
            "board": self.board_name,
            "simulated_s": sim_s,
            "wall_s": self.wall_s,
            "realtime_factor": sim_s / self.wall_s if self.wall_s > 0 else None,
            "events": self.kernel.events,
            "motors": motors,
        }
        if self.firmware is not None and hasattr(self.firmware, "summary"):
            out["firmware"] = self.firmware.summary()
            for key in getattr(self.firmware, "SUMMARY_TOP", ()):   # rover: odometry at top level
                if key in out["firmware"]:
                    out[key] = out["firmware"].pop(key)
        motors = list(self.motors.values())
        ticks = self.kernel.now * len(motors)
        cpus = [getattr(m["mcu"], "cpu", None) for m in self.members.values()]
        out["engine"] = {"name": self.kernel.engine,
                         "fast_fraction": (sum(m.fast_ticks for m in motors) / ticks) if ticks else 0.0,
                         "served_isrs": sum(getattr(c, "served_isrs", 0) for c in cpus)}
        warned = [w for p in self.peripherals() for w in getattr(p, "warnings", ())]
        if warned:                 # specification limits the firmware exceeded (not errors unless strict)
            out["warnings"] = warned
        for part in self.parts.values():                             # rover: pose, battery_v
            if hasattr(part, "summary_entries"):
                out.update(part.summary_entries())
        return out


def _bare_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def unitless(value) -> bool:
    """A time argument the API refuses: a bool, or a string without a unit ("50"), which the
    command line and scenarios would not take as seconds (a number of seconds is an int or float)."""
    return isinstance(value, bool) or (isinstance(value, str) and _bare_number(value))


def load(board: str, firmware=True, overrides: dict | None = None, **kw) -> Simulation:
    """Build a simulation of a board profile (a name from ``mcusim boards`` or a .toml path).

    ``overrides`` are ``--set`` pairs: ``{"motor1.load_inertia": 2e-5, "/motor1/set_pos": 1.57}``.
    ``firmware``: True (the profile's firmware), False (none) or the path of an ELF image to run
    on the board's Cortex-M core (``docs/firmware.md``).
    """
    if overrides is not None and not isinstance(overrides, Mapping):
        raise ConfigError(f"overrides = {overrides!r}: expected a mapping of --set keys to values, "
                          f'e.g. {{"motor1.R": 2.0}}')
    return Simulation(board, firmware=firmware, overrides=overrides, **kw)


def _endpoint_name(ep) -> str:
    """What holds a UART, for a message: a pty path, a UDP link or the endpoint's ``label``."""
    if getattr(ep, "path", None):
        return f"the pty {ep.path}"
    if getattr(ep, "mode", None) in ("udpin", "udpout"):
        return f"the UDP link {ep.mode}:{ep.host}:{ep.port}"
    return getattr(ep, "label", None) or f"a {type(ep).__name__}"
