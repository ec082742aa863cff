"""Trace recorders. VCD through pyvcd: pins, IRQ lines and plant variables.

VCD time is written in picoseconds: the base tick (1/216 MHz = 4629.6 ps) is not a whole number
of any VCD unit, so each tick is rounded to the nearest picosecond. Ticks are thousands of ps
apart, so order and distinctness of edges are preserved; the exact tick of an edge is
``round(t_ps · base_hz / 1e12)``.

:func:`write_gtkw` (or ``VcdTrace.write_gtkw()``) writes a GTKWave save file next to the VCD that
opens it with the signals grouped: one group per board scope with its pins (and USART TXD lines),
one per I2C bus, one with the interrupt lines, one with the plant (reals drawn as analog steps).
``gtkwave run.gtkw`` opens both.

Buses: every I2C bus of the board (a peripheral's ``bus``, an :class:`mcusim.i2c.I2cBus`; a bus
shared by the MCUs of a system is traced once) gets wires ``<bus>_SCL``/``<bus>_SDA`` in the scope
``<board>.<bus>`` (``ciaa-edu.i2c0.i2c0_SCL``; in a system ``elementall.i2c0.i2c0_SCL``), and every
LPC43xx USART a wire ``<USART>_TXD`` in its MCU's scope, drawn bit by bit from the byte-level models
by :mod:`mcusim.tracebus` (exact edges; see there for the timing and rounding).

Simultaneous changes: the changes of one timestamp are written in the order the variables were
declared, whatever order the models reported them in, and only each variable's last value of the
timestamp (a pin set and cleared again within one tick shows no pulse), so the two engines write
the same bytes.

Reorder buffer: those buses report a byte when it ends, so its edges lie in the past. Every value
change therefore goes through a buffer ordered by (tick, arrival) and is written to the VCD once it
is older than ``now - lag``; ``lag`` (base ticks) is the largest the bus tracers asked for (2 ms
when made, more for a slower bus). With no bus traced ``lag`` is 0 and changes are written at
once, as before. ``flush()`` (after every ``Simulation.run``) writes what is older than
``now - lag`` and stamps the VCD at that tick, so a VCD read before ``close()`` lacks the last
``lag`` of signal; ``close()`` writes everything up to ``now`` (edges drawn ahead of ``now``, like
the SCL fall ``H`` after a START, are dropped if the run ends first).

Other tools: sigrok-cli (0.5.x; 0.7.2 tested) reads this VCD as it is (``sigrok-cli -I vcd:downsample=1000
-i run.vcd -P pwm:data=PE9 -A pwm``). It takes the ps timescale at face value (a 1 THz sample rate:
``downsample=1000`` makes 1 ns samples and a fast decode; ``downsample=100000``, 100 ns samples,
is plenty for I2C at 100 kHz and UART at 115200 Bd), skips the real variables, and names channels
by the variable alone, without the scope: in a system, pins of the same name on several boards
(``PB1`` of mcm1..mcm4) are then ambiguous (bus wires carry the bus or USART name for that reason).
Decoding the buses: ``-P i2c:scl=i2c0_SCL:sda=i2c0_SDA`` and ``-P uart:tx=USART2_TXD:baudrate=115200``.
"""

from __future__ import annotations

import heapq
import itertools
import os

from vcd import VCDWriter

from .errors import ConfigError, TimeError
from .kernel import PRIO_OBSERVE
from .outputs import open_output


class VcdTrace:
    def __init__(self, sim, path, sample="50us"):
        self.sim = sim
        self.base_hz = sim.timebase.base_hz
        try:
            self.period = sim.timebase.ticks(sample, rounding=True)
        except TimeError as exc:    # a bad unit, not a number
            raise ConfigError(f"VCD sample {sample!r}: {exc}") from None
        if self.period <= 0:        # else a VCD without its plant variables' samples, silently
            raise ConfigError(f"VCD sample {sample!r}: must be at least one base tick "
                              f"(1/{sim.timebase.base_hz} s); the command line's finest is 1us")
        # (group, full hierarchical name, VCD type) of every variable, in declaration order; the
        # group is a board scope, a bus scope, "irq" or "plant" (see write_gtkw)
        self.signals: list[tuple[str, str, str]] = []
        self._order: dict = {}      # variable -> its index in signals (the write order in a timestamp)
        self._pend: list = []       # the changes of timestamp _pend_ps not written yet (see _write)
        self._pend_ps = None
        self.path, self._file = open_output(path, "VCD")   # open for the trace's lifetime; close() closes it
        self.w = VCDWriter(self._file, timescale="1 ps", date="", comment=f"mcusim {sim.board_name}")
        board = sim.board_name
        now = self._ps(sim.kernel.now)
        self._closed = False
        # reorder buffer (see the module doc): (tick, seq, var, value); nothing older than _mark may
        # be queued (it is written or may be); lag = 0 writes straight through
        self.lag = 0
        self.late_edges = 0         # changes queued older than _mark, moved to _mark (see tracebus)
        self._heap: list = []
        self._seq = itertools.count()
        self._mark = self._start = sim.kernel.now
        self.buses: list = []       # the bus waveform tracers (mcusim.tracebus)
        self._waves: dict = {}      # var -> [Waveform, last tick whose edges are written]
        # one scope per board (a system's boards under <system>.<member>)
        system = len(sim.members) > 1 or board not in sim.members
        for mname, member in sim.members.items():
            self._member_vars(f"{board}.{mname}" if system else board, member)
        # I2C buses, each once (a system's boards share them), in a scope of their own
        from .i2c import I2cBus
        from .tracebus import I2cWaveform
        seen = set()
        for member in sim.members.values():
            for p in member["mcu"].periph.values():
                bus = getattr(p, "bus", None)
                if isinstance(bus, I2cBus) and id(bus) not in seen:
                    seen.add(id(bus))
                    self.buses.append(I2cWaveform(self, bus, f"{board}.{bus.name}", self.base_hz))
        if system:   # board pins wired to system parts ("rcm.GPIO3_3"), and the system's own nets
            for dotted in sim.profile.get("pins", {}):
                mname, _, pin_name = dotted.partition(".")
                self._wire(f"{board}.{mname}", pin_name, sim.members[mname]["mcu"].pin(pin_name))
            for name, part in sorted(sim.parts.items()):
                for attr in ("enable_out",):
                    net = getattr(part, attr, None)
                    if net is not None and hasattr(net, "listen"):
                        self._wire(f"{board}.plant", f"{name}.{attr}", net, group="plant")
        # plant variables, sampled on a uniform grid; protection flags as wires
        self._reals = []
        for name, motor in sorted(sim.motors.items()):
            self._reals.append((self._var("plant", f"{board}.plant", f"{name}.angle_rad", "real",
                                          init=motor.output_angle), motor, "output_angle"))
            self._reals.append((self._var("plant", f"{board}.plant", f"{name}.current_a", "real",
                                          init=motor.current), motor, "current"))
        for name, part in sorted(sim.parts.items()):
            net = getattr(part, "ocd", None)
            if net is not None and hasattr(net, "listen"):
                self._wire(f"{board}.plant", f"{name}.ocd", net, group="plant")
        if self._reals:
            sim.kernel.at(sim.kernel.now, self._sample, prio=PRIO_OBSERVE)
        self._t0 = now

    def _var(self, group: str, scope: str, name: str, var_type: str, **kw):
        var = self.w.register_var(scope, name, var_type, **kw)
        self._order[var] = len(self.signals)
        self.signals.append((group, gtkwave_name(scope, name), var_type))
        return var

    def _write(self, var, ps: int, value) -> None:
        """Write a change at ``ps``. The changes of one timestamp are written in the order the
        variables were declared (each variable's own changes in the order they came), so a VCD
        does not depend on the order in which models happened to report simultaneous changes:
        the two engines (docs/engine.md) write the same bytes for the same edges."""
        if ps != self._pend_ps:
            self._write_pending()
            self._pend_ps = ps
        self._pend.append((self._order[var], var, value))

    def _write_pending(self) -> None:
        """Each variable's last value of the timestamp: a change undone within one tick is no
        edge (edge by edge, a compare match and a mode write on one tick set a pin and clear it
        again; the chip's output changes on clock edges, and the fast engine reports only the
        outcome), and pyvcd writes nothing for a value that did not change."""
        if self._pend:
            ps, change = self._pend_ps, self.w.change
            last = {}
            for order, var, value in self._pend:
                last[order] = (var, value)
            for order in sorted(last):
                var, value = last[order]
                change(var, ps, value)
            self._pend.clear()

    def _wire(self, scope: str, name: str, net, group: str | None = None) -> None:
        var = self._var(scope if group is None else group, scope, name, "wire", size=1, init=net.level)
        net.listen(lambda n, var=var: self._net_changed(var, n), waves=True)
        if net.wave is not None:
            self._waves[var] = [net.wave, self.sim.kernel.now]

    # --- steady waveforms (fast engine): edges drawn from the descriptor as the trace streams -----------
    def _net_changed(self, var, net) -> None:
        now = self.sim.kernel.now
        if var in self._waves:          # the old waveform's edges before now, then the new state
            self._expand_waves(now)
            del self._waves[var]
        if net.wave is not None:
            self._waves[var] = [net.wave, now]
        self._now_change(var, net.level)

    def _expand_waves(self, t: int, inclusive: bool = False) -> None:
        """Write the edges of the active waveforms up to tick ``t`` (before it unless ``inclusive``),
        all variables merged in time order: the VCD needs its timestamps in order."""
        if not self._waves:
            return
        last = t if inclusive else t - 1
        edges = []
        for var, ent in self._waves.items():
            w, done = ent
            if done < last:
                edges.extend((tick, var, lv) for tick, lv in w.edges(done, last))
                ent[1] = last
        if not edges:
            return
        edges.sort(key=lambda e: e[0])
        if self.lag:
            for tick, var, lv in edges:
                heapq.heappush(self._heap, (tick, next(self._seq), var, lv))
        else:
            for tick, var, lv in edges:
                self._write(var, self._ps(tick), lv)

    # --- reorder buffer ---------------------------------------------------------------------------
    def add_wire(self, scope: str, name: str, init: int = 0):
        """A 1-bit wire driven through :meth:`change` (grouped with ``scope``)."""
        return self._var(scope, scope, name, "wire", size=1, init=init)

    def request_lag(self, ticks: int) -> None:
        """Hold changes ``ticks`` base ticks before writing them (the lag only grows)."""
        if ticks > self.lag:
            if not self.lag:    # changes were written straight through up to now
                self._mark = max(self._mark, self.sim.kernel.now)
            self.lag = int(ticks)

    def change(self, var, tick: int, value) -> None:
        """``var`` takes ``value`` at base tick ``tick``, which may lie up to ``lag`` in the past
        (or in the future). Older ticks are moved to the oldest one still open (``late_edges``)."""
        if self._closed:
            return
        if tick < self._mark:
            tick = self._mark
            self.late_edges += 1
        heapq.heappush(self._heap, (tick, next(self._seq), var, value))
        self._drain(self.sim.kernel.now - self.lag)

    def _now_change(self, var, value) -> None:
        now = self.sim.kernel.now
        if self._waves:
            self._expand_waves(now)
        if self.lag:
            heapq.heappush(self._heap, (now, next(self._seq), var, value))
            self._drain(now - self.lag)
        else:
            self._write(var, self._ps(now), value)

    def _drain(self, limit: int) -> None:
        """Write every queued change at or before ``limit``; nothing older may be queued after."""
        if limit <= self._mark:
            return
        if self._waves:
            self._expand_waves(limit, inclusive=True)
        self._mark = limit
        heap = self._heap
        while heap and heap[0][0] <= limit:
            tick, _, var, value = heapq.heappop(heap)
            self._write(var, self._ps(tick), value)

    def _member_vars(self, scope: str, member: dict) -> None:
        mcu, profile = member["mcu"], member["profile"]
        # pins wired to the plant, named as on the chip
        for pin_name in profile.get("pins", {}):
            self._wire(scope, pin_name, mcu.pin(pin_name))
        # interrupt lines, named after the peripheral's vector
        names = {}
        for spec in profile.get("peripheral", []):
            irqs = spec.get("irqs", {"irq": spec["irq"]} if "irq" in spec else {})
            if not irqs:        # AVR models carry their vectors: {"compa": 11, ...}, (1, 2) or one
                p = mcu.periph.get(spec["name"])
                vec = getattr(p, "vectors", None)
                if isinstance(vec, dict):
                    irqs = dict(vec)
                elif isinstance(vec, (tuple, list)):
                    irqs = {f"int{k}": n for k, n in enumerate(vec)}
                elif isinstance(getattr(p, "vector", None), int):
                    irqs = {"irq": p.vector}
            shared = len(set(irqs.values())) == 1
            for kind, n in irqs.items():
                suffix = {"update": "UP"}.get(kind, kind.upper())  # CMSIS: TIM1_UP_TIM10_IRQn
                names.setdefault(n, spec["name"] if shared else f"{spec['name']}_{suffix}")
        irq_vars = {n: self._var("irq", f"{scope}.irq", name, "wire", size=1, init=0)
                    for n, name in sorted(names.items())}

        def on_line(n, level):
            var = irq_vars.get(n)
            if var is not None:
                self._now_change(var, int(level))
        if irq_vars and hasattr(mcu.nvic, "line_listeners"):
            mcu.nvic.line_listeners.append(on_line)
        # the TXD line of each USART that declares one (``traced_txd``: the LPC43xx's), drawn bit
        # by bit from its byte-level model (mcusim.tracebus)
        from .tracebus import UartWaveform
        for p in mcu.periph.values():
            if getattr(p, "traced_txd", False):
                self.buses.append(UartWaveform(self, p, scope, self.base_hz))

    def _ps(self, ticks: int) -> int:
        return (ticks * 2 * 10**12 + self.base_hz) // (2 * self.base_hz)

    def _sample(self):
        if self._closed:
            return
        for var, obj, attr in self._reals:
            self._now_change(var, float(getattr(obj, attr)))
        self.sim.kernel.after(self.period, self._sample, prio=PRIO_OBSERVE)

    def flush(self, now: int) -> None:
        """Write what can no longer change (older than ``now - lag``) and stamp the VCD there."""
        if not self.lag:
            self._expand_waves(now, inclusive=True)
            self._write_closed_ticks(now)
            self.w.flush(self._ps(now))
            return
        self._drain(now - self.lag)
        self._write_closed_ticks(self._mark)
        if self._mark > self._start:    # (not before: changes at the start still go in $dumpvars)
            self.w.flush(self._ps(self._mark))

    def _write_closed_ticks(self, t: int) -> None:
        """Write the pending changes unless they are tick ``t``'s, which may still be undone: a
        register written from Python after a run that ended on a compare match's tick."""
        if self._pend_ps != self._ps(t) or t <= self._start:
            self._write_pending()

    def close(self, now: int) -> None:
        """Write every change up to ``now`` (later ones, drawn ahead by a bus, are dropped)."""
        if not self._closed:
            self._closed = True
            if self.lag:
                self._drain(now)
                self._heap.clear()
            else:
                self._expand_waves(now, inclusive=True)
            self._write_pending()
            self.w.close(self._ps(now))
            self._file.close()

    def write_gtkw(self, path=None) -> str:
        """Write the GTKWave save file for this VCD (see :func:`write_gtkw`); returns its path."""
        return write_gtkw(self, path)


GTKW_ANALOG_ROWS = 3   # extra rows of height under each analog trace


def gtkwave_name(scope: str, name: str) -> str:
    """The name GTKWave gives a VCD variable ``name`` of ``scope``: the scope's path, a dot and
    the name, which is escaped with a backslash where it holds a dot itself (GTKWave's hierarchy
    delimiter; a layout naming ``board.plant.motor1.angle_rad`` shows nothing, silently, where
    GTKWave has ``board.plant.\\motor1.angle_rad``)."""
    return f"{scope}.\\{name}" if "." in name else f"{scope}.{name}"


def write_gtkw(vcd_trace: VcdTrace, path=None, *, dumpfile=None, savefile=None) -> str:
    """Write a GTKWave save file (``.gtkw``) for ``vcd_trace``: by default next to the VCD, with
    the same name and the suffix ``.gtkw``. Returns the path written.

    Groups: one per board scope with its pins and USART TXD lines (``nucleo-f746``; in a system
    ``elementall.mcm1`` ...), one per I2C bus with its SCL and SDA (``ciaa-edu.i2c0``), then
    ``interrupts`` with the interrupt lines of every board, ``plant`` with the plant's
    wires (protection flags, the enable line) and reals (motor angle and current, drawn as
    analog steps). Signals are named as GTKWave names them (:func:`gtkwave_name`:
    ``nucleo-f746.irq.TIM3``, ``nucleo-f746.plant.\\motor1.angle_rad``). The dump file is named relative to the layout's
    folder (GTKWave looks there), so the pair can be moved together; ``dumpfile`` and
    ``savefile`` give the names the files will have if they are written under other names first.
    """
    from vcd.gtkw import GTKWFlag, GTKWSave

    vcd_path = os.path.abspath(vcd_trace.path if dumpfile is None else dumpfile)
    if path is None:
        root, _ = os.path.splitext(vcd_path)
        path = root + ".gtkw"
    path = os.fspath(path)
    final = os.path.abspath(savefile if savefile is not None else path)
    rel_vcd = os.path.relpath(vcd_path, os.path.dirname(final))
    groups: dict[str, list[tuple[str, str]]] = {}
    for group, name, var_type in vcd_trace.signals:
        groups.setdefault(group, []).append((name, var_type))
    order = [g for g in groups if g not in ("irq", "plant")] + [g for g in ("irq", "plant") if g in groups]
    with open(path, "w") as f:
        gtkw = GTKWSave(f)
        gtkw.comment(f"mcusim {vcd_trace.sim.board_name}: signals grouped by board, bus, interrupts, plant")
        gtkw.dumpfile(rel_vcd, abspath=False)
        gtkw.savefile(os.path.basename(final), abspath=False)
        gtkw.timestart(0)
        board = vcd_trace.sim.board_name
        gtkw.treeopen(board)
        for group in order:
            with gtkw.group({"irq": "interrupts"}.get(group, group)):
                for name, var_type in groups[group]:
                    if var_type == "real":
                        gtkw.trace(name, datafmt="signed", extraflags=GTKWFlag.analog_step)
                        for _ in range(GTKW_ANALOG_ROWS):
                            gtkw.blank(analog_extend=True)
                    else:
                        gtkw.trace(name, datafmt="bin")
    return path
