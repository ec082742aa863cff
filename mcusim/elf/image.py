"""Reading an ELF image: its loadable segments, its entry, its symbols (``image.symbols[name]``)
and the function that holds a code address (``image.where(pc)`` -> ``"pid_update+0x1c"``).

Every way an ELF can be unusable (not an ELF, not 32-bit little-endian ARM, no loadable segment)
is one :class:`~mcusim.errors.ConfigError` naming the file.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import ConfigError, read_input

PF_X = 1


@dataclass
class Segment:
    address: int        # load (physical) address: where the bytes sit at reset
    data: bytes         # the file's bytes, padded with zeros to p_memsz
    executable: bool
    sections: tuple = ()    # the names of the allocated sections it holds (.text, .data ...)
    vaddr: int | None = None    # where it runs, if not where it is loaded (code copied to RAM)

    @property
    def code_addresses(self) -> tuple:
        """Where its bytes may run as code: the load address of an executable segment, and the
        run address of any segment the start-up code copies elsewhere (a function placed in .data
        runs from RAM, although the linker marks that segment read-write only)."""
        at = (self.address,) if self.executable else ()
        return at if self.vaddr in (None, self.address) else at + (self.vaddr,)


@dataclass
class ElfImage:
    path: str
    entry: int
    segments: list
    symbols: dict = field(default_factory=dict)        # name -> address (thumb bit clear)
    sizes: dict = field(default_factory=dict)          # name -> st_size
    _funcs: list = field(default_factory=list)         # sorted (start, end, name) of FUNC symbols
    _starts: list = field(default_factory=list)

    def where(self, pc: int) -> str:
        """``name+0xoff`` of the function holding ``pc`` (or of the nearest symbol before it),
        else the hex address."""
        pc &= ~1
        i = bisect.bisect_right(self._starts, pc) - 1
        if i >= 0:
            start, end, name = self._funcs[i]
            if pc < end or end == start:
                return name if pc == start else f"{name}+{pc - start:#x}"
        return f"{pc:#010x}"

    def function(self, pc: int) -> str | None:
        """The name of the function whose range holds ``pc``, or None."""
        pc &= ~1
        i = bisect.bisect_right(self._starts, pc) - 1
        if i >= 0 and self._funcs[i][0] <= pc < self._funcs[i][1]:
            return self._funcs[i][2]
        return None

    def symbol(self, name: str) -> int:
        try:
            return self.symbols[name]
        except KeyError:
            raise ConfigError(f"{self.path}: no symbol {name!r} in the ELF's symbol table") from None


def shipped_images() -> dict:
    """{name: path} of the compiled images shipped with mcusim (``controlmotor``, ...)."""
    from importlib.resources import files
    root = Path(str(files("mcusim.fw"))) / "controlmotor_c"
    return {p.stem: p for p in sorted(root.glob("*.elf"))}


def resolve_firmware(path):
    """``path`` if it names a file; else a shipped image's name (``controlmotor`` or
    ``controlmotor.elf``), as ``--scenario`` takes shipped scenario names; ConfigError if neither."""
    if not str(path).strip():
        raise ConfigError("--firmware: an empty name; give the path of an ELF image (or a shipped image's "
                          "name: " + ", ".join(shipped_images()) + ")")
    p = Path(path)
    if p.exists() or len(p.parts) > 1:
        return path                      # a path: read_elf reports what is wrong with it
    shipped = shipped_images()
    name = p.stem if p.suffix == ".elf" else p.name
    if name in shipped:
        return shipped[name]
    raise ConfigError(f"firmware {str(path)!r}: no such file, and no shipped image of that name "
                      f"(shipped: {', '.join(shipped) or 'none'})")


def read_elf(path) -> ElfImage:
    """Parse ``path`` (an ARM ELF executable); ConfigError for anything that cannot run."""
    from elftools.common.exceptions import ELFError
    from elftools.elf.elffile import ELFFile
    from elftools.elf.sections import SymbolTableSection
    where = str(path)
    try:
        raw = read_input(path, "firmware image (ELF)", 256 << 20)
    except OSError as exc:
        raise ConfigError(f"cannot read firmware {where!r}: {exc.strerror or exc}") from None
    if raw[:4] != b"\x7fELF":
        raise ConfigError(f"{where}: not an ELF file (it starts with {raw[:4]!r}); --firmware takes an ELF "
                          "image built for the board's Cortex-M core")
    ident_class, ident_data = (raw[4], raw[5]) if len(raw) >= 6 else (0, 0)
    if ident_class in (1, 2) and ident_data in (1, 2) and (ident_class, ident_data) != (1, 1):
        # another class or byte order: say which machine it is for, read in its own byte order
        from elftools.elf.enums import ENUM_E_MACHINE
        num = int.from_bytes(raw[18:20], "little" if ident_data == 1 else "big") if len(raw) >= 20 else None
        machine = next((k for k, v in ENUM_E_MACHINE.items() if v == num), f"machine {num}")
        raise ConfigError(f"{where}: an ELF for {machine} ({32 * ident_class}-bit, "
                          f"{'little' if ident_data == 1 else 'big'}-endian); the board's core needs a "
                          "32-bit little-endian ARM (EM_ARM) image")
    if len(raw) < 52:
        raise ConfigError(f"{where}: a truncated ELF file ({len(raw)} bytes; its header alone is 52)")
    import io
    try:
        elf = ELFFile(io.BytesIO(raw))
        machine = elf["e_machine"]
        if elf["e_type"] != "ET_EXEC" and machine == "EM_ARM":
            kind = {"ET_REL": "a relocatable object (.o)", "ET_DYN": "a shared object",
                    "ET_CORE": "a core dump"}.get(elf["e_type"], f"of type {elf['e_type']}")
            raise ConfigError(f"{where}: {kind}, not a linked executable (ET_EXEC): link it for the board's "
                              "memory map first")
        if machine != "EM_ARM" or elf.elfclass != 32 or not elf.little_endian:
            raise ConfigError(f"{where}: an ELF for {machine} ({elf.elfclass}-bit, "
                              f"{'little' if elf.little_endian else 'big'}-endian); the board's core "
                              "needs a 32-bit little-endian ARM (EM_ARM) image")
        segments = []
        for seg in elf.iter_segments():
            if seg["p_type"] != "PT_LOAD" or seg["p_memsz"] == 0:
                continue
            data = seg.data()
            if seg["p_filesz"] == 0:
                continue            # .bss-like: zeroed by the startup code, nothing to load
            names = tuple(sec.name for sec in elf.iter_sections()
                          if sec["sh_flags"] & 2 and sec["sh_size"] and seg.section_in_segment(sec))
            segments.append(Segment(seg["p_paddr"], bytes(data), bool(seg["p_flags"] & PF_X), names,
                                    seg["p_vaddr"]))
        if not segments:
            raise ConfigError(f"{where}: the ELF has no loadable segment (PT_LOAD with contents)")
        image = ElfImage(where, elf["e_entry"], segments)
        funcs = []
        for sec in elf.iter_sections():
            if not isinstance(sec, SymbolTableSection):
                continue
            for sym in sec.iter_symbols():
                kind = sym["st_info"]["type"]
                if not sym.name or kind not in ("STT_FUNC", "STT_OBJECT", "STT_NOTYPE") or \
                        sym["st_shndx"] == "SHN_UNDEF" or sym.name.startswith("$"):
                    continue
                addr = sym["st_value"] & ~1 if kind == "STT_FUNC" else sym["st_value"]
                if sym["st_info"]["bind"] == "STB_GLOBAL" or sym.name not in image.symbols:
                    image.symbols[sym.name] = addr
                    image.sizes[sym.name] = sym["st_size"]
                if kind == "STT_FUNC":
                    funcs.append((addr, addr + sym["st_size"], sym["st_info"]["bind"] != "STB_WEAK", sym.name))
    except ConfigError:
        raise
    except (ELFError, ValueError, KeyError, IndexError, AssertionError) as exc:   # truncated or corrupt
        raise ConfigError(f"{where}: not a valid ELF file, truncated or corrupt ({len(raw)} bytes; the "
                          f"ELF reader says: {exc})") from None
    # one name per function: at a start shared by weak aliases of a handler (startup code's
    # UsageFault_Handler = Default_Handler, ...) the strong symbol names it, whatever the sort
    best = {}
    for start, end, strong, name in funcs:
        key = (start, end)
        if key not in best or (strong and not best[key][0]):
            best[key] = (strong, name)
    image._funcs = sorted((start, end, name) for (start, end), (_, name) in best.items())
    image._starts = [f[0] for f in image._funcs]
    return image
