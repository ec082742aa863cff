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
IMAGES = ("ticks", "exc", "fpframe", "rtos", "faults", "cycles")
CFLAGS = ["-mcpu=cortex-m7", "-mthumb", "-mfpu=fpv5-sp-d16", "-mfloat-abi=hard", "-O2", "-g",
          "-ffreestanding", "-nostartfiles", "-nostdlib", "-Wl,--gc-sections", "-Wl,--build-id=none",
          "-ffile-prefix-map=" + str(SRC) + "=.", "-T", "link.ld"]


def gcc():
    return shutil.which("arm-none-eabi-gcc")


def build(name: str, out_dir: Path) -> Path:
    out = Path(out_dir) / f"{name}.elf"
    subprocess.run([gcc(), *CFLAGS, "startup.c", f"{name}.c", "-o", str(out.resolve()), "-lgcc"],
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
