"""The engine's run loop: time, the firmware's errors named, files refused before anything runs."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from rig.mcu.engine import AvrEngine, EngineConfig, FirmwareError
from tests.mcu.conftest import MCUS, firmware

CLOCK = 16_000_000


def engine(name: str, mcu: str, **kw: object) -> AvrEngine:
    return AvrEngine(EngineConfig(mcu, CLOCK, firmware(name, mcu), **kw), None)  # type: ignore[arg-type]


@pytest.mark.parametrize("mcu", MCUS)
def test_time_is_the_cycle_counter_over_the_clock(mcu: str) -> None:
    with engine("busy", mcu, hang_ns=0) as e:
        for t in (1_000_000, 2_000_000, 2_000_001, 7_500_000):
            assert e.run_until(t).kind == "reached"
            assert e.cycle >= t * CLOCK // 10**9
            assert e.cycle - t * CLOCK / 1e9 < 4  # an instruction at most past the time asked
            assert e.now_ns == e.cycle * 10**9 // CLOCK
        assert e.run_until(1_000_000).kind == "reached" and e.now_ns >= 7_500_000  # earlier: nothing


def test_the_same_image_runs_the_same_cycles() -> None:
    runs = []
    for _ in range(2):
        with engine("busy", "atmega328p", hang_ns=0) as e:
            e.run_until(3_000_000)
            runs.append((e.cycle, e.figures()["instructions"], e.peek(0x100), e.peek(0x101)))
    assert runs[0] == runs[1]


@pytest.mark.parametrize("mcu", MCUS)
def test_a_firmware_with_no_bus_and_no_pulses_hangs(mcu: str) -> None:
    with engine("busy", mcu, hang_ns=20_000_000) as e:
        stop = e.run_until(10_000_000)
        assert stop.kind == "reached"
        stop = e.run_until(30_000_000)
        assert stop.kind == "hung" and "no TWI transaction and no motor pulse for 20 ms" in stop.what
        assert e.run_until(40_000_000) == stop  # final


@pytest.mark.parametrize("mcu", MCUS)
def test_sleep_with_interrupts_off_never_wakes(mcu: str) -> None:
    with engine("sleep_cli", mcu) as e:
        stop = e.run_until(5_000_000)
        assert stop.kind == "sleeping" and stop.cycle < 100 and "never wakes" in stop.what
        assert stop.describe().startswith("fell asleep for good: sleep with interrupts off: it never wakes "
                                          "(pc 0x")


@pytest.mark.parametrize("mcu", MCUS)
def test_a_jump_past_the_program_is_a_crash_with_its_pc(mcu: str) -> None:
    with engine("wild_jump", mcu) as e:
        stop = e.run_until(5_000_000)
        assert stop.kind == "crashed" and stop.pc == 0x6000 and "outside the program" in stop.what
        assert "pc 0x06000" in stop.describe()


@pytest.mark.parametrize("mcu", MCUS)
def test_an_invalid_opcode_is_a_crash_at_its_pc(mcu: str) -> None:
    path = firmware("bad_opcode", mcu)
    with engine("bad_opcode", mcu) as e:
        stop = e.run_until(5_000_000)
    assert stop.kind == "crashed" and "invalid opcode 0x0001" in stop.what
    assert 0 < stop.pc < path.stat().st_size and stop.cycle < 1000


@pytest.mark.parametrize("mcu", MCUS)
def test_a_watchdog_reset_loop_ends_the_run(mcu: str) -> None:
    with engine("watchdog", mcu, watchdog_resets=3) as e:
        stop = e.run_until(1_000_000_000)
        figures = e.figures()
    assert stop.kind == "watchdog" and "3 times" in stop.what
    assert stop.describe().startswith("was reset by its watchdog in a loop: 3 times (pc 0x")
    # WDTO_15MS is 2048 cycles of the 128 kHz oscillator: 16 ms, three times
    assert 47_000_000 < stop.cycle * 10**9 // CLOCK < 50_000_000
    assert figures["watchdog_resets"] == 3


def test_files_that_are_not_avr_firmware_are_refused(tmp_path: Path) -> None:
    text = tmp_path / "notes.txt"
    text.write_text("hello\n")
    with pytest.raises(FirmwareError, match="neither an AVR ELF nor an Intel HEX"):
        engine_for(text)
    # ELF headers of other machines (the System V ABI's e_machine: 62 x86-64, 40 ARM) say what they are
    for name, width, machine, words in (("x86.elf", 2, 62, "x86-64 (machine 62), 64-bit little-endian"),
                                        ("arm.elf", 1, 40, "ARM (machine 40), 32-bit little-endian")):
        other = tmp_path / name
        other.write_bytes(b"\x7fELF" + bytes([width, 1, 1]) + bytes(9) + (2).to_bytes(2, "little")
                          + machine.to_bytes(2, "little") + bytes(44))
        with pytest.raises(FirmwareError, match=re.escape(f"an ELF for {words}; an AVR image is for AVR "
                                                          "(machine 83), 32-bit little-endian")):
            engine_for(other)
    bad = tmp_path / "bad.hex"
    bad.write_text(":100000000C9434000C943E000C943E000C943E0000\n")
    with pytest.raises(FirmwareError, match="checksum"):
        engine_for(bad)
    with pytest.raises(FirmwareError, match="cannot read"):
        engine_for(tmp_path / "missing.elf")


def test_a_firmware_bigger_than_flash_is_refused(tmp_path: Path) -> None:
    big = tmp_path / "big.hex"
    lines = []
    for addr in range(0, 0x8010, 16):  # 32 KB + 16: one record past the ATmega328P's flash
        rec = bytes([16, (addr >> 8) & 0xFF, addr & 0xFF, 0]) + bytes(16)
        if addr == 0:
            lines.append(":020000040000FA")  # (an extended linear address record: upper 16 bits 0)
        lines.append(":" + (rec + bytes([-sum(rec) & 0xFF])).hex().upper())
    lines.append(":00000001FF")
    big.write_text("\n".join(lines) + "\n")
    with pytest.raises(FirmwareError, match=f"{0x8010} bytes; the MCU has {32 * 1024}"):
        engine_for(big)
    AvrEngine(EngineConfig("atmega2560", CLOCK, big), None).close()  # 256 KB: it fits


def test_an_intel_hex_runs_as_its_elf(tmp_path: Path) -> None:
    import subprocess

    elf = firmware("watchdog", "atmega328p")
    hexfile = tmp_path / "watchdog.hex"
    subprocess.run(["avr-objcopy", "-O", "ihex", "-R", ".eeprom", str(elf), str(hexfile)], check=True)
    stops = []
    for path in (elf, hexfile):
        with AvrEngine(EngineConfig("atmega328p", CLOCK, path), None) as e:
            stops.append(e.run_until(1_000_000_000))
    assert stops[0] == stops[1] and stops[0].kind == "watchdog"


def engine_for(path: Path) -> AvrEngine:
    return AvrEngine(EngineConfig("atmega328p", CLOCK, path), None)


def test_a_closed_engine_says_so() -> None:
    e = engine("busy", "atmega328p")
    e.close()
    e.close()
    with pytest.raises(RuntimeError, match="closed"):
        e.run_until(1_000)


def test_an_eeprom_image_bigger_than_the_eeprom_is_refused() -> None:
    with pytest.raises(FirmwareError, match="EEPROM image is 1025 bytes; the atmega328p's EEPROM is 1024"):
        engine("busy", "atmega328p", eeprom=bytes(1025))


@pytest.mark.parametrize("mcu", MCUS)
def test_the_wdton_fuse_keeps_the_watchdog_on(mcu: str) -> None:
    with engine("wdt_clear", mcu, hang_ns=0) as e:
        assert e.run_until(100_000_000).kind == "reached"  # no fuse: wdt_disable holds
    with engine("wdt_clear", mcu, hang_ns=0, watchdog_always_on=True) as e:
        stop = e.run_until(100_000_000)
    assert stop.kind == "watchdog"
    assert 47_000_000 < stop.cycle * 10**9 // CLOCK < 50_000_000  # 16 ms (WDP 0), three times


@pytest.mark.parametrize("name", ["mega2560-gy86", "promini328-gy86"])
def test_a_shipped_board_configures_the_engine(name: str) -> None:
    from rig.mcu import board as boards
    from rig.mcu.engine import config_for

    b = boards.load(name)
    cfg = config_for(b, firmware("busy", b.mcu.name), hang_ns=0)
    assert [m.pin for m in cfg.motors] == [m.pin for m in sorted(b.motors, key=lambda m: m.motor)]
    with AvrEngine(cfg, None) as e:
        assert e.run_until(1_000_000).kind == "reached"
        assert e.pulses() == [[], [], [], []]  # (the busy loop drives no timer)
