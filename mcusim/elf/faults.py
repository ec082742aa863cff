"""What the compiled-firmware core says when an image cannot load or faults, in the user's terms:
the address and region of a failed fetch, the invalid state of a branch with bit 0 clear and its
caller, a BKPT without a debugger (semihosting), unicorn's own errors, and an image too big for
the board's memory. :class:`mcusim.elf.core.CortexMCore` raises them (its HardFault report adds
the PC, its function and the simulated time)."""

from __future__ import annotations

from unicorn import arm_const as A

CPU_EXCEPTIONS = {   # QEMU's exception numbers, as unicorn reports them
    4: "data abort",
    17: "no coprocessor (a floating-point instruction with the FPU disabled)",
    18: "invalid state (a branch to an address with bit 0 clear: EPSR.T = 0, ARM state does not exist "
        "on Cortex-M; an INVSTATE UsageFault on the chip)",
    19: "invalid PC on exception return",
}

# Armv7-M ARM B3.1, the default memory map: regions that are Execute Never
XN_REGIONS = ((0x40000000, 0x60000000, "Peripheral"), (0xA0000000, 0xE0000000, "Device"),
              (0xE0000000, 1 << 32, "System"))


def unmapped_hint(address, kind) -> str:
    """Why nothing answers at ``address``, where the default memory map says what lives there:
    a peripheral the board does not model is more likely than a bad pointer."""
    if kind == "cortex-m4" and (0x22000000 <= address < 0x24000000 or 0x42000000 <= address < 0x44000000):
        return " (a bit-band alias: bit-banding is not modelled)"
    if 0x40000000 <= address < 0x60000000:
        return " (Peripheral region: a peripheral this board does not model, or a wrong address)"
    if 0xE0000000 <= address < 0xE0100000:
        return " (a Cortex-M system register mcusim does not model)"
    return ""


def fetch_fault(address) -> str:
    """An instruction fetch that failed at ``address``: from an Execute Never region, or from
    where there is no code."""
    for lo, hi, name in XN_REGIONS:
        if lo <= address < hi:
            return (f"instruction fetch from {address:#010x}, in the {name} region, which is Execute Never "
                    "(a MemManage fault on the chip)")
    return f"instruction fetch from {address:#010x}, where there is no code (prefetch abort)"


def invstate(core, pc) -> str:
    """A branch to ``pc`` with bit 0 clear, and the caller LR names."""
    lr = core.uc.reg_read(A.UC_ARM_REG_LR)
    return (f"{CPU_EXCEPTIONS[18]}; branched to {pc:#010x}, LR {lr:#010x} "
            f"({core.where(lr & ~1)}, after the call if it was one)")


def uc_error_text(err) -> str:
    """Unicorn's error, said as the kind of access it was."""
    text = str(err)
    if "UNMAPPED" in text.upper():
        return f"access to unmapped memory ({text})"
    if "PROT" in text.upper():
        return f"access the memory does not allow ({text}; flash is not written by a store)"
    if "INSN" in text.upper():
        return "undefined instruction"
    return text


def bkpt_text(core, pc) -> str:
    """A BKPT without a debugger (on the chip it escalates to HardFault): its immediate, and for
    0xAB what that is (an Arm semihosting call, which needs a host to answer it)."""
    try:
        imm = core.read(pc & ~1, 2)[0]
    except Exception:   # noqa: BLE001 (unicorn's UcError: nothing readable there)
        return "BKPT with no debugger attached"
    if imm == 0xAB:
        return ("BKPT #0xab, a semihosting call, with no debugger attached to answer it: semihosting "
                "is not supported (link with --specs=nosys.specs instead of rdimon.specs, or drop "
                "initialise_monitor_handles)")
    return f"BKPT #{imm:#04x} with no debugger attached"


def outside(core, image, seg) -> str:
    """What a loadable segment that does not fit the board's memory overflows: its sections, and
    by how many bytes it runs past the memory it starts in."""
    what = f" ({', '.join(seg.sections)})" if seg.sections else ""
    start, size = seg.address, len(seg.data)
    m, off = core._region(start, 1)
    if m is None:
        names = ", ".join(f"{x.name} {x.base:#010x}-{x.base + x.size - 1:#010x}" for x in core.memories)
        return (f"{image.path}: a loadable segment{what} at {start:#010x} ({size} bytes) lies outside "
                f"the board's memory ({names})")
    end = start - off + m.size
    m, off = core._region(end, 1)
    while m is not None:        # (memories that follow each other, as DTCM and SRAM1, are one span)
        end += m.size - off
        m, off = core._region(end, 1)
    return (f"{image.path}: a loadable segment{what} at {start:#010x} ({size} bytes) overflows the "
            f"board's memory by {start + size - end} bytes: it runs to {start + size - 1:#010x}, the "
            f"memory from {start:#010x} ends at {end - 1:#010x}")
