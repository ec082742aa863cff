"""Fast-forward through idle loops: the core at a branch to itself (``for (;;) {}``, ``b .``).

``while (1) {}`` at the end of ``main`` with the work in interrupt handlers is the commonest shape
of firmware, and spun instruction by instruction it costs the block hook's Python once per
instruction (about 1.4 million a second). Nothing in such a loop can change anything: it makes
no access, sets no flag, pends nothing, so an interrupt is taken only when a quantum starts
(after a kernel event) and the loop spins until the quantum's count runs out. The core therefore
retires the whole quantum at once, PC still at the loop: the same instruction count and the same
time as spinning (DWT CYCCNT reads the time), the same next quantum, so every interrupt is
entered at the same tick and the register log and the VCD are the same. With PRIMASK set the
quanta simply run to the end of the run.

A branch to itself: T2 ``B`` with offset -4 (0xE7FE) or T4 ``B.W`` with offset -4 (0xF7FF
0xBFFE), unconditional (not in an IT block), in Thumb state, with no debugger attached (gdb
steps and breaks on it) and no interrupt able to preempt (one an unmask hook would take).
"""

from __future__ import annotations

from unicorn import arm_const as A

#: fast-forward through branches to self; off: spin them instruction by instruction (the tests
#: compare both)
IDLE_SKIP = True

_T2 = b"\xfe\xe7"
_T4 = b"\xff\xf7\xfe\xbf"


def self_branches(segments) -> dict[int, int]:
    """Address -> length of each branch to itself in the executable segments."""
    found = {}
    for seg in segments:
        if not seg.code_addresses:
            continue
        d = seg.data
        for code in (_T2, _T4):
            i = d.find(code)
            while i >= 0:
                if i % 2 == 0:
                    for base in seg.code_addresses:
                        found[base + i] = len(code)
                i = d.find(code, i + 1)
    return found


def spinning(core, pc) -> bool:
    """The core at pc would spin in a branch to itself until the quantum's end."""
    size = core._idle.get(pc)
    if size is None or not IDLE_SKIP or core.debug is not None:
        return False
    try:
        if core.read(pc, size) != (_T2 if size == 2 else _T4):     # (code in RAM may change)
            return False
    except Exception:   # noqa: BLE001 (unicorn's UcError: no memory there any more)
        return False
    xpsr = core.uc.reg_read(A.UC_ARM_REG_XPSR)
    if xpsr & 0x0700FC00 != 0x01000000:      # Thumb state (EPSR.T), outside an IT block
        return False
    return not core.exc.can_preempt()
