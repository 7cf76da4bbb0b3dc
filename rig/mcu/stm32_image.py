"""An STM32 firmware file checked before QEMU runs it: an ARM ELF (32-bit little-endian, machine 40)
whose loadable segments lie in the file and in the chip's memories, with a vector table at the start of
flash that QEMU can boot from (an initial stack pointer in RAM, a Thumb reset handler in flash). Anything
else (an AVR image, a file cut short, a raw binary) is refused with the reason; otherwise QEMU would lock
up at reset or load garbage (RM0090 and RM0383 2.3, memory map; ARMv7-M B1.5.3, the vector table). The
memories are the MCU's (rig/mcu/mcus.py): an F405 image with code above 512 KB or its stack in the CCM
RAM is refused for an F411."""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Final

from rig.mcu.image import FirmwareError, _elf_kind, _sections
from rig.mcu.mcus import MCUS, Mcu

EM_ARM: Final = 40
PT_LOAD: Final = 1


def _inside(address: int, size: int, region: tuple[int, int]) -> bool:
    start, length = region
    return start <= address and address + size <= start + length


def check_image(path: Path, mcu: Mcu = MCUS["stm32f405"]) -> None:
    """FirmwareError unless ``path`` is an ARM ELF ``mcu``'s machine can boot."""
    path = Path(path)
    flash = (mcu.flash_base, mcu.flash)  # (also aliased at 0 when booting from it)
    size = f"{mcu.flash // 1024} KB" if mcu.flash < 1024 * 1024 else f"{mcu.flash // (1024 * 1024)} MB"
    chip = mcu.name.upper()
    if not path.is_file():
        raise FirmwareError(f"{path}: no such file")
    data = path.read_bytes()
    if len(data) < 52 or data[:4] != b"\x7fELF":
        raise FirmwareError(f"{path}: not an ELF file ({len(data)} bytes); the STM32 tier runs ARM ELF "
                            "images (arm-none-eabi-gcc's output)")
    if data[4] != 1 or data[5] != 1 or struct.unpack_from("<H", data, 18)[0] != EM_ARM:
        raise FirmwareError(f"{path}: an ELF for {_elf_kind(data)}; an STM32 image is for ARM (machine "
                            f"{EM_ARM}), 32-bit little-endian")
    phoff, = struct.unpack_from("<I", data, 28)
    phentsize, phnum = struct.unpack_from("<HH", data, 42)
    vectors: bytes | None = None
    for i in range(phnum):
        at = phoff + i * phentsize
        if phentsize < 32 or at + 32 > len(data):
            raise FirmwareError(f"{path}: cut short: program header {i} lies outside the file")
        kind, offset, _vaddr, paddr, filesz = struct.unpack_from("<IIIII", data, at)
        if kind != PT_LOAD or filesz == 0:
            continue
        if offset + filesz > len(data):
            raise FirmwareError(f"{path}: cut short: segment {i} ends at byte {offset + filesz}, the file "
                                f"has {len(data)}")
        if not (_inside(paddr, filesz, flash) or _inside(paddr, filesz, (0, flash[1]))):
            raise FirmwareError(f"{path}: segment {i} loads at 0x{paddr:08x}..0x{paddr + filesz:08x}, "
                                f"outside the {chip}'s {size} flash (0x{flash[0]:08x})")
        if paddr in (0, flash[0]) and filesz >= 8:
            vectors = data[offset:offset + 8]
    _sections(path, data)  # (FirmwareError when the section headers or a section lie past the file)
    if vectors is None:
        raise FirmwareError(f"{path}: nothing loads at the start of flash (0x08000000): no vector table to "
                            "boot from")
    sp, reset = struct.unpack("<II", vectors)
    if not any(_inside(sp - 4, 4, ram) for ram in mcu.rams):
        rams = ", ".join(f"0x{a:08x} {n // 1024} KB" for a, n in mcu.rams)
        raise FirmwareError(f"{path}: the vector table's initial stack pointer 0x{sp:08x} is not in the "
                            f"{chip}'s RAM ({rams})")
    if not reset & 1 or not (_inside(reset & ~1, 2, flash) or _inside(reset & ~1, 2, (0, flash[1]))):
        raise FirmwareError(f"{path}: the reset vector 0x{reset:08x} is not a Thumb address in flash")


#: the section an STM32 firmware keeps its settings image in (dut/stm32/main.c: the reference FC's
#: configuration, config_image.h's layout), as an EEPROM holds the AVR build's
CONFIG_SECTION: Final = ".fc_config"


def config_section(data: bytes) -> tuple[int, int, int] | None:
    """CONFIG_SECTION's address in flash, its offset in the ELF file ``data`` and its size; None when the
    firmware has none (``data`` passed check_image)."""
    shoff, = struct.unpack_from("<I", data, 32)
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", data, 46)
    headers = [struct.unpack_from("<IIIIII", data, shoff + i * shentsize) for i in range(shnum)]
    strtab_at = headers[shstrndx][4] if shstrndx < shnum else 0
    for name_at, _kind, _flags, addr, offset, size in headers:
        name = bytes(data[strtab_at + name_at:]).split(b"\0", 1)[0].decode("ascii", "replace")
        if name == CONFIG_SECTION:
            return addr, offset, size
    return None


def with_settings(path: Path, settings: bytes, out: Path) -> Path:
    """A copy of ``path`` at ``out`` whose CONFIG_SECTION starts with ``settings`` (the rest erased
    flash, 0xFF), as a board whose settings sector was written; ``path`` itself when it has no such
    section (a firmware that keeps its settings elsewhere, as an AVR firmware may ignore its EEPROM);
    FirmwareError when the section is smaller than the settings."""
    data = bytearray(Path(path).read_bytes())
    section = config_section(bytes(data))
    if section is None:
        return Path(path)
    _addr, offset, size = section
    if size < len(settings):
        raise FirmwareError(f"{path}: its {CONFIG_SECTION} section has {size} bytes, the settings "
                            f"{len(settings)}")
    data[offset:offset + size] = settings + b"\xff" * (size - len(settings))
    out.write_bytes(bytes(data))
    return out
