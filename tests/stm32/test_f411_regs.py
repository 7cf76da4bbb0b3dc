"""The F411's own PWR, FLASH-interface and GPIO register tables, its 8 flash sectors and their erase times,
and RCC_DCKCFGR.TIMPRE, against RM0383 rev 3 and DS10314 (the STM32F411xC/E datasheet): the test firmware
f411_regs.c reports them on rig-stm32f411 at the 16 MHz HSI; the same firmware on rig-stm32f405 gets the
F405's (RM0090, DS8626), so each table is the chip's own. Every expected value is the manual's (section
named) or a formula of it written here."""

from __future__ import annotations

import subprocess

import pytest

from tests.stm32.conftest import reports, run_to_done

HSI_HZ = 16_000_000
#: RM0383 5.4.1 (PWR_CR): LPDS, PDDS, PVDE, PLS[2:0], DBP, FPDS, LPLVDS, MRLVDS, ADCDC1, VOS[1:0], FMSSR,
#: FISSR; CWUF and CSBF (bits 2, 3) are write-only and read 0. Reset: VOS = 10, scale 2
F411_PWR_CR_WRITABLE = (1 << 0 | 1 << 1 | 1 << 4 | 0x7 << 5 | 1 << 8 | 1 << 9 | 1 << 10 | 1 << 11 | 1 << 13
                        | 0x3 << 14 | 1 << 20 | 1 << 21)
F411_PWR_CR_RESET = 0b10 << 14
#: RM0090 5.4.1 (the F405's PWR_CR): VOS is one bit, 14, reset 1 (scale 1)
F405_PWR_CR_WRITABLE = 1 << 0 | 1 << 1 | 1 << 4 | 0x7 << 5 | 1 << 8 | 1 << 9 | 1 << 14
F405_PWR_CR_RESET = 1 << 14
#: PWR_CSR (RM0383 5.4.2, RM0090 5.4.2): BRR (3) follows BRE (9), EWUP (8), VOSRDY (14)
CSR_BRR, CSR_EWUP, CSR_BRE, CSR_VOSRDY = 1 << 3, 1 << 8, 1 << 9, 1 << 14
#: FLASH_ACR (RM0383 3.8.1, RM0090 3.9.1): LATENCY[2:0] on both (ST's stm32f411xe.h and stm32f405xx.h mask
#: it 0x7; the F42x's is four bits), PRFTEN, ICEN, DCEN
ACR_LATENCY, ACR_CACHES = 0x7, 1 << 8 | 1 << 9 | 1 << 10
#: FLASH_SR and FLASH_CR (RM0383 3.8.4, 3.8.5)
SR_BSY = 1 << 16
CR_SER, CR_STRT, CR_EOPIE, CR_LOCK = 1 << 1, 1 << 16, 1 << 24, 1 << 31
#: RM0383 8.4.1, 8.4.3, 8.4.4: ports A and B reset with their debug pins as alternate functions, PA13
#: (SWDIO) at very high speed; the other ports 0
F411_GPIO_RESET = {"gpioa_moder": 0xA800_0000, "gpioa_ospeedr": 0x0C00_0000, "gpioa_pupdr": 0x6400_0000,
                   "gpiob_moder": 0x0000_0280, "gpiob_ospeedr": 0x0000_00C0, "gpiob_pupdr": 0x0000_0100,
                   "gpioc_moder": 0, "gpioc_ospeedr": 0, "gpioh_moder": 0}
#: DS10314, flash memory programming: typical sector erase times by parallelism (PSIZE)
F411_ERASE_S = {("erase5", "x32"): 1.0, ("erase2", "x16"): 0.3, ("erase4", "x8"): 1.2}
#: DS8626's (the F405's): one typical time per sector size, whatever the parallelism
F405_ERASE_S = {("erase5", "x32"): 2.0, ("erase2", "x16"): 0.4, ("erase4", "x8"): 1.2}
#: a mass erase at x32: DS10314's typical 4 s (8 at x8, 5.5 at x16), DS8626's 16 s
F411_MASS_ERASE_S, F405_MASS_ERASE_S = 4.0, 16.0
#: the firmware's wait after EOP (the WFI loop that sees it, one DWT read), and the polling loop that sees
#: TIM2's UIF
LOOP_CYCLES = 8
#: tim2_periods() in f411_regs.c: 10 periods of ARR + 1 = 1000 ticks, PSC 0
TIM2_TICKS = 10 * 1000
#: RM0383 6.3.23 (RCC_DCKCFGR)
TIMPRE = 1 << 24
#: what f411_regs.c programs in the sector after each one erased, and in sector 7
NEXT_PROGRAMMED, SECTOR7_PROGRAMMED = 0x9ABC_DEF0, 0x0F1E_2D3C


def _run(machine: str) -> subprocess.CompletedProcess[str]:
    return run_to_done("f411_regs", "-d", "guest_errors", machine=machine)


@pytest.fixture(scope="module")
def done() -> subprocess.CompletedProcess[str]:
    return _run("rig-stm32f411")


@pytest.fixture(scope="module")
def r(done: subprocess.CompletedProcess[str]) -> dict[str, int]:
    return reports(done.stdout)


@pytest.fixture(scope="module")
def f405_done() -> subprocess.CompletedProcess[str]:
    return _run("rig-stm32f405")


def cycles(seconds: float) -> int:
    return round(seconds * HSI_HZ)


def timer_hz(hclk: int, apb_div: int, timpre: bool) -> int:
    """RM0383 6.3.23, TIMPRE: 0: PCLKx when the APB prescaler divides by 1, else 2 x PCLKx; 1: HCLK when
    it divides by 1, 2 or 4, else 4 x PCLKx."""
    pclk = hclk // apb_div
    if timpre:
        return hclk if apb_div <= 4 else 4 * pclk
    return pclk if apb_div == 1 else 2 * pclk


def test_pwr_is_the_f411s(r: dict[str, int]) -> None:
    """RM0383 5.4.1: PWR_CR resets to scale 2 and has the F411's bits; 5.4.2: PWR_CSR resets to 0 but for
    VOSRDY (the regulator is ready: its settling is not modelled), BRR follows BRE."""
    assert r["pwr_cr_reset"] == F411_PWR_CR_RESET
    assert r["pwr_csr_reset"] & ~CSR_VOSRDY == 0
    assert r["pwr_cr_ones"] == F411_PWR_CR_WRITABLE
    assert r["pwr_csr_ones"] == CSR_VOSRDY | CSR_BRE | CSR_EWUP | CSR_BRR


def test_each_voltage_scale_reads_back_with_vosrdy(r: dict[str, int]) -> None:
    """RM0383 5.4.1 VOS[15:14] (01 scale 3, 10 scale 2, 11 scale 1) and 5.4.2 VOSRDY: each scale written
    reads back, and the regulator reports itself ready at it."""
    for vos in (1, 2, 3):
        assert r[f"vos{vos}_cr"] == F411_PWR_CR_RESET & ~(0x3 << 14) | vos << 14
        assert r[f"vos{vos}_csr"] & CSR_VOSRDY, vos


def test_the_flash_interface_is_the_f411s(r: dict[str, int]) -> None:
    """RM0383 3.8.1: ACR resets to 0 and takes LATENCY[2:0] and the caches' enables; 3.8.4 SR resets to 0;
    3.8.5 CR to LOCK; 3.8.6 OPTCR to 0x0FFFAAED."""
    assert r["flash_acr_reset"] == 0
    assert r["flash_acr_ones"] == ACR_CACHES | ACR_LATENCY
    assert r["flash_sr_reset"] == 0
    assert r["flash_cr_reset"] == CR_LOCK
    assert r["flash_optcr_reset"] == 0x0FFF_AAED


def test_gpio_ports_reset_as_the_f411s(r: dict[str, int]) -> None:
    for name, value in F411_GPIO_RESET.items():
        assert r[f"{name}_reset"] == value, name


def test_sector_erases_take_ds10314s_times(r: dict[str, int]) -> None:
    """DS10314's typical erase times, which shorten as PSIZE widens: sector 5 (128 KB, RM0383 table 4) at
    x32 in 1 s, sector 2 (16 KB) at x16 in 0.3 s, sector 4 (64 KB) at x8 in 1.2 s, from STRT to EOP; each
    erases its sector (RM0383 3.5.3: to 0xFF) and not the next."""
    for (sector, psize), seconds in F411_ERASE_S.items():
        name = f"{sector}_{psize}_cycles"
        assert cycles(seconds) <= r[name] <= cycles(seconds) + LOOP_CYCLES, name
        assert r[f"{sector}_word"] == 0xFFFF_FFFF, sector
        assert r[f"{sector}_next"] == NEXT_PROGRAMMED, sector


def test_a_mass_erase_takes_ds10314s_time(r: dict[str, int]) -> None:
    """The firmware's last act, run from RAM (it erases the firmware's own code): MER at x32, STRT to EOP."""
    seconds = F411_MASS_ERASE_S
    assert cycles(seconds) <= r["mass_erase_x32_cycles"] <= cycles(seconds) + LOOP_CYCLES


def test_there_is_no_sector_8(r: dict[str, int], done: subprocess.CompletedProcess[str]) -> None:
    """RM0383 3.8.5: SNB 0-7 are the sectors, other values are "not allowed" and no flag of SR (3.8.4) is
    named for them: the erase does not start (no BSY, STRT cleared), no sector is erased, and the machine
    logs it under -d guest_errors."""
    assert r["snb8_sr"] == 0
    assert r["snb8_cr"] == CR_EOPIE | 2 << 8 | 8 << 3 | CR_SER
    assert r["snb8_sector7"] == SECTOR7_PROGRAMMED
    assert "SER with sector 8 (of 0..7)" in done.stderr


@pytest.mark.parametrize("div,timpre", [(1, False), (1, True), (4, False), (4, True), (8, False), (8, True)])
def test_timpre_sets_the_timers_clock(r: dict[str, int], div: int, timpre: bool) -> None:
    """TIM2 (on APB1) counts TIM2_TICKS ticks in TIM2_TICKS x HCLK / f_TIM cycles, f_TIM by RM0383 6.3.23's
    rule: with APB1 divided by 4, TIMPRE makes it HCLK (16 MHz) instead of 2 x PCLK1 (8 MHz); by 8,
    4 x PCLK1 (8 MHz) instead of 2 x PCLK1 (4 MHz); undivided, PCLK1 either way."""
    name = f"tim2_div{div}{'_timpre' if timpre else ''}_cycles"
    expected = TIM2_TICKS * HSI_HZ // timer_hz(HSI_HZ, div, timpre)
    assert abs(r[name] - expected) <= LOOP_CYCLES, (name, r[name], expected)
    assert r["rcc_dckcfgr_ones"] == TIMPRE  # RM0383 6.3.23: TIMPRE is DCKCFGR's only bit modelled


def test_the_f405_keeps_its_own_tables(f405_done: subprocess.CompletedProcess[str]) -> None:
    """The same firmware on rig-stm32f405: RM0090 5.4.1's PWR_CR (one VOS bit, scale 1 at reset), 3.9.1's
    ACR, port A's OSPEEDR (0 in the F405's table), DS8626's erase times (one per sector size),
    a sector 8 that exists (table 5: the erase starts, BSY), and no DCKCFGR (offset 0x8C is reserved:
    reads 0, writes ignored and logged, so the timers' clock stays 2 x PCLK1)."""
    f405 = reports(f405_done.stdout)
    assert f405["pwr_cr_reset"] == F405_PWR_CR_RESET
    assert f405["pwr_cr_ones"] == F405_PWR_CR_WRITABLE
    assert f405["flash_acr_ones"] == ACR_CACHES | ACR_LATENCY
    assert f405["gpioa_ospeedr_reset"] == 0
    for (sector, psize), seconds in F405_ERASE_S.items():
        name = f"{sector}_{psize}_cycles"
        assert cycles(seconds) <= f405[name] <= cycles(seconds) + LOOP_CYCLES, name
    seconds = F405_MASS_ERASE_S
    assert cycles(seconds) <= f405["mass_erase_x32_cycles"] <= cycles(seconds) + LOOP_CYCLES
    assert f405["snb8_sr"] & SR_BSY
    assert f405["snb8_sector7"] == SECTOR7_PROGRAMMED
    assert f405["rcc_dckcfgr_ones"] == 0
    assert "rig-stm32f4-rcc: write of reserved offset 0x8c" in f405_done.stderr
    for div in (1, 4, 8):
        expected = TIM2_TICKS * HSI_HZ // timer_hz(HSI_HZ, div, False)
        assert abs(f405[f"tim2_div{div}_timpre_cycles"] - expected) <= LOOP_CYCLES, div


def test_two_runs_print_the_same_bytes(done: subprocess.CompletedProcess[str]) -> None:
    assert _run("rig-stm32f411").stdout == done.stdout
