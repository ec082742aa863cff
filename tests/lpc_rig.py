"""A bare LPC4337 (Cortex-M4 at 204 MHz) for peripheral tests: kernel, bus, NVIC (3 priority
bits, 53 interrupts), SCB, and optionally the CPU runtime (12-cycle entry) and an RTOS.
Peripherals are added by each test: ``periph = Adc("ADC0", mcu, mcu.core_clock, ...)``,
``mcu.bus.attach(0x400E3000, periph)``.

``extra_hz`` adds clocks to the time base (a 16 MHz AVR on the same bus, for example)."""

from mcusim.firmware import Cpu, Rtos
from mcusim.irq import Nvic, Scb
from mcusim.kernel import Kernel
from mcusim.mcu import Mcu
from mcusim.registers import Bus
from mcusim.time import TimeBase

CORE_HZ = 204_000_000


def bare_lpc4337(cpu: bool = False, extra_hz=()) -> Mcu:
    tb = TimeBase([CORE_HZ, *extra_hz])
    clock = tb.clock("BASE_M4", CORE_HZ)
    mcu = Mcu("LPC4337", Kernel(tb), Bus("lpc4337.bus"), clock)
    mcu.clocks["SYSCLK"] = clock
    mcu.irq = mcu.nvic = Nvic(num_irqs=53, prio_bits=3)
    mcu.bus.attach(0xE000E100, mcu.nvic)
    mcu.bus.attach(0xE000ED00, Scb(mcu.nvic))
    if cpu:
        mcu.cpu = Cpu(mcu.kernel, clock, mcu.irq, entry_latency=12)
        mcu.rtos = Rtos(mcu.cpu)
    return mcu
