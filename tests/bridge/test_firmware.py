"""The bridge firmware for the STM32G431 (bridge/stm32g4, built by rig/bridge/firmware.py): its ELF as
the MCU will boot it (the vector table at 0x08000000: the initial stack pointer in SRAM, the reset
handler a Thumb address in flash), the .bin a flasher writes, the budgets, and our ELF reader against
binutils' readelf."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

from rig.bridge import firmware as fw


@pytest.fixture(scope="module")
def elf() -> Path:
    return fw.build()


def test_the_vector_table_boots_from_flash_with_the_stack_in_sram(elf: Path) -> None:
    v = fw.vectors(elf, 16 + 102)
    sp, reset = v[0], v[1]
    assert fw.SRAM_BASE < sp <= fw.SRAM_BASE + fw.SRAM_SIZE and sp % 8 == 0
    assert reset & 1 == 1, "the reset handler must be a Thumb address (odd)"
    assert fw.FLASH_BASE <= reset - 1 < fw.FLASH_BASE + fw.FLASH_SIZE
    assert reset == fw.entry(elf)
    text = next(s for s in fw.sections(elf) if s.name == ".text")
    handlers = [h for h in v[1:] if h]
    assert len(v) == 16 + 102 and len(handlers) >= 10
    assert all(h & 1 and text.addr <= h - 1 < text.addr + text.size for h in handlers)


def test_the_bin_is_the_flash_image_from_0x08000000(elf: Path) -> None:
    image = (elf.parent / "bridge.bin").read_bytes()
    v = fw.vectors(elf, 2)
    assert int.from_bytes(image[0:4], "little") == v[0] and int.from_bytes(image[4:8], "little") == v[1]
    assert len(image) == fw.budget(elf).flash
    assert (elf.parent / "bridge.map").read_text().count("reset_handler") >= 1


def test_budgets_are_within_the_g431_and_a_smaller_part_fails(elf: Path) -> None:
    b = fw.budget(elf)
    b.check()
    assert 0 < b.flash < fw.FLASH_SIZE and 4096 < b.ram < fw.SRAM_SIZE  # the stack alone is 4 KB
    with pytest.raises(fw.FirmwareError, match="over budget: flash"):
        fw.budget(elf, flash_size=b.flash - 1).check()
    with pytest.raises(fw.FirmwareError, match="over budget: RAM"):
        fw.budget(elf, ram_size=b.ram - 1).check()


def test_our_elf_reader_agrees_with_readelf(elf: Path) -> None:
    out = subprocess.run(["arm-none-eabi-readelf", "-S", "-W", str(elf)], capture_output=True, text=True,
                         check=True).stdout
    theirs = {}
    for m in re.finditer(r"\]\s+(\.\S+)\s+\S+\s+([0-9a-f]{8})\s+([0-9a-f]{6})\s+([0-9a-f]{6})", out):
        theirs[m.group(1)] = (int(m.group(2), 16), int(m.group(3), 16), int(m.group(4), 16))
    ours = {s.name: (s.addr, s.offset, s.size) for s in fw.sections(elf) if s.name}
    assert ours == theirs and ".isr_vector" in ours


def test_a_file_that_is_not_an_arm_elf_is_refused(tmp_path: Path) -> None:
    bad = tmp_path / "x.elf"
    bad.write_bytes(b"not an elf at all" * 4)
    with pytest.raises(fw.FirmwareError, match="not a 32-bit little-endian ELF"):
        fw.sections(bad)
    with pytest.raises(fw.FirmwareError, match="not ARM"):
        x86 = tmp_path / "x86.elf"  # a 32-bit little-endian ELF header of an x86 program (EM_386)
        x86.write_bytes(b"\x7fELF\x01\x01\x01" + bytes(11) + (3).to_bytes(2, "little") + bytes(40))
        fw.sections(x86)


def symbols(elf: Path) -> dict[str, int]:
    out = subprocess.run(["arm-none-eabi-nm", str(elf)], capture_output=True, text=True, check=True).stdout
    return {w[2]: int(w[0], 16) for w in (line.split() for line in out.splitlines()) if len(w) == 3}


#: the STM32G4's interrupt positions (RM0440, NVIC chapter, vector table), written down here apart from
#: bridge/stm32g4/regs.h
IRQS = {"dma1_ch2_irq": 12, "tim2_irq": 28, "i2c1_ev_irq": 31, "i2c1_er_irq": 32, "usart1_irq": 37,
        "i2c3_ev_irq": 92, "i2c3_er_irq": 93}


def test_each_interrupt_the_firmware_handles_sits_at_its_place(elf: Path) -> None:
    v, sym = fw.vectors(elf, 16 + 102), symbols(elf)
    assert v[1] == sym["reset_handler"] | 1
    for name, irq in IRQS.items():
        assert v[16 + irq] == sym[name] | 1, name
    default = sym["default_handler"] | 1
    assert v[3] == default  # HardFault: spins until the watchdog resets the MCU
    assert sum(1 for h in v[16:] if h) == len(IRQS)  # nothing else is enabled, nothing else has a handler


def test_the_firmware_has_no_heap_and_no_stdio(elf: Path) -> None:
    """The core is written for no heap and no OS (bridge/core/hal.h): nothing of malloc or printf may be
    linked in (newlib's would pull in a heap through _sbrk and kilobytes of formatting)."""
    names = set(symbols(elf))
    assert not names & {"malloc", "_malloc_r", "free", "_sbrk", "printf", "_printf_r", "_vfprintf_r", "puts"}
    assert {"reset_handler", "main", "bridge_poll", "chip_advance"} <= names  # (the symbols are read)
