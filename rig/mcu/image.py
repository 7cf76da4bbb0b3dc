"""A firmware file read into the flash and EEPROM images the engine loads: an AVR ELF (its loadable
segments at their load addresses, as avr-objcopy takes them) or an Intel HEX. Anything else is refused
here, before anything runs, with the reason: a file is never trusted (a DUT's build output may be
anything). Refused: an image bigger than the MCU's flash; a file cut short (an ELF whose segments or
sections end past the file, an Intel HEX with no end-of-file record); an image for another MCU, which
would run into a false "hung" or "invalid opcode": an ELF says its architecture (e_flags, avr-gcc's
"avr:6") and usually its device (avr-libc's ``.note.gnu.avr.deviceinfo``, simavr's ``.mmcu``); any image
shows its vector table (avr-gcc's: one JMP per vector, as many as the MCU has)."""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Final

from rig.mcu.mcus import MCUS

#: flash and EEPROM sizes in bytes, by the MCU's name as simavr spells it
FLASH: Final = {name: m.flash for name, m in MCUS.items()}
EEPROM: Final = {name: m.eeprom for name, m in MCUS.items()}
EM_AVR: Final = 83
#: avr-gcc's address spaces in an ELF: flash below, then RAM, EEPROM, fuses, lock bits, signature
EEPROM_BASE: Final = 0x810000
RAM_BASE: Final = 0x800000


class FirmwareError(ValueError):
    """The file is not a firmware the engine can run; the message says why."""


@dataclass(frozen=True)
class Image:
    flash: bytes
    eeprom: bytes | None


@dataclass(frozen=True)
class _Elf:
    """What an AVR ELF holds and says of itself."""

    flash: dict[int, bytes]
    eeprom: dict[int, bytes]
    arch: int  #: e_flags' architecture (avr-gcc's avr5, avr6, ...; 0: not said)
    device: str | None  #: the -mmcu it was built for, when a section says it
    device_from: str  #: that section's name


#: e_machine values a firmware file is likely to carry by mistake (the System V ABI's registry)
ELF_MACHINES: Final = {3: "x86", 8: "MIPS", 20: "PowerPC", 21: "PowerPC64", 40: "ARM", 62: "x86-64",
                       83: "AVR", 94: "Xtensa", 183: "AArch64", 243: "RISC-V"}
#: e_flags' architecture bits (binutils' include/elf/avr.h EF_AVR_MACH)
EF_AVR_MACH: Final = 0x7F
SHT_NOBITS: Final = 8
DEVICE_SECTIONS: Final = (".note.gnu.avr.deviceinfo", ".mmcu")
#: simavr's avr_mcu_section.h: a .mmcu record (tag, length, data) of tag AVR_MMCU_TAG_NAME
MMCU_TAG_NAME: Final = 1


def _elf(path: Path, data: bytes) -> _Elf:
    if len(data) < 52:
        raise FirmwareError(f"{path}: cut short: an ELF header is 52 bytes, the file has {len(data)}")
    if data[4] != 1 or data[5] != 1 or struct.unpack_from("<H", data, 18)[0] != EM_AVR:
        raise FirmwareError(f"{path}: an ELF for {_elf_kind(data)}; an AVR image is for AVR (machine "
                            f"{EM_AVR}), 32-bit little-endian")
    phoff, = struct.unpack_from("<I", data, 28)
    flags, = struct.unpack_from("<I", data, 36)
    phentsize, phnum = struct.unpack_from("<HH", data, 42)
    flash: dict[int, bytes] = {}
    eeprom: dict[int, bytes] = {}
    for i in range(phnum):
        at = phoff + i * phentsize
        if at + 32 > len(data):
            raise FirmwareError(f"{path}: cut short: program header {i} lies outside the file")
        kind, offset, _vaddr, paddr, filesz = struct.unpack_from("<IIIII", data, at)
        if kind != 1 or filesz == 0:  # PT_LOAD with bytes
            continue
        if offset + filesz > len(data):
            raise FirmwareError(f"{path}: cut short: segment {i} ends at byte {offset + filesz}, the file "
                                f"has {len(data)}")
        chunk = data[offset:offset + filesz]
        if paddr < RAM_BASE:
            flash[paddr] = chunk
        elif EEPROM_BASE <= paddr < EEPROM_BASE + 0x10000:
            eeprom[paddr - EEPROM_BASE] = chunk
    sections = _sections(path, data)
    device, device_from = None, ""
    for name in DEVICE_SECTIONS:
        if name in sections and (device := _device(name, sections[name])):
            device_from = name
            break
    return _Elf(flash, eeprom, flags & EF_AVR_MACH, device, device_from)


def _elf_kind(data: bytes) -> str:
    """What an ELF header says it is for: "x86-64 (machine 62), 64-bit little-endian"."""
    width = {1: "32-bit", 2: "64-bit"}.get(data[4], f"ELF class {data[4]}")
    order = {1: "little-endian", 2: "big-endian"}.get(data[5], f"data encoding {data[5]}")
    machine = struct.unpack_from("<H" if data[5] != 2 else ">H", data, 18)[0]
    return f"{ELF_MACHINES.get(machine, 'an unknown machine')} (machine {machine}), {width} {order}"


def _sections(path: Path, data: bytes) -> dict[str, bytes]:
    """The sections that say the device, by name; FirmwareError when the section headers or a section's
    bytes lie past the file (a linker writes them last: a file cut short loses them first)."""
    shoff, = struct.unpack_from("<I", data, 32)
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", data, 46)
    if shoff == 0 or shnum == 0:
        return {}
    end = shoff + shnum * shentsize
    if shentsize < 40 or end > len(data):
        raise FirmwareError(f"{path}: cut short: its section headers end at byte {end}, the file has "
                            f"{len(data)}")
    headers = [struct.unpack_from("<IIIIII", data, shoff + i * shentsize) for i in range(shnum)]
    for i, (_name, kind, _flags, _addr, offset, size) in enumerate(headers):
        if kind != SHT_NOBITS and offset + size > len(data):
            raise FirmwareError(f"{path}: cut short: section {i} ends at byte {offset + size}, the file has "
                                f"{len(data)}")
    if shstrndx >= shnum:
        return {}
    strtab_at, strtab_size = headers[shstrndx][4], headers[shstrndx][5]
    strtab = data[strtab_at:strtab_at + strtab_size]
    out: dict[str, bytes] = {}
    for name_at, _kind, _flags, _addr, offset, size in headers:
        name = strtab[name_at:].split(b"\0", 1)[0].decode("ascii", "replace")
        if name in DEVICE_SECTIONS:
            out[name] = data[offset:offset + size]
    return out


def _device(section: str, body: bytes) -> str | None:
    """The device a section names: avr-libc's note (an ELF note "AVR" whose descriptor is six sizes,
    the offset table's length, one offset, then a string table holding the -mmcu name) or simavr's
    .mmcu records; None when it does not say."""
    name = b""
    if section == ".mmcu":
        at = 0
        while at + 2 <= len(body):
            tag, size = body[at], body[at + 1]
            if tag == MMCU_TAG_NAME:
                name = body[at + 2:at + 2 + size].split(b"\0", 1)[0]
                break
            at += 2 + size
    elif len(body) >= 12:
        namesz, descsz, _kind = struct.unpack_from("<III", body, 0)
        desc_at = 12 + (namesz + 3) // 4 * 4
        desc = body[desc_at:desc_at + descsz]
        if len(desc) >= 33:
            offset, = struct.unpack_from("<I", desc, 28)
            name = desc[32 + offset:].split(b"\0", 1)[0]
    text = name.decode("ascii", "replace").strip().lower()
    return text if text.isprintable() and text else None


def _hex(path: Path, text: str) -> dict[int, bytes]:
    chunks: dict[int, bytes] = {}
    base = 0
    for n, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if not line:
            continue
        try:
            if not line.startswith(":"):
                raise ValueError("no ':'")
            rec = bytes.fromhex(line[1:])
        except ValueError as exc:
            raise FirmwareError(f"{path}:{n}: not an Intel HEX record ({exc})") from None
        if len(rec) < 5 or len(rec) != rec[0] + 5:
            raise FirmwareError(f"{path}:{n}: record length does not match its count")
        if sum(rec) & 0xFF:
            raise FirmwareError(f"{path}:{n}: bad checksum")
        count, addr, kind, payload = rec[0], rec[1] << 8 | rec[2], rec[3], rec[4:4 + rec[0]]
        if kind == 0:
            chunks[base + addr] = payload
        elif kind == 1:
            return chunks
        elif kind == 2 and count == 2:
            base = (payload[0] << 8 | payload[1]) << 4
        elif kind == 4 and count == 2:
            base = (payload[0] << 8 | payload[1]) << 16
        elif kind not in (3, 5):
            raise FirmwareError(f"{path}:{n}: unknown record type {kind}")
    raise FirmwareError(f"{path}: cut short: no end-of-file record (:00000001FF) after its last line")


def _flatten(path: Path, chunks: dict[int, bytes], size: int, what: str) -> bytes:
    end = max((a + len(c) for a, c in chunks.items()), default=0)
    if end > size:
        raise FirmwareError(f"{path}: the {what} image is {end} bytes; the MCU has {size}")
    image = bytearray(b"\xff" * end)
    for addr, chunk in chunks.items():
        image[addr:addr + len(chunk)] = chunk
    return bytes(image)


def _for_this_mcu(path: Path, elf: _Elf | None, flash: bytes, mcu: str) -> None:
    """FirmwareError naming both MCUs when the image was built for another one: the ELF's device, then
    its architecture; then, for any image, the vector table's length when it is another MCU's."""
    want = MCUS[mcu]
    if elf is not None and elf.device is not None and elf.device != mcu:
        raise FirmwareError(f"{path}: built for the {elf.device} (its {elf.device_from}); the board's MCU "
                            f"is the {mcu}")
    if elf is not None and elf.arch and elf.arch != want.avr_arch:
        same = [m.name for m in MCUS.values() if m.avr_arch == elf.arch]
        like = f" (as the {same[0]})" if same else ""
        raise FirmwareError(f"{path}: built for another MCU: its ELF header says avr:{elf.arch}{like}; the "
                            f"board's {mcu} is avr:{want.avr_arch}")
    jumps = _vector_jumps(flash)
    if jumps and jumps != want.vectors:
        other = [m.name for m in MCUS.values() if m.vectors == jumps]
        if other:
            raise FirmwareError(f"{path}: built for another MCU: its vector table has {jumps} entries, as "
                                f"the {other[0]}'s; the board's {mcu} has {want.vectors}")


def _vector_jumps(flash: bytes) -> int:
    """How many 4-byte JMP instructions (1001 010k kkkk 110k, then 16 bits) the image starts with: the
    length of avr-gcc's vector table (0: the image does not start with one)."""
    n = 0
    while 4 * n + 4 <= len(flash) and (flash[4 * n] | flash[4 * n + 1] << 8) & 0xFE0E == 0x940C:
        n += 1
    return n


def load(path: Path, mcu: str) -> Image:
    """The flash and EEPROM images of ``path`` for ``mcu``; raises FirmwareError."""
    if mcu not in FLASH:
        raise FirmwareError(f"unknown MCU {mcu!r}; choose one of {', '.join(FLASH)}")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise FirmwareError(f"{path}: cannot read it ({exc.strerror})") from None
    eeprom: dict[int, bytes] = {}
    elf = None
    if data.startswith(b"\x7fELF"):
        elf = _elf(path, data)
        flash, eeprom = elf.flash, elf.eeprom
    elif data.lstrip()[:1] == b":":
        try:
            text = data.decode("ascii")
        except UnicodeDecodeError:
            raise FirmwareError(f"{path}: starts like Intel HEX but is not ASCII") from None
        flash = _hex(path, text)
    else:
        raise FirmwareError(f"{path}: neither an AVR ELF nor an Intel HEX file")
    image = _flatten(path, flash, FLASH[mcu], "flash")
    if not image:
        raise FirmwareError(f"{path}: no bytes for flash")
    _for_this_mcu(path, elf, image, mcu)
    return Image(image, _flatten(path, eeprom, EEPROM[mcu], "EEPROM") if eeprom else None)


def load_eeprom(path: Path, mcu: str) -> bytes:
    """An EEPROM image to preload: Intel HEX when the file is named so (avr-objcopy's ``.eep``, ``.hex``),
    else raw bytes (as the run's eeprom.bin: a raw image may start with ':'), no bigger than the MCU's
    EEPROM; raises FirmwareError."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise FirmwareError(f"{path}: cannot read it ({exc.strerror})") from None
    if path.suffix.lower() in (".eep", ".hex", ".ihex"):
        try:
            chunks = _hex(path, data.decode("ascii"))
        except UnicodeDecodeError:
            raise FirmwareError(f"{path}: starts like Intel HEX but is not ASCII") from None
        data = _flatten(path, chunks, EEPROM[mcu], "EEPROM")
    elif len(data) > EEPROM[mcu]:
        raise FirmwareError(f"{path}: the EEPROM image is {len(data)} bytes; the {mcu} has {EEPROM[mcu]}")
    return data
