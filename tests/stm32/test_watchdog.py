"""The rig's STM32F405 independent watchdog (qemu/hw/rig_stm32_iwdg.c) against RM0090 section 19, and
its reset as the rig's verdict: the test firmware tests/stm32/firmware/watchdog.c (at the 16 MHz HSI)
reports IWDG's registers, times PR's and RLR's updates with DWT_CYCCNT, refreshes the started watchdog
at SysTick's ticks, then stops refreshing; its second boot reports the reset flags and the cycles from
the last refresh to the reset. Through the link (Stm32Engine), the reset ends the run naming the pc the
firmware was at. Expected values are the manual's, and its timeout formula, written here."""

from __future__ import annotations

import subprocess

import pytest

from rig.mcu import board as boards
from rig.mcu.stm32_link import Stm32Config, Stm32Engine
from tests.stm32.conftest import engine_or_skip, firmware, reports, run_firmware, run_to_done

HSI_HZ = 16_000_000
#: the LSI's nominal frequency (DS8626: 32 kHz typical), the IWDG's clock
LSI_HZ = 32_000
#: the firmware's set-up (watchdog.c)
PR, RLR = 1, 199
#: RM0090 19.4.4: PVU and RVU stay set while the value crosses to the VDD domain, five LSI cycles
UPDATE_LSI_CYCLES = 5
#: the firmware's loops (an SR or DWT read, a compare, a branch; a store): how late each sees its event
LOOP_CYCLES = 8
#: RM0090 7.3.21 (RCC_CSR): the reset flags
PINRSTF, IWDGRSTF = 1 << 26, 1 << 29
STEP_NS = 1_000_000


def timeout_s(pr: int, rlr: int) -> float:
    """RM0090 19.3.3 and table 107: the counter counts RLR + 1 ticks of 4 * 2^PR LSI cycles."""
    return 4 * 2 ** min(pr, 6) * (rlr + 1) / LSI_HZ


@pytest.fixture(scope="module")
def run() -> subprocess.CompletedProcess[str]:
    done = run_to_done("watchdog")
    return done


@pytest.fixture(scope="module")
def r(run: subprocess.CompletedProcess[str]) -> dict[str, int]:
    return reports(run.stdout)


def test_registers_at_reset(r: dict[str, int]) -> None:
    """RM0090 19.4: PR 0, RLR 0xFFF, SR 0."""
    assert (r["iwdg_pr_reset"], r["iwdg_rlr_reset"], r["iwdg_sr_reset"]) == (0, 0xFFF, 0)


def test_pr_and_rlr_need_the_key_and_take_five_lsi_cycles(r: dict[str, int]) -> None:
    """19.3.4: PR and RLR writable only after 0x5555 in KR; a write during PVU is not taken."""
    assert r["pr_without_key"] == 0
    update = round(UPDATE_LSI_CYCLES * HSI_HZ / LSI_HZ)
    for name in ("pvu_cycles", "rvu_cycles"):
        assert update <= r[name] <= update + LOOP_CYCLES, name
    assert (r["iwdg_pr"], r["iwdg_rlr"]) == (PR, RLR)  # (PR = 6 written during PVU was not taken)


def test_a_refreshed_watchdog_does_not_reset(r: dict[str, int]) -> None:
    """40 refreshes, each before the timeout, over many timeouts: no reset until the refreshes stop."""
    timeout = round(timeout_s(PR, RLR) * HSI_HZ)
    assert r["refreshed"] == 40
    assert r["longest_refresh_gap"] < timeout
    assert r["refreshed_for_cycles"] > 10 * timeout


def test_the_watchdog_resets_after_its_timeout(r: dict[str, int]) -> None:
    """Not refreshed, the IWDG resets the chip timeout_s after the last reload (50 ms), with IWDGRSTF and
    PINRSTF in RCC_CSR (7.3.21; the power-on flags were cleared by RMVF), and the reset stops it."""
    timeout = round(timeout_s(PR, RLR) * HSI_HZ)
    assert timeout == 800_000
    assert timeout - LOOP_CYCLES <= r["reset_after_cycles"] <= timeout
    assert r["boot2_csr"] == IWDGRSTF | PINRSTF
    assert r["boot2_iwdg_pr"] == 0


def test_two_runs_are_identical(run: subprocess.CompletedProcess[str]) -> None:
    assert run_firmware(engine_or_skip(), firmware("watchdog")).stdout == run.stdout


def test_a_watchdog_reset_ends_the_run_naming_the_pc() -> None:
    """Through the link, at 1 ms steps: the reset is a crash naming IWDG and the pc of the loop that let
    the watchdog run out (starve(), whose address the firmware reports), at its instant."""
    elf = firmware("watchdog")
    nm = subprocess.run(["arm-none-eabi-nm", "-S", str(elf)], capture_output=True, text=True, check=True)
    start, size = next((int(w[0], 16), int(w[1], 16)) for w in map(str.split, nm.stdout.splitlines())
                       if w[-1] == "starve")
    engine = Stm32Engine(Stm32Config(boards.load("stm32f405-gy86"), elf, engine_or_skip(), hang_ns=0), None)
    try:
        t = 0
        while (stop := engine.run_until(t := t + STEP_NS)).kind == "reached":
            assert t < 5_000_000_000
        out = reports(engine.output())
        figures = engine.figures()
    finally:
        engine.close()
    assert stop.kind == "crashed"
    assert stop.what.startswith("watchdog reset (IWDG) (CFSR 0x00000000, HFSR 0x00000000)")
    assert start <= stop.pc < start + size and out["starve_pc"] == start
    assert figures["resets"] == 1
    assert "refreshed_for_cycles" in out and "boot2_csr" not in out


# ---- the window watchdog (qemu/hw/rig_stm32_wwdg.c, RM0090 section 20; tests/stm32/firmware/wwdg.c) ----
WDGTB = 3
WWDGRSTF = 1 << 30
#: the interrupt's entry after the event (the core's stacking, the handler's DWT read)
ENTRY_CYCLES = 16


def wwdg_count_cycles(wdgtb: int) -> int:
    """20.3: the counter counts once every 4096 * 2^WDGTB PCLK1 cycles."""
    return 4096 * 2 ** wdgtb


@pytest.fixture(scope="module")
def w() -> dict[str, int]:
    done = run_to_done("wwdg")
    return reports(done.stdout)


def test_wwdg_registers_at_reset_and_without_its_clock(w: dict[str, int]) -> None:
    """20.6: CR 0x7F, CFR 0x7F, SR 0; nothing answers without RCC_APB1ENR.WWDGEN (7.3.13)."""
    assert w["cr_unclocked"] == 0
    assert (w["cr_reset"], w["cfr_reset"], w["sr_reset"]) == (0x7F, 0x7F, 0)
    assert w["cr_running"] == 1 << 7  # WDGA
    assert w["cfr_window"] == 1 << 9 | WDGTB << 7 | 0x50  # EWI stays set: only a reset clears it


def test_the_early_wakeup_comes_at_0x40(w: dict[str, int]) -> None:
    """20.3: EWIF when the counter reaches 0x40: 0x7F - 0x40 counts after each refresh to 0x7F; the
    interrupt refreshes it, so the watchdog never resets meanwhile."""
    period = (0x7F - 0x40) * wwdg_count_cycles(WDGTB)
    assert period <= w["wakeup_0"] <= period + ENTRY_CYCLES
    for i in range(1, 4):
        gap = w[f"wakeup_{i}"] - w[f"wakeup_{i - 1}"]
        assert period <= gap <= period + ENTRY_CYCLES, i


def test_a_refresh_above_the_window_and_a_timeout_reset(w: dict[str, int]) -> None:
    """20.3: a refresh while the counter is above W resets (WWDGRSTF, PINRSTF); not refreshed, the reset
    comes t_PCLK1 * 4096 * 2^WDGTB * (T[5:0] + 1) after the last refresh (T = 0x7F)."""
    assert w["boot2_csr"] == WWDGRSTF | PINRSTF
    assert w["boot2_cr"] == 0  # (its clock off again after the reset)
    assert w["boot3_csr"] == WWDGRSTF | PINRSTF
    timeout = wwdg_count_cycles(WDGTB) * (0x3F + 1)
    assert timeout == 2_097_152  # (PCLK1 cycles, which are DWT's: APB1 is undivided at reset)
    assert timeout - LOOP_CYCLES <= w["reset_after_cycles"] <= timeout


def test_a_wwdg_reset_ends_the_run_naming_it() -> None:
    engine = Stm32Engine(Stm32Config(boards.load("stm32f405-gy86"), firmware("wwdg"), engine_or_skip(),
                                     hang_ns=0), None)
    try:
        t = 0
        while (stop := engine.run_until(t := t + STEP_NS)).kind == "reached":
            assert t < 5_000_000_000
    finally:
        engine.close()
    assert stop.kind == "crashed" and stop.what.startswith("watchdog reset (WWDG)")
