"""External interrupts from pins on rig-stm32f405 (qemu/hw/rig_stm32_exti.c): tests/stm32/firmware/exti.c,
with PD1 wired to PA0, against RM0090: SYSCFG's registers (9.2: reset values 0, EXTICRx's EXTIn fields
bits 15:0, PMC's MII_RMII_SEL bit 23, CMPCR's READY bit 8 once CMP_PD is set, no access without
RCC_APB2ENR.SYSCFGEN), EXTI's (12.3: reset values 0, 23 lines in bits 22:0; PR set by a selected edge
and cleared by writing 1; SWIER's 1 sets PR and is cleared with it), and the NVIC lines of table 61
(EXTI0 6, EXTI1 7, EXTI2 8, EXTI9_5 23, EXTI15_10 40)."""

from __future__ import annotations

from tests.stm32.conftest import engine_or_skip, firmware, reports, run_firmware

WIRES = "rig-stm32f405,wires=PD1-PA0"
#: RM0090 12.3: the 23 EXTI lines (0..15 from the pins, 16..22 PVD, RTC alarm, OTG FS, Ethernet, OTG HS,
#: tamper, RTC wake-up)
LINES = (1 << 23) - 1


def run() -> tuple[dict[str, int], str]:
    done = run_firmware(engine_or_skip(), firmware("exti"), machine=WIRES)
    assert done.returncode == 0, done.stdout + done.stderr
    return reports(done.stdout), done.stdout


def test_syscfg_and_exti_registers_as_rm0090_gives_them() -> None:
    got, out = run()
    assert got["syscfg_exticr1_clock_off"] == 0, out  # (the write with SYSCFGEN clear is lost)
    for name in ("memrmp", "pmc", "exticr1", "exticr2", "exticr3", "exticr4", "cmpcr"):
        assert got[f"syscfg_{name}"] == 0, name
    for name in ("imr", "emr", "rtsr", "ftsr", "swier", "pr"):
        assert got[f"exti_{name}"] == 0, name
    assert got["syscfg_pmc_ones"] == 1 << 23
    assert got["syscfg_exticr4_ones"] == 0xFFFF
    assert got["syscfg_cmpcr_powered"] == 1 | 1 << 8
    for i in range(4):  # IMR, EMR, RTSR, FTSR
        assert got[f"exti_ones_{i}"] == LINES


def test_a_selected_edge_sets_pr_and_unmasked_interrupts() -> None:
    got, out = run()
    # masked (IMR 0): the rising edge sets PR (12.3.6) and no handler runs; writing 1 clears it
    assert got["line0_masked_pr"] == 1 and got["line0_masked_entries"] == 0, out
    assert got["line0_pr_cleared"] == 0
    assert got["line0_falling_unselected_pr"] == 0  # (FTSR 0: a falling edge is no trigger)
    # unmasked: EXTI0 (NVIC 6) once for the rising edge, with PR set in the handler; not for the falling
    assert got["line0_rising_entries"] == 1 and got["line0_rising_pr_in_handler"] & 1
    assert got["line0_falling_entries"] == 1
    assert got["line0_both_entries"] == 3  # (RTSR and FTSR: each edge)
    assert got["line0_pr_after"] == 0


def test_each_line_follows_the_port_exticr_selects() -> None:
    got, out = run()
    assert got["line5_pa5_entries"] == 0, out  # (EXTICR2 selects PB5 for line 5)
    assert got["line5_pb5_rising_entries"] == 1 and got["line5_pr_in_handler"] == 1 << 5
    assert got["line5_pb5_falling_entries"] == 2
    assert got["line13_pc13_entries"] == 2 and got["line13_pr_in_handler"] == 1 << 13


def test_software_triggers_and_a_pending_bit_left_set() -> None:
    got, out = run()
    assert got["swier1_entries"] == 1 and got["swier1_pr_in_handler"] & 1 << 1, out
    assert got["swier_after_pr_write"] == 0  # (12.3.5: cleared by writing 1 to PR)
    # a handler that leaves PR set is entered again until it clears it (the third time here)
    assert got["swier2_entries"] == 3
    assert got["pr_end"] == 0


def test_two_runs_print_the_same_bytes() -> None:
    assert run()[1] == run()[1]
