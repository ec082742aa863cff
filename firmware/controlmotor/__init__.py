"""Port of the ControlMotorROS thesis firmware (STM32F746 + X-NUCLEO-IHM04A1, two gearmotors).

Modules mirror the C sources: ``pwm`` (pwm.c), ``encoder`` (encoder.c), ``pid_controller``
(pid_controller.c) and ``app`` (main.c: FreeRTOS PID tasks and the micro-ROS topic app).

Two bugs of the thesis are kept reachable with ``variant="thesis"``; the default ``"correct"``
fixes them (see each module):

1. position = revolutions + CNT/ARR·2π — the 2π applies to the revolutions too, and with
   ARR = pulses per turn one turn is ARR+1 counts;
2. ARR = 4319 for both PWM timers assumes a 216 MHz timer clock, but TIM2 counts at 108 MHz
   (APB1 /4, TIMPRE = 0), so bridge B runs at 25 kHz instead of 50 kHz.
"""

VARIANTS = ("correct", "thesis")
