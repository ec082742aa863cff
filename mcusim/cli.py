"""The ``mcusim`` command line: ``boards``, ``run``, ``bench``."""

from __future__ import annotations

import argparse
import contextlib
import json
import statistics
import sys
import time

from .engine import DEFAULT_ENGINE, ENGINES

from .errors import ConfigError, McusimError, TimeError
from .progress import run_with_progress
from .time import parse_duration

EXAMPLES_RUN = """examples:
  mcusim run nucleo-f746
  mcusim run nucleo-f746 --duration 500ms --set /motor1/set_pos=1.57 --vcd out.vcd
  mcusim run nucleo-f746 --set motor1.load_inertia=2e-5 --set firmware.variant=thesis --summary s.json
  mcusim run pro-mini --set velocity=10 --duration 3s
  mcusim run elementall --set cmd_vel.linear=0.5 --set cmd_vel.angular=0.2 --duration 10s --summary out.json
  mcusim run elementall --set mcm3.present=false --set battery.count=2
  mcusim run nucleo-f746 --scenario scenarios/step_response.toml --plot step.png --csv step.csv
  mcusim run nucleo-f746 --duration 5ms --register-log regs.jsonl --register-log-filter TIM1,TIM2

exit status: 0 the run completed; 1 the firmware reported a fault, a scenario expectation
failed, or the simulation hit an error; 2 a usage error (bad board, key, value, unit, scenario
file or output path)
"""
EXAMPLES_TRACE = """examples:
  mcusim trace nucleo-f746 --duration 1ms --filter TIM1
  mcusim trace pro-mini --duration 20ms --set velocity=10 --filter TWI,ADC
  mcusim trace elementall --duration 200ms --filter rcm.I2C0
"""
EXAMPLES_BOARDS = """examples:
  mcusim boards
"""
EXAMPLES_BENCH = """examples:
  mcusim bench nucleo-f746 --repeat 3
  mcusim bench elementall --duration 1s --json bench.json
"""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2, no traceback
        self.print_usage(sys.stderr)
        print(f"mcusim: error: {message}", file=sys.stderr)
        sys.exit(2)


def _kv(text: str) -> tuple[str, str]:
    key, eq, value = text.partition("=")
    if not eq or not key:
        raise argparse.ArgumentTypeError(f"--set expects KEY=VALUE, got {text!r}")
    return key.strip(), value.strip()


def _duration(text: str):
    try:
        return parse_duration(text)
    except TimeError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _run_arguments(r) -> None:
    r.add_argument("board", help="profile name (see `mcusim boards`) or path to a .toml")
    r.add_argument("--duration", type=_duration, default=None,
                   help="simulated time (default: the scenario's, else 2s)")
    r.add_argument("--set", dest="sets", type=_kv, action="append", default=[], metavar="KEY=VALUE",
                   help="topic (/motor1/set_pos=1.57) or parameter (motor1.J=6e-6, firmware.variant=thesis)")
    r.add_argument("--no-firmware", action="store_true", help="peripherals and plant only")
    r.add_argument("--quiet", "-q", action="store_true", help="no progress bar on stderr")
    r.add_argument("--strict", action="store_true",
                   help="specification limits are errors, not warnings (an ADC clock above 4.5 MHz)")
    r.add_argument("--engine", choices=ENGINES, default=DEFAULT_ENGINE,
                   help="fast (default: steady waveforms, whole PWM periods at once) or reference (every "
                        "edge its own event); both give the same results")


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog="mcusim", description="Tick-accurate simulator of MCU peripherals, firmware and plants.")
    sub = p.add_subparsers(dest="cmd", required=True, parser_class=_Parser)
    sub.add_parser("boards", help="list the board and system profiles", epilog=EXAMPLES_BOARDS,
                   formatter_class=argparse.RawDescriptionHelpFormatter)
    r = sub.add_parser("run", help="run a board's firmware against its plant", epilog=EXAMPLES_RUN,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    _run_arguments(r)
    r.add_argument("--scenario", metavar="FILE", help="script the run: timed commands, disturbances, "
                   "faults, expectations (a .toml path or a name in scenarios/)")
    r.add_argument("--vcd", metavar="FILE", help="write pins, IRQ lines and plant variables as VCD "
                   "(and a GTKWave layout FILE.gtkw)")
    r.add_argument("--vcd-sample", type=_duration, default=parse_duration("50us"),
                   help="sampling period of the real-valued plant variables in the VCD (default 50us)")
    r.add_argument("--csv", metavar="FILE", help="write plant and firmware variables on a uniform grid")
    r.add_argument("--sample", type=_duration, default=parse_duration("1ms"),
                   help="grid of --csv and --plot (default 1ms)")
    r.add_argument("--plot", metavar="FILE.png", help="draw set point and position or velocity, duty and "
                   "current (and the rover's path) with matplotlib")
    r.add_argument("--register-log", metavar="FILE", help="every firmware register access as JSON lines "
                   "('-' for stdout)")
    r.add_argument("--register-log-filter", metavar="NAMES", help="only these peripherals or registers: "
                   "TIM3, TIM3.CCR1, GPIO*, mcm1.TWI (comma-separated)")
    r.add_argument("--summary", metavar="FILE", help="write the summary as JSON")
    t = sub.add_parser("trace", help="print the firmware's register accesses (run --register-log -)",
                       epilog=EXAMPLES_TRACE, formatter_class=argparse.RawDescriptionHelpFormatter)
    _run_arguments(t)
    t.add_argument("--filter", dest="register_log_filter", metavar="NAMES",
                   help="only these peripherals or registers: TIM3, TIM3.CCR1, GPIO* (comma-separated)")
    t.set_defaults(scenario=None)
    b = sub.add_parser("bench", help="real-time factor of a fixed scenario", epilog=EXAMPLES_BENCH,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    b.add_argument("board", help="profile name (see `mcusim boards`)")
    b.add_argument("--duration", type=_duration, default=parse_duration("1s"),
                   help="simulated time of each run (default 1s)")
    b.add_argument("--repeat", type=int, default=3, help="runs per engine; the median is reported (default 3)")
    b.add_argument("--engine", choices=ENGINES + ("both",), default=DEFAULT_ENGINE,
                   help="fast (default), reference, or both in one process with the speedup")
    b.add_argument("--json", metavar="FILE", help="write the figures as JSON")
    return p


def _print_summary(s: dict) -> None:
    rtf = s["realtime_factor"]
    print(f"{s['board']}: simulated {s['simulated_s']:.6f} s in {s['wall_s']:.2f} s wall "
          f"({rtf:.3f}x real time), {s['events']:,} events" if rtf else
          f"{s['board']}: simulated {s['simulated_s']:.6f} s, {s['events']:,} events")
    if s["motors"]:
        print(f"{'motor':<10}{'angle (rad)':>14}{'setpoint (rad)':>16}{'speed (rpm)':>14}{'peak current (A)':>18}")
        for name, m in s["motors"].items():
            sp = m.get("setpoint_rad")
            print(f"{name:<10}{m['angle_rad']:>14.4f}{(f'{sp:.4f}' if sp is not None else '-'):>16}"
                  f"{m['speed_rpm']:>14.2f}{m['peak_current_a']:>18.3f}")
    for key, label in (("pose", "true pose"), ("odometry", "odometry")):
        if key in s:
            p = s[key]
            print(f"{label:<10} x = {p['x']:.4f} m, y = {p['y']:.4f} m, yaw = {p['yaw']:.4f} rad")
    if "battery_v" in s:
        print(f"battery    {s['battery_v']:.3f} V (lowest {s.get('battery_min_v', s['battery_v']):.3f} V, "
              f"state of charge {100 * s.get('battery_soc', 1):.2f} %)")
    for w in s.get("warnings", ()):
        print(f"warning: {w}")
    fw = s.get("firmware")
    if fw:
        print("firmware: " + ", ".join(f"{k} = {(f'{v:.3f}' if isinstance(v, float) else v)}" for k, v in fw.items()))


def _build(args, scenario):
    """The simulation a ``run``/``trace`` asks for (a scenario's board and [set], or the profile's
    demo command), with the register log attached from reset when one is asked for."""
    from contextlib import nullcontext

    from .board import read_profile
    from .reglog import RegisterLog, capture_startup, release
    from .sim import load
    log_to = getattr(args, "register_log", None)
    with (capture_startup() if log_to is not None else nullcontext()) as startup:
        try:
            if scenario is not None:
                sim = scenario.build(args.board, dict(args.sets), not args.no_firmware, engine=args.engine)
                for p in sim.peripherals() if args.strict else ():
                    if hasattr(p, "strict"):
                        p.strict = True
                try:
                    scenario.apply(sim)
                except McusimError:
                    sim.discard()
                    raise
            else:
                sets = {} if args.no_firmware else dict(read_profile(args.board)[0].get("run", {}).get("set", {}))
                sets.update(dict(args.sets))  # the profile's demo command, overridden by --set
                sim = load(args.board, firmware=not args.no_firmware, overrides=sets, strict=args.strict,
                           engine=args.engine)
        except BaseException:
            if startup is not None:
                release(startup)
            raise
    if log_to is not None:
        out = sys.stdout if log_to == "-" else log_to
        try:
            sim._traces.append(RegisterLog(sim, out, filter=args.register_log_filter, startup=startup))
        except BaseException:
            sim.discard()
            raise
    return sim


def cmd_run(args) -> int:
    from .scenario import load_scenario
    scenario = load_scenario(args.scenario) if args.scenario else None
    if scenario is not None and args.duration is not None:
        scenario.duration = args.duration         # end-of-run checks and reports follow the run
    duration = args.duration if args.duration is not None else (
        scenario.duration if scenario is not None else parse_duration("2s"))
    _check_outputs(args)
    sim = _build(args, scenario)
    try:
        vcd = sim.trace_vcd(args.vcd, sample=args.vcd_sample) if args.vcd else None
        csv = sim.trace_csv(args.csv, sample=args.sample, keep=bool(args.plot)) if (args.csv or args.plot) else None
    except BaseException:
        sim.close()
        raise
    try:
        run_with_progress(sim, duration, quiet=args.quiet or args.register_log == "-")
    finally:
        sim.close()
    s = sim.summary()
    if scenario is not None:
        s.update(scenario.report_entries())
    report = sys.stderr if args.register_log == "-" else sys.stdout    # keep stdout for the log
    with contextlib.redirect_stdout(report):
        _print_summary(s)
        if scenario is not None:
            for line in scenario.format_results():
                print(line)
        if vcd is not None:
            print(f"VCD written to {args.vcd} (GTKWave layout: {vcd.write_gtkw()})")
        if args.csv:
            print(f"CSV written to {args.csv}")
        if args.plot:
            from .plot import plot_run
            plot_run(csv, args.plot, title=s["board"])
            print(f"plot written to {args.plot}")
    if args.summary:
        with open(args.summary, "w") as f:
            json.dump(s, f, indent=2)
    failed = []
    if scenario is not None and scenario.failed:
        failed.append("a scenario expectation failed")
    faults = (s.get("firmware") or {}).get("faults")
    if faults:
        failed.append(f"the firmware reported: {', '.join(faults)}")
    for why in failed:
        print(f"mcusim: {why}", file=sys.stderr)
    return 1 if failed else 0


def _check_outputs(args) -> None:
    """Output files whose folder does not exist, or a plot format matplotlib cannot write, are
    usage errors found before the run, not after it."""
    import os
    for opt in ("vcd", "csv", "plot", "summary", "register_log"):
        path = getattr(args, opt, None)
        if path and path != "-":
            folder = os.path.dirname(os.path.abspath(path))
            if not os.path.isdir(folder):
                raise ConfigError(f"--{opt.replace('_', '-')} {path}: no folder {folder}")
    if getattr(args, "plot", None):
        ext = os.path.splitext(args.plot)[1].lower()
        if ext not in (".png", ".pdf", ".svg", ".jpg", ".jpeg"):
            raise ConfigError(f"--plot {args.plot}: the file name must end in .png, .pdf, .svg or .jpg")
    if getattr(args, "sample", None) is not None and args.sample <= 0:
        raise ConfigError(f"--sample {args.sample}: must be positive")


def cmd_trace(args) -> int:
    args.register_log = "-"
    for name in ("vcd", "csv", "plot", "summary"):
        setattr(args, name, None)
    return cmd_run(args)


def bench(board: str, duration, repeat: int = 3, engine: str = DEFAULT_ENGINE) -> dict:
    """Run the profile's fixed ``[bench.set]`` scenario ``repeat`` times; figures of the median run.
    ``engine="both"`` runs the fast and the reference engine alternately in this process and adds
    ``reference_realtime_factor`` and ``speedup`` (fast over reference)."""
    if engine == "both":
        fast, ref = {}, {}
        runs = [bench(board, duration, 1, e) for _ in range(repeat) for e in ENGINES]
        fast = _median_of([r for r in runs if r["engine"] == "fast"])
        ref = _median_of([r for r in runs if r["engine"] == "reference"])
        fast["reference_realtime_factor"] = ref["realtime_factor"]
        fast["reference_wall_s_median"] = ref["wall_s_median"]
        fast["speedup"] = fast["realtime_factor"] / ref["realtime_factor"]
        fast["engine"] = "both"
        return fast
    from .board import read_profile
    from .sim import load
    profile = read_profile(board)[0]
    scenario = profile.get("bench", {}).get("set") or profile.get("run", {}).get("set", {})
    runs = []
    for _ in range(repeat):
        sim = load(board, overrides=dict(scenario), engine=engine)
        t0 = time.perf_counter()
        sim.run(seconds=duration)
        wall = time.perf_counter() - t0
        runs.append((wall, sim.kernel.events, sim.time_s, sim.summary()["engine"]["fast_fraction"]))
    walls = [r[0] for r in runs]
    wall = statistics.median(walls)
    events, sim_s = runs[0][1], runs[0][2]
    return {"board": board, "scenario": ", ".join(f"{k}={v:g}" for k, v in scenario.items()), "simulated_s": sim_s,
            "wall_s_median": wall, "wall_s_min": min(walls), "wall_s_max": max(walls),
            "realtime_factor": sim_s / wall, "events": events, "events_per_wall_s": events / wall,
            "repeat": repeat, "engine": engine, "fast_fraction": runs[0][3]}


def _median_of(runs: list) -> dict:
    walls = sorted(r["wall_s_median"] for r in runs)
    out = dict(min(runs, key=lambda r: abs(r["wall_s_median"] - statistics.median(walls))))
    out.update(wall_s_median=statistics.median(walls), wall_s_min=walls[0], wall_s_max=walls[-1],
               repeat=len(runs), realtime_factor=out["simulated_s"] / statistics.median(walls))
    return out


def cmd_bench(args) -> int:
    if args.repeat < 1:
        raise ConfigError(f"--repeat {args.repeat}: must be at least 1")
    r = bench(args.board, args.duration, args.repeat, args.engine)
    print(f"{r['board']} bench ({r['scenario']}): {r['simulated_s']:.3f} s simulated, "
          f"median wall {r['wall_s_median']:.2f} s (min {r['wall_s_min']:.2f}, max {r['wall_s_max']:.2f}) "
          f"over {r['repeat']} runs")
    name = "fast" if r["engine"] == "both" else r["engine"]
    print(f"real-time factor {r['realtime_factor']:.3f} simulated s per wall s ({name} engine, "
          f"{100 * r['fast_fraction']:.0f} % of the motor time in whole-period chunks); "
          f"{r['events']:,} events ({r['events_per_wall_s']:,.0f} per wall s)")
    if r["engine"] == "both":
        print(f"reference engine {r['reference_realtime_factor']:.3f}; speedup {r['speedup']:.1f}x "
              f"(fast over reference, measured in this process)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(r, f, indent=2)
    return 0


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    print(f"mcusim: warning: {message}", file=sys.stderr)


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    import warnings
    warnings.showwarning = _one_line_warning
    try:
        if args.cmd == "boards":
            from .board import board_names, read_profile
            for name in board_names():
                prof = read_profile(name)[0]
                print(f"{name:<16}{(prof.get('board') or prof.get('system', {})).get('description', '')}")
            return 0
        if args.cmd == "run":
            return cmd_run(args)
        if args.cmd == "bench":
            return cmd_bench(args)
        if args.cmd == "trace":
            return cmd_trace(args)
    except (ConfigError, TimeError) as exc:
        print(f"mcusim: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:              # `mcusim trace ... | head`: the reader has gone
        import os
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except OSError as exc:                # an output file that cannot be written
        print(f"mcusim: error: {exc.filename or ''}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    except McusimError as exc:
        print(f"mcusim: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("mcusim: interrupted", file=sys.stderr)
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
