"""What an uploaded firmware is, told from its first bytes: a Linux program the service runs as the DUT
(an ELF for this host's machine, or a script with a ``#!`` line), or an image the MCU tier flies on a
board: an AVR image (an ELF for AVR, or Intel HEX) on an AVR board, an ARM image (a 32-bit
little-endian ELF for ARM) on an STM32 board. Anything else is refused on upload with what it looks like, so a
file never reaches the wrong engine (an AVR ELF started as a shell script fails with ``Syntax error``
deep in a run's log; here it is a 422 naming both).

Only the head is read: the image is checked whole against the board's MCU when a run names both
(rig/mcu/engines.py, as ``rig run --mcu`` checks it)."""

from __future__ import annotations

import struct
import sys
from pathlib import Path
from typing import Final

from rig.mcu.image import ELF_MACHINES, EM_AVR

#: how many bytes of an upload are looked at
HEAD: Final = 4096
ET_EXEC, ET_DYN = 2, 3
#: kinds: what the service does with each
LINUX: Final = ("linux-elf", "script")
AVR: Final = ("avr-elf", "intel-hex")
ARM: Final = ("arm-elf",)
#: the image kinds each MCU engine flies (rig/mcu/mcus.py's ``engine``), and the kinds in words
ENGINE_KINDS: Final = {"avr": AVR, "stm32": ARM}
ENGINE_IMAGES: Final = {"avr": "an AVR image (ELF or Intel HEX)", "stm32": "an ARM image (ELF)"}
#: every kind that flies on a board
BOARD_KINDS: Final = AVR + ARM
EM_ARM: Final = 40
#: magic numbers of files people upload by mistake, for the refusal's words
OTHER_MAGIC: Final = ((b"\x89PNG", "a PNG image"), (b"PK\x03\x04", "a ZIP archive"),
                      (b"\x1f\x8b", "a gzip file"), (b"%PDF", "a PDF document"), (b"MZ", "a Windows program"),
                      (b"\xcf\xfa\xed\xfe", "a macOS program"))


class ImageKindError(ValueError):
    """Not a firmware the service can run; the message says what was received."""


def machine_name(machine: int) -> str:
    return ELF_MACHINES.get(machine, f"machine {machine}")


def host_machine() -> int:
    """This host's ELF machine, read from the running Python's own executable (what the kernel runs)."""
    return _elf_header(Path(sys.executable).resolve().read_bytes()[:64])[1]


def _elf_header(head: bytes) -> tuple[int, int]:
    """(e_type, e_machine) of an ELF header, either byte order."""
    if len(head) < 20:
        raise ImageKindError("an ELF header cut short")
    order = "<" if head[5] == 1 else ">"
    kind, machine = struct.unpack_from(order + "HH", head, 16)
    return kind, machine


def kind_of(head: bytes) -> str:
    """The kind of a firmware from its first bytes (LINUX, AVR or ARM); ImageKindError in words otherwise."""
    if head.startswith(b"\x7fELF"):
        kind, machine = _elf_header(head)
        if machine == EM_AVR:
            return "avr-elf"
        host = host_machine()
        if machine == EM_ARM and machine != host and head[4:6] == b"\x01\x01":  # ELFCLASS32, little-endian
            return "arm-elf"
        if machine != host:
            raise ImageKindError(f"an ELF for {machine_name(machine)}: neither an MCU image (AVR, or ARM "
                                 f"32-bit little-endian) nor a program this host ({machine_name(host)}) runs")
        if kind not in (ET_EXEC, ET_DYN):
            raise ImageKindError(f"an ELF for {machine_name(machine)} that is no program (ELF type {kind}: "
                                 "an object file or a core dump?)")
        return "linux-elf"
    if head.startswith(b"#!"):
        return "script"
    if head.lstrip()[:1] == b":":
        return "intel-hex"
    for magic, what in OTHER_MAGIC:
        if head.startswith(magic):
            raise ImageKindError(f"{what}: neither a Linux program nor an MCU image")
    try:
        head.decode("utf-8")
    except UnicodeDecodeError:
        shown = " ".join(f"{b:02x}" for b in head[:8])
        raise ImageKindError(f"binary data beginning {shown}: neither a Linux program (an ELF or a #! "
                             "script) nor an MCU image (an AVR or ARM ELF, or Intel HEX)") from None
    raise ImageKindError("text without a #! line: neither a script the service can run nor Intel HEX")


def describe(kind: str) -> str:
    """A kind in words: what a refusal says it received."""
    return {"linux-elf": "a Linux program (ELF)", "script": "a Linux program (a #! script)",
            "avr-elf": "an AVR image (ELF)", "intel-hex": "an AVR image (Intel HEX)",
            "arm-elf": "an ARM image (ELF)"}.get(kind, kind)
