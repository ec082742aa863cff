"""PID_v1.cpp / PID_v1.h, br3ttb Arduino-PID-Library v1.2.1, as built for AVR.

On AVR ``double`` is IEEE binary32 (``__SIZEOF_DOUBLE__ == 4``), so every ``double`` here is a
``numpy.float32`` scalar and every binary operation is one float32 operation with its result
rounded, in the order the C evaluates it (avr-gcc has no FMA and does not contract). Integer to
floating conversions are done where the C does them: ``(double)SampleTime``, the literal ``1000``
in ``/1000``, ``(double)NewSampleTime``, the ``0`` of ``0 - kp`` and the ``0, 255`` of the default
limits. Arguments arrive as Python floats and are rounded to float32 on entry, as a C call with
``double`` (= float) parameters would.

The three pointers ``myInput``, ``myOutput``, ``mySetpoint`` become the attributes ``input``,
``output`` and ``setpoint``; assigning to one rounds to float32, like storing to the C variable.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

AUTOMATIC = 1
MANUAL = 0
DIRECT = 0
REVERSE = 1
P_ON_M = 0
P_ON_E = 1

_f32 = np.float32
_ZERO = _f32(0)          # the int 0 of ``0 - kp`` converted to double: 0 - 0.0 is +0.0, not -0.0
_THOUSAND = _f32(1000)


def _ulong(x: int) -> int:
    return int(x) & 0xFFFFFFFF


def _int16(x: int) -> int:
    """An AVR ``int`` parameter: 16-bit, two's complement (gcc truncates on conversion)."""
    return ((int(x) + 0x8000) & 0xFFFF) - 0x8000


class PID:
    def __init__(self, kp: float, ki: float, kd: float, *pon_dir: int, p_on: int | None = None,
                 direction: int | None = None, millis: Callable[[], int] | None = None):
        """The C++ overloads PID(Kp, Ki, Kd, POn, ControllerDirection) and PID(Kp, Ki, Kd,
        ControllerDirection) (POn = P_ON_E): after the gains, two values are POn and the
        direction, one is the direction, as ``PID(2, 5, 1, DIRECT)`` means in C. The input, output
        and set point pointers are the attributes; ``millis`` is the core's ``millis()``."""
        if len(pon_dir) > 2 or (pon_dir and (p_on is not None or direction is not None)):
            raise TypeError("PID(kp, ki, kd[, POn], direction): POn and direction positionally or by keyword")
        if len(pon_dir) == 2:
            p_on, direction = pon_dir
        elif len(pon_dir) == 1:
            direction = pon_dir[0]
        p_on = P_ON_E if p_on is None else p_on
        direction = DIRECT if direction is None else direction
        if millis is None:
            raise TypeError("PID needs millis=callable returning the Arduino millis() value")
        self._millis = millis
        self._input = _f32(0)
        self._output = _f32(0)
        self._setpoint = _f32(0)
        # members of a global object are zero-initialised (.bss)
        self.disp_kp = self.disp_ki = self.disp_kd = _f32(0)
        self.kp = self.ki = self.kd = _f32(0)
        self.controller_direction = DIRECT
        self.p_on = P_ON_E
        self.last_time = 0
        self.output_sum = _f32(0)
        self.last_input = _f32(0)
        self.sample_time = 0
        self.out_min = self.out_max = _f32(0)
        self.in_auto = False
        self.p_on_e = False

        self.set_output_limits(0, 255)   # default output limit corresponds to the arduino pwm limits
        self.sample_time = 100           # default Controller Sample Time is 0.1 seconds
        self.set_controller_direction(direction)
        self.set_tunings(kp, ki, kd, p_on)
        self.last_time = _ulong(self._millis() - self.sample_time)

    # the user's variables behind myInput / myOutput / mySetpoint
    @property
    def input(self) -> float:
        return float(self._input)

    @input.setter
    def input(self, v: float) -> None:
        self._input = _f32(v)

    @property
    def output(self) -> float:
        return float(self._output)

    @output.setter
    def output(self, v: float) -> None:
        self._output = _f32(v)

    @property
    def setpoint(self) -> float:
        return float(self._setpoint)

    @setpoint.setter
    def setpoint(self, v: float) -> None:
        self._setpoint = _f32(v)

    def compute(self) -> bool:
        if not self.in_auto:
            return False
        now = _ulong(self._millis())
        time_change = _ulong(now - self.last_time)
        if time_change >= self.sample_time:
            # Compute all the working error variables
            input = self._input
            error = self._setpoint - input
            d_input = input - self.last_input
            self.output_sum = self.output_sum + self.ki * error

            # Add Proportional on Measurement if P_ON_M is specified
            if not self.p_on_e:
                self.output_sum = self.output_sum - self.kp * d_input

            if self.output_sum > self.out_max:
                self.output_sum = self.out_max
            elif self.output_sum < self.out_min:
                self.output_sum = self.out_min

            # Add Proportional on Error if P_ON_E is specified
            if self.p_on_e:
                output = self.kp * error
            else:
                output = _ZERO

            # Compute Rest of PID Output
            output = output + (self.output_sum - self.kd * d_input)

            if output > self.out_max:
                output = self.out_max
            elif output < self.out_min:
                output = self.out_min
            self._output = output

            # Remember some variables for next time
            self.last_input = input
            self.last_time = now
            return True
        return False

    def set_tunings(self, kp: float, ki: float, kd: float, p_on: int | None = None) -> None:
        if p_on is None:  # the 3-argument overload: the last-remembered POn
            p_on = self.p_on
        kp, ki, kd = _f32(kp), _f32(ki), _f32(kd)
        if kp < 0 or ki < 0 or kd < 0:
            return

        self.p_on = p_on
        self.p_on_e = p_on == P_ON_E

        self.disp_kp, self.disp_ki, self.disp_kd = kp, ki, kd

        sample_time_in_sec = _f32(self.sample_time) / _THOUSAND
        self.kp = kp
        self.ki = ki * sample_time_in_sec
        self.kd = kd / sample_time_in_sec

        if self.controller_direction == REVERSE:
            self.kp = _ZERO - self.kp
            self.ki = _ZERO - self.ki
            self.kd = _ZERO - self.kd

    def set_sample_time(self, new_sample_time: int) -> None:
        new_sample_time = _int16(new_sample_time)
        if new_sample_time > 0:
            ratio = _f32(new_sample_time) / _f32(self.sample_time)
            self.ki = self.ki * ratio
            self.kd = self.kd / ratio
            self.sample_time = _ulong(new_sample_time)

    def set_output_limits(self, lo: float, hi: float) -> None:
        lo, hi = _f32(lo), _f32(hi)
        if lo >= hi:
            return
        self.out_min = lo
        self.out_max = hi

        if self.in_auto:
            if self._output > self.out_max:
                self._output = self.out_max
            elif self._output < self.out_min:
                self._output = self.out_min

            if self.output_sum > self.out_max:
                self.output_sum = self.out_max
            elif self.output_sum < self.out_min:
                self.output_sum = self.out_min

    def set_mode(self, mode: int) -> None:
        new_auto = mode == AUTOMATIC
        if new_auto and not self.in_auto:
            # we just went from manual to auto
            self._initialize()
        self.in_auto = new_auto

    def _initialize(self) -> None:
        self.output_sum = self._output
        self.last_input = self._input
        if self.output_sum > self.out_max:
            self.output_sum = self.out_max
        elif self.output_sum < self.out_min:
            self.output_sum = self.out_min

    def set_controller_direction(self, direction: int) -> None:
        if self.in_auto and direction != self.controller_direction:
            self.kp = _ZERO - self.kp
            self.ki = _ZERO - self.ki
            self.kd = _ZERO - self.kd
        self.controller_direction = direction

    def get_kp(self) -> float:
        return float(self.disp_kp)

    def get_ki(self) -> float:
        return float(self.disp_ki)

    def get_kd(self) -> float:
        return float(self.disp_kd)

    def get_mode(self) -> int:
        return AUTOMATIC if self.in_auto else MANUAL

    def get_direction(self) -> int:
        return self.controller_direction
