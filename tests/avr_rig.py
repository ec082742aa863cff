"""A bare ATmega328P at 16 MHz for peripheral tests: kernel, data bus, interrupt controller, SREG,
and optionally the CPU runtime (4-cycle entry). Peripherals are added by each test."""

from mcusim.periph.avr.cpu import AvrCpuRegs

from mcusim.firmware import Cpu, Rtos
from mcusim.irq import AvrInterrupts
from mcusim.kernel import Kernel
from mcusim.mcu import Mcu
from mcusim.registers import Bus
from mcusim.time import TimeBase


def bare_atmega328p(cpu: bool = False, engine: str = "reference") -> Mcu:
    tb = TimeBase([16_000_000])
    clock = tb.clock("cpu", 16_000_000)
    mcu = Mcu("atmega328p", Kernel(tb, engine=engine), Bus(), clock)
    mcu.irq = mcu.nvic = AvrInterrupts()
    mcu.bus.attach_registers(0, AvrCpuRegs("CPU", mcu))
    if cpu:
        mcu.cpu = Cpu(mcu.kernel, clock, mcu.irq, entry_latency=4)
        mcu.rtos = Rtos(mcu.cpu)
    return mcu
