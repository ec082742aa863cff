"""CSV trace: plant and firmware variables on a uniform time grid.

``CsvTrace(sim, "run.csv", sample="1ms")`` samples, at every t = k·sample (k = 0, 1, ...; the
first grid point at or after the time the trace is attached), by a kernel event at
:data:`~mcusim.kernel.PRIO_OBSERVE`, so a row sees the state of its tick after the hardware, the
plant and the firmware of that tick. ``sample`` must be a whole number of base ticks (``1ms`` is
216 000 ticks at 216 MHz, 816 000 in the rover's 816 MHz base). One header row; units are in the
column names:

* ``time_s``: k·sample written exactly (``0.003``, not ``0.0030000000000000001``);
* per motor ``<m>.angle_rad``, ``<m>.speed_rpm`` (output shaft), ``<m>.current_a``;
* per bridge with a supply input (BTS7960) ``<b>.supply_v``;
* per battery ``<b>.voltage_v`` (terminal), ``<b>.soc`` (0..1), ``<b>.current_a``;
* per rover body ``<body>.x_m``, ``<body>.y_m``, ``<body>.yaw_rad`` (the true pose);
* firmware variables, read from the firmware's own state (never through the bus, so they add no
  register accesses), as each firmware declares them (its ``csv_columns(motors, member)``):

  - ControlMotor (nucleo-f746): ``motorN.setpoint_rad`` (the PID set point, from
    ``/motorN/set_pos``), ``motorN.duty_pct`` (the duty last written, −100..100),
    ``motorN.fw_position_rad`` (``/motorN/get_pos``, published every executor spin; empty before
    the first);
  - OpenRover module (pro-mini, and mcmN in a rover): ``<m>.setpoint_rpm``, ``<m>.velocity_rpm``
    (measured by the firmware), ``<m>.duty_pct`` (TimerOne duty / 1024), ``<m>.fw_current_a``
    (measured on the IS pins), ``<m>`` being the module's motor (``motor``, ``mcm1.motor``);
  - rover_control (ciaa-edu, rcm): ``odometry.x_m``, ``odometry.y_m``, ``odometry.yaw_rad``,
    ``battery.measured_v`` (the controller's filtered battery reading; empty before the first),
    ``cmd_vel.linear_m_s``, ``cmd_vel.angular_rad_s`` (the command the controller holds).

The rows are on that grid, and where the run ends between two grid points one more row holds the
state at its end (``close(now)``). Empty cells are values not available yet. ``keep=True`` also keeps every row in memory
(``rows``, ``column(name)``), which :func:`mcusim.plot.plot_run` draws from; ``path=None`` with
``keep=True`` records in memory only. The trace follows the ``flush(now)`` / ``close(now)``
protocol of :class:`~mcusim.trace.VcdTrace`, so ``Simulation._traces`` can hold it.
"""

from __future__ import annotations

import csv
import math
from fractions import Fraction

from .errors import ConfigError, TimeError
from .kernel import PRIO_OBSERVE
from .outputs import open_output

RPM_PER_RAD_S = 60 / (2 * math.pi)


def _exact_decimal(t: Fraction) -> str:
    """``t`` as an exact decimal string when it has one (denominator 2^a·5^b), else repr(float)."""
    d = t.denominator
    twos = fives = 0
    while d % 2 == 0:
        d //= 2
        twos += 1
    while d % 5 == 0:
        d //= 5
        fives += 1
    if d != 1:
        return repr(float(t))
    digits = max(twos, fives)
    if digits == 0:
        return str(t.numerator)
    scaled = t.numerator * 10**digits // t.denominator
    sign = "-" if scaled < 0 else ""
    s = str(abs(scaled)).rjust(digits + 1, "0")
    return f"{sign}{s[:-digits]}.{s[-digits:]}".rstrip("0").rstrip(".")


def _fmt(v) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return "1" if v else "0"
    if isinstance(v, int):
        return str(v)
    return repr(float(v))


def _kind(obj) -> str:
    return type(obj).__name__


def plant_columns(sim) -> list[tuple[str, object]]:
    """(column, getter) of the plant variables of ``sim``, in a fixed order."""
    cols: list[tuple[str, object]] = []
    for name, m in sorted(sim.motors.items()):
        cols += [(f"{name}.angle_rad", lambda m=m: m.output_angle),
                 (f"{name}.speed_rpm", lambda m=m: m.output_speed * RPM_PER_RAD_S),
                 (f"{name}.current_a", lambda m=m: m.current)]
    for name, part in sorted(sim.parts.items()):
        if hasattr(part, "set_supply") and hasattr(part, "motor") and hasattr(part.params, "Vs"):
            cols.append((f"{name}.supply_v", lambda p=part: p.params.Vs))
    for name, part in sorted(sim.parts.items()):
        if hasattr(part, "soc") and hasattr(part, "voltage") and hasattr(part, "connect"):
            cols += [(f"{name}.voltage_v", lambda p=part: p.voltage()),
                     (f"{name}.soc", lambda p=part: p.soc),
                     (f"{name}.current_a", lambda p=part: p.current)]
    for name, part in sorted(sim.parts.items()):
        if hasattr(part, "pose_at_now"):
            cols += [(f"{name}.x_m", lambda p=part: p.pose_at_now()[0]),
                     (f"{name}.y_m", lambda p=part: p.pose_at_now()[1]),
                     (f"{name}.yaw_rad", lambda p=part: p.pose_at_now()[2])]
    return cols


def _member_motors(sim, mname: str, member: dict) -> list[str]:
    """Names (as in ``sim.parts``) of the motors of one member, in declaration order."""
    system = len(sim.members) > 1 or mname != sim.board_name
    out = []
    for pname, part in member["parts"].items():
        if _kind(part) == "DcMotor":
            out.append(f"{mname}.{pname}" if system else pname)
    return out


def firmware_columns(sim) -> list[tuple[str, object]]:
    """(column, getter) of the firmware variables each member's firmware exposes: the firmware
    declares them (``csv_columns(motors, member)``: the member's motor names as columns take
    them, and its name in a system), so that this module knows no firmware."""
    cols: list[tuple[str, object]] = []
    for mname, member in sim.members.items():
        fw = member.get("firmware")
        declare = getattr(fw, "csv_columns", None)
        if declare is not None:
            cols += declare(_member_motors(sim, mname, member), mname)
    return cols


def _fmt_sample(sample) -> str:
    if isinstance(sample, (Fraction, int, float)):
        from .params import fmt_duration
        return fmt_duration(sample)
    return repr(sample)


class CsvTrace:
    """Sample plant and firmware variables every ``sample`` into a CSV file (and/or memory)."""

    def __init__(self, sim, path=None, sample="1ms", keep: bool = False):
        if path is None and not keep:
            raise ConfigError("CsvTrace: give a path, or keep=True to record in memory")
        self.sim = sim
        self.kernel = sim.kernel
        self.base_hz = sim.timebase.base_hz
        try:
            self.period = sim.timebase.ticks(sample)
        except TimeError as exc:   # not a whole number of base ticks, or a bad unit
            raise ConfigError(f"CSV sample {_fmt_sample(sample)}: {exc}") from None
        if self.period <= 0:
            raise ConfigError(f"CSV sample {_fmt_sample(sample)} must be positive")
        self.sample_s = Fraction(self.period, self.base_hz)
        cols = plant_columns(sim) + firmware_columns(sim)
        self.columns = ["time_s"] + [c for c, _ in cols]
        if len(set(self.columns)) != len(self.columns):
            raise ConfigError(f"CsvTrace: duplicate columns in {self.columns}")
        self._getters = [g for _, g in cols]
        self.keep = keep
        self.rows: list[list] = []       # with keep: [time_s (float), values...] per row
        self.ticks: list[int] = []       # with keep: the base tick of each row
        self._own = False
        self._file = None
        self.path = None
        if path is not None:
            if hasattr(path, "write"):
                self._file = path
            else:
                self.path, self._file = open_output(path, "CSV", newline="")
                self._own = True
            self._csv = csv.writer(self._file, lineterminator="\n")
            self._csv.writerow(self.columns)
        self._closed = False
        self._last = None                                  # the tick of the last row written
        self._k = -(-self.kernel.now // self.period)      # first grid point at or after now
        self._ev = self.kernel.at(self._k * self.period, self._sample, prio=PRIO_OBSERVE)

    def _sample(self) -> None:
        if self._closed:
            return
        k = self._k
        self._row(k * self.sample_s)
        self._k = k + 1
        self._ev = self.kernel.at(self._k * self.period, self._sample, prio=PRIO_OBSERVE)

    def _row(self, t: Fraction) -> None:
        values = [g() for g in self._getters]
        if self._file is not None:
            self._csv.writerow([_exact_decimal(t)] + [_fmt(v) for v in values])
        if self.keep:
            self.rows.append([float(t)] + [None if v is None else float(v) for v in values])
            self.ticks.append(self.kernel.now)
        self._last = self.kernel.now

    # --- in-memory access ---------------------------------------------------------------------------
    def column(self, name: str) -> list:
        """The kept values of one column (``keep=True``)."""
        try:
            i = self.columns.index(name)
        except ValueError:
            raise ConfigError(f"no column {name!r}; columns: {', '.join(self.columns)}") from None
        return [r[i] for r in self.rows]

    def as_dict(self) -> dict[str, list]:
        """Kept rows as ``{column: [values...]}``."""
        return {c: [r[i] for r in self.rows] for i, c in enumerate(self.columns)}

    # --- the trace protocol of Simulation._traces ---------------------------------------------------
    def flush(self, now: int) -> None:
        if self._file is not None and not self._closed:
            self._file.flush()

    def close(self, now: int | None = None) -> None:
        if self._closed:
            return
        if now is not None and self._last is not None and now > self._last:
            # the run ended between grid points: one last row where it ended, so that the file
            # holds the end state (a sample that does not divide the duration, or is longer)
            self._row(Fraction(now, self.base_hz))
        self._closed = True
        if self._ev is not None:
            self._ev.cancel()
        if self._file is not None:
            if self._own:
                self._file.close()
            else:
                self._file.flush()


def read_csv(path) -> dict[str, list]:
    """A CSV written by :class:`CsvTrace` as ``{column: [float or None, ...]}``."""
    with open(path, newline="") as f:
        reader = csv.reader(f)
        header = next(reader)
        cols: dict[str, list] = {c: [] for c in header}
        for row in reader:
            for c, v in zip(header, row, strict=True):
                cols[c].append(float(v) if v != "" else None)
    return cols
