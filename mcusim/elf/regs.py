"""Fast access to the core's 32-bit registers: unicorn's C batch calls through ctypes, without
the Python binding's per-register dispatch (which costs several microseconds per register and
dominates exception entry and return)."""

from __future__ import annotations

import ctypes

try:                                    # unicorn 2.1's binding layout
    from unicorn.unicorn_py3.unicorn import uclib
except ImportError:                     # another layout: the binding's own batch calls
    uclib = None


class RegBlock:
    """Read or write a fixed list of 32-bit registers in one call."""

    def __init__(self, uc, regs):
        self.uc, self.regs = uc, tuple(regs)
        if uclib is None:
            self.read = lambda: [v & 0xFFFFFFFF for v in uc.reg_read_batch(self.regs)]
            self.write = lambda values: uc.reg_write_batch(list(zip(self.regs, values)))
            return
        self.uch = uc._uch
        self.n = len(regs)
        self.ids = (ctypes.c_int * self.n)(*regs)
        self.vals = (ctypes.c_uint64 * self.n)()
        self.ptrs = (ctypes.c_void_p * self.n)(*(ctypes.addressof(self.vals) + 8 * i for i in range(self.n)))

    def read(self):
        if uclib.uc_reg_read_batch(self.uch, self.ids, self.ptrs, self.n):
            raise RuntimeError("uc_reg_read_batch failed")
        return [v & 0xFFFFFFFF for v in self.vals]

    def write(self, values):
        for i, v in enumerate(values):
            self.vals[i] = v & 0xFFFFFFFF
        if uclib.uc_reg_write_batch(self.uch, self.ids, self.ptrs, self.n):
            raise RuntimeError("uc_reg_write_batch failed")
