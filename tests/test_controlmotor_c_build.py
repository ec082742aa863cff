"""The C ControlMotorROS firmware (firmware/controlmotor_c): the committed images are what the
sources build to, and they keep the contract the ELF runner relies on: the topic globals with the
types and sizes the topics file declares, a vector table whose reset vector is a thumb address in
flash, and loadable segments inside the STM32F746's memory map."""

import io
import re
import shutil
import subprocess
import tomllib
from pathlib import Path

import pytest
from elftools.elf.constants import SH_FLAGS
from elftools.elf.elffile import ELFFile

ROOT = Path(__file__).resolve().parent.parent
FW = ROOT / "firmware" / "controlmotor_c"
IMAGES = {"controlmotor.elf": "correct", "controlmotor_thesis.elf": "thesis"}

# RM0385 §2.2.2 (STM32F74xxx memory map) for the STM32F746ZG (1 MB flash, 320 KB SRAM)
FLASH_AXIM = range(0x0800_0000, 0x0810_0000)
FLASH_ITCM = range(0x0020_0000, 0x0030_0000)
ITCM_RAM = range(0x0000_4000)                     # from 0x00000000
SRAM = range(0x2000_0000, 0x2005_0000)           # DTCM 64 KB + SRAM1 240 KB + SRAM2 16 KB
REGIONS = (FLASH_AXIM, FLASH_ITCM, ITCM_RAM, SRAM)

# topic type -> (size in bytes, DWARF 5 §7.8 base-type encoding: DW_ATE_boolean 2, float 4, signed 5,
# signed_char 6, unsigned 7, unsigned_char 8)
TYPES = {"bool": (1, 2), "u8": (1, 8), "i8": (1, 6), "u16": (2, 7), "i16": (2, 5), "u32": (4, 7),
         "i32": (4, 5), "f32": (4, 4), "f64": (8, 4)}
# the topics the Python port exposes (mcusim.fw.controlmotor.app), which the C image must expose too
PORT_TOPICS = {f"/motor{n}/{name}": (kind, direction) for n in (1, 2)
               for name, kind, direction in (("set_pos", "f32", "sub"), ("enable", "bool", "sub"),
                                             ("get_pos", "f32", "pub"))}


def _topics(image):
    return tomllib.loads((FW / image).with_suffix("").with_suffix(".topics.toml").read_text())["topics"]


def _inside(lo, size, region):
    return size == 0 or (lo in region and lo + size - 1 in region)


class Image:
    def __init__(self, name):
        self.elf = ELFFile(io.BytesIO((FW / name).read_bytes()))
        self.symbols = {s.name: s for s in self.elf.get_section_by_name(".symtab").iter_symbols() if s.name}
        self.variables = self._dwarf_variables()

    def _dwarf_variables(self):
        """name -> (byte size, encoding) of every global variable's base type, through
        volatile/const/typedef."""
        out = {}
        for cu in self.elf.get_dwarf_info().iter_CUs():
            for die in cu.iter_DIEs():
                if die.tag != "DW_TAG_variable" or "DW_AT_name" not in die.attributes:
                    continue
                t = die.get_DIE_from_attribute("DW_AT_type") if "DW_AT_type" in die.attributes else None
                while t is not None and t.tag in ("DW_TAG_volatile_type", "DW_TAG_const_type", "DW_TAG_typedef"):
                    t = t.get_DIE_from_attribute("DW_AT_type")
                if t is not None and t.tag == "DW_TAG_base_type":
                    out[die.attributes["DW_AT_name"].value.decode()] = (
                        t.attributes["DW_AT_byte_size"].value, t.attributes["DW_AT_encoding"].value)
        return out

    def section_of(self, sym):
        return self.elf.get_section(sym["st_shndx"])

    def read(self, address, size):
        """Bytes at a load (physical) address, from the PT_LOAD segments."""
        for seg in self.elf.iter_segments():
            lo = seg["p_paddr"]
            if seg["p_type"] == "PT_LOAD" and lo <= address and address + size <= lo + seg["p_filesz"]:
                return seg.data()[address - lo:address - lo + size]
        raise AssertionError(f"{address:#x} is in no loadable segment")


@pytest.fixture(params=sorted(IMAGES), scope="module")
def image(request):
    img = Image(request.param)
    img.name = request.param
    return img


def test_the_topics_file_names_the_python_ports_topics_with_their_types():
    for image in IMAGES:
        topics = _topics(image)
        assert {name: (t["type"], t["direction"]) for name, t in topics.items()} == PORT_TOPICS, image


def test_every_topic_symbol_is_a_global_of_the_declared_type_and_size(image):
    for name, t in _topics(image.name).items():
        size, encoding = TYPES[t["type"]]
        sym = image.symbols[t["symbol"]]
        assert sym["st_info"]["type"] == "STT_OBJECT" and sym["st_info"]["bind"] == "STB_GLOBAL", name
        assert sym["st_size"] == size, name
        assert image.variables[t["symbol"]] == (size, encoding), name
        # the host writes subscribed topics and reads published ones: both live in writable SRAM
        assert image.section_of(sym)["sh_flags"] & SH_FLAGS.SHF_WRITE, name
        assert _inside(sym["st_value"], size, SRAM), name
        if "count" in t:
            count = image.symbols[t["count"]]
            assert count["st_size"] == 4 and image.variables[t["count"]] == TYPES["u32"], name
            assert _inside(count["st_value"], 4, SRAM), name


def test_the_build_flag_selects_the_variant(image):
    sym = image.symbols["controlmotor_variant"]
    text = image.read(sym["st_value"], sym["st_size"])
    assert text == IMAGES[image.name].encode() + b"\0"


def test_the_vector_table_gives_a_stack_in_sram_and_a_thumb_reset_vector_in_flash(image):
    """ARMv7-M ARM B1.5.3: word 0 is the initial SP, word 1 the reset vector with bit 0 (Thumb) set;
    the STM32F7 boots from flash with the table at 0x08000000 (RM0385 §2.4, BOOT_ADD0 default)."""
    sp = int.from_bytes(image.read(0x0800_0000, 4), "little")
    reset = int.from_bytes(image.read(0x0800_0004, 4), "little")
    assert sp % 8 == 0 and SRAM.start < sp <= SRAM.stop
    assert reset & 1 == 1
    assert (reset & ~1) in FLASH_AXIM
    assert reset == image.symbols["Reset_Handler"]["st_value"] | 1 == image.elf.header["e_entry"]


def test_every_loadable_segment_lies_in_the_f746_memory_map(image):
    segments = [s for s in image.elf.iter_segments() if s["p_type"] == "PT_LOAD"]
    assert segments
    for s in segments:
        assert any(_inside(s["p_paddr"], s["p_filesz"], r) for r in REGIONS), hex(s["p_paddr"])
        assert any(_inside(s["p_vaddr"], s["p_memsz"], r) for r in REGIONS), hex(s["p_vaddr"])


def test_the_image_is_hard_float_thumb_code_for_an_arm_core(image):
    h = image.elf.header
    assert h["e_machine"] == "EM_ARM" and image.elf.elfclass == 32 and image.elf.little_endian
    assert h["e_flags"] & 0x400            # EF_ARM_ABI_FLOAT_HARD: float arguments in s0..s15


def _compiler_of(image):
    return Image(image).elf.get_section_by_name(".comment").data().rstrip(b"\0").decode()


needs_toolchain = pytest.mark.skipif(not (shutil.which("arm-none-eabi-gcc") and shutil.which("make")),
                                     reason="arm-none-eabi-gcc (Debian gcc-arm-none-eabi) or make is not installed")


def _same_compiler():
    """Byte-for-byte equality holds for the compiler that built the images; skip under another."""
    version = subprocess.run(["arm-none-eabi-gcc", "--version"], capture_output=True, text=True,
                             check=True).stdout.splitlines()[0]
    built_with = _compiler_of("controlmotor.elf")            # "GCC: (15:12.2.rel1-1) 12.2.1 20221205"
    if built_with.removeprefix("GCC: ") != version.removeprefix("arm-none-eabi-gcc "):
        pytest.skip(f"the images were built by {built_with!r}, this compiler is {version!r}")


@needs_toolchain
def test_make_check_rebuilds_the_committed_images_byte_for_byte():
    _same_compiler()
    r = subprocess.run(["make", "-s", "-C", str(FW), "check"], capture_output=True, text=True, timeout=300,
                       check=False)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "match a fresh build" in r.stdout


@needs_toolchain
def test_make_check_fails_on_a_stale_committed_image(tmp_path):
    copy = tmp_path / "controlmotor_c"
    shutil.copytree(FW, copy, ignore=shutil.ignore_patterns("build"))
    elf = copy / "controlmotor.elf"
    data = bytearray(elf.read_bytes())
    data[0x1000 + 0x100] ^= 0xFF                               # a byte of code
    elf.write_bytes(bytes(data))
    r = subprocess.run(["make", "-s", "-C", str(copy), "check"], capture_output=True, text=True, timeout=300,
                       check=False)
    assert r.returncode != 0
    assert "controlmotor.elf differs from a fresh build" in r.stdout + r.stderr


@pytest.mark.heavy
@needs_toolchain
def test_the_readmes_make_commands_run_as_documented(tmp_path):
    """Every command of firmware/controlmotor_c/README.md, in a copy of the folder."""
    _same_compiler()
    readme = (FW / "README.md").read_text()
    lines = [line.split("#")[0].split() for block in re.findall(r"```sh\n(.*?)```", readme, re.DOTALL)
             for line in block.splitlines() if line.strip()]
    assert [w[:3] for w in lines] == [["make", "-C", "firmware/controlmotor_c"]] * 3
    copy = tmp_path / "controlmotor_c"
    shutil.copytree(FW, copy, ignore=shutil.ignore_patterns("build"))
    for words in lines:
        r = subprocess.run(["make", "-C", str(copy), *words[3:]], capture_output=True, text=True, timeout=300,
                           check=False)
        assert r.returncode == 0, (words, r.stdout + r.stderr)
    for image in IMAGES:                                     # make rebuilt them: the same bytes
        assert (copy / image).read_bytes() == (FW / image).read_bytes()
    assert not (copy / "build").exists()                     # make clean
