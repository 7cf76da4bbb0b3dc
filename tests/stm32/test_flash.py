"""Flash programming on the rig's STM32F405 (qemu/hw/rig_stm32_flash_if.c) against RM0090 section 3 (3.5
to 3.9): the test firmware tests/stm32/firmware/flash_prog.c programs and erases the flash at the 16 MHz
HSI, times each operation from its start to EOP with DWT_CYCCNT, writes settings, resets the chip by
AIRCR.SYSRESETREQ and reads them back on its second boot. The expected values are the manual's register
descriptions, and the operations' times DS8626's typical ones (the STM32F405 datasheet, flash memory
programming), written here."""

from __future__ import annotations

import struct
import subprocess

import pytest

from rig.mcu import board as boards
from rig.mcu.stm32_image import config_section
from rig.mcu.stm32_link import Stm32Config, Stm32Engine
from tests.stm32.conftest import engine_or_skip, firmware, reports, run_firmware, run_to_done

HSI_HZ = 16_000_000
#: DS8626, flash memory programming, typical (x32 parallelism): a word, a 16, 64 and 128 KB sector
PROGRAM_S = 16e-6
ERASE_S = {16: 0.4, 64: 1.2, 128: 2.0}
#: the firmware's wait after the operation's end: the loop that sees EOP (or BSY clear), one DWT read
LOOP_CYCLES = 8
#: RM0090 3.9.4 (FLASH_SR) and 3.9.5 (FLASH_CR)
SR_EOP, SR_PGPERR, SR_PGSERR, SR_BSY = 1 << 0, 1 << 6, 1 << 7, 1 << 16
CR_SER, CR_EOPIE, CR_LOCK = 1 << 1, 1 << 24, 1 << 31
#: RM0090 7.3.21 (RCC_CSR): the reset flags
PINRSTF, SFTRSTF = 1 << 26, 1 << 28
#: what the firmware writes into its .fc_config section, sector 1 (flash_prog.c)
SETTINGS = (0x52494731, 0x0000_01F4, 0x3F80_0000, 0xC0FF_EE00)


@pytest.fixture(scope="module")
def run() -> subprocess.CompletedProcess[str]:
    done = run_to_done("flash_prog")
    return done


@pytest.fixture(scope="module")
def r(run: subprocess.CompletedProcess[str]) -> dict[str, int]:
    return reports(run.stdout)


def cycles(seconds: float) -> int:
    return round(seconds * HSI_HZ)


def test_registers_at_reset(r: dict[str, int]) -> None:
    assert r["flash_sr_reset"] == 0  # 3.9.4
    assert r["flash_cr_reset"] == CR_LOCK  # 3.9.5


def test_a_write_without_the_program_sequence_is_a_sequence_error(r: dict[str, int]) -> None:
    """3.9.4 PGSERR: a write to the flash while CR is not set up for it (locked, or PG clear); the cell
    keeps its value (erased flash reads 0xFF: 3.5.3)."""
    assert r["locked_write_before"] == 0xFFFF_FFFF
    assert r["locked_write_sr"] == SR_PGSERR and r["locked_write_word"] == 0xFFFF_FFFF
    assert r["sr_cleared"] == 0  # write 1 to clear
    assert r["cr_unlocked"] == 0  # 3.5.1: KEY1 then KEY2 clear LOCK
    assert r["no_pg_sr"] == SR_PGSERR and r["no_pg_word"] == 0xFFFF_FFFF


def test_a_word_programmed_is_busy_for_its_time_then_ends_with_eop(r: dict[str, int]) -> None:
    """3.5.4: BSY while the word is programmed; EOP (EOPIE set) and the FLASH interrupt at its end."""
    assert r["program_sr_busy"] & SR_BSY
    assert cycles(PROGRAM_S) <= r["program_cycles"] <= cycles(PROGRAM_S) + LOOP_CYCLES
    assert r["program_word"] == 0x1234_5678
    assert r["program_alias"] == 0x1234_5678  # RM0090 2.4: the flash also at 0 when booting from it


def test_programming_only_clears_bits(r: dict[str, int]) -> None:
    """A flash cell goes from 1 to 0 when programmed, only an erase sets it: the new word ANDs the old."""
    assert r["and_word"] == 0x1234_5678 & 0xF0F0_F0F0


def test_a_write_of_another_size_than_psize_is_a_parallelism_error(r: dict[str, int]) -> None:
    """3.9.4 PGPERR: a byte with PSIZE x32, and a misaligned word, which the core puts on the bus as
    bytes (ARMv7-M A3.2.1); nothing is programmed."""
    assert r["psize_sr"] == SR_PGPERR and r["psize_word"] == 0xFFFF_FFFF
    assert r["misaligned_sr"] == SR_PGPERR and r["misaligned_word"] == 0xFFFF_FFFF
    # a byte with PSIZE x8 and a half-word with x16 are programmed (little-endian)
    assert r["x8_x16_word"] == 0x1234_FF5A
    assert r["sr_after_programs"] == 0


def test_sector_erases_take_their_times_and_erase_the_sector(r: dict[str, int]) -> None:
    """3.5.3: SER, SNB, STRT; table 5's sectors: 1 is 16 KB, 4 is 64 KB, 11 is 128 KB."""
    for name, kb in (("erase1_cycles", 16), ("erase4_cycles", 64), ("erase11_cycles", 128)):
        assert cycles(ERASE_S[kb]) <= r[name] <= cycles(ERASE_S[kb]) + LOOP_CYCLES, name
    assert r["erase11_first"] == r["erase11_word1"] == r["erase11_last"] == 0xFFFF_FFFF
    # STRT cleared by the hardware at the end (3.9.5); SER, SNB = 4, PSIZE x32, EOPIE as written
    assert r["cr_after_erase"] == CR_EOPIE | 2 << 8 | 4 << 3 | CR_SER


def test_each_operation_interrupts_once(r: dict[str, int]) -> None:
    """Four programs (two words, a byte, a half-word) and three erases, each an EOP interrupt (NVIC 4)."""
    assert r["eop_interrupts"] == 7


def test_a_wrong_key_locks_until_reset(r: dict[str, int]) -> None:
    """3.5.1: a wrong key sequence locks CR until the next reset; after it the keys unlock again."""
    assert r["cr_relocked"] == CR_LOCK
    assert r["cr_wrong_key"] == CR_LOCK
    assert r["boot2_cr"] == CR_LOCK
    assert r["boot2_cr_unlocked"] == 0


def test_settings_written_survive_a_system_reset(r: dict[str, int]) -> None:
    """The flash keeps what was programmed through a reset; RCC_CSR after a software reset: SFTRSTF and
    PINRSTF (7.3.21; the power-on flags were cleared by RMVF on the first boot)."""
    assert r["boot2_csr"] == SFTRSTF | PINRSTF
    assert tuple(r[f"settings_{i}"] for i in range(4)) == SETTINGS
    assert r["settings_at"] == 0x0800_4000  # (RM0090 table 5: sector 1)


def test_the_rig_reads_the_settings_the_firmware_wrote() -> None:
    """Through the link, at 1 ms steps: the firmware's reset request does not end the run (it is counted),
    and at the end the engine's eeprom() is the .fc_config section as the firmware programmed it: the
    settings, the rest of the sector erased."""
    elf = firmware("flash_prog")
    section = config_section(elf.read_bytes())
    assert section is not None and section[2] == 0x4000
    engine = Stm32Engine(Stm32Config(boards.load("stm32f405-gy86"), elf, engine_or_skip(), hang_ns=0), None)
    try:
        t = 0
        while "boot2_cr=" not in engine.output():
            stop = engine.run_until(t := t + 1_000_000)
            assert stop.kind == "reached", stop.describe()
        settings = engine.eeprom()
        resets = engine.figures()["resets"]
    finally:
        engine.close()
    assert resets == 1
    assert settings == struct.pack("<4I", *SETTINGS) + b"\xff" * (0x4000 - 16)


def test_two_runs_are_identical(run: subprocess.CompletedProcess[str]) -> None:
    again = run_firmware(engine_or_skip(), firmware("flash_prog"))
    assert again.stdout == run.stdout
