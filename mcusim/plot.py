"""Plots of a run from its sampled variables (matplotlib, Agg backend, no display needed).

``plot_run(samples, "run.png")`` draws, per motor, one row of two panels:

* left: the firmware's set point and the plant's position (rad) when the firmware controls
  position (ControlMotor: ``<m>.setpoint_rad``), or its velocity set point, the measured velocity
  and the plant's speed (rpm) when it controls velocity (OpenRover module: ``<m>.setpoint_rpm``);
  the position alone without firmware;
* right: the motor current (A) and, on a second axis, the duty (%) when the firmware has one;

then, for a rover, the xy path (the body's true pose and the controller's odometry, m) and the
battery (terminal and measured voltage, V). ``samples`` is a :class:`~mcusim.csvtrace.CsvTrace`
created with ``keep=True``, a ``{column: values}`` mapping with the CSV's column names, or the
path of a CSV the trace wrote. Returns the :class:`matplotlib.figure.Figure`.

Needs matplotlib (``pip install 'mcusim[plot]'``).
"""

from __future__ import annotations

import os


def _columns(samples) -> dict[str, list]:
    if hasattr(samples, "as_dict"):
        if not samples.rows and samples.keep is False:
            from .errors import ConfigError
            raise ConfigError("plot_run: the CsvTrace kept no rows (create it with keep=True)")
        return samples.as_dict()
    if isinstance(samples, (str, os.PathLike)):
        from .csvtrace import read_csv
        return read_csv(samples)
    return {k: list(v) for k, v in samples.items()}


def _nan(values):
    return [float("nan") if v is None else v for v in values]


def _motors(cols) -> list[str]:
    return [c[: -len(".angle_rad")] for c in cols if c.endswith(".angle_rad")]


def plot_run(samples, path=None, title: str | None = None, dpi: int = 100):
    """Draw the run; write a PNG (or any format matplotlib knows by the suffix) to ``path`` when
    given. Returns the Figure."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from .errors import ConfigError

    cols = _columns(samples)
    if "time_s" not in cols:
        raise ConfigError("plot_run: no time_s column in the samples")
    t = cols["time_s"]
    motors = _motors(cols)
    rover = "body.x_m" in cols
    battery = "battery.voltage_v" in cols
    rows = len(motors) + (1 if rover or battery else 0)
    if rows == 0:
        raise ConfigError("plot_run: nothing to draw (no motor, body or battery columns)")
    fig = Figure(figsize=(11, 2.6 * rows + 0.6), dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(rows, 2)
    if title:
        fig.suptitle(title)

    def line(ax, key, label, **kw):
        if key in cols:
            return ax.plot(t, _nan(cols[key]), label=label, **kw)[0]
        return None

    for r, m in enumerate(motors):
        # --- left: position or velocity with its set point
        ax = fig.add_subplot(grid[r, 0])
        if f"{m}.setpoint_rpm" in cols:     # a velocity loop (pro-mini) or a position loop
            sp, fw, plant, unit, what, label = "setpoint_rpm", "velocity_rpm", "speed_rpm", "speed (rpm)", \
                "velocity", "speed"
        else:
            sp, fw, plant, unit, what, label = "setpoint_rad", "fw_position_rad", "angle_rad", "angle (rad)", \
                "position", "angle"
        line(ax, f"{m}.{sp}", f"{m} set point", linestyle="--", color="k", drawstyle="steps-post")
        line(ax, f"{m}.{fw}", f"{m} {what} (firmware)", color="tab:orange", drawstyle="steps-post")
        line(ax, f"{m}.{plant}", f"{m} {label} (plant)", color="tab:blue")
        ax.set_ylabel(unit)
        ax.set_title(f"{m}: {what}")
        ax.set_xlabel("time (s)")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize="small")
        # --- right: current, duty on a second axis
        ax = fig.add_subplot(grid[r, 1])
        handles = [h for h in (line(ax, f"{m}.current_a", f"{m} current", color="tab:red"),
                               line(ax, f"{m}.fw_current_a", f"{m} current (firmware)",
                                    color="tab:pink", linestyle=":", drawstyle="steps-post"))
                   if h is not None]
        ax.set_ylabel("current (A)")
        ax.set_xlabel("time (s)")
        ax.set_title(f"{m}: current" + (" and duty" if f"{m}.duty_pct" in cols else ""))
        ax.grid(True, alpha=0.3)
        if f"{m}.duty_pct" in cols:
            ax2 = ax.twinx()
            h = line(ax2, f"{m}.duty_pct", f"{m} duty", color="tab:green", drawstyle="steps-post",
                     alpha=0.8)
            ax2.set_ylabel("duty (%)")
            handles.append(h)
        ax.legend(handles, [h.get_label() for h in handles], loc="best", fontsize="small")

    r = len(motors)
    if rover:
        ax = fig.add_subplot(grid[r, 0])
        ax.plot(_nan(cols["body.x_m"]), _nan(cols["body.y_m"]), label="true pose", color="tab:blue")
        if "odometry.x_m" in cols:
            ax.plot(_nan(cols["odometry.x_m"]), _nan(cols["odometry.y_m"]), label="odometry",
                    color="tab:orange", linestyle="--")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_title("path")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize="small")
    if battery:
        ax = fig.add_subplot(grid[r, 1] if rover else grid[r, :])     # alone: the whole row
        line(ax, "battery.voltage_v", "terminal voltage", color="tab:blue")
        line(ax, "battery.measured_v", "measured (firmware)", color="tab:orange", drawstyle="steps-post")
        ax.set_xlabel("time (s)")
        ax.set_ylabel("voltage (V)")
        ax.set_title("battery")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize="small")
    if path is not None:
        fig.savefig(os.fspath(path), dpi=dpi)
    return fig
