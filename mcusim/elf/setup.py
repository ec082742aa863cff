"""Building the compiled-firmware side of a board: memories, core, system registers, firmware."""

from __future__ import annotations

from ..errors import ConfigError
from .image import read_elf
from .memory import build_memories


def check_elf_board(profile: dict, where: str, path) -> tuple:
    """The ELF and the board's memories, or ConfigError if this board cannot run it."""
    core = profile.get("core", {})
    if not str(core.get("kind", "")).startswith("cortex-m"):
        raise ConfigError(f"{where}: --firmware runs a Cortex-M ELF; this board's core is {core.get('kind')!r}")
    if not profile.get("memory"):
        raise ConfigError(f"{where}: the board declares no [[memory]] regions, so it cannot load an ELF "
                          "(see docs/boards.md, [[memory]])")
    image = read_elf(path)
    return image, build_memories(profile["memory"])


def attach_memories(bus, memories) -> None:
    for m in memories:
        for base in (m.base, *m.aliases):
            bus.attach(base, m, m.size)


def build_core(profile: dict, mcu, image, memories):
    """The unicorn core, the SCB/DWT/FPU/STIR/CoreDebug/MPU/ITM registers (and the Cortex-M7's
    cache maintenance operations); returns the core."""
    from .core import CortexMCore
    from .scb import CoreDebug, CoreScb, Dwt, Fpu, Stir
    from .scs_extra import CacheMaintenance, Itm, Mpu, ScnScb
    core_spec = profile["core"]
    kind = core_spec.get("kind", "cortex-m4")
    boot = core_spec.get("boot_address", 0)
    # a vector table is aligned to its size rounded up to a power of two, at least 128 bytes
    # (ARMv7-M ARM B3.2.5, VTOR): 16 system entries and the NVIC's lines, 4 bytes each
    size = 4 * (16 + core_spec.get("nvic_irqs", 98))
    align = max(128, 1 << (size - 1).bit_length())
    if boot % align:
        msg = (f"[core] boot_address = {boot:#x}: a vector table of {size // 4} entries is aligned to "
               f"{align} bytes; the nearest are {boot - boot % align:#x} and {boot - boot % align + align:#x}")
        raise profile.err(msg, "core", None, "boot_address") if hasattr(profile, "err") else ConfigError(msg)
    bus = mcu.bus
    dwt, fpu = Dwt(mcu), Fpu("FPU")
    bus.attach(0xE000EDF0, CoreDebug(dwt))
    bus.attach(0xE000EF00, Stir(mcu.nvic))
    bus.attach(0xE000EF30, fpu)
    bus.attach(0xE0001000, dwt)
    bus.attach(0xE0000000, Itm("ITM"))
    bus.attach(0xE000E000, ScnScb(core_spec.get("nvic_irqs", 98)))
    bus.attach(0xE000ED90, Mpu())
    if kind == "cortex-m7":
        bus.attach(0xE000EF50, CacheMaintenance("CACHE"))
    core = CortexMCore(mcu, image, memories, kind=kind, cpi=core_spec.get("cycles_per_instruction", 1),
                       entry_latency=core_spec.get("entry_latency", 12),
                       boot_address=boot)
    fpu.exc = core.exc
    scb = CoreScb(mcu.nvic, core.exc, kind)
    bus.attach(0xE000ED00, scb)           # on the NVIC's page, already mapped into the core
    mcu.periph["SCB"] = scb
    return core
