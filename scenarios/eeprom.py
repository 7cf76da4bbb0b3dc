"""The AVR reference firmware's configuration as an EEPROM image, built from a scenario's ``[fc]``
table: the AVR has no file to read ``fc.conf`` from, so the MCU tier preloads these bytes instead.

The layout is generated from the one key table, ``dut/src/config_keys.h`` (read by ``fc_keys``), as the
firmware's ``dut/src/config_image.c`` generates it from the same table, so neither can drift: a layout
word (the CRC-16 of the table's signature) makes the firmware refuse an image written for another table.
Keys absent from the table keep the firmware's defaults (a presence bit per key); ``profile`` is applied
before the keys; path keys (``i2c_path``, ``rc_path``, ``telemetry_path``) are the Linux FC's and take no
room. Pure data: nothing here runs a session.

    python -m rig.scenarios.eeprom SCENARIO -o fc.eep [--ihex]
"""

from __future__ import annotations

import argparse
import struct
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Final

from rig.scenarios import LIBRARY, fc_keys

MAGIC: Final = 0x4346  # "FC"
NO_PROFILE: Final = 0xFF
EEPROM_BYTES: Final = 4096  # the ATmega2560's


class EepromError(ValueError):
    """An [fc] table that cannot become an image: an unknown key or profile, a bad value."""


def crc16(data: bytes, crc: int = 0xFFFF) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF), as dut/src/config_image.c's fc_crc16."""
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


def layout() -> int:
    """The layout word: the CRC-16 of "name:KindCount;" for every key in table order."""
    sig = "".join(f"{k.name}:{k.kind}{k.count};" for k in fc_keys.keys().values())
    return crc16(sig.encode("ascii"))


def size() -> int:
    keys = list(fc_keys.keys().values())
    values = sum(4 * k.count if k.kind == "D" else 4 if k.kind == "I" else 0 for k in keys)
    return 6 + (len(keys) + 7) // 8 + values + 2


def image(fc: Mapping[str, object]) -> bytes:
    """The EEPROM image for a scenario's ``[fc]`` table (``Scenario.fc``: values as text, or TOML
    values). Raises EepromError naming the key for anything the firmware would refuse."""
    keys = list(fc_keys.keys().values())
    profile = NO_PROFILE
    given: dict[str, list[float]] = {}
    for name, raw in fc.items():
        if name == "profile":
            names = fc_keys.profiles()
            if raw not in names:
                raise EepromError(f"[fc] profile: expected one of {', '.join(names)}, got {raw!r}")
            profile = names.index(str(raw))
            continue
        key = fc_keys.keys().get(name)
        if key is None:
            raise EepromError(f"[fc] {name}: not a key of the reference FC")
        if key.kind == "S":
            continue  # a Linux path: nothing to store on the AVR
        text, why = key.check(raw)
        if why is not None:
            raise EepromError(f"[fc] {name}: {why}")
        values = [float(x) for x in text.split(",")]
        if key.kind == "I" and not -32768 <= values[0] <= 32767:
            raise EepromError(f"[fc] {name}: {values[0]:g} does not fit the AVR's 16-bit int")
        given[name] = values
    present = bytearray((len(keys) + 7) // 8)
    body = bytearray()
    for k, key in enumerate(keys):
        if key.kind == "S":
            continue
        vals = given.get(key.name)
        if vals is not None:
            present[k // 8] |= 1 << (k % 8)
        if key.kind == "I":
            body += struct.pack("<i", int(vals[0]) if vals else 0)
        else:
            body += struct.pack(f"<{key.count}f", *(vals or [0.0] * key.count))
    out = struct.pack("<HHBB", MAGIC, layout(), profile, len(keys)) + bytes(present) + bytes(body)
    out += struct.pack("<H", crc16(out))
    assert len(out) == size() <= EEPROM_BYTES
    return out


def ihex(data: bytes) -> str:
    """Intel HEX of ``data`` at address 0 (avrdude's ``-U eeprom:w:FILE:i``)."""
    lines = []
    for at in range(0, len(data), 16):
        chunk = data[at:at + 16]
        rec = bytes([len(chunk), at >> 8 & 0xFF, at & 0xFF, 0]) + chunk
        lines.append(f":{rec.hex().upper()}{(-sum(rec)) & 0xFF:02X}")
    lines.append(":00000001FF")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    from rig.scenarios.schema import ScenarioError, load

    ap = argparse.ArgumentParser(prog="python -m rig.scenarios.eeprom", description=__doc__.split("\n\n")[0])
    ap.add_argument("scenario", help="a scenario file, or a name from the library")
    ap.add_argument("-o", "--out", required=True, help="the image file to write")
    ap.add_argument("--ihex", action="store_true", help="write Intel HEX instead of raw bytes")
    a = ap.parse_args(argv)
    path = Path(a.scenario)
    if not path.exists():
        path = LIBRARY / f"{a.scenario}.toml"
    try:
        data = image(load(path).fc)
    except (ScenarioError, EepromError, OSError) as e:
        print(f"scenarios.eeprom: {e}", file=sys.stderr)
        return 2
    if a.ihex:
        Path(a.out).write_text(ihex(data))
    else:
        Path(a.out).write_bytes(data)
    print(f"{a.out}: {len(data)} of {EEPROM_BYTES} EEPROM bytes", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
