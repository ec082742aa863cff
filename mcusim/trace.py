"""Trace recorders. VCD through pyvcd: pins, IRQ lines and plant variables.

VCD time is written in picoseconds: the base tick (1/216 MHz = 4629.6 ps) is not a whole number
of any VCD unit, so each tick is rounded to the nearest picosecond. Ticks are thousands of ps
apart, so order and distinctness of edges are preserved; the exact tick of an edge is
``round(t_ps · base_hz / 1e12)``.
"""

from __future__ import annotations

from vcd import VCDWriter

from .kernel import PRIO_OBSERVE


class VcdTrace:
    def __init__(self, sim, path, sample="50us"):
        self.sim = sim
        self.base_hz = sim.timebase.base_hz
        self._file = open(path, "w")  # noqa: SIM115 (open for the trace's lifetime; close() closes it)
        self.w = VCDWriter(self._file, timescale="1 ps", date="", comment=f"mcusim {sim.board_name}")
        board = sim.board_name
        now = self._ps(sim.kernel.now)
        self._closed = False
        # one scope per board (a system's boards under <system>.<member>)
        system = len(sim.members) > 1 or board not in sim.members
        for mname, member in sim.members.items():
            self._member_vars(f"{board}.{mname}" if system else board, member)
        if system:   # board pins wired to system parts ("rcm.GPIO3_3"), and the system's own nets
            for dotted in sim.profile.get("pins", {}):
                mname, _, pin_name = dotted.partition(".")
                self._wire(f"{board}.{mname}", pin_name, sim.members[mname]["mcu"].pin(pin_name))
            for name, part in sorted(sim.parts.items()):
                for attr in ("enable_out",):
                    net = getattr(part, attr, None)
                    if net is not None and hasattr(net, "listen"):
                        self._wire(f"{board}.plant", f"{name}.{attr}", net)
        # plant variables, sampled on a uniform grid; protection flags as wires
        self._reals = []
        for name, motor in sorted(sim.motors.items()):
            self._reals.append((self.w.register_var(f"{board}.plant", f"{name}.angle_rad", "real",
                                                    init=motor.output_angle), motor, "output_angle"))
            self._reals.append((self.w.register_var(f"{board}.plant", f"{name}.current_a", "real",
                                                    init=motor.current), motor, "current"))
        for name, part in sorted(sim.parts.items()):
            net = getattr(part, "ocd", None)
            if net is not None and hasattr(net, "listen"):
                var = self.w.register_var(f"{board}.plant", f"{name}.ocd", "wire", size=1, init=net.level)
                net.listen(lambda n, var=var: self.w.change(var, self._ps(self.sim.kernel.now), n.level))
        self.period = sim.timebase.ticks(sample, rounding=True)
        if self._reals and self.period > 0:
            sim.kernel.at(sim.kernel.now, self._sample, prio=PRIO_OBSERVE)
        self._t0 = now

    def _wire(self, scope: str, name: str, net) -> None:
        var = self.w.register_var(scope, name, "wire", size=1, init=net.level)
        net.listen(lambda n, var=var: self.w.change(var, self._ps(self.sim.kernel.now), n.level))

    def _member_vars(self, scope: str, member: dict) -> None:
        mcu, profile = member["mcu"], member["profile"]
        # pins wired to the plant, named as on the chip
        for pin_name in profile.get("pins", {}):
            self._wire(scope, pin_name, mcu.pin(pin_name))
        # interrupt lines, named after the peripheral's vector
        names = {}
        for spec in profile.get("peripheral", []):
            irqs = spec.get("irqs", {"irq": spec["irq"]} if "irq" in spec else {})
            shared = len(set(irqs.values())) == 1
            for kind, n in irqs.items():
                suffix = {"update": "UP"}.get(kind, kind.upper())  # CMSIS: TIM1_UP_TIM10_IRQn
                names.setdefault(n, spec["name"] if shared else f"{spec['name']}_{suffix}")
        irq_vars = {n: self.w.register_var(f"{scope}.irq", name, "wire", size=1, init=0)
                    for n, name in sorted(names.items())}

        def on_line(n, level):
            var = irq_vars.get(n)
            if var is not None:
                self.w.change(var, self._ps(self.sim.kernel.now), int(level))
        if irq_vars and hasattr(mcu.nvic, "line_listeners"):
            mcu.nvic.line_listeners.append(on_line)

    def _ps(self, ticks: int) -> int:
        return (ticks * 2 * 10**12 + self.base_hz) // (2 * self.base_hz)

    def _sample(self):
        if self._closed:
            return
        t = self._ps(self.sim.kernel.now)
        for var, obj, attr in self._reals:
            self.w.change(var, t, float(getattr(obj, attr)))
        self.sim.kernel.after(self.period, self._sample, prio=PRIO_OBSERVE)

    def flush(self, now: int) -> None:
        self.w.flush(self._ps(now))

    def close(self, now: int) -> None:
        if not self._closed:
            self._closed = True
            self.w.close(self._ps(now))
            self._file.close()
