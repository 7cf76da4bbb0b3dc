"""The STM32F411 (rig-stm32f411, rig/mcu/mcus.py's stm32f411, the board stm32f411-blackpill-gy86) against
its reference manual, RM0383 rev 3, and its datasheet, DS10314: the test firmware f411_map.c reports the
F411's RCC at reset, its memory map probed word by word (a BusFault counted for each absent address), and
100 MHz set up from the Black Pill's 25 MHz crystal; the image check refuses what only an F405 holds; the
reference FC built for the board (build/stm32/fc-f411.elf) flies through `rig run`, twice alike. Every
expected value is the manual's (section named) or a formula of its clock tree written here."""

from __future__ import annotations

import json
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from rig.mcu.board import BoardError, load
from rig.mcu.image import FirmwareError
from rig.mcu.mcus import MCUS
from rig.mcu.stm32_image import check_image
from tests.stm32.conftest import REPO, engine_or_skip, firmware, reports, run_firmware
from tests.stm32.test_reference_fc import DURATION_S, PWM_PERIOD_S, SCENARIO, STEP_DEG

HSI_HZ = 16_000_000
HSE_HZ = 25_000_000  # the Black Pill's crystal
BOARD = "stm32f411-blackpill-gy86"
#: RM0383 2.3 (memory map) and table 1 (register boundary addresses): what the F405 has and the F411 not
ABSENT = {"flash_end": 0x0808_0000, "alias_end": 0x0008_0000, "sram_end": 0x2002_0000, "ccm": 0x1000_0000,
          "tim6": 0x4000_1000, "tim8": 0x4001_0400, "usart3": 0x4000_4800, "gpiof": 0x4002_1400,
          "gpioi": 0x4002_2000, "can1": 0x4000_6400, "uart7": 0x4000_7800}
PRESENT = ("flash_last", "sram_last", "tim3", "tim11", "gpioh")
#: ARMv7-M B3.2.15, the BusFault status register (CFSR bits 15:8): BFARVALID and PRECISERR
BFSR_PRECISE = (1 << 15) | (1 << 9)


def _run(machine: str) -> subprocess.CompletedProcess[str]:
    return run_firmware(engine_or_skip(), firmware("f411_map"), "-global", f"rig-stm32f4-rcc.hse-hz={HSE_HZ}",
                        "-d", "guest_errors", machine=machine)


@pytest.fixture(scope="module")
def done() -> subprocess.CompletedProcess[str]:
    done = _run("rig-stm32f411")
    assert done.returncode == 0, f"status {done.returncode}\n{done.stdout}\n{done.stderr}"
    return done


@pytest.fixture(scope="module")
def r(done: subprocess.CompletedProcess[str]) -> dict[str, int]:
    return reports(done.stdout)


def test_rcc_at_reset_is_the_f411s(r: dict[str, int]) -> None:
    """RM0383 6.3.1-6.3.24 and the RCC register map: the reset values that differ from the F405's."""
    assert r["rcc_cr_reset"] & 0xFFFF00FF == 0x0000_0083
    assert r["rcc_pllcfgr_reset"] == 0x2400_3010
    assert r["rcc_ahb1enr_reset"] == 0  # no CCM RAM, so no CCMDATARAMEN (the F405's 0x00100000)
    assert r["rcc_ahb1lpenr_reset"] == 0x0061_900F
    assert r["rcc_ahb2lpenr_reset"] == 0x0000_0080
    assert r["rcc_apb1lpenr_reset"] == 0x10E2_C80F
    assert r["rcc_apb2lpenr_reset"] == 0x0007_7930
    assert r["rcc_plli2scfgr_reset"] == 0x2400_3000
    assert r["rcc_dckcfgr_reset"] == 0


def test_rcc_enables_only_what_the_f411_has(r: dict[str, int]) -> None:
    """All ones written: the enable bits RM0383 6.3.10-6.3.13 define (GPIOA-E and H, CRC, DMA1/2; TIM2-5,
    WWDG, SPI2/3, USART2, I2C1-3, PWR; TIM1, USART1/6, ADC1, SDIO, SPI1/4, SYSCFG, TIM9-11, SPI5),
    DCKCFGR's TIMPRE, and nothing at AHB3ENR (reserved: no FSMC)."""
    gpio = sum(1 << b for b in (0, 1, 2, 3, 4, 7))
    assert r["rcc_ahb1enr_ones"] == gpio | 1 << 12 | 1 << 21 | 1 << 22
    assert r["rcc_apb1enr_ones"] == (0xF | 1 << 11 | 1 << 14 | 1 << 15 | 1 << 17 | 0x7 << 21 | 1 << 28)
    assert r["rcc_apb2enr_ones"] == (1 << 0 | 1 << 4 | 1 << 5 | 1 << 8 | 1 << 11 | 1 << 12 | 1 << 13 | 1 << 14
                                     | 0x7 << 16 | 1 << 20)
    assert r["rcc_dckcfgr_ones"] == 1 << 24
    assert r["rcc_ahb3enr_ones"] == 0


def test_the_memory_map_is_the_f411s(r: dict[str, int], done: subprocess.CompletedProcess[str]) -> None:
    """The last word of the 512 KB flash (and its alias at 0) and of the 128 KB SRAM read; the word after
    each, the CCM RAM and the F405's peripherals the F411 lacks answer with a bus error: a precise
    BusFault with BFAR the address read (ARMv7-M B1.5.8), logged under -d guest_errors."""
    for name in PRESENT:
        assert r[f"{name}_faults"] == 0, name
    for name, address in ABSENT.items():
        assert r[f"{name}_faults"] == 1, name
        assert r[f"{name}_bfar"] == address, name
    assert r["bus_fault_bfsr"] == BFSR_PRECISE
    assert r["tim6_store_faults"] == 1
    assert "read of 0x40001000: TIM6 (not on the F411)" in done.stderr
    assert "write of 0x40001000: TIM6 (not on the F411)" in done.stderr


def test_the_f405_machine_has_what_the_f411_lacks() -> None:
    """The same firmware on rig-stm32f405: its 1 MB of flash, CCM RAM, TIM6, TIM8, USART3, GPIOF and GPIOI
    answer; its SRAM ends at 128 KB as the F411's (RM0090 2.3: SRAM1 and SRAM2, 112 + 16 KB)."""
    done = _run("rig-stm32f405")
    assert done.returncode == 0, done.stdout + done.stderr
    r = reports(done.stdout)
    f405_has = ("flash_end", "alias_end", "ccm", "tim6", "tim8", "usart3", "gpiof", "gpioi", "can1")
    for name in (*f405_has, *PRESENT):
        assert r[f"{name}_faults"] == 0, name
    assert r["sram_end_faults"] == 1 and r["sram_end_bfar"] == ABSENT["sram_end"]
    assert r["rcc_ahb1enr_reset"] == 0x0010_0000  # RM0090 7.3.10: CCMDATARAMEN


def test_100_mhz_from_the_25_mhz_crystal(r: dict[str, int]) -> None:
    """RM0383 6.3.2: f_VCO = f_HSE x PLLN / PLLM, f_SYSCLK = f_VCO / PLLP; the same loop (the same
    instructions, so the same virtual time under icount) counts HCLK cycles in proportion."""
    pll = r["rcc_pllcfgr"]
    m, n, p = pll & 0x3F, pll >> 6 & 0x1FF, 2 * ((pll >> 16 & 0x3) + 1)
    assert (m, n, p) == (25, 200, 2) and pll & 1 << 22  # PLLSRC = HSE
    sysclk = HSE_HZ // m * n // p
    assert sysclk == 100_000_000
    assert r["rcc_cfgr_pll"] & 0xF == 0b1010  # SW = SWS = PLL
    for counter in ("cycles", "ticks"):
        slow, fast = r[f"spin_{counter}_16mhz"], r[f"spin_{counter}_100mhz"]
        assert abs(fast - slow * sysclk / HSI_HZ) <= 2 * sysclk / HSI_HZ, (counter, slow, fast)


def test_two_runs_print_the_same_bytes(done: subprocess.CompletedProcess[str]) -> None:
    again = _run("rig-stm32f411")
    assert again.stdout == done.stdout


def _elf(tmp_path: Path, segments: list[tuple[int, bytes]]) -> Path:
    """An ARM ELF of program headers only (no sections), each segment loaded at its address."""
    header, phsize = 52, 32
    body = b"".join(data for _, data in segments)
    out = bytearray(struct.pack("<4sBBBB8xHHIIIIIHHHHHH", b"\x7fELF", 1, 1, 1, 0, 2, 40, 1, 0x0800_0009,
                                header, 0, 0x0500_0400, header, phsize, len(segments), 40, 0, 0))
    offset = header + phsize * len(segments)
    for address, data in segments:
        out += struct.pack("<IIIIIIII", 1, offset, address, address, len(data), len(data), 5, 4)
        offset += len(data)
    path = tmp_path / "image.elf"
    path.write_bytes(bytes(out + body))
    return path


def test_the_image_check_refuses_what_only_an_f405_holds(tmp_path: Path) -> None:
    """RM0383 2.3: 512 KB of flash from 0x08000000 and 128 KB of SRAM from 0x20000000, no CCM RAM."""
    f405, f411 = MCUS["stm32f405"], MCUS["stm32f411"]
    vectors = struct.pack("<II", 0x2002_0000, 0x0800_0009)
    fits = _elf(tmp_path, [(0x0800_0000, vectors + b"\0" * 8)])
    check_image(fits, f405)
    check_image(fits, f411)
    ccm_stack = _elf(tmp_path, [(0x0800_0000, struct.pack("<II", 0x1001_0000, 0x0800_0009))])
    check_image(ccm_stack, f405)
    with pytest.raises(FirmwareError, match=r"stack pointer 0x10010000 is not in the STM32F411's RAM "
                                            r"\(0x20000000 128 KB\)"):
        check_image(ccm_stack, f411)
    high_code = _elf(tmp_path, [(0x0800_0000, vectors), (0x0808_0000, b"\0" * 16)])
    check_image(high_code, f405)
    with pytest.raises(FirmwareError, match=r"segment 1 loads at 0x08080000\.\.0x08080010, outside the "
                                            r"STM32F411's 512 KB flash \(0x08000000\)"):
        check_image(high_code, f411)


def test_rig_run_refuses_an_f405_only_image_for_the_black_pill(tmp_path: Path) -> None:
    """Before QEMU starts: exit 2, the reason on one line."""
    elf = _elf(tmp_path, [(0x0800_0000, struct.pack("<II", 0x1001_0000, 0x0800_0009))])
    done = subprocess.run([sys.executable, "-m", "rig.cli", "run", "--mcu", BOARD, "--firmware", str(elf),
                           "hover_turbulence", "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, timeout=120, cwd=REPO)
    assert done.returncode == 2, done.stdout + done.stderr
    lines = [ln for ln in done.stderr.splitlines() if "stack pointer 0x10010000" in ln]
    assert len(lines) == 1 and "STM32F411's RAM" in lines[0], done.stderr


def test_the_board_file() -> None:
    """DS10314 table 9: I2C1 on PB8/PB9 (AF4), TIM3 CH1-CH4 on PA6, PA7, PB0, PB1 (AF2), USART1 RX PA10,
    USART2 TX PA2; the Black Pill's 25 MHz crystal; the F411's 100 MHz."""
    b = load(BOARD)
    assert b.mcu is MCUS["stm32f411"] and b.mcu.machine == "rig-stm32f411"
    assert (b.clock_hz, b.hse_hz) == (100_000_000, HSE_HZ)
    assert [(m.motor, m.pin, m.timer, m.channel) for m in b.motors] == [
        (1, "PA6", 3, "1"), (2, "PA7", 3, "2"), (3, "PB0", 3, "3"), (4, "PB1", 3, "4")]
    assert b.rc is not None and (b.rc.protocol, b.rc.uart) == ("sbus", 1)
    assert b.mcu.usarts[1][0] == "PA10" and b.telemetry_uart == 2 and b.mcu.usarts[2][1] == "PA2"
    pins = {m.pin for m in b.motors}
    assert not pins & {"PB8", "PB9", *b.mcu.usarts[1], *b.mcu.usarts[2]}


def test_a_board_using_what_the_f411_lacks_is_refused(tmp_path: Path) -> None:
    text = (REPO / "rig/mcu/boards" / f"{BOARD}.toml").read_text()
    for bad, message in ((("timer = 3\nchannel = \"1\"", "timer = 8\nchannel = \"1\""), "no TIM8_CH1"),
                         (("uart = 2 ", "uart = 3 "), "telemetry.uart"),
                         (("clock_hz = 100_000_000", "clock_hz = 168_000_000"), "clock_hz"),
                         (("hse_hz = 25_000_000", "hse_hz = 50_000_000"), "hse_hz")):
        path = tmp_path / "bad.toml"
        path.write_text(text.replace(*bad, 1))
        with pytest.raises(BoardError, match=message):
            load(path)


def _fly(tmp_path: Path, name: str) -> Path:
    done = subprocess.run(["make", "-s", "--no-print-directory", "INSTALLED=1", "stm32"], cwd=REPO,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    scenario = tmp_path / "stm32_fc_step.toml"
    scenario.write_text(SCENARIO)
    out = tmp_path / name
    done = subprocess.run([sys.executable, "-m", "rig.cli", "run", "--mcu", BOARD, "--firmware",
                           str(REPO / "build/stm32/fc-f411.elf"), str(scenario), "--out", str(out)],
                          capture_output=True, text=True, timeout=600, cwd=REPO)
    assert done.returncode == 0, done.stdout + done.stderr
    return out / "stm32_fc_step"


def test_the_reference_fc_flies_on_the_black_pill_twice_alike(tmp_path: Path) -> None:
    """The reference FC for the board (100 MHz, I2C1 on PB8/PB9, TIM3's four channels, telemetry on
    USART2) flies test_reference_fc's roll step: a pass, a pulse each 2041 us on each motor (TIM3 at
    2 x 50 MHz / 100 / 2041: RM0383 6.2, the timer clock twice PCLK1), and a second run the same."""
    engine_or_skip()
    out = _fly(tmp_path, "a")
    r = json.loads((out / "result.json").read_text())
    assert r["verdict"] == "pass", r["error"]
    assert [m["outcome"] for m in r["measurements"]] == ["pass", "pass"]
    mcu = r["metadata"]["mcu"]
    assert mcu["twi_nacks"] == 0 and mcu["ipsr"] == 0 and mcu["cfsr"] == 0
    periods = DURATION_S / PWM_PERIOD_S
    assert len(mcu["motor_pulses"]) == 4
    assert all(periods - 5 <= n <= periods + 2 for n in mcu["motor_pulses"]), mcu["motor_pulses"]
    text = (out / "dut-telemetry.txt").read_text()
    lines = text[:text.rfind("\n") + 1].splitlines()  # whole lines (the run's end may cut the last)
    assert lines[0] == "# fc: STM32F411 reference FC"
    last = dict(kv.split("=", 1) for kv in [ln for ln in lines if ln.startswith("T ")][-1].split()[1:])
    assert last["armed"] == "1" and last["rc"] == "1" and last["overruns"] == "0"
    assert abs(float(last["roll"]) - STEP_DEG) < 1.0
    again = _fly(tmp_path, "b")
    assert (again / "dut-telemetry.txt").read_text() == text
    r2 = json.loads((again / "result.json").read_text())
    assert r2["measurements"] == r["measurements"]
    assert r2["metadata"]["mcu"]["motor_pulses"] == mcu["motor_pulses"]
