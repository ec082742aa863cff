"""The ``mcusim`` command line: ``boards``, ``run``, ``trace``, ``bench``.

Every mistake in what a user gives (arguments, ``--set`` values, scenario and board files, output
paths) is one line on stderr and exit status 2, found before the run starts; the outputs are
written so that a run that fails leaves no half-written file posing as complete
(:mod:`mcusim.outputs`). What the commands accept (arguments, ``--help`` and its examples) is
:mod:`mcusim.cli_args`."""

from __future__ import annotations

import contextlib
import gc
import io
import json
import os
import re
import signal
import sys
from fractions import Fraction
from pathlib import Path

from .cli_args import _parser
from .errors import ConfigError, McusimError, TimeError, read_input
from .params import fmt_duration, fmt_duration_exact


def _firmware(args):
    """What ``load(firmware=...)`` takes: the ELF's path, or whether the profile's firmware runs."""
    elf = getattr(args, "firmware", None)
    if elf is None:
        if getattr(args, "gdb", None) is not None:
            raise ConfigError("--gdb debugs a compiled image: give --firmware APP.ELF")
        return not args.no_firmware
    if args.no_firmware:
        raise ConfigError("--firmware and --no-firmware contradict each other")
    return elf


def _print_summary(s: dict) -> None:
    rtf = s["realtime_factor"]
    eng = s.get("engine", {}).get("name")
    eng = f", {eng} engine" if eng else ""
    print(f"{s['board']}: simulated {s['simulated_s']:.6f} s in {s['wall_s']:.2f} s wall "
          f"({rtf:.3f}x real time{eng}), {s['events']:,} events" if rtf else
          f"{s['board']}: simulated {s['simulated_s']:.6f} s{eng}, {s['events']:,} events")
    if s["motors"]:
        w = max(10, *(len(n) + 2 for n in s["motors"]))
        print(f"{'motor':<{w}}{'angle (rad)':>14}{'setpoint (rad)':>16}{'speed (rpm)':>14}{'peak current (A)':>18}")
        for name, m in s["motors"].items():
            sp = m.get("setpoint_rad")
            print(f"{name:<{w}}{m['angle_rad']:>14.4f}{(f'{sp:.4f}' if sp is not None else '-'):>16}"
                  f"{m['speed_rpm']:>14.2f}{m['peak_current_a']:>18.3f}")
    for key, label in (("pose", "true pose"), ("odometry", "odometry")):
        if key in s:
            p = s[key]
            print(f"{label:<10} x = {p['x']:.4f} m, y = {p['y']:.4f} m, yaw = {p['yaw']:.4f} rad")
    if "battery_v" in s:
        print(f"{'battery':<10} {s['battery_v']:.3f} V (lowest {s.get('battery_min_v', s['battery_v']):.3f} V, "
              f"state of charge {100 * s.get('battery_soc', 1):.2f} %)")
    fw = s.get("firmware")
    if fw:
        print("firmware: " + ", ".join(f"{k} = {(f'{v:.3f}' if isinstance(v, float) else v)}" for k, v in fw.items()))


def _run_sets(args) -> dict:
    """The ``--set`` pairs of a run without a scenario: the profile's ``[run.set]`` demo command
    unless the user gives a topic or input of their own (which replace it), then the user's."""
    from .board import is_input_key, read_profile
    user = dict(args.sets)
    if args.no_firmware or getattr(args, "firmware", None) or getattr(args, "mavlink", None):
        # the demo command is the profile firmware's; with a MAVLink link the host commands
        return user
    profile = read_profile(args.board)[0]
    demo = profile.get("run", {}).get("set", {})
    if any(is_input_key(profile, k) for k in user):
        return user
    return {**demo, **user}


def _in_run_set(args, sets: dict, exc: ConfigError) -> ConfigError:
    """``exc`` located at the board file's line when it is about a key of its ``[run.set]`` demo
    command (the user did not give that key): the mistake is in the file, not on the command line."""
    from .board import read_profile
    msg = str(exc)
    user = dict(args.sets)
    profile = read_profile(args.board)[0]
    for key in profile.get("run", {}).get("set", {}):
        if key in user or key not in sets or not hasattr(profile, "err"):
            continue
        text = msg.removeprefix("--set ")   # the key came from the file
        if text[len(key):len(key) + 1] in (":", " ", "=") and text.startswith(key) or repr(key) in text:
            return profile.err(f"[run.set] {text}", "run", None, "set", key)
    return exc


def _build(args, scenario, log_target):
    """The simulation a ``run``/``trace`` asks for (a scenario's board and [set], or the profile's
    demo command), with the register log attached from reset when one is asked for."""
    from contextlib import nullcontext

    from .reglog import RegisterLog, capture_startup, release
    from .sim import load
    with (capture_startup() if log_target is not None else nullcontext()) as startup:
        try:
            if scenario is not None:
                sim = scenario.build(args.board, dict(args.sets), _firmware(args), engine=args.engine)
                for p in sim.peripherals() if args.strict else ():
                    if hasattr(p, "strict"):
                        p.strict = True
                try:
                    scenario.apply(sim)
                except BaseException:
                    sim.discard()
                    raise
            else:
                sets = _run_sets(args)
                try:
                    sim = load(args.board, firmware=_firmware(args), overrides=sets, strict=args.strict,
                               engine=args.engine)
                except ConfigError as exc:
                    raise _in_run_set(args, sets, exc) from None
        except BaseException:
            if startup is not None:
                release(startup)
            raise
    if log_target is not None:
        out = sys.stdout if log_target == "-" else log_target
        try:
            sim.register_log = RegisterLog(sim, out, filter=args.register_log_filter, startup=startup)
            sim._traces.append(sim.register_log)
        except BaseException:
            sim.discard()
            raise
    return sim


def _check_run_args(args) -> None:
    for opt in ("vcd", "csv", "plot", "summary", "register_log", "scenario"):
        if getattr(args, opt, None) == "":
            raise ConfigError(f"--{opt.replace('_', '-')}: an empty file name")
    if getattr(args, "register_log_filter", None) is not None:
        if args.register_log is None:
            raise ConfigError("--register-log-filter needs --register-log FILE (or '-' for stdout)")
        if not args.register_log_filter.replace(",", "").replace(";", "").strip():
            opt = "--filter" if args.cmd == "trace" else "--register-log-filter"
            raise ConfigError(f"{opt} is empty: name peripherals or registers (TIM3, "
                              "TIM3.CCR1, GPIO*), or leave it out to log every access")
    # a sampling grid without the output it is for would be ignored: say so instead
    if getattr(args, "sample", None) is not None and not (args.csv or args.plot):
        raise ConfigError("--sample is the grid of --csv and --plot; give one of them")
    if getattr(args, "vcd_sample", None) is not None and not args.vcd:
        raise ConfigError("--vcd-sample is the sampling period of --vcd; give --vcd FILE")
    if hasattr(args, "sample"):
        args.sample = Fraction(1, 1000) if args.sample is None else args.sample
        args.vcd_sample = Fraction(50, 10**6) if args.vcd_sample is None else args.vcd_sample
    if args.duration is not None and args.duration > args.max_duration:
        raise ConfigError(f"--duration {fmt_duration(args.duration)}: longer than the limit of "
                          f"{fmt_duration(args.max_duration)} (raise it with --max-duration)")


def _input_files(args, scenario=None) -> list:
    """Every file the command reads, which no output may overwrite: the scenario, the board's
    profile (a shipped one given by name too), a system's member profiles, the ``--firmware``
    image and its topic map."""
    from .board import profile_files
    files = [scenario.path] if scenario is not None else []
    files += profile_files(args.board)
    elf = getattr(args, "firmware", None)
    if elf:
        from .elf.image import resolve_firmware
        elf = resolve_firmware(elf)
        files += [elf, Path(elf).with_suffix(".topics.toml")]
    return files


def _outputs(args, scenario):
    """The run's output files, checked (writable, distinct, not an input, what they need)."""
    from .outputs import Outputs, check_plot
    outs = Outputs(_input_files(args, scenario))
    files = {}
    for opt, value in (("--vcd", args.vcd), ("--csv", args.csv), ("--plot", args.plot), ("--summary", args.summary)):
        if value == "-":
            raise ConfigError(f"{opt} -: standard output is for --register-log only; give a file name")
    if args.vcd:
        files["vcd"] = outs.add("--vcd", args.vcd, streamed=True)
        if not files["vcd"].special:    # /dev/null and the like: no layout file next to a device
            files["gtkw"] = outs.add("--vcd (its GTKWave layout)", os.path.splitext(args.vcd)[0] + ".gtkw")
    if args.csv:
        files["csv"] = outs.add("--csv", args.csv, streamed=True)
    if args.plot:
        check_plot(args.plot)
        files["plot"] = outs.add("--plot", args.plot)
    if args.register_log is not None and args.register_log != "-":
        files["register_log"] = outs.add("--register-log", args.register_log, streamed=True)
    if args.summary:
        files["summary"] = outs.add("--summary", args.summary)
    outs.check()
    return outs, files


def cmd_run(args) -> int:
    from .progress import run_with_progress
    from .scenario import load_scenario
    _check_run_args(args)
    scenario = load_scenario(args.scenario, args.duration) if args.scenario else None
    if scenario is not None:
        if args.duration is not None:
            scenario.duration = args.duration         # end-of-run checks and reports follow the run
        elif scenario.duration > args.max_duration:
            raise ConfigError(f"{scenario.path}:{scenario.duration_line()}: [scenario] duration "
                              f"{fmt_duration(scenario.duration)} is longer than the limit of "
                              f"{fmt_duration(args.max_duration)} (raise it with --max-duration)")
    link = getattr(args, "mavlink", None)
    if link is not None:
        from .hostudp import parse_link
        parse_link(link)
        if scenario is not None and scenario.uses_mavlink:
            raise ConfigError(f"--mavlink {link}: the scenario {scenario.path} sends or expects MAVLink, so its "
                              "own ground station holds the MAVLink port; drop --mavlink, or the scenario's "
                              "mavlink actions and expectations")
    duration = args.duration if args.duration is not None else (
        scenario.duration if scenario is not None else args.max_duration if link else args.default_duration)
    if duration > args.max_duration:
        raise ConfigError(f"the run's default duration {fmt_duration(duration)} is longer than the limit of "
                          f"{fmt_duration(args.max_duration)} given by --max-duration; give a --duration")
    outs, files = _outputs(args, scenario)
    sim = None
    try:
        log = files["register_log"].target if "register_log" in files else args.register_log
        sim = _build(args, scenario, log)
        if sim.timebase.ticks(duration, rounding=True) == 0:
            raise ConfigError(f"--duration {fmt_duration(duration)}: shorter than one base tick "
                              f"(1/{sim.timebase.base_hz} s)")
        # times given on the command line are exact, as in scenarios: one off the base tick is refused
        checks = [("--duration", duration, "try 10ms or 2s")]
        if files.get("csv") or files.get("plot"):
            checks.append(("--sample", args.sample, "try 1ms or 100us"))
        if "vcd" in files:
            checks.append(("--vcd-sample", args.vcd_sample, "try 50us or 1ms"))
        for opt, value, hint in checks:
            try:
                sim.timebase.ticks(value)
            except TimeError:
                hz = sim.timebase.base_hz
                nearest = Fraction(round(Fraction(value) * hz), hz)
                if nearest > 0 and 10**12 % nearest.denominator == 0:   # a short decimal: offer it
                    hint = f"the nearest is {fmt_duration(nearest)}"
                else:           # else the nearest whole microsecond or nanosecond that is whole ticks
                    for unit, name in ((Fraction(1, 10**6), "microsecond"), (Fraction(1, 10**9), "nanosecond")):
                        near = round(Fraction(value) / unit) * unit
                        if near > 0 and (near * hz).denominator == 1:
                            hint = f"the nearest whole {name} is {fmt_duration(near)}"
                            break
                raise ConfigError(f"{opt} {fmt_duration_exact(value)}: not a whole number of base ticks "
                                  f"(1/{hz} s); {hint}") from None
        gdb = None
        if args.gdb is not None:
            from .elf.gdb import GdbServer
            gdb = GdbServer(sim, args.gdb)
            sim._closers.append(gdb.finish)
            gdb.wait_for_client()
        vcd = sim.trace_vcd(files["vcd"].target, sample=args.vcd_sample) if "vcd" in files else None
        csv = (sim.trace_csv(files["csv"].target if "csv" in files else None, sample=args.sample,
                             keep=bool(args.plot)) if ("csv" in files or "plot" in files) else None)
        pace = endpoint = None
        if link is not None:
            endpoint = _attach_mavlink(sim, link)
        try:
            if getattr(args, "realtime", False):
                from .realtime import run_realtime
                note = None if endpoint is None else (lambda: _link_line(endpoint))
                pace = run_realtime(sim, duration, note=note)
            else:
                # this process runs one simulation: the model built so far lives as long as the
                # process, so the cycle collector's full passes need not walk it again and again
                # (about 5 % of a rover run)
                gc.freeze()
                run_with_progress(sim, duration, quiet=args.quiet or args.register_log == "-")
        except McusimError as exc:      # a fault found during the run: say when
            if not getattr(exc, "has_time", False):      # (a core fault names its instant itself)
                exc.sim_time = sim.time_s
            raise
        sim.close()
        outs.commit_streamed()      # the run completed: a failure to write what follows is no reason to doubt them
        s = sim.summary()
        if scenario is not None:
            s.update(scenario.report_entries())
        if endpoint is not None:
            s["link"] = {"rx_dropped": endpoint.rx_dropped, "tx_dropped": endpoint.dropped}
        if vcd is not None and "gtkw" in files:
            from .trace import write_gtkw
            with _writing(files["gtkw"]):
                write_gtkw(vcd, files["gtkw"].target, dumpfile=args.vcd, savefile=args.vcd and
                           os.path.splitext(args.vcd)[0] + ".gtkw")
        if args.plot:
            from .plot import plot_run
            with _writing(files["plot"]):
                plot_run(csv, files["plot"].target, title=s["board"])
        if args.summary:
            with _writing(files["summary"]), open(files["summary"].target, "w") as f:
                json.dump(s, f, indent=2)
        outs.commit()
    except BaseException:
        if sim is not None:
            with contextlib.suppress(Exception):
                sim.close()
        for part in outs.abandon():
            print(f"mcusim: the run did not complete: partial output left in {part}", file=sys.stderr)
        raise
    report = sys.stderr if args.register_log == "-" else sys.stdout    # keep stdout for the log
    with contextlib.redirect_stdout(report):
        _print_summary(s)
        if pace is not None:
            print(pace.line())
        if endpoint is not None:
            print(_link_line(endpoint))
        if scenario is not None:
            for line in scenario.format_results():
                print(line)
        if vcd is not None:
            print(f"VCD written to {args.vcd}" + (f" (GTKWave layout: {files['gtkw'].path})" if "gtkw" in files else ""))
        if args.csv:
            print(f"CSV written to {args.csv}")
        if args.plot:
            print(f"plot written to {args.plot}")
        if args.summary:
            print(f"summary written to {args.summary}")
        if getattr(args, "register_log", None) not in (None, "-"):
            logged = getattr(getattr(sim, "register_log", None), "lines", None)
            empty = (f" (no access: the filter {args.register_log_filter} names registers this run "
                     "never touched)" if logged == 0 and args.register_log_filter else "")
            print(f"register log written to {args.register_log}{empty}")
    failed = []
    if scenario is not None and scenario.failed:
        failed.append("a scenario expectation failed")
    faults = (s.get("firmware") or {}).get("faults")
    if faults:
        if scenario is not None and scenario.reads_summary("firmware.faults"):
            # the scenario checks the faults itself (an expected fault is a pass): say, not fail
            print(f"mcusim: the firmware reported: {', '.join(faults)} (checked by the scenario)", file=sys.stderr)
        else:
            failed.append(f"the firmware reported: {', '.join(faults)}")
    for why in failed:
        print(f"mcusim: {why}", file=sys.stderr)
    return 1 if failed else 0


def _attach_mavlink(sim, spec: str) -> None:
    """Connect the firmware's MAVLink UART (its ``MAVLINK_UART``) to the host link ``spec``."""
    from .hostudp import describe, open_link
    from .mavlink import mavlink_port
    try:
        uart, member = mavlink_port(sim)
    except ConfigError as exc:
        raise ConfigError(f"--mavlink: {exc}") from None
    endpoint = open_link(spec)
    sim._closers.append(endpoint.close)
    sim.connect_serial(uart, endpoint, member=member)
    print(f"MAVLink: {describe(endpoint)}", flush=True)
    return endpoint


def _link_line(endpoint) -> str:
    return (f"MAVLink link: {endpoint.rx_dropped} bytes from the host dropped (more than {endpoint.rx_buffer} "
            f"waiting for the USART), {endpoint.dropped} bytes to the host dropped")


def cmd_trace(args) -> int:
    args.register_log = "-"
    for name in ("vcd", "csv", "plot", "summary"):
        setattr(args, name, None)
    return cmd_run(args)


def cmd_bench(args) -> int:
    from .bench import bench
    from .outputs import Outputs
    if args.duration > args.max_duration:
        raise ConfigError(f"--duration {fmt_duration(args.duration)}: longer than the limit of "
                          f"{fmt_duration(args.max_duration)} (raise it with --max-duration)")
    if args.json == "":
        raise ConfigError("--json: an empty file name")
    if args.json == "-":
        raise ConfigError("--json -: give a file name (the figures are printed on standard output "
                          "as well)")
    outs = Outputs(_input_files(args))
    out = outs.add("--json", args.json) if args.json else None
    outs.check()
    total = args.repeat * (2 if args.engine == "both" else 1)
    done = []

    def on_run(engine):         # a line on a terminal's stderr, rewritten before each run
        done.append(engine)
        sys.stderr.write(f"\rbench run {len(done)}/{total} ({engine} engine, "
                         f"{fmt_duration(args.duration)} simulated) ")
        sys.stderr.flush()
    show = not args.quiet and getattr(sys.stderr, "isatty", lambda: False)()
    try:
        try:
            r = bench(args.board, args.duration, args.repeat, args.engine, args.firmware or True,
                      on_run if show else None)
        finally:
            if show and done:       # clear the progress line, also before an error's message
                sys.stderr.write("\r" + " " * 100 + "\r")
                sys.stderr.flush()
        if out is not None:
            with open(out.target, "w") as f:
                json.dump(r, f, indent=2)
        outs.commit()
    except BaseException:
        outs.abandon()
        raise
    print(f"{r['board']} bench ({r['scenario']}): {r['simulated_s']:.3f} s simulated, "
          f"median wall {r['wall_s_median']:.2f} s (min {r['wall_s_min']:.2f}, max {r['wall_s_max']:.2f}) "
          f"over {r['repeat']} run{'s' if r['repeat'] != 1 else ''}")
    name = "fast" if r["engine"] == "both" else r["engine"]
    print(f"real-time factor {r['realtime_factor']:.3f} simulated s per wall s ({name} engine, "
          f"{100 * r['fast_fraction']:.0f} % of the motor time in whole-period chunks, "
          f"{r['served_isrs']:,} handler runs served in closed form); "
          f"{r['events']:,} events ({r['events_per_wall_s']:,.0f} per wall s)")
    if "instructions" in r:
        print(f"{r['instructions']:,} instructions ({r['instructions_per_wall_s']:,.0f} per wall s)")
    if r["engine"] == "both":
        print(f"reference engine: real-time factor {r['reference_realtime_factor']:.3f}; speedup "
              f"{r['speedup']:.1f}x (fast over reference, measured in this process)")
    if r["faults"]:
        print(f"mcusim bench: the firmware reported: {', '.join(r['faults'])}; these are the figures of "
              f"a run that stopped doing its work (exit status 1)", file=sys.stderr)
        return 1
    return 0


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    print(f"mcusim: warning: {_short(message)}", file=sys.stderr)


def _short(exc, limit: int = 600) -> str:
    """An error message on one line of reasonable length (a 5000-character key is cut)."""
    text = " ".join(str(exc).split("\n"))
    if len(text) > limit:       # a huge key or value first, so that the list after it stays readable
        text = re.sub(r"\S{256,}", lambda m: m.group()[:60] + "...", text)   # (a file path stays whole)
    return text if len(text) <= limit else text[:limit - 3] + "..."


@contextlib.contextmanager
def _writing(out):
    """A file written after the run: an OSError names its option and path (not a temporary);
    once written it gets its name at once, whatever happens to the next one."""
    try:
        yield
    except OSError as exc:
        exc.filename = f"{out.option} {out.path}"
        raise
    out.commit()


def _os_error(exc: OSError, args) -> str:
    if exc.filename:
        return f"{exc.filename}: {exc.strerror or exc}"
    outs = [f"{opt} {getattr(args, a)}" for a, opt in (("vcd", "--vcd"), ("csv", "--csv"), ("plot", "--plot"),
            ("summary", "--summary"), ("register_log", "--register-log"), ("json", "--json"))
            if getattr(args, a, None)]
    return f"cannot write {' or '.join(outs) or 'an output'}: {exc.strerror or exc}"


def _negative_values(argv: list) -> list:
    """``--duration -5ms`` as ``--duration=-5ms``: argparse takes a value that starts with ``-`` and
    a digit for an option, so the user would hear "expected one argument" instead of what is wrong
    with the value."""
    out = []
    for a in argv:
        if (out and out[-1].startswith("--") and "=" not in out[-1] and len(a) > 1 and a[0] == "-"
                and (a[1].isdigit() or a[1] == ".")):
            out[-1] += "=" + a
        else:
            out.append(a)
    return out


def main(argv=None) -> int:
    """Run the command line ``argv`` (default ``sys.argv[1:]``); returns the exit status (also
    for --help, 0, and for a usage error found by the argument parser, 2)."""
    try:
        parser = _parser()
        argv = _negative_values(sys.argv[1:] if argv is None else list(argv))
        args, extra = parser.parse_known_args(argv)
        if extra:       # name the command whose --help lists what it takes
            where = f"see mcusim {args.cmd} --help"
            if args.cmd in argv and argv.index(extra[0]) < argv.index(args.cmd):
                moved = [a for a in argv if a not in extra]
                at = moved.index(args.cmd) + 1
                with contextlib.suppress(SystemExit), contextlib.redirect_stderr(io.StringIO()):
                    if not parser.parse_known_args(moved[:at] + extra + moved[at:])[1]:
                        where = f"options of a command go after its name: mcusim {args.cmd} {' '.join(extra)} ..."
            print(f"mcusim: error: unrecognized arguments: {' '.join(extra)} ({where})", file=sys.stderr)
            return 2
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else 2
    import warnings
    old_showwarning = warnings.showwarning
    warnings.showwarning = _one_line_warning
    old_term = _on_sigterm()
    try:
        if args.cmd == "boards":
            from .board import board_names, read_profile, shipped_text
            if args.show is not None:
                if args.kinds:
                    raise ConfigError("boards: give --show BOARD or --kinds, not both")
                if args.show.endswith(".toml") and args.show not in board_names():
                    read_profile(args.show)         # a path, as wherever a board is named: checked
                    sys.stdout.write(read_input(args.show, "board", 4 << 20).decode("utf-8"))
                else:
                    sys.stdout.write(shipped_text(args.show))
                return 0
            if args.kinds:
                from .kinds import reference
                for group, title in (("peripheral", "Peripheral kinds"), ("part", "Part kinds"),
                                     ("firmware", "Firmware kinds")):
                    print(f"### {title}\n\n{reference(group)}")
                return 0
            for name in board_names():
                prof = read_profile(name)[0]
                print(f"{name:<16}{(prof.get('board') or prof.get('system', {})).get('description', '')}")
            return 0
        if args.cmd == "run":
            args.default_duration = Fraction(2)
            return cmd_run(args)
        if args.cmd == "bench":
            return cmd_bench(args)
        if args.cmd == "trace":
            args.default_duration = Fraction(1, 1000)
            return cmd_trace(args)
    except (ConfigError, TimeError) as exc:
        print(f"mcusim: error: {_short(exc)}", file=sys.stderr)
        return 2
    except BrokenPipeError:              # `mcusim trace ... | head`: the reader has gone
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except OSError as exc:                # an output that cannot be written (a full disk, /dev/full)
        print(f"mcusim: error: {_os_error(exc, args)}", file=sys.stderr)
        return 2
    except McusimError as exc:
        when = getattr(exc, "sim_time", None)
        print(f"mcusim: error: {_short(exc)}" + (f" (at simulated t = {when:.9f} s)" if when is not None else ""),
              file=sys.stderr)
        return 1
    except _Terminated:
        print("mcusim: terminated", file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        print("mcusim: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:              # a bug of mcusim: one line, the traceback on request
        if os.environ.get("MCUSIM_DEBUG"):
            raise
        print(f"mcusim: internal error: {type(exc).__name__}: {str(exc)[:300]} (this is a bug in mcusim; "
              "MCUSIM_DEBUG=1 shows the traceback)", file=sys.stderr)
        return 1
    finally:
        warnings.showwarning = old_showwarning
        if old_term is not None:
            signal.signal(signal.SIGTERM, old_term)
    return 0


class _Terminated(KeyboardInterrupt):
    """SIGTERM, turned into an exception so that a run cleans up as after Ctrl-C."""


def _on_sigterm():
    """Install the SIGTERM handler (main thread only); returns the previous one, or None."""
    import threading
    if threading.current_thread() is not threading.main_thread():
        return None

    def handler(signum, frame):
        raise _Terminated()
    return signal.signal(signal.SIGTERM, handler)


if __name__ == "__main__":
    sys.exit(main())
