"""EDU-CIAA-NXP board support for ``rover_control``: pins, the battery ADC, the system timer.

Everything here goes through the LPC4337's registers on the MCU bus, as NuttX's board code and
drivers do (``lpc43_gpio_write``/``lpc43_gpio_read`` on the GPIO port block, the ADC's CR/STAT/DRn,
the Cortex-M SysTick). Pins are those of the EDU-CIAA-NXP schematic: the free GPIO pins
of header P2 for the E-stop input, the motor-enable output and the buzzer, and the board LEDs.

The battery ADC read is a software-started single conversion on ADC0 (CR.START = 001, poll
STAT.DONEn, read DRn, clear START), as sAPI's ``adcRead`` does at 200 kS/s (CLKDIV = 92 with a
204 MHz APB3). NuttX's ``lpc43_adc.c`` lower half offers either one conversion per open() or
continuous burst conversions with one interrupt per scan (§1.6), which at a MHz ADC clock is
~10^5 interrupts per second for a voltage that changes over seconds; the port reads one sample per
battery period instead (the deviation from NuttX is this driver, not the monitor's logic).
"""

from __future__ import annotations

GPIO_BASE = 0x400F4000
GPIO_DIR, GPIO_PIN, GPIO_SET, GPIO_CLR = 0x2000, 0x2100, 0x2200, 0x2280

ADC0_BASE = 0x400E3000
ADC_CR, ADC_STAT, ADC_DR0 = 0x000, 0x030, 0x010
ADC_CR_PDN, ADC_CR_START_NOW = 1 << 21, 1 << 24
ADC_DR_DONE = 1 << 31
ADC_CLKDIV_200KSPS = 92          # sAPI adcInit at 204 MHz: 2.1935 MHz ADC clock, 199.4 kS/s

SYST_CSR, SYST_RVR, SYST_CVR = 0xE000E010, 0xE000E014, 0xE000E018
SCB_SHPR3 = 0xE000ED20

# (port, bit) of the pins rover_control uses (EDU-CIAA header P2 and on-board LEDs, §2.4)
PINS = {
    "ESTOP": (3, 0),     # P2 "GPIO0" (P6_1): E-stop sense, active low, pulled up
    "MOTOR_EN": (3, 3),  # P2 "GPIO1" (P6_4): motor-enable line to the IBT-2 INH pins (via the E-stop)
    "BUZZER": (3, 4),    # P2 "GPIO2" (P6_5): buzzer driver, active high
    "LED1": (0, 14),     # P2_10: heartbeat
    "LED2": (1, 11),     # P2_11: fault
    "LED3": (1, 12),     # P2_12: motors enabled
}


class CiaaBoard:
    def __init__(self, mcu, adc_clkdiv: int = ADC_CLKDIV_200KSPS):
        self.mcu, self.bus = mcu, mcu.bus
        self.adc = mcu.periph.get("ADC0")
        self.adc_clkdiv = adc_clkdiv        # CR.CLKDIV: PCLK / (CLKDIV + 1) is the ADC clock

    # --- GPIO (lpc43_gpio_config / lpc43_gpio_write / lpc43_gpio_read) ------------------------
    def gpio_config_output(self, pin: str, level: int = 0) -> None:
        port, bit = PINS[pin]
        self.gpio_write(pin, level)
        d = self.bus.read32(GPIO_BASE + GPIO_DIR + 4 * port)
        self.bus.write32(GPIO_BASE + GPIO_DIR + 4 * port, d | (1 << bit))

    def gpio_config_input(self, pin: str) -> None:
        port, bit = PINS[pin]
        d = self.bus.read32(GPIO_BASE + GPIO_DIR + 4 * port)
        self.bus.write32(GPIO_BASE + GPIO_DIR + 4 * port, d & ~(1 << bit))

    def gpio_write(self, pin: str, level) -> None:
        port, bit = PINS[pin]
        reg = GPIO_SET if level else GPIO_CLR
        self.bus.write32(GPIO_BASE + reg + 4 * port, 1 << bit)

    def gpio_read(self, pin: str) -> int:
        port, bit = PINS[pin]
        return (self.bus.read32(GPIO_BASE + GPIO_PIN + 4 * port) >> bit) & 1

    # --- ADC0 single conversion -------------------------------------------------------------
    def adc_init(self) -> None:
        self.bus.write32(ADC0_BASE + ADC_CR, ADC_CR_PDN | self.adc_clkdiv << 8)

    async def adc_read(self, rtos, channel: int) -> int:
        """One conversion of ``channel``: the 10-bit code."""
        cr = ADC_CR_PDN | self.adc_clkdiv << 8 | 1 << channel
        self.bus.write32(ADC0_BASE + ADC_CR, cr | ADC_CR_START_NOW)
        while not self.bus.read32(ADC0_BASE + ADC_STAT) & (1 << channel):
            await rtos.wait_signal(self.adc.done)     # the busy-wait, without one pass per poll
        dr = self.bus.read32(ADC0_BASE + ADC_DR0 + 4 * channel)
        self.bus.write32(ADC0_BASE + ADC_CR, cr)        # START = 000 (sAPI clears it after the read)
        return (dr >> 6) & 0x3FF

    # --- system timer (NuttX arm up_timer_initialize on SysTick) ------------------------------
    def systick_init(self, core_hz: int, tick_hz: int) -> None:
        reload = core_hz // tick_hz - 1
        if not 0 < reload < 1 << 24:
            raise ValueError(f"SysTick reload {reload} does not fit 24 bits")
        shpr3 = self.bus.read32(SCB_SHPR3)
        self.bus.write32(SCB_SHPR3, (shpr3 & 0x00FFFFFF) | (0xE0 << 24))   # lowest of 8 priorities
        self.bus.write32(SYST_RVR, reload)
        self.bus.write32(SYST_CVR, 0)
        self.bus.write32(SYST_CSR, 0b111)          # processor clock, TICKINT, ENABLE
