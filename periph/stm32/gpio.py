"""STM32F7 GPIO port (RM0385 §6): MODER, OTYPER, OSPEEDR, PUPDR, IDR, ODR, BSRR, LCKR, AFRL/AFRH.

Each port owns 16 pin nets named ``P<port><n>`` (``PE9``). Modes (MODER):

* 00 input: the port does not drive the pin; IDR reads the pin level; PUPDR sets the level of an
  undriven net (pull-up 1, pull-down 0);
* 01 output: ODR drives the pin (push-pull; open-drain drives only 0 and releases on 1);
* 10 alternate function: AFRL/AFRH select the function; for a timer channel the timer's output
  ``Port`` drives the pin when the timer enables the output, and the pin always feeds the timer's
  input net ``TIx`` (the input path of an AF pin is always on, as on the chip);
* 11 analog: not driven, IDR reads 0.

Alternate functions come from the STM32F746 datasheet (DS10916, table "Alternate function
mapping"); only timer channels are listed here, the functions this model can route. Selecting an
AF number on a pin in AF mode that is not in the table raises UnsupportedConfiguration, except
AF0 (the reset value: system functions), which leaves the pin undriven, so that firmware may set
MODER before AFR.
"""

from __future__ import annotations

from mcusim.errors import ConfigError, UnsupportedConfiguration
from mcusim.registers import Field, Peripheral, Register

# (pin, AF number) -> (peripheral, channel). DS10916 Table 12 (AF1 TIM1/2, AF2 TIM3/4/5, AF3 TIM8).
STM32F746_TIMER_AF = {
    ("PA0", 1): ("TIM2", 1), ("PA0", 2): ("TIM5", 1), ("PA1", 1): ("TIM2", 2), ("PA1", 2): ("TIM5", 2),
    ("PA2", 1): ("TIM2", 3), ("PA2", 2): ("TIM5", 3), ("PA3", 1): ("TIM2", 4), ("PA3", 2): ("TIM5", 4),
    ("PA5", 1): ("TIM2", 1), ("PA6", 2): ("TIM3", 1), ("PA7", 2): ("TIM3", 2),
    ("PA8", 1): ("TIM1", 1), ("PA9", 1): ("TIM1", 2), ("PA10", 1): ("TIM1", 3), ("PA11", 1): ("TIM1", 4),
    ("PA15", 1): ("TIM2", 1), ("PB0", 2): ("TIM3", 3), ("PB1", 2): ("TIM3", 4), ("PB3", 1): ("TIM2", 2),
    ("PB4", 2): ("TIM3", 1), ("PB5", 2): ("TIM3", 2), ("PB6", 2): ("TIM4", 1), ("PB7", 2): ("TIM4", 2),
    ("PB8", 2): ("TIM4", 3), ("PB9", 2): ("TIM4", 4), ("PB10", 1): ("TIM2", 3), ("PB11", 1): ("TIM2", 4),
    ("PC6", 2): ("TIM3", 1), ("PC7", 2): ("TIM3", 2), ("PC8", 2): ("TIM3", 3), ("PC9", 2): ("TIM3", 4),
    ("PC6", 3): ("TIM8", 1), ("PC7", 3): ("TIM8", 2), ("PC8", 3): ("TIM8", 3), ("PC9", 3): ("TIM8", 4),
    ("PD12", 2): ("TIM4", 1), ("PD13", 2): ("TIM4", 2), ("PD14", 2): ("TIM4", 3), ("PD15", 2): ("TIM4", 4),
    ("PE9", 1): ("TIM1", 1), ("PE11", 1): ("TIM1", 2), ("PE13", 1): ("TIM1", 3), ("PE14", 1): ("TIM1", 4),
    ("PH10", 2): ("TIM5", 1), ("PH11", 2): ("TIM5", 2), ("PH12", 2): ("TIM5", 3), ("PI0", 2): ("TIM5", 4),
    ("PI5", 3): ("TIM8", 1), ("PI6", 3): ("TIM8", 2), ("PI7", 3): ("TIM8", 3), ("PI2", 3): ("TIM8", 4),
}

_MODE_IN, _MODE_OUT, _MODE_AF, _MODE_ANALOG = 0, 1, 2, 3

# RM0385 §6.4 reset values that are not 0: the debug pins (PA13 SWDIO pull-up, PA14 SWCLK pull-down,
# PA15 JTDI pull-up, PB3 JTDO/SWO, PB4 NJTRST pull-up) in alternate function 0, very high speed on
# PA13 and PB3
_PORT_RESET = {
    "A": {"MODER": 0xA800_0000, "OSPEEDR": 0x0C00_0000, "PUPDR": 0x6400_0000},
    "B": {"MODER": 0x0000_0280, "OSPEEDR": 0x0000_00C0, "PUPDR": 0x0000_0100},
}


def _pin_fields(prefix, width):
    return tuple(Field(f"{prefix}{n}", n * width, width) for n in range(32 // width))


class Gpio(Peripheral):
    SIZE = 0x400
    REGISTERS = (
        Register("MODER", 0x00, on_write="_reconfigure", fields=_pin_fields("MODER", 2)),
        Register("OTYPER", 0x04, on_write="_reconfigure", fields=_pin_fields("OT", 1)[:16]),
        Register("OSPEEDR", 0x08, fields=_pin_fields("OSPEEDR", 2)),
        Register("PUPDR", 0x0C, on_write="_reconfigure", fields=_pin_fields("PUPDR", 2)),
        Register("IDR", 0x10, on_read="_read_idr", fields=tuple(Field(f"IDR{n}", n, access="r") for n in range(16))),
        Register("ODR", 0x14, on_write="_reconfigure", fields=_pin_fields("ODR", 1)[:16]),
        Register("BSRR", 0x18, on_write="_write_bsrr", fields=tuple(Field(f"BS{n}", n, access="w") for n in range(16))
                 + tuple(Field(f"BR{n}", 16 + n, access="w") for n in range(16))),
        Register("LCKR", 0x1C, fields=(Field("LCK", 0, 16, modelled=False), Field("LCKK", 16, modelled=False))),
        Register("AFRL", 0x20, on_write="_reconfigure", fields=_pin_fields("AFRL", 4)),
        Register("AFRH", 0x24, on_write="_reconfigure", fields=tuple(Field(f"AFRH{n + 8}", 4 * n, 4) for n in range(8))),
    )

    def __init__(self, name, mcu, port: str, af_table=None):
        super().__init__(name)
        self.mcu, self.port = mcu, port
        self.af_table = STM32F746_TIMER_AF if af_table is None else af_table
        if f"P{port}0" in mcu.pins:
            raise ConfigError(f"{name}: port {port} is declared twice (another GPIO peripheral has it)")
        self.pins = [mcu.add_pin(f"P{port}{n}") for n in range(16)]
        self._routes: dict[int, tuple] = {}  # pin -> (timer, channel) while in AF mode
        self._listeners_on: set = set()
        self._otyper_seen = 0
        reset = _PORT_RESET.get(port)
        if reset:
            self.value.update(reset)
            self._reconfigure(0, 0)     # the debug pins' pulls

    # --- registers ------------------------------------------------------------------------
    def _read_idr(self, stored):
        moder = self.value["MODER"]
        v = 0
        for n, net in enumerate(self.pins):
            if (moder >> 2 * n) & 3 != _MODE_ANALOG and net.level:
                v |= 1 << n
        return v

    def _write_bsrr(self, old, new):
        set_, reset = new & 0xFFFF, (new >> 16) & 0xFFFF
        self.value["ODR"] = (self.value["ODR"] & ~reset) | set_  # BS has priority over BR
        self._reconfigure(0, 0)

    def _reconfigure(self, old, new):
        moder, odr = self.value["MODER"], self.value["ODR"]
        otyper, pupdr = self.value["OTYPER"], self.value["PUPDR"]
        afr = self.value["AFRL"] | (self.value["AFRH"] << 32)
        flipped = otyper ^ self._otyper_seen
        for n, net in enumerate(self.pins):
            if flipped >> n & 1:
                # open drain needs every edge of a waveform, push-pull none: each timer output this
                # pin listens to (whether routed now or not: its listener stays connected) decides
                # again, also where the pin was an input when OTYPER changed (it kept the old choice)
                for pin, (tim, ch) in self._listeners_on:
                    if pin == n:
                        self.mcu.periph[tim].oc[ch].refresh()
            mode = (moder >> 2 * n) & 3
            pull = (pupdr >> 2 * n) & 3
            net.pull = None if mode == _MODE_ANALOG else {1: 1, 2: 0}.get(pull)  # analog: no pulls
            if pull == 3:
                raise UnsupportedConfiguration(self.name, "PUPDR", f"PUPDR{n}", 3, "is reserved")
            route = None
            level = None
            if mode == _MODE_OUT:
                bit = (odr >> n) & 1
                level = 0 if (otyper >> n) & 1 and not bit else (None if (otyper >> n) & 1 else bit)
            elif mode == _MODE_AF:
                af = (afr >> 4 * n) & 0xF
                key = (net.name, af)
                if af == 0:
                    pass  # AF0, the system functions (MCO, SWD, trace): not routed, the pin is not driven
                elif key not in self.af_table:
                    reg = "AFRL" if n < 8 else "AFRH"
                    raise UnsupportedConfiguration(self.name, reg, f"{reg}{n}", af,
                                                   f"(alternate function of {net.name}) is not modelled")
                else:
                    route = self.af_table[key]
            self._route(n, route)
            if route is not None:
                port = self.mcu.periph[route[0]].oc[route[1]]
                if port.wave is not None and not (otyper >> n) & 1:
                    net.set_wave(self.name, port.wave)   # fast engine: a push-pull PWM output
                    continue
                level = self._af_level(n, port.value)
            net.set(self.name, level)
        self._otyper_seen = otyper

    def _af_level(self, n, value):
        """An AF output in open-drain mode (OTYPER=1) drives only 0 and releases on 1."""
        if value is not None and (self.value["OTYPER"] >> n) & 1:
            return 0 if value == 0 else None
        return value

    def _route(self, n, route):
        old = self._routes.get(n)
        if old == route:
            return
        if old is not None:
            self.mcu.periph[old[0]].ti[old[1]].set(self.name, None)
        if route is None:
            self._routes.pop(n, None)
            return
        self._routes[n] = route
        tim = self.mcu.periph[route[0]]
        net = self.pins[n]
        key = (n, route)
        if key not in self._listeners_on:  # connect once; the callbacks check the route is current
            self._listeners_on.add(key)
            # waveforms pass through a push-pull pin as they are; open drain needs every edge
            tim.oc[route[1]].listen(lambda port, n=n, route=route: self._oc_changed(n, route, port),
                                    waves=lambda n=n: not (self.value["OTYPER"] >> n) & 1)
            net.listen(lambda net, n=n, route=route: self._pin_changed(n, route, net), waves=True,
                       sinks=lambda desc, n=n, route=route: self._pin_sinks(n, route, desc))
        self._pin_changed(n, route, net)

    def _oc_changed(self, n, route, port):
        if self._routes.get(n) == route:
            if port.wave is not None and not (self.value["OTYPER"] >> n) & 1:
                self.pins[n].set_wave(self.name, port.wave)
            else:
                self.pins[n].set(self.name, self._af_level(n, port.value))

    def _pin_sinks(self, n, route, desc):
        """Who reads a level descriptor on pin ``n`` through this route: the timer input's readers
        (an IDR read takes the pin's level at its tick, so it needs no edges)."""
        if self._routes.get(n) != route:
            return []
        return self.mcu.periph[route[0]].ti[route[1]].wave_sinks(desc)

    def _pin_changed(self, n, route, net):
        if self._routes.get(n) == route:
            ti = self.mcu.periph[route[0]].ti[route[1]]
            if net.wave is not None:
                ti.set_wave(self.name, net.wave)
            else:
                ti.set(self.name, net.level)
