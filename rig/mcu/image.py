"""A firmware file read into the flash and EEPROM images the engine loads: an AVR ELF (its loadable
segments at their load addresses, as avr-objcopy takes them) or an Intel HEX. Anything else, or an image
bigger than the MCU's flash, is refused here, before anything runs, with the reason: a file is never
trusted (a DUT's build output may be anything)."""

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


def _elf(path: Path, data: bytes) -> tuple[dict[int, bytes], dict[int, bytes]]:
    if len(data) < 52 or data[4] != 1 or data[5] != 1:
        raise FirmwareError(f"{path}: an ELF, but not AVR's kind (32-bit little-endian)")
    machine = struct.unpack_from("<H", data, 18)[0]
    if machine != EM_AVR:
        raise FirmwareError(f"{path}: an ELF for machine {machine}, not AVR's ({EM_AVR})")
    phoff, = struct.unpack_from("<I", data, 28)
    phentsize, phnum = struct.unpack_from("<HH", data, 42)
    flash: dict[int, bytes] = {}
    eeprom: dict[int, bytes] = {}
    for i in range(phnum):
        at = phoff + i * phentsize
        if at + 32 > len(data):
            raise FirmwareError(f"{path}: program header {i} lies outside the file")
        kind, offset, _vaddr, paddr, filesz = struct.unpack_from("<IIIII", data, at)
        if kind != 1 or filesz == 0:  # PT_LOAD with bytes
            continue
        if offset + filesz > len(data):
            raise FirmwareError(f"{path}: segment {i} lies outside the file")
        chunk = data[offset:offset + filesz]
        if paddr < RAM_BASE:
            flash[paddr] = chunk
        elif EEPROM_BASE <= paddr < EEPROM_BASE + 0x10000:
            eeprom[paddr - EEPROM_BASE] = chunk
    return flash, eeprom


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
            break
        elif kind == 2 and count == 2:
            base = (payload[0] << 8 | payload[1]) << 4
        elif kind == 4 and count == 2:
            base = (payload[0] << 8 | payload[1]) << 16
        elif kind not in (3, 5):
            raise FirmwareError(f"{path}:{n}: unknown record type {kind}")
    return chunks


def _flatten(path: Path, chunks: dict[int, bytes], size: int, what: str) -> bytes:
    end = max((a + len(c) for a, c in chunks.items()), default=0)
    if end > size:
        raise FirmwareError(f"{path}: the {what} image is {end} bytes; the MCU has {size}")
    image = bytearray(b"\xff" * end)
    for addr, chunk in chunks.items():
        image[addr:addr + len(chunk)] = chunk
    return bytes(image)


def load(path: Path, mcu: str) -> Image:
    """The flash and EEPROM images of ``path`` for ``mcu``; raises FirmwareError."""
    if mcu not in FLASH:
        raise FirmwareError(f"unknown MCU {mcu!r}; choose one of {', '.join(FLASH)}")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise FirmwareError(f"{path}: cannot read it ({exc.strerror})") from None
    eeprom: dict[int, bytes] = {}
    if data.startswith(b"\x7fELF"):
        flash, eeprom = _elf(path, data)
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
    return Image(image, _flatten(path, eeprom, EEPROM[mcu], "EEPROM") if eeprom else None)
