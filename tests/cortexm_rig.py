"""A bare Cortex-M for runtime tests: kernel, bus, NVIC, SCB, SysTick, CPU and RTOS at 216 MHz
(one core cycle is one base tick)."""

from mcusim.periph.cortexm.systick import SysTick

from mcusim.firmware import Cpu, Rtos
from mcusim.irq import Nvic, Scb
from mcusim.kernel import Kernel
from mcusim.mcu import Mcu
from mcusim.registers import Bus
from mcusim.time import TimeBase

NVIC = 0xE000E100


def rig():
    tb = TimeBase([216_000_000])
    k = Kernel(tb)
    bus = Bus()
    core = tb.clock("core", 216_000_000)
    mcu = Mcu("t", k, bus, core)
    mcu.nvic = Nvic()
    bus.attach(NVIC, mcu.nvic)
    bus.attach(0xE000ED00, Scb(mcu.nvic))
    bus.attach(0xE000E010, SysTick("SysTick", mcu, core, tb.clock("ref", 27_000_000)))
    mcu.cpu = Cpu(k, core, mcu.nvic)
    mcu.rtos = Rtos(mcu.cpu)
    return mcu


def enable(m, n, prio):
    m.write32(NVIC + 4 * (n >> 5), 1 << (n & 31))          # ISER
    m.write8(NVIC + 0x300 + n, prio << 4)                   # IPR byte, 4 implemented bits
