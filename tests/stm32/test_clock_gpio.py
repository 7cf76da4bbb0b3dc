"""The rig's STM32F405 models (qemu/hw) against the reference manual, RM0090 rev 19: the clock and GPIO
test firmware (tests/stm32/firmware/clock_gpio.c) reports the registers at reset, through the clock
set-up of ST's CMSIS/HAL for 168 MHz from an 8 MHz crystal, and through GPIO use; every expected value
below is the manual's (section and table named), or a formula of its clock tree written here."""

from __future__ import annotations

import subprocess

import pytest

from tests.stm32.conftest import engine_or_skip, firmware, reports, run_firmware, run_to_done

HSI_HZ = 16_000_000
HSE_HZ = 8_000_000  # the machine's default crystal, as on the common F405 boards


@pytest.fixture(scope="module")
def run() -> tuple[str, dict[str, int]]:
    done = run_to_done("clock_gpio")
    return done.stdout, reports(done.stdout)


@pytest.fixture(scope="module")
def r(run: tuple[str, dict[str, int]]) -> dict[str, int]:
    return run[1]


def test_clock_registers_at_reset(r: dict[str, int]) -> None:
    """RM0090 7.3.1-7.3.21 and table 34: the reset values (CR's HSICAL is the factory's, not compared)."""
    assert r["rcc_cr_reset"] & 0xFFFF00FF == 0x0000_0083  # HSITRIM = 16, HSIRDY, HSION
    assert r["rcc_pllcfgr_reset"] == 0x2400_3010
    assert r["rcc_cfgr_reset"] == 0
    assert r["rcc_ahb1enr_reset"] == 0x0010_0000  # CCMDATARAMEN
    assert r["rcc_apb1lpenr_reset"] == 0x36FE_C9FF
    assert r["rcc_csr_reset"] == 0x0E00_0000  # PORRSTF, PINRSTF, BORRSTF
    assert r["flash_acr_reset"] == 0  # 3.9.1: zero wait states
    assert r["flash_cr_reset"] == 0x8000_0000  # 3.9.5: LOCK
    assert r["dwt_cyccnt_reset"] == 0


def test_system_init_leaves_the_reset_state(r: dict[str, int]) -> None:
    """CMSIS SystemInit writes the reset values back: CR as at reset (HSI on and ready, nothing else)."""
    assert r["rcc_cr_system_init"] == r["rcc_cr_reset"]


def test_pwr_answers_only_with_its_clock(r: dict[str, int]) -> None:
    assert r["pwr_cr_unclocked"] == 0
    assert r["pwr_cr_clocked"] == 0x0000_4000  # 5.4.1: VOS = 1 at reset


def test_a_switch_to_a_source_that_is_not_ready_does_not_happen(r: dict[str, int]) -> None:
    cfgr = r["rcc_cfgr_sw_hse_off"]
    assert cfgr & 0x3 == 0b01 and cfgr >> 2 & 0x3 == 0b00  # SW = HSE, SWS still HSI


def test_the_hal_clock_set_up_reaches_168_mhz(r: dict[str, int]) -> None:
    """Ready flags follow their enables, SWS follows SW, the wait states read back as written."""
    cr, cfgr, pll = r["rcc_cr_pll"], r["rcc_cfgr_pll"], r["rcc_pllcfgr"]
    assert cr & (1 << 16) and cr & (1 << 17)  # HSEON, HSERDY
    assert cr & (1 << 24) and cr & (1 << 25)  # PLLON, PLLRDY
    assert cfgr & 0x3 == 0b10 and cfgr >> 2 & 0x3 == 0b10  # SW = SWS = PLL
    assert r["flash_acr"] == 0x705  # ICEN, DCEN, PRFTEN, LATENCY = 5 WS (table 10: 150-168 MHz at 2.7-3.6 V)
    m, n, p = pll & 0x3F, pll >> 6 & 0x1FF, 2 * ((pll >> 16 & 0x3) + 1)
    assert pll >> 22 & 1 == 1  # PLLSRC = HSE
    assert HSE_HZ // m * n // p == 168_000_000  # 7.3.2: f(VCO) = f(in) * N / M, f(PLL) = f(VCO) / P
    assert r["hse_polls"] < 1000  # HSERDY followed HSEON (the polls are the firmware's loop, not time)


def test_a_clock_source_in_use_cannot_be_stopped(r: dict[str, int]) -> None:
    """7.3.1: HSEON and PLLON cannot be cleared while they clock the system; HSION can once unused."""
    cr = r["rcc_cr_stop_all"]
    assert cr & (1 << 24) and cr & (1 << 25) and cr & (1 << 16) and cr & (1 << 17)
    assert not cr & 0x3  # HSION and HSIRDY cleared


def test_cyccnt_and_systick_count_the_core_clock(r: dict[str, int]) -> None:
    """The same loop (the same instructions, so the same virtual time under -icount) takes 168/16 times
    as many cycles after the switch to the PLL: each count is within one cycle of time x frequency."""
    ratio_num, ratio_den = 168_000_000, HSI_HZ
    for slow, fast in (("dwt_spin_hsi", "dwt_spin_pll"), ("systick_spin_hsi", "systick_spin_pll")):
        assert r[slow] > 1000, slow
        off_by = abs(r[fast] * ratio_den - r[slow] * ratio_num)
        assert off_by <= ratio_num + ratio_den, (slow, r[slow], r[fast])


def test_flash_unlocks_with_the_key_sequence(r: dict[str, int]) -> None:
    assert r["flash_cr_unlocked"] >> 31 == 0  # 3.5.1: KEY1 then KEY2 clear LOCK
    assert r["flash_cr_relocked"] >> 31 == 1


def test_gpio_reset_values_and_clock_gating(r: dict[str, int]) -> None:
    """8.4: a port's registers answer only with its clock on; ports A and B reset with the debug pins'
    configuration."""
    assert r["gpiod_moder_unclocked"] == 0
    assert r["gpiod_moder_reset"] == 0  # the write with the clock off was lost
    assert r["gpioa_moder_reset"] == 0xA800_0000
    assert r["gpioa_pupdr_reset"] == 0x6400_0000
    assert r["gpiob_moder_reset"] == 0x0000_0280
    assert r["gpiob_ospeedr_reset"] == 0x0000_00C0
    assert r["gpiob_pupdr_reset"] == 0x0000_0100


def test_gpio_configuration_reads_back(r: dict[str, int]) -> None:
    assert r["gpiod_moder"] == (1 << 24) | (1 << 2) | (3 << 4)
    assert r["gpiod_otyper"] == 1 << 1
    assert r["gpiod_ospeedr"] == 2 << 24
    assert r["gpiod_afrl"] == 0x0000_0700
    assert r["gpiod_afrh"] == 0x0004_0000


def test_gpio_pins_follow_outputs_and_pulls(r: dict[str, int]) -> None:
    """IDR: PD0 input pulled up reads 1, pulled down 0; PD1 open drain released reads its pull-up; PD2
    analog reads 0 whatever its pull; PD12 push-pull reads its ODR bit."""
    assert r["gpiod_idr_start"] == 0b001  # PD0 pulled up; PD1 open drain driving its ODR 0; PD12 low
    assert r["gpiod_odr_set"] == (1 << 12) | (1 << 1)
    assert r["gpiod_idr_set"] == (1 << 12) | (1 << 1) | 1
    assert r["gpiod_bsrr_read"] == 0  # 8.4.7: write-only
    assert r["gpiod_odr_reset"] == 1 << 1
    assert r["gpiod_odr_both"] == (1 << 12) | (1 << 1)  # BS wins over BR
    assert r["gpiod_idr_pulldown"] == 1 << 12  # PD0 pulled down, PD1 floating, PD12 high
    assert r["gpiod_toggles"] == 10


def test_gpio_lock_freezes_the_locked_pins_configuration(r: dict[str, int]) -> None:
    """8.4.8: after LCKK=1, 0, 1 with the same LCK bits, a read shows LCKK; the locked pin's mode no
    longer changes until reset, the others' do, and LCKR stays as locked."""
    assert r["gpiod_lckr_read1"] == (1 << 16) | (1 << 12)
    assert r["gpiod_lckr_read2"] == (1 << 16) | (1 << 12)
    assert r["gpiod_moder_locked"] == (1 << 24) | (1 << 26)  # PD12 still output, PD13 now output
    assert r["gpiod_lckr_after_clear"] == (1 << 16) | (1 << 12)


def test_the_peripheral_reset_restores_a_port(r: dict[str, int]) -> None:
    """7.3.5 (AHB1RSTR.GPIODRST) and 8.4.8: the port's reset values again, and the lock released."""
    assert r["gpiod_moder_after_reset"] == 0
    assert r["gpiod_odr_after_reset"] == 0
    assert r["gpiod_lckr_after_reset"] == 0


def test_two_runs_are_identical(run: tuple[str, dict[str, int]]) -> None:
    again = run_firmware(engine_or_skip(), firmware("clock_gpio"))
    assert again.stdout == run[0]


def test_the_machine_is_the_rigs() -> None:
    """QEMU lists the rig's machine beside its own F405 board."""
    done = subprocess.run([str(engine_or_skip()), "-M", "help"], capture_output=True, text=True, timeout=30)
    assert "rig-stm32f405" in done.stdout and "netduinoplus2" in done.stdout


def test_the_clock_tree_follows_the_boards_crystal() -> None:
    """With a 25 MHz crystal (-global rig-stm32f4-rcc.hse-hz) the same PLL settings (M=8, N=336, P=2)
    make 25/8 x 336/2 = 525 MHz: the loop's cycles scale by that over the HSI's 16 MHz."""
    crystal = ("-global", "rig-stm32f4-rcc.hse-hz=25000000")
    done = run_firmware(engine_or_skip(), firmware("clock_gpio"), *crystal)
    assert done.returncode == 0, done.stderr
    r = reports(done.stdout)
    pll_hz = 25_000_000 // 8 * 336 // 2
    off_by = abs(r["dwt_spin_pll"] * HSI_HZ - r["dwt_spin_hsi"] * pll_hz)
    assert off_by <= pll_hz + HSI_HZ, (r["dwt_spin_hsi"], r["dwt_spin_pll"])
