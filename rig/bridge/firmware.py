"""Builds the bridge firmware for the STM32G431 (bridge/stm32g4 + bridge/core + the chip core,
emulators/chips) with Debian's arm-none-eabi-gcc into build/firmware/bridge.elf, .bin and .map, and
checks its budgets: flash against the G431's 128 KB, RAM (data, bss and the reserved stack) against
its 32 KB, printing both margins and failing when either is over. The ELF is read here with struct
(no ELF library is installed): its sections and the vector table a test checks.

``python -m rig.bridge.firmware`` (what `make firmware` runs) builds when a source is newer and prints
the budgets; ``--check`` only checks an ELF already built.
"""

from __future__ import annotations

import argparse
import hashlib
import struct
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from rig.bridge import gen
from rig.emulators.chips import gen as chips_gen
from rig.plant.artifacts import BUILD
from rig.plant.native_build import NativeBuildError, compile_c

REPO = Path(__file__).resolve().parents[2]
OUT = BUILD / "firmware"
ELF = OUT / "bridge.elf"
SOURCES_DIRS = (REPO / "bridge" / "stm32g4", REPO / "bridge" / "core", REPO / "emulators" / "chips")
LINKER_SCRIPT = REPO / "bridge" / "stm32g4" / "stm32g431.ld"
CC = "arm-none-eabi-gcc"
OBJCOPY = "arm-none-eabi-objcopy"
#: the STM32G431's core: a Cortex-M4 with the single-precision FPU, hard-float ABI (tests/bridge/tools.py
#: runs the core's tests with the same flags under QEMU)
M4_FLAGS = ("-mcpu=cortex-m4", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv4-sp-d16")
#: after compile_c's own (-Wall -Wextra -Werror -ffp-contract=off): size first, unused code dropped
CFLAGS = ("-std=c99", "-Os", "-g", "-ffunction-sections", "-fdata-sections")

#: RM0440 §2.2.2 and the datasheet: the G431KB/CB's flash and SRAM (SRAM1 + SRAM2 + CCM SRAM)
FLASH_BASE, FLASH_SIZE = 0x0800_0000, 128 * 1024
SRAM_BASE, SRAM_SIZE = 0x2000_0000, 32 * 1024

SHF_ALLOC = 0x2


class FirmwareError(RuntimeError):
    """The build failed, the ELF is not what it must be, or a budget is over."""


@dataclass(frozen=True)
class Section:
    name: str
    type: int
    flags: int
    addr: int
    offset: int
    size: int


def sources() -> list[Path]:
    return sorted(p for d in SOURCES_DIRS for p in d.iterdir() if p.suffix in (".c", ".h"))


def firmware_hash() -> bytes:
    """The first 8 bytes of the SHA-256 of the firmware's sources (names and contents, in order) and
    the generated headers: what HELLO_REPLY reports as firmware_sha256, so `rig bridge probe` tells
    which sources a board runs."""
    h = hashlib.sha256()
    for p in [*sources(), LINKER_SCRIPT, gen.OUT, chips_gen.OUT]:
        h.update(p.relative_to(REPO).as_posix().encode() + b"\0" + p.read_bytes())
    return h.digest()[:8]


def build(out: Path = OUT) -> Path:
    """build/firmware/bridge.elf (.bin, .map beside it), rebuilt when a source is newer."""
    headers = [gen.write(), chips_gen.write()]
    elf = out / "bridge.elf"
    deps = [*sources(), LINKER_SCRIPT, *headers, Path(__file__)]
    if elf.is_file() and elf.stat().st_mtime >= max(p.stat().st_mtime for p in deps):
        return elf
    c_files = [p for p in sources() if p.suffix == ".c"]
    includes = [f"-I{d}" for d in (headers[0].parent, *SOURCES_DIRS)]
    flags = [*M4_FLAGS, *CFLAGS, f"-DFIRMWARE_SHA=0x{firmware_hash().hex()}ull", *includes, "-nostartfiles",
             "--specs=nano.specs", "--specs=nosys.specs", "-Wl,--gc-sections",
             f"-Wl,-Map={out / 'bridge.map'}", f"-T{LINKER_SCRIPT}"]
    tmp = elf.with_suffix(".tmp.elf")
    try:
        compile_c(c_files, tmp, "the bridge firmware", libs=["-lm"], cc=CC, flags=flags)
    except NativeBuildError as e:
        raise FirmwareError(f"{e} (tools/bootstrap.sh installs gcc-arm-none-eabi)") from e
    subprocess.run([OBJCOPY, "-O", "binary", str(tmp), str(out / "bridge.bin")], check=True)
    tmp.replace(elf)
    return elf


def sections(elf: Path) -> list[Section]:
    """The section headers of a 32-bit little-endian ARM ELF."""
    data = elf.read_bytes()
    if data[:4] != b"\x7fELF" or data[4] != 1 or data[5] != 1:
        raise FirmwareError(f"{elf}: not a 32-bit little-endian ELF")
    machine = struct.unpack_from("<H", data, 18)[0]
    if machine != 40:  # EM_ARM
        raise FirmwareError(f"{elf}: machine {machine}, not ARM (40)")
    shoff, = struct.unpack_from("<I", data, 32)
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", data, 46)
    if shoff + shnum * shentsize > len(data) or shstrndx >= shnum:
        raise FirmwareError(f"{elf}: section headers out of the file")
    raw = [struct.unpack_from("<10I", data, shoff + i * shentsize) for i in range(shnum)]
    strtab = raw[shstrndx]
    names = data[strtab[4]:strtab[4] + strtab[5]]

    def name(off: int) -> str:
        return names[off:names.index(b"\0", off)].decode()

    return [Section(name(r[0]), r[1], r[2], r[3], r[4], r[5]) for r in raw]


def load_extents(elf: Path) -> list[tuple[int, int]]:
    """(physical address, bytes in the file) of each loaded segment: where a flasher writes what
    (.data's initial values sit in flash after the code, at their load address)."""
    data = elf.read_bytes()
    sections(elf)  # (checks it is a 32-bit little-endian ARM ELF)
    phoff, = struct.unpack_from("<I", data, 28)
    phentsize, phnum = struct.unpack_from("<HH", data, 42)
    if phoff + phnum * phentsize > len(data):
        raise FirmwareError(f"{elf}: program headers out of the file")
    out = []
    for i in range(phnum):
        p_type, _, _, paddr, filesz = struct.unpack_from("<5I", data, phoff + i * phentsize)
        if p_type == 1 and filesz:  # PT_LOAD
            out.append((paddr, filesz))
    return out


def entry(elf: Path) -> int:
    return int(struct.unpack_from("<I", elf.read_bytes(), 24)[0])


def vectors(elf: Path, count: int = 16) -> list[int]:
    """The first ``count`` words of the vector table (.isr_vector): the initial stack pointer, then the
    handlers (Thumb: odd)."""
    sec = next((s for s in sections(elf) if s.name == ".isr_vector"), None)
    if sec is None or sec.addr != FLASH_BASE:
        raise FirmwareError(f"{elf}: no .isr_vector at {FLASH_BASE:#x}")
    data = elf.read_bytes()[sec.offset:sec.offset + min(sec.size, 4 * count)]
    return list(struct.unpack(f"<{len(data) // 4}I", data))


@dataclass(frozen=True)
class Budget:
    flash: int
    ram: int
    flash_size: int = FLASH_SIZE
    ram_size: int = SRAM_SIZE

    def lines(self) -> list[str]:
        def line(what: str, used: int, size: int) -> str:
            return (f"{what:5} {used:7d} of {size:7d} bytes ({100 * used / size:5.1f} %), "
                    f"margin {size - used:7d} bytes")
        return [line("flash", self.flash, self.flash_size), line("RAM", self.ram, self.ram_size)]

    def check(self) -> None:
        over = [what for what, used, size in (("flash", self.flash, self.flash_size),
                                              ("RAM", self.ram, self.ram_size)) if used > size]
        if over:
            raise FirmwareError(f"over budget: {', '.join(over)}\n" + "\n".join(self.lines()))


def budget(elf: Path, flash_size: int = FLASH_SIZE, ram_size: int = SRAM_SIZE) -> Budget:
    """Flash: from 0x08000000 to the end of the last byte loaded there (code, constants, the vector
    table, .data's initial values, and the alignment gaps between them: the .bin's length). RAM: every
    allocated section in SRAM (.data, .bss, the stack the linker script reserves)."""
    ends = [a + n for a, n in load_extents(elf) if FLASH_BASE <= a < FLASH_BASE + 0x1000_0000]
    flash = max(ends) - FLASH_BASE if ends else 0
    ram = sum(s.size for s in sections(elf)
              if s.flags & SHF_ALLOC and SRAM_BASE <= s.addr < SRAM_BASE + 0x1000_0000)
    return Budget(flash, ram, flash_size, ram_size)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m rig.bridge.firmware", description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", type=Path, help="only check this ELF's budgets")
    args = ap.parse_args(argv)
    try:
        elf = args.check or build()
        b = budget(elf)
        print(f"firmware {elf.relative_to(REPO) if elf.is_relative_to(REPO) else elf}:")
        for line in b.lines():
            print("  " + line)
        if not args.check:
            print(f"  hash  {firmware_hash().hex()} (HELLO_REPLY's firmware_sha256: "
                  "rig bridge probe shows it)")
        b.check()
    except FirmwareError as e:
        print(f"firmware: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
