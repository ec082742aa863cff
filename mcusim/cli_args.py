"""What the ``mcusim`` command line accepts: its commands, their arguments, the examples their
``--help`` shows (each one is run by the test suite), and the checks of argument values (one line
on stderr and exit status 2 for a bad one). :mod:`mcusim.cli` runs the commands."""

from __future__ import annotations

import argparse
import sys
from fractions import Fraction

from .engine import DEFAULT_ENGINE, ENGINES
from .errors import ConfigError
from .params import _show, fmt_duration, user_duration

MAX_DURATION = Fraction(600)        # simulated seconds a run may last unless --max-duration says more
MIN_SAMPLE = Fraction(1, 10**6)     # the finest --sample and --vcd-sample grid: 1 us

EXAMPLES_RUN = """examples:
  mcusim run nucleo-f746
  mcusim run nucleo-f746 --duration 500ms --set /motor1/set_pos=1.57 --vcd out.vcd
  mcusim run nucleo-f746 --set motor1.load_inertia=2e-5 --set firmware.variant=thesis --summary s.json
  mcusim run pro-mini --set velocity=10 --duration 3s
  mcusim run elementall --set cmd_vel.linear=0.5 --set cmd_vel.angular=0.2 --duration 10s --summary out.json
  mcusim run elementall --set mcm3.present=false --set battery.count=2
  mcusim run nucleo-f746 --scenario step_response --plot step.png --csv step.csv
  mcusim run nucleo-f746 --duration 5ms --register-log regs.jsonl --register-log-filter TIM1,TIM2
  mcusim run nucleo-f746 --firmware controlmotor --set /motor1/set_pos=1.57
  mcusim run elementall --mavlink udpout:127.0.0.1:14550 --realtime --duration 60s
  mcusim run ciaa-edu --mavlink pty --realtime --duration 60s

durations take a unit (2s, 500ms, 20us); a run may last at most 600s of simulated time unless
--max-duration raises the limit. --set topics and inputs (/motor1/set_pos=1.57, velocity=10)
replace the profile's demo command; parameters (motor1.R=2.5, firmware.kp=300) do not.
--mavlink pty prints the pty's path: connect the ground station (mavproxy, pymavlink) to it while
the run goes on, with --realtime so that it keeps pace with the wall clock.

exit status: 0 the run completed; 1 the firmware reported a fault (unless a scenario checks
firmware.faults), a scenario expectation failed, or the simulation hit an error; 2 a usage error
(bad board, key, value, unit, scenario or board file, or output path), found before the run starts
"""
EXAMPLES_TRACE = """examples:
  mcusim trace nucleo-f746 --duration 1ms --filter TIM1
  mcusim trace pro-mini --duration 20ms --set velocity=10 --filter TWI,ADC
  mcusim trace elementall --duration 200ms --filter rcm.I2C0

the register log (JSON lines) goes to stdout, the run's summary to stderr.
exit status as for `mcusim run`.
"""
EXAMPLES_BOARDS = """examples:
  mcusim boards
  mcusim boards --show nucleo-f746
  mcusim boards --kinds

a profile is described in docs/boards.md; a copy of a shipped one is a good start for a board
of your own: mcusim boards --show nucleo-f746 > my-board.toml, edit, mcusim run my-board.toml
"""
EXAMPLES_BENCH = """examples:
  mcusim bench nucleo-f746 --repeat 3
  mcusim bench elementall --duration 1s --json bench.json

the board runs the fixed command of its profile's [bench.set] table (else [run.set]); the
figures are those of the median run. exit status: 0; 1 the firmware reported a fault (the figures
are printed, and listed under "faults" in --json); 2 a usage error.
"""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2, no traceback
        print(f"{self.prog}: error: {message} (see {self.prog} --help)", file=sys.stderr)
        sys.exit(2)


def _kv(text: str) -> tuple[str, str]:
    key, eq, value = text.partition("=")
    if not eq or not key.strip():
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    return key.strip(), value.strip()


def _duration(text: str) -> Fraction:
    try:
        return user_duration(text, "")
    except ConfigError as exc:
        raise argparse.ArgumentTypeError(str(exc).lstrip(" :=")) from None


def _sample(text: str) -> Fraction:
    d = _duration(text)
    if d < MIN_SAMPLE:
        raise argparse.ArgumentTypeError(f"{fmt_duration(d)}: the finest sampling grid is 1us")
    return d


def _port(text: str) -> int:
    if not text.isdigit() or len(text) > 5 or not 0 < int(text) < 65536:
        raise argparse.ArgumentTypeError(f"{_show(text)}: expected a TCP port number from 1 to 65535")
    return int(text)


def _repeat(text: str) -> int:
    try:
        n = int(text) if len(text) <= 20 else None
    except ValueError:
        n = None
    if n is None:
        raise argparse.ArgumentTypeError(f"{_show(text)}: expected a whole number from 1 to 100")
    if not 1 <= n <= 100:
        raise argparse.ArgumentTypeError(f"{n}: must be from 1 to 100")
    return n


def _common_arguments(r, default_duration: str, what: str) -> None:
    r.add_argument("board", help="profile name (see `mcusim boards`) or path to a .toml profile")
    r.add_argument("--duration", type=_duration, default=None, metavar="TIME",
                   help=f"simulated time, with a unit: 2s, 500ms, 20us (default: {what}{default_duration})")
    r.add_argument("--max-duration", type=_duration, default=MAX_DURATION, metavar="TIME",
                   help="the longest run allowed, a guard against typos (default 600s)")
    r.add_argument("--set", dest="sets", type=_kv, action="append", default=[], metavar="KEY=VALUE",
                   help="topic (/motor1/set_pos=1.57), input (velocity=10) or parameter "
                        "(motor1.J=6e-6, firmware.variant=thesis); repeatable")
    r.add_argument("--no-firmware", action="store_true", help="peripherals and plant only")
    r.add_argument("--firmware", metavar="APP.ELF", help="run a compiled Cortex-M image instead of the "
                   "profile's firmware (docs/firmware.md)")
    r.add_argument("--gdb", type=_port, metavar="PORT", help="with --firmware: wait for gdb on this TCP port "
                   "(target extended-remote :PORT), halted at reset")
    r.add_argument("--quiet", "-q", action="store_true", help="no progress bar on stderr")
    r.add_argument("--strict", action="store_true",
                   help="specification limits are errors, not warnings (an ADC clock above 4.5 MHz)")
    r.add_argument("--engine", choices=ENGINES, default=DEFAULT_ENGINE,
                   help="fast (default: steady waveforms, whole PWM periods at once) or reference (every "
                        "edge its own event); both give the same results")


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version
    try:
        return version("mcusim")
    except PackageNotFoundError:       # run from a source tree that is not installed
        return "(not installed)"


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog="mcusim", description="Tick-accurate simulator of MCU peripherals, firmware and plants.")
    p.add_argument("--version", action="version", version=f"mcusim {_version()}")
    sub = p.add_subparsers(dest="cmd", required=True, parser_class=_Parser, metavar="{boards,run,trace,bench}")
    bo = sub.add_parser("boards", help="list the board and system profiles", epilog=EXAMPLES_BOARDS,
                        formatter_class=argparse.RawDescriptionHelpFormatter)
    bo.add_argument("--show", metavar="BOARD", help="print a shipped profile (to copy it into a board of your own)")
    bo.add_argument("--kinds", action="store_true", help="list the peripheral, part and firmware kinds a "
                    "profile may name, with their parameters (the project's own and registered ones)")
    r = sub.add_parser("run", help="run a board's firmware against its plant", epilog=EXAMPLES_RUN,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    _common_arguments(r, "2s", "the scenario's, else ")
    r.add_argument("--scenario", metavar="FILE", help="script the run: timed commands, disturbances, "
                   "faults, expectations (a .toml path or the name of a shipped scenario: step_response)")
    r.add_argument("--vcd", metavar="FILE", help="write pins, IRQ lines and plant variables as VCD "
                   "(and a GTKWave layout FILE.gtkw)")
    r.add_argument("--vcd-sample", type=_sample, default=None, metavar="TIME",
                   help="sampling period of the real-valued plant variables in the VCD (default 50us, at least 1us)")
    r.add_argument("--csv", metavar="FILE", help="write plant and firmware variables on a uniform grid")
    r.add_argument("--sample", type=_sample, default=None, metavar="TIME",
                   help="grid of --csv and --plot (default 1ms, at least 1us)")
    r.add_argument("--plot", metavar="FILE.png", help="draw set point and position or velocity, duty and "
                   "current (and the rover's path); needs matplotlib: pip install 'mcusim[plot]'")
    r.add_argument("--register-log", metavar="FILE", help="every firmware register access as JSON lines "
                   "('-' for stdout)")
    r.add_argument("--register-log-filter", metavar="NAMES", help="with --register-log: only these "
                   "peripherals or registers: TIM1, TIM1.CCR1, GPIO*, mcm1.TWI (comma-separated)")
    r.add_argument("--summary", metavar="FILE", help="write the summary as JSON")
    r.add_argument("--mavlink", metavar="LINK", help="connect the firmware's MAVLink port to the host: pty "
                   "(prints its path), udpout:HOST:PORT or udpin:HOST:PORT; the profile's demo command is not "
                   "applied (default duration: --max-duration)")
    r.add_argument("--realtime", action="store_true", help="pace simulated time to the wall clock (sleep "
                   "when ahead; report the lag when the simulation is slower than real time)")
    t = sub.add_parser("trace", help="print the firmware's register accesses (run --register-log -)",
                       epilog=EXAMPLES_TRACE, formatter_class=argparse.RawDescriptionHelpFormatter)
    _common_arguments(t, "1ms", "")
    t.add_argument("--filter", dest="register_log_filter", metavar="NAMES",
                   help="only these peripherals or registers: TIM1, TIM1.CCR1, GPIO* (comma-separated)")
    t.set_defaults(scenario=None)
    b = sub.add_parser("bench", help="real-time factor of a fixed scenario", epilog=EXAMPLES_BENCH,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    b.add_argument("board", help="profile name (see `mcusim boards`) or path to a .toml profile")
    b.add_argument("--duration", type=_duration, default=Fraction(1), metavar="TIME",
                   help="simulated time of each run, with a unit (default 1s)")
    b.add_argument("--max-duration", type=_duration, default=MAX_DURATION, metavar="TIME",
                   help="the longest run allowed (default 600s)")
    b.add_argument("--repeat", type=_repeat, default=3, metavar="N",
                   help="runs per engine, 1 to 100; the figures are the median run's (default 3)")
    b.add_argument("--engine", choices=ENGINES + ("both",), default=DEFAULT_ENGINE,
                   help="fast (default), reference, or both alternately in one process with the speedup")
    b.add_argument("--json", metavar="FILE", help="write the figures as JSON")
    b.add_argument("--quiet", "-q", action="store_true", help="no progress line on stderr")
    b.add_argument("--firmware", metavar="APP.ELF", help="bench a compiled Cortex-M image instead of the "
                   "profile's firmware")
    return p
