"""Images the engine must refuse before anything runs, each with a reason that names what is wrong: an
image built for another MCU (its ELF's device or architecture, a .hex's vector table) and a file cut
short. The images are the test firmwares, built for one MCU and offered to the other, or cut with
Python; what their headers say is checked against avr-readelf's words and the datasheets' vector counts
(57 for the ATmega2560, 26 for the ATmega328P), not against the loader."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from rig.mcu.image import FirmwareError, load
from tests.mcu.conftest import MCUS, REPO, firmware

OTHER = {"atmega328p": "atmega2560", "atmega2560": "atmega328p"}
ARCH = {"atmega328p": 5, "atmega2560": 6}  # avr-gcc -mmcu: avr5, avr6
VECTORS = {"atmega328p": 26, "atmega2560": 57}
BOARD = {"atmega328p": "promini328-gy86", "atmega2560": "mega2560-gy86"}


def objcopy(elf: Path, out: Path, *args: str) -> Path:
    subprocess.run(["avr-objcopy", *args, str(elf), str(out)], check=True)
    return out


def readelf_flags(elf: Path) -> str:
    header = subprocess.run(["avr-readelf", "-h", str(elf)], check=True, capture_output=True,
                            text=True).stdout
    return next(line.split(":", 1)[1].strip() for line in header.splitlines() if "Flags" in line)


@pytest.mark.parametrize("built_for", MCUS)
def test_an_elf_for_another_mcu_is_refused_naming_both(built_for: str) -> None:
    board_mcu = OTHER[built_for]
    with pytest.raises(FirmwareError) as err:
        load(firmware("imu_reader", built_for), board_mcu)
    said = str(err.value)
    assert f"built for the {built_for} (its .note.gnu.avr.deviceinfo)" in said
    assert f"the board's MCU is the {board_mcu}" in said


@pytest.mark.parametrize("built_for", MCUS)
def test_without_its_device_note_the_elf_header_says_the_architecture(built_for: str, tmp_path: Path) -> None:
    elf = objcopy(firmware("imu_reader", built_for), tmp_path / "bare.elf",
                  "--remove-section", ".note.gnu.avr.deviceinfo")
    arch, want = ARCH[built_for], ARCH[OTHER[built_for]]
    assert readelf_flags(elf).endswith(f"avr:{arch}")
    with pytest.raises(FirmwareError, match=f"its ELF header says avr:{arch} \\(as the {built_for}\\); the "
                                            f"board's {OTHER[built_for]} is avr:{want}"):
        load(elf, OTHER[built_for])
    assert load(elf, built_for).flash  # its own MCU takes it


def test_simavrs_mmcu_section_names_the_device_too(tmp_path: Path) -> None:
    """simavr's avr_mcu_section.h: records of (tag, length, data), AVR_MMCU_TAG_NAME = 1 with a 64-byte
    string, the AVR_MMCU_TAG (0, 0) anchor."""
    records = tmp_path / "mmcu.bin"
    records.write_bytes(bytes([1, 64]) + b"atmega328p".ljust(64, b"\0") + bytes([0, 0]))
    elf = objcopy(firmware("imu_reader", "atmega328p"), tmp_path / "mmcu.elf",
                  "--remove-section", ".note.gnu.avr.deviceinfo", "--add-section", f".mmcu={records}")
    with pytest.raises(FirmwareError, match=r"built for the atmega328p \(its \.mmcu\)"):
        load(elf, "atmega2560")


@pytest.mark.parametrize("built_for", MCUS)
def test_a_hex_for_another_mcu_is_refused_by_its_vector_table(built_for: str, tmp_path: Path) -> None:
    hexfile = objcopy(firmware("imu_reader", built_for), tmp_path / "fw.hex", "-O", "ihex", "-R", ".eeprom")
    board_mcu = OTHER[built_for]
    words = (f"its vector table has {VECTORS[built_for]} entries, as the {built_for}'s; the board's "
             f"{board_mcu} has {VECTORS[board_mcu]}")
    with pytest.raises(FirmwareError, match=words):
        load(hexfile, board_mcu)
    assert load(hexfile, built_for).flash


def test_the_cli_refuses_it_with_exit_2_before_anything_runs(tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, "-m", "rig.cli", "exec", "--mcu", BOARD["atmega2560"],
                           "--firmware", str(firmware("imu_reader", "atmega328p")), "--duration", "1",
                           "--summary", str(tmp_path / "s.json")],
                          capture_output=True, text=True, cwd=REPO, timeout=120)
    assert done.returncode == 2
    assert "built for the atmega328p" in done.stderr and "the board's MCU is the atmega2560" in done.stderr
    assert done.stdout == ""  # (no telemetry: nothing ran)


def test_an_elf_cut_short_is_refused(tmp_path: Path) -> None:
    """Cut after its program headers, its segments lie past the end; cut inside its sections (the
    debugging ones the linker writes after the code), the section headers do."""
    data = firmware("imu_reader", "atmega2560").read_bytes()
    for cut, words in ((148, "cut short: segment 0 ends at byte"),
                       (len(data) // 2, "cut short: its section headers end at byte")):
        short = tmp_path / f"cut{cut}.elf"
        short.write_bytes(data[:cut])
        with pytest.raises(FirmwareError, match=words):
            load(short, "atmega2560")


def test_a_hex_without_its_end_of_file_record_is_refused(tmp_path: Path) -> None:
    whole = objcopy(firmware("imu_reader", "atmega328p"), tmp_path / "fw.hex", "-O", "ihex", "-R", ".eeprom")
    lines = whole.read_text().splitlines()
    assert lines[-1] == ":00000001FF"  # Intel HEX's end-of-file record
    assert load(whole, "atmega328p").flash
    for keep in (len(lines) - 1, len(lines) // 2):
        short = tmp_path / f"cut{keep}.hex"
        short.write_text("\n".join(lines[:keep]) + "\n")
        with pytest.raises(FirmwareError, match=r"cut short: no end-of-file record \(:00000001FF\)"):
            load(short, "atmega328p")
