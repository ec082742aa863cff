"""Build the test images in tests/elf_src with arm-none-eabi-gcc (reproducibly: fixed flags, no
paths), into tests/elf_bin (committed, so the tests run without the toolchain).

    python tests/elf_build.py          # rebuild every image in place
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).parent / "elf_src"
BIN = Path(__file__).parent / "elf_bin"
IMAGES = ("ticks", "exc", "fpframe", "rtos", "faults", "cycles", "order", "sched", "masks", "lpc_ticks", "armv7m",
          "corefaults", "itcm", "idle")
LINK = {"itcm": "link_itcm.ld"}   # the linker script of an image that needs its own
COMMON = ["-mthumb", "-O2", "-g", "-ffreestanding", "-nostartfiles", "-nostdlib", "-Wl,--gc-sections",
          "-Wl,--build-id=none", "-ffile-prefix-map=" + str(SRC) + "=."]
STM32F746 = ["-mcpu=cortex-m7", "-mfpu=fpv5-sp-d16", "-mfloat-abi=hard", "-T", "link.ld"]
LPC4337 = ["-mcpu=cortex-m4", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard", "-T", "link_lpc.ld"]


def gcc():
    return shutil.which("arm-none-eabi-gcc")


def build(name: str, out_dir: Path) -> Path:
    out = Path(out_dir) / f"{name}.elf"
    chip = LPC4337 if name.startswith("lpc_") else STM32F746
    if name in LINK:
        chip = [*chip[:-1], LINK[name]]
    subprocess.run([gcc(), *COMMON, *chip, "startup.c", f"{name}.c", "-o", str(out.resolve()), "-lgcc"],
                   cwd=SRC, check=True, capture_output=True)
    topics = SRC / f"{name}.topics.toml"
    if topics.exists():
        shutil.copy(topics, Path(out_dir) / topics.name)
    return out


if __name__ == "__main__":
    if gcc() is None:
        sys.exit("arm-none-eabi-gcc is not installed")
    BIN.mkdir(exist_ok=True)
    for name in IMAGES:
        print(build(name, BIN))
