"""main.c of the ControlMotorROS firmware: pin and timer setup, two FreeRTOS PID tasks and the
micro-ROS app with the topics ``/motorN/set_pos`` (rad, subscribed), ``/motorN/enable`` (bool,
subscribed) and ``/motorN/get_pos`` (rad, published), N = 1, 2.

Board wiring (thesis pin table): bridge A = TIM1 CH1/CH2 on PE9/PE11, EN-A on PF15; bridge B =
TIM2 CH1/CH4 on PA5/PA3, EN-B on PF5; motor 1 encoder = TIM3 on PB4/PB5; motor 2 encoder = TIM4 on
PD12/PD13.

Where the thesis gives no figure, these are our choices (all overridable as ``firmware.<name>``):
PID period 5 ms, executor spin 10 ms, the gains below, and the declared cycle costs. The micro-ROS
transport is not simulated: a message published by the host is taken by the executor at its next
spin, as rclc_executor_spin_some would find it.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

from mcusim.fw.controlmotor import VARIANTS
from mcusim.fw.controlmotor.encoder import (
    Encoder,
    encoder_get_position,
    encoder_set_reset,
    encoder_timn_start,
    encoder_update_callback,
)
from mcusim.fw.controlmotor.pid_controller import BRIDGE_A, BRIDGE_B, PidController
from mcusim.fw.controlmotor.pwm import Pwm, pwm_enable, pwm_timn_set_duty, pwm_timn_start
from mcusim.fw.stm32hal import cortex
from mcusim.fw.stm32hal import gpio as hal_gpio
from mcusim.fw.stm32hal import tim as hal_tim
from mcusim.fw.stm32hal.rcc import SystemCoreClock
from mcusim.fw.stm32hal.regs import Stm32f7

from mcusim.errors import ConfigError
from mcusim.params import Param, firmware_params, shortest_f32

TIM3_IRQn, TIM4_IRQn = 29, 30
configTICK_RATE_HZ = 1000

DEFAULTS = {
    "variant": Param("correct", choices=VARIANTS, doc="\"thesis\" runs the literal code with its two bugs"),
    "pid_period_ms": Param(5, min=1, max=1000, unit="ms", doc="period of the two PID tasks (FreeRTOS ticks of 1 ms)"),
    "executor_period_ms": Param(10, min=1, max=1000, unit="ms", doc="micro-ROS executor spin period"),
    # gains tuned on this model for a 1.57 rad step: 2.8 % overshoot, within 3 counts after 0.71 s,
    # no OCD trip (τD = 0.02 s overshoots 0.23 rad and trips the OCD when braking from full speed)
    "kp": Param(400.0, min=0, max=1e6, unit="%/rad", doc="duty per rad of output-shaft error"),
    "kd": Param(0.05, min=0, max=100, unit="s", doc="derivative time τD"),
    "ki": Param(0.25, min=0, max=1e4, unit="s", doc="integral time τI (0: no integral action)"),
    "windup_limit": Param(2.0, min=0, max=1e6, unit="rad·samples", doc="bound on the error sum"),
    "encoder_filter": Param(0, min=0, max=15, doc="ICxF input filter of the encoder timers"),
    # ARR = counts - 1 must fit the 16-bit encoder timers; one quadrature cycle is 4 counts
    "counts_per_turn": Param(1920, min=4, max=65536, unit="counts/output turn",
                             doc="encoder counts per output-shaft turn (64 CPR x 30:1); variant thesis: at most 65535"),
    # declared execution costs in core cycles (estimates for -O2 code on the M7 with FPU)
    "cycles_pid": Param(1500, min=0, max=10_000_000, unit="cycles", doc="cost of one PID step"),
    "cycles_encoder_isr": Param(120, min=0, max=1_000_000, unit="cycles", doc="cost of the encoder ISR"),
    "cycles_systick": Param(150, min=0, max=100_000, unit="cycles", doc="cost of the SysTick handler"),
    "cycles_executor": Param(6000, min=0, max=10_000_000, unit="cycles", doc="cost of one executor spin"),
}
# what a host may send (``--set /motor1/set_pos=1.57``): |set point| up to 1000 rad (159 output
# turns, about half a minute at full speed) keeps a typo from becoming a run that never settles
SET_POS = Param(0.0, min=-1000.0, max=1000.0, unit="rad", doc="output-shaft angle set point")
ENABLE = Param(True, doc="bridge enable")
# the topics a host publishes to (``--set /motor1/set_pos=1.57``), n = 1, 2 (mcusim boards --kinds)
INPUTS = {"/motor<n>/set_pos": SET_POS, "/motor<n>/enable": ENABLE}


@dataclass
class Topic:
    name: str
    type: type
    direction: str           # "sub" (host -> firmware) or "pub" (firmware -> host)
    value: object = None
    count: int = 0


class ControlMotorFirmware:
    PARAMS = DEFAULTS            # declared parameters (firmware.<name>), checked by mcusim.params
    CORE = "cortex-m"            # the cores it runs on (a profile's [core] kind starts with it)
    INPUTS = INPUTS              # the topics a host publishes to, checked (mcusim boards --kinds)

    def __init__(self, mcu, **params):
        self.p = firmware_params(DEFAULTS, params)
        self.mcu, self.cpu, self.rtos = mcu, mcu.cpu, mcu.rtos
        self.dev = Stm32f7(mcu.bus)
        self.pid = PidController()
        self.enabled = {BRIDGE_A: True, BRIDGE_B: True}
        self.topics: dict[str, Topic] = {}
        for n in (1, 2):
            self.topics[f"/motor{n}/set_pos"] = Topic(f"/motor{n}/set_pos", float, "sub")
            self.topics[f"/motor{n}/enable"] = Topic(f"/motor{n}/enable", bool, "sub")
            self.topics[f"/motor{n}/get_pos"] = Topic(f"/motor{n}/get_pos", float, "pub")
        self._inbox: list[tuple[str, object]] = []
        self.main()

    # --- host side of the micro-ROS topics --------------------------------------------------
    def check_input(self, name: str, value):
        """The message ``value`` for topic ``name`` as the topic's type, or ConfigError."""
        topic = self.topics.get(name)
        if topic is None or topic.direction != "sub":
            subs = [t for t in self.topics if self.topics[t].direction == "sub"]
            raise ConfigError(f"no subscribed topic {name!r}; the firmware subscribes to {', '.join(subs)}")
        return (SET_POS if topic.type is float else ENABLE).check(value, name)

    def publish(self, name: str, value) -> None:
        self._inbox.append((name, self.check_input(name, value)))

    def topic(self, name: str):
        if name not in self.topics:
            raise ConfigError(f"no topic {name!r}; topics: {', '.join(self.topics)}")
        return self.topics[name].value

    def set_point(self, motor: int) -> float:
        """The PID's set point (a float32 in the C) as the shortest decimal of that float32, as a
        host reads a float: the 1.57 published reads 1.57."""
        return shortest_f32(float(self.pid.pids[motor - 1].set_point))

    def csv_columns(self, motors: list[str], member: str) -> list[tuple[str, object]]:
        """(column, getter) of the variables a CSV trace samples (mcusim.csvtrace): per motor the
        PID set point, the duty and the position the firmware publishes."""
        cols = []
        for n in (1, 2):
            prefix = motors[n - 1] if len(motors) >= n else f"motor{n}"
            cols += [(f"{prefix}.setpoint_rad", lambda n=n: self.set_point(n)),
                     (f"{prefix}.duty_pct", lambda b=n - 1: self.pwm[b].duty),
                     (f"{prefix}.fw_position_rad", lambda n=n: self.topics[f"/motor{n}/get_pos"].value)]
        return cols

    # --- main.c -------------------------------------------------------------------------------
    def main(self) -> None:
        dev, v = self.dev, self.p["variant"]
        self.MX_GPIO_Init()
        self.htim1 = hal_tim.TIM_HandleTypeDef(dev.TIM1)
        self.htim2 = hal_tim.TIM_HandleTypeDef(dev.TIM2)
        self.htim3 = hal_tim.TIM_HandleTypeDef(dev.TIM3)
        self.htim4 = hal_tim.TIM_HandleTypeDef(dev.TIM4)
        self.pwm = {
            BRIDGE_A: Pwm(self.htim1, 2, hal_tim.TIM_CHANNEL_1, hal_tim.TIM_CHANNEL_2, dev.GPIOF, 15, v),
            BRIDGE_B: Pwm(self.htim2, 1, hal_tim.TIM_CHANNEL_1, hal_tim.TIM_CHANNEL_4, dev.GPIOF, 5, v),
        }
        cpt, filt = self.p["counts_per_turn"], self.p["encoder_filter"]
        if v == "thesis" and cpt > 0xFFFF:
            # the thesis sets ARR = counts per turn: 65536 reads back as 0 from the 16-bit ARR,
            # which stops the counter, and its CNT/ARR then divides by zero
            raise ConfigError(f"firmware.counts_per_turn = {cpt} with firmware.variant = 'thesis': the thesis "
                              f"sets ARR = counts per turn, which the 16-bit encoder timers cannot hold "
                              f"(at most 65535 there; the correct variant sets ARR = counts - 1)")
        self.enc = {
            BRIDGE_A: Encoder(self.htim3, cpt, TIM3_IRQn, v, filter=filt),
            BRIDGE_B: Encoder(self.htim4, cpt, TIM4_IRQn, v, filter=filt),
        }
        period = self.p["pid_period_ms"] / 1000
        for b in (BRIDGE_A, BRIDGE_B):
            pwm_timn_start(self.pwm[b])
            pwm_enable(self.pwm[b], True)
            self.pid.pid_set_parameters(b, self.p["kp"], self.p["kd"], self.p["ki"], self.p["windup_limit"])
            self.pid.pid_set_period(b, period)
            self.pid.pid_reset(b)
        for b, irqn in ((BRIDGE_A, TIM3_IRQn), (BRIDGE_B, TIM4_IRQn)):
            self.cpu.vector(irqn, (lambda e=self.enc[b]: self.encoder_irq_handler(e)),
                            cost=self.p["cycles_encoder_isr"])
            cortex.HAL_NVIC_SetPriority(dev, irqn, 5)
            cortex.HAL_NVIC_EnableIRQ(dev, irqn)
            encoder_timn_start(self.enc[b])
        # FreeRTOS: tasks, then vTaskStartScheduler (SysTick at configTICK_RATE_HZ)
        self.cpu.vector(cortex.SysTick_IRQn, self.rtos.systick_handler, cost=self.p["cycles_systick"])
        self.rtos.create_task("pid_a", partial(self.pid_task, BRIDGE_A), priority=3)
        self.rtos.create_task("pid_b", partial(self.pid_task, BRIDGE_B), priority=3)
        self.rtos.create_task("microros", self.microros_task, priority=2)
        cortex.HAL_SYSTICK_Config(dev, SystemCoreClock // configTICK_RATE_HZ)

    def MX_GPIO_Init(self) -> None:
        dev = self.dev
        dev.RCC.AHB1ENR = dev.RCC.AHB1ENR | 0b111111  # GPIOA..F clocks
        dev.RCC.APB2ENR = dev.RCC.APB2ENR | 0b1       # TIM1
        dev.RCC.APB1ENR = dev.RCC.APB1ENR | 0b111     # TIM2, TIM3, TIM4
        out = {"Mode": hal_gpio.GPIO_MODE_OUTPUT_PP, "Pull": hal_gpio.GPIO_NOPULL}
        for port, pin in ((dev.GPIOF, 15), (dev.GPIOF, 5)):
            hal_gpio.HAL_GPIO_WritePin(port, pin, 0)
            hal_gpio.HAL_GPIO_Init(port, hal_gpio.GPIO_InitTypeDef(pin, **out))
        for port, pin, af in ((dev.GPIOE, 9, 1), (dev.GPIOE, 11, 1), (dev.GPIOA, 5, 1), (dev.GPIOA, 3, 1),
                              (dev.GPIOB, 4, 2), (dev.GPIOB, 5, 2), (dev.GPIOD, 12, 2), (dev.GPIOD, 13, 2)):
            hal_gpio.HAL_GPIO_Init(port, hal_gpio.GPIO_InitTypeDef(
                pin, Mode=hal_gpio.GPIO_MODE_AF_PP, Pull=hal_gpio.GPIO_NOPULL,
                Speed=hal_gpio.GPIO_SPEED_FREQ_VERY_HIGH, Alternate=af))

    # --- interrupts -------------------------------------------------------------------------
    def encoder_irq_handler(self, enc: Encoder) -> None:
        """TIM3_IRQHandler / TIM4_IRQHandler -> HAL_TIM_IRQHandler -> PeriodElapsedCallback."""
        hal_tim.HAL_TIM_IRQHandler(enc.htim, lambda h: encoder_update_callback(enc))

    # --- tasks --------------------------------------------------------------------------------
    async def pid_task(self, bridge: int):
        period_ticks = self.p["pid_period_ms"] * configTICK_RATE_HZ // 1000
        wake = self.rtos.tick_count
        while True:
            if self.enabled[bridge]:
                position = encoder_get_position(self.enc[bridge])
                await self.cpu.cycles(self.p["cycles_pid"])
                duty = self.pid.pid_apply(bridge, position)
                pwm_timn_set_duty(self.pwm[bridge], duty)
            wake += period_ticks
            await self.rtos.delay_until(wake)

    async def microros_task(self):
        period_ticks = self.p["executor_period_ms"] * configTICK_RATE_HZ // 1000
        wake = self.rtos.tick_count
        while True:
            await self.cpu.cycles(self.p["cycles_executor"])
            inbox, self._inbox = self._inbox, []
            for name, value in inbox:  # subscription callbacks
                motor = int(name[6])
                bridge = motor - 1
                self.topics[name].value = value
                self.topics[name].count += 1
                if name.endswith("/set_pos"):
                    self.pid.pid_set_point(bridge, value)
                elif name.endswith("/enable"):
                    self.set_enable(bridge, value)
            for b, n in ((BRIDGE_A, 1), (BRIDGE_B, 2)):  # publishers
                t = self.topics[f"/motor{n}/get_pos"]
                # a float message: the host reads it as the shortest decimal of the float32, as it
                # reads an image's f32 topic (docs/firmware.md)
                t.value = shortest_f32(encoder_get_position(self.enc[b]))
                t.count += 1
            wake += period_ticks
            await self.rtos.delay_until(wake)

    def set_enable(self, bridge: int, enable: bool) -> None:
        if enable and not self.enabled[bridge]:
            self.pid.pid_reset(bridge)
        if not enable:
            pwm_timn_set_duty(self.pwm[bridge], 0.0)
        pwm_enable(self.pwm[bridge], enable)
        self.enabled[bridge] = enable

    def reset_position(self, bridge: int) -> None:
        encoder_set_reset(self.enc[bridge])
