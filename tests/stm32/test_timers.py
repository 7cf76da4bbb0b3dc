"""The rig's STM32F405 timers (qemu/hw/rig_stm32_timer.c) against RM0090 sections 17-20: the test
firmware tests/stm32/firmware/timers_pwm.c reports register values, pin pulses it measured with DWT_CYCCNT
and interrupt counts; the engine's pulse trace (-global rig-stm32f4-timer.trace-pulses=on) gives each
channel's pulse as latched at the start of a period. Expected values are RM0090's register descriptions
and its formulas, written here: f_timer = PCLK x 2 when the APB prescaler is not 1 (7.2), a counter tick
(PSC + 1) / f_timer, an edge-aligned period (ARR + 1) ticks, a center-aligned one 2 x ARR."""

from __future__ import annotations

import functools
import json
import re
import select
import socket
import subprocess
from pathlib import Path

import pytest

from tests.stm32.conftest import (
    ICOUNT_SHIFT,
    RUN_TIMEOUT_S,
    engine_or_skip,
    firmware,
    reports,
    run_firmware,
    run_to_done,
)

CORE_HZ = 168_000_000
#: ST's 168 MHz set-up: APB1 = HCLK / 4, APB2 = HCLK / 2, so each timer clock is twice its bus's
APB1_TIMER_HZ = 2 * CORE_HZ // 4
APB2_TIMER_HZ = 2 * CORE_HZ // 2
#: the firmware's set-ups (timers_pwm.c)
PWM = {"psc": 83, "arr": 2040, "ccr": 1500}  # TIM4 CH1: 1 us ticks, 490 Hz
ONESHOT = {"psc": 20, "arr": 3999, "ccr": 1500}  # TIM1 CH1: 8 MHz ticks, 2 kHz, 187.5 us
WINDOW_S = 0.1
#: the firmware's polling loop (an IDR read, a compare, a branch, a DWT read): how late it can see an edge
POLL_CYCLES = 16
TRACE = re.compile(r"rig-stm32f4-timer: t_ns=(\d+) TIM(\d+) ch(\d) high_ticks=(\d+) period_ticks=(\d+) "
                   r"clock_hz=(\d+)")
NO_EDGE = 0xFFFF_FFFF
TRACE_PULSES = ("-global", "rig-stm32f4-timer.trace-pulses=on")


def period_s(timer_hz: int, psc: int, arr: int) -> float:
    """RM0090 17.3.1/18.3.1: the counter counts (PSC + 1) timer clocks per step, ARR + 1 steps."""
    return (psc + 1) * (arr + 1) / timer_hz


def cycles(seconds: float) -> int:
    return round(seconds * CORE_HZ)


@functools.cache
def checked_run(name: str, *qemu_args: str) -> subprocess.CompletedProcess[str]:
    """A test firmware's run (once per test session), which must have reported to its end."""
    return run_to_done(name, *qemu_args)


def traced_run() -> subprocess.CompletedProcess[str]:
    return checked_run("timers_pwm", *TRACE_PULSES)


@pytest.fixture(scope="module")
def r() -> dict[str, int]:
    return reports(traced_run().stdout)


def pulses(timer: int, channel: int, name: str = "timers_pwm") -> list[tuple[int, int, int]]:
    """(high ticks, period ticks, timer clock) each time the channel's latched pulse changed in the
    traced run of the test firmware @name"""
    trace = checked_run(name, *TRACE_PULSES).stderr
    return [(int(m[4]), int(m[5]), int(m[6])) for m in TRACE.finditer(trace)
            if (int(m[2]), int(m[3])) == (timer, channel)]


def test_registers_reset_to_zero(r: dict[str, int]) -> None:
    """RM0090 17.4-20.4: every timer register resets to 0 (ARR included, as the manual's register
    descriptions give it); with its RCC clock off a timer drops writes and reads 0."""
    assert r["tim4_cr1_unclocked"] == 0
    for t in range(1, 15):
        assert r[f"tim{t}_or_of_registers"] == 0, t


#: RM0090's writable bits: DIER (17.4.4, 18.4.4, 19.4.4, 19.5.2, 20.4.3), CR1 less CEN (DIR reads 0:
#: read-only in center-aligned mode, which CMS = 11 selects), CCER (17.4.9, 18.4.9, 19.4.8, 19.5.6)
WRITABLE = {
    "advanced": (0x7FFF, 0x3EE, 0x3FFF, 0xFFFF),
    "general32": (0x5F5F, 0x3EE, 0xBBBB, 0xFFFF_FFFF),
    "general16": (0x5F5F, 0x3EE, 0xBBBB, 0xFFFF),
    "two_channel": (0x47, 0x38E, 0xBB, 0xFFFF),
    "one_channel": (0x03, 0x386, 0x0B, 0xFFFF),
    "basic": (0x101, 0x08E, 0, 0xFFFF),
}
KINDS = {1: "advanced", 8: "advanced", 2: "general32", 5: "general32", 3: "general16", 4: "general16",
         9: "two_channel", 12: "two_channel", 10: "one_channel", 11: "one_channel", 13: "one_channel",
         14: "one_channel", 6: "basic", 7: "basic"}


#: CR2 (17.4.2: OIS, MMS, CCDS, CCUS, CCPC; 18.4.2: TI1S, MMS, CCDS; TIM9/12 and 20.4.2: MMS; none on
#: TIM10/11/13/14) and OR, the remap bits of TIM2 (ITR1_RMP), TIM5 (TI4_RMP) and TIM11 (TI1_RMP) only
CR2_WRITABLE = {"advanced": 0x7FFD, "general32": 0xF8, "general16": 0xF8, "two_channel": 0x70,
                "one_channel": 0, "basic": 0x70}
OR_WRITABLE = {2: 0xC00, 5: 0xC0, 11: 0x3}


@pytest.mark.parametrize("timer", sorted(KINDS))
def test_writable_bits(r: dict[str, int], timer: int) -> None:
    dier, cr1, ccer, arr = WRITABLE[KINDS[timer]]
    assert r[f"tim{timer}_dier_ones"] == dier
    assert r[f"tim{timer}_cr1_ones"] == cr1
    assert r[f"tim{timer}_ccer_ones"] == ccer
    assert r[f"tim{timer}_arr_ones"] == arr  # 32-bit on TIM2 and TIM5 only
    assert r[f"tim{timer}_cr2_ones"] == CR2_WRITABLE[KINDS[timer]]
    assert r[f"tim{timer}_or_ones"] == OR_WRITABLE.get(timer, 0)


def test_ug_sets_the_update_flag(r: dict[str, int]) -> None:
    assert r["tim4_sr_after_ug"] == 1  # UIF (URS = 0)


def test_tim4_pwm_at_490_hz_on_its_pin(r: dict[str, int]) -> None:
    """PD12 (AF2) follows TIM4 CH1 in PWM mode 1: high for CCR1 ticks of each ARR + 1."""
    assert (r["tim4_psc"], r["tim4_arr"], r["tim4_ccr1"]) == (PWM["psc"], PWM["arr"], PWM["ccr"])
    period = period_s(APB1_TIMER_HZ, PWM["psc"], PWM["arr"])
    assert round(1 / period) == 490
    high = PWM["ccr"] * (PWM["psc"] + 1) / APB1_TIMER_HZ
    assert abs(r["tim4_high_cycles"] - cycles(high)) <= POLL_CYCLES
    assert abs(r["tim4_period_cycles"] - cycles(period)) <= POLL_CYCLES


def test_tim4_latched_pulse(r: dict[str, int]) -> None:
    """The pulse the rig reads: latched at the first period, in timer-clock ticks."""
    ticks = PWM["psc"] + 1
    assert pulses(4, 1) == [(PWM["ccr"] * ticks, (PWM["arr"] + 1) * ticks, APB1_TIMER_HZ)]


def test_tim1_oneshot125_only_with_moe(r: dict[str, int]) -> None:
    """17.4.18: TIM1's outputs stay off until BDTR.MOE; then PA8 (AF1) carries a 187.5 us pulse every
    500 us, on the 168 MHz APB2 timer clock."""
    assert r["tim1_high_without_moe"] == NO_EDGE
    assert r["tim1_bdtr"] == 1 << 15
    high = ONESHOT["ccr"] * (ONESHOT["psc"] + 1) / APB2_TIMER_HZ
    assert 125e-6 <= high <= 250e-6  # OneShot125's range
    assert abs(r["tim1_high_cycles"] - cycles(high)) <= POLL_CYCLES
    period = period_s(APB2_TIMER_HZ, ONESHOT["psc"], ONESHOT["arr"])
    assert abs(r["tim1_period_cycles"] - cycles(period)) <= POLL_CYCLES
    ticks = ONESHOT["psc"] + 1
    assert pulses(1, 1) == [(ONESHOT["ccr"] * ticks, (ONESHOT["arr"] + 1) * ticks, APB2_TIMER_HZ)]


def test_update_and_compare_interrupts_per_period(r: dict[str, int]) -> None:
    """One update and one CC1 interrupt per period over a 100 ms window (TIM4 on NVIC 30, TIM1's UP on 25
    and CC on 27): the window holds WINDOW / period periods, give or take the one under way."""
    for timer, hz, setup in (("tim4", APB1_TIMER_HZ, PWM), ("tim1", APB2_TIMER_HZ, ONESHOT)):
        expected = WINDOW_S / period_s(hz, setup["psc"], setup["arr"])
        for kind in ("update", "compare"):
            assert abs(r[f"{timer}_{kind}_interrupts"] - expected) <= 1, (timer, kind, expected)


def test_ccr_preload(r: dict[str, int]) -> None:
    """18.3.9: with OC2PE a CCR2 written mid-period (CNT 500, CCR2 1000 -> 200) waits for the update:
    PD13 stays high; without it the new value acts at once (CNT > 200: low). Reads give the written
    value both ways; the next period is 200 us high."""
    assert r["preload_pin_after_write"] == 1
    assert r["direct_pin_after_write"] == 0
    assert r["preload_ccr_read"] == r["direct_ccr_read"] == 200
    for name in ("preload_high_next", "direct_high_next"):
        assert abs(r[name] - cycles(200e-6)) <= POLL_CYCLES, name


def test_center_aligned_pwm(r: dict[str, int]) -> None:
    """18.3.9 (center-aligned PWM): up to ARR and down again, 2 x ARR ticks a period, PWM mode 1 high
    while CNT < CCR3 both ways: 2 x CCR3 ticks (TIM3 CH3 on PB0, ARR 1000, CCR3 250, 1 us ticks)."""
    assert abs(r["tim3_center_high_cycles"] - cycles(2 * 250e-6)) <= POLL_CYCLES
    assert abs(r["tim3_center_period_cycles"] - cycles(2 * 1000e-6)) <= POLL_CYCLES
    assert pulses(3, 3) == [(2 * 250 * 84, 2 * 1000 * 84, APB1_TIMER_HZ)]


def test_the_rcc_reset_restores_a_timer(r: dict[str, int]) -> None:
    """7.3.7 (APB1RSTR.TIM4RST): back to the reset values."""
    assert (r["tim4_arr_after_reset"], r["tim4_cr1_after_reset"], r["tim4_ccer_after_reset"]) == (0, 0, 0)


def test_two_runs_are_identical() -> None:
    """The same image: the same reports and the same pulse trace, byte for byte."""
    again = run_firmware(engine_or_skip(), firmware("timers_pwm"), *TRACE_PULSES)
    assert (again.stdout, again.stderr) == (traced_run().stdout, traced_run().stderr)


#: timer_capture.c's wiring: TIM4 CH1 (PD12) into TIM2 CH1 (PA0), TIM4 CH2 (PD13) into TIM3 CH1 (PA6), the
#: firmware's own PD1 into TIM3 CH2 (PA7)
WIRES = ("-M", "rig-stm32f405,wires=PD12-PA0+PD13-PA6+PD1-PA7")
PPM_US = (1000, 1500, 2000, 1200)
PPM_PERIOD_US = 2041


def capture_run() -> subprocess.CompletedProcess[str]:
    return checked_run("timer_capture", *WIRES)


@pytest.fixture(scope="module")
def c() -> dict[str, int]:
    return reports(capture_run().stdout)


def test_ppm_pulses_captured_by_tim2(c: dict[str, int]) -> None:
    """18.3.5/18.3.6: TIM2 CH1 captures PA0's rising edges, CH2 (CC2S = 10: TI1) its falling ones, in
    84 MHz ticks. TIM4's update interrupt writes the next width into the preloaded CCR1, so period k
    (k >= 1) carries the width written at the update before it, PPM_US[k - 1] (the first pulse began
    when CC1E was set, just before CEN: not compared)."""
    us = APB1_TIMER_HZ // 1_000_000
    assert c["ppm_captures"] >= 10
    for k in range(1, 10):
        assert c[f"ppm_width_{k}"] == PPM_US[(k - 1) % 4] * us, k
    for k in range(1, 10):
        assert c[f"ppm_period_{k}"] == PPM_PERIOD_US * us, k


def test_both_edges_and_reading_clears_the_flag(c: dict[str, int]) -> None:
    """CC1P = CC1NP = 1 captures both edges: TIM4 CH2's 700 us high and 2041 - 700 us low, alternating,
    in TIM3's 1 us ticks; reading CCR1 clears CC1IF (18.4.5)."""
    assert c["tim3_sr_after_ccr_read"] == 0
    intervals = [c[f"edge_interval_{k}"] for k in range(1, 5)]
    assert sorted(intervals) == sorted([700, PPM_PERIOD_US - 700] * 2)
    assert intervals[0] != intervals[1]


def test_a_pin_the_firmware_toggles_is_captured(c: dict[str, int]) -> None:
    """PD1 set every 500 us by DWT_CYCCNT: TIM3 CH2 (1 us ticks) sees the rising edges 500 ticks apart;
    with IC2PSC = 01 (18.4.7: a capture every 2 events) 1000 apart, and one more edge captures nothing."""
    assert c["toggle_interval_us"] == 500
    assert c["toggle_interval_div2_us"] == 1000
    assert c["toggle_one_more_edge_us"] == 1000


def test_pwm_input_mode(c: dict[str, int]) -> None:
    """18.3.6: IC1 on TI1's rising edges, IC2 on its falling ones and the slave mode controller resetting
    the counter on TI1FP1 (reset mode, 18.3.14, which sets TIF): CCR1 reads the period and CCR2 the high
    time of TIM4 CH2's pulses in TIM3's 1 us ticks (the manual's timing figure captures the count before
    the reset's own tick: within one)."""
    assert abs(c["pwm_input_period_us"] - PPM_PERIOD_US) <= 1
    assert abs(c["pwm_input_high_us"] - 700) <= 1
    assert c["pwm_input_sr"] == 1 << 6


def test_trigger_mode_starts_the_counter(c: dict[str, int]) -> None:
    """18.3.14 (trigger mode, SMS = 110): the counter starts at TI1FP1's rising edge: CEN set by the
    hardware, TIF with it."""
    assert c["trigger_cr1_before"] & 1 == 0
    assert c["trigger_cr1_after"] & 1 == 1
    assert c["trigger_sr"] == 1 << 6


def test_unread_captures_set_overcapture(c: dict[str, int]) -> None:
    """18.4.5: a capture while CCxIF is still set sets CCxOF: CC1IF, CC2IF, CC1OF, CC2OF."""
    assert c["tim2_sr_unread"] == (1 << 1) | (1 << 2) | (1 << 9) | (1 << 10)


def test_captures_are_deterministic() -> None:
    again = run_firmware(engine_or_skip(), firmware("timer_capture"), *WIRES)
    assert again.stdout == capture_run().stdout


def test_a_bad_wire_is_refused() -> None:
    """A wire that names no pin, or a pin that already drives something (PB6: I2C1's SCL), stops the
    machine with a message naming it."""
    engine = engine_or_skip()
    for spec, words in (("PD12-PZ1", "not a pair of pins"), ("PB6-PA0", "already drives")):
        done = subprocess.run([str(engine), "-M", f"rig-stm32f405,wires={spec}", "-nodefaults", "-display",
                               "none", "-kernel", str(firmware("timer_capture"))],
                              stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=30)
        assert done.returncode == 1 and words in done.stderr, (spec, done.stderr)


@pytest.fixture(scope="module")
def m() -> dict[str, int]:
    return reports(checked_run("timer_modes", *TRACE_PULSES).stdout)


def test_advanced_timer_counting_down_with_repetitions(m: dict[str, int]) -> None:
    """17.3.2/17.3.3: TIM8 counts down from ARR 999 at 1 us (PSC 167 on 168 MHz), DIR reads back set;
    PWM mode 1 counting down is high while CNT <= CCR1: 301 of 1000 ticks; with RCR 2 the update event
    comes every third underflow: 10 in 30 ms."""
    assert m["tim8_cr1"] & (1 << 4)
    us = APB2_TIMER_HZ // (167 + 1)
    assert abs(m["tim8_down_high_cycles"] - cycles(301 / us)) <= POLL_CYCLES
    assert abs(m["tim8_down_period_cycles"] - cycles(1000 / us)) <= POLL_CYCLES
    assert abs(m["tim8_updates_30ms"] - 0.030 / (3 * 1000 / us)) <= 1
    assert pulses(8, 1, "timer_modes") == [(301 * 168, 1000 * 168, APB2_TIMER_HZ)]


@pytest.mark.parametrize(("name", "arr"), [("direct", 500), ("preload", 1000)])
def test_arr_written_mid_period(m: dict[str, int], name: str, arr: int) -> None:
    """18.3.1: without ARPE a new ARR (500, written at CNT >= 100 of ARR 1000) ends this very period;
    with ARPE the period runs to the old ARR. The update comes after ARR - CNT + 1 ticks of 1 us, less
    the part of the tick the counter was into when CNT was read."""
    at = m[f"arr_{name}_cnt"]
    expected = cycles((arr - at + 1) * 1e-6)
    assert expected - cycles(1e-6) - POLL_CYCLES <= m[f"arr_{name}_cycles"] <= expected + POLL_CYCLES


def test_the_prescaler_changes_at_the_update(m: dict[str, int]) -> None:
    """18.3.1 (figure 'prescaler division change'): PSC written mid-period (83 -> 167) is taken at the
    next update event: the period under way ends at the old rate (1000 - CNT ticks of 1 us), the ones
    after it are 1000 ticks of 2 us, 2 ms."""
    rest = cycles((1000 - m["psc_cnt_at_write"]) * 1e-6)
    assert rest - cycles(1e-6) - POLL_CYCLES <= m["psc_rest_of_period_cycles"] <= rest + POLL_CYCLES
    for name in ("psc_first_period_cycles", "psc_second_period_cycles"):
        assert abs(m[name] - cycles(2000e-6)) <= POLL_CYCLES, name


def test_update_request_source_disable_and_one_pulse(m: dict[str, int]) -> None:
    """20.4.1 (TIM7): UG sets UIF unless URS; UDIS stops update events (500 us at ARR 99 with no UIF),
    clearing it lets them come; in one-pulse mode the counter stops at the update: CEN cleared, CNT 0."""
    assert m["tim7_sr_ug_with_urs"] == 0
    assert m["tim7_sr_ug"] == 1
    assert m["tim7_sr_udis"] == 0
    assert m["tim7_sr_counting"] == 1
    assert m["tim7_cr1_one_pulse"] == 1 << 3  # OPM left, CEN cleared
    assert m["tim7_cnt_one_pulse"] == 0
    assert m["tim7_sr_one_pulse"] == 1


def test_pwm_mode_2_and_an_inverted_output(m: dict[str, int]) -> None:
    """18.4.7: PWM mode 2 is inactive while CNT < CCR3 (high 2041 - 500 us); 18.4.9: CC4P inverts PWM
    mode 1 (high 2041 - 300 us). The latched pulses say the same in ticks."""
    period = 2041
    assert abs(m["pwm2_high_cycles"] - cycles((period - 500) * 1e-6)) <= POLL_CYCLES
    assert abs(m["inverted_high_cycles"] - cycles((period - 300) * 1e-6)) <= POLL_CYCLES
    for name in ("pwm2_period_cycles", "inverted_period_cycles"):
        assert abs(m[name] - cycles(period * 1e-6)) <= POLL_CYCLES
    assert pulses(4, 3, "timer_modes")[0] == ((period - 500) * 84, period * 84, APB1_TIMER_HZ)
    assert pulses(4, 4, "timer_modes")[0] == ((period - 300) * 84, period * 84, APB1_TIMER_HZ)


def test_the_timer_clock_follows_the_apb_prescaler(m: dict[str, int]) -> None:
    """7.2: APB1 at HCLK / 8 makes the timer clock 2 x 21 = 42 MHz: the same ticks last twice as long,
    and the latched pulse is the same ticks at the new clock."""
    slow_hz = 2 * CORE_HZ // 8
    assert abs(m["pwm2_slow_high_cycles"] - cycles(1541 * 84 / slow_hz)) <= POLL_CYCLES
    assert abs(m["pwm2_slow_period_cycles"] - cycles(2041 * 84 / slow_hz)) <= POLL_CYCLES
    assert pulses(4, 3, "timer_modes")[1:] == [(1541 * 84, 2041 * 84, slow_hz)]


def test_an_undivided_apb_clock_is_not_doubled(m: dict[str, int]) -> None:
    """7.2: the timer clock is twice PCLK only when the APB prescaler is not 1: with PPRE1 = /1 TIM6
    (PSC 167, ARR 999) takes 168 x 1000 / 168 MHz = 1000 us a period."""
    assert abs(m["apb1_undivided_period_cycles"] - cycles(168 * 1000 / CORE_HZ)) <= POLL_CYCLES


def test_toggle_on_match_and_forced_levels(m: dict[str, int]) -> None:
    """19.4.7 (TIM9): toggle on match flips PE5 once a period (500 us at ARR 499): high one period, low
    the next; forced active and inactive levels reach PE6 at once."""
    assert abs(m["toggle_high_cycles"] - cycles(500e-6)) <= POLL_CYCLES
    assert abs(m["toggle_period_cycles"] - cycles(1000e-6)) <= POLL_CYCLES
    assert (m["forced_high_pin"], m["forced_low_pin"]) == (1, 0)


def test_complementary_outputs(m: dict[str, int]) -> None:
    """17.3.11 (dead time 0): CH2N alone (CC2NE) is OC2REF through CC2NP, 300 of 1000 us on PB0; with
    CH3 and CH3N both on, CH3N is the complement: 400 us high on PA10, 600 us on PB1. Their pulses are
    latched as ch2n and ch3n."""
    for name, high_us in (("ch2n", 300), ("ch3", 400), ("ch3n", 600)):
        assert abs(m[f"{name}_high_cycles"] - cycles(high_us * 1e-6)) <= POLL_CYCLES, name
        assert abs(m[f"{name}_period_cycles"] - cycles(1000e-6)) <= POLL_CYCLES, name
    trace = checked_run("timer_modes", *TRACE_PULSES).stderr
    assert "TIM1 ch2n high_ticks=50400 period_ticks=168000 clock_hz=168000000" in trace
    assert "TIM1 ch3n high_ticks=100800 period_ticks=168000 clock_hz=168000000" in trace


def test_two_timers_share_an_interrupt_line(m: dict[str, int]) -> None:
    """Table 61: TIM1's update and TIM10's global interrupt are one NVIC line (25); neither hides the
    other's: 30 ms hold 60 periods of 500 us and 100 of 300 us."""
    assert abs(m["tim1_updates_30ms"] - 60) <= 1
    assert abs(m["tim10_updates_30ms"] - 100) <= 1


def qom_get(qmp_socket: Path, requests: list[tuple[str, str]]) -> list[int]:
    """QMP's qom-get for each (path, property), over QEMU's QMP socket."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
        sock.settimeout(RUN_TIMEOUT_S)
        sock.connect(str(qmp_socket))
        stream = sock.makefile("rw")
        json.loads(stream.readline())  # the greeting
        values = []
        for command in [{"execute": "qmp_capabilities"},
                        *({"execute": "qom-get", "arguments": {"path": path, "property": prop}}
                          for path, prop in requests)]:
            stream.write(json.dumps(command) + "\n")
            stream.flush()
            reply = json.loads(stream.readline())
            assert "return" in reply, reply
            values.append(reply["return"])
        return values[1:]


def test_latched_pulses_read_from_outside_over_qmp(tmp_path: Path) -> None:
    """What a session reads, without semihosting: each timer is /machine/timN, its channels' latched
    pulses its read-only properties. pwm_hold.c leaves four motors' pulses on TIM4 (1000, 1250, 1500,
    2000 us at 490 Hz, 1 us ticks from 84 MHz) and OneShot125 on TIM1 CH1 (1500 ticks of 8 MHz)."""
    qmp = tmp_path / "qmp.sock"
    cmd = [str(engine_or_skip()), "-M", "rig-stm32f405", "-nodefaults", "-display", "none", "-chardev",
           "stdio,id=semi", "-semihosting-config", "enable=on,target=native,chardev=semi", "-icount",
           f"shift={ICOUNT_SHIFT},sleep=off", "-qmp", f"unix:{qmp},server=on,wait=off", "-kernel",
           str(firmware("pwm_hold"))]
    with subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                          text=True) as qemu:
        try:
            assert qemu.stdout is not None
            assert select.select([qemu.stdout], [], [], RUN_TIMEOUT_S)[0], "no 'ready' from the firmware"
            assert qemu.stdout.readline() == "ready\n"
            tim4 = [("/machine/tim4", f"ch{ch}-high-ticks") for ch in range(1, 5)]
            rest = [("/machine/tim4", "period-ticks"), ("/machine/tim4", "clock-hz"),
                    ("/machine/tim1", "ch1-high-ticks"), ("/machine/tim1", "period-ticks"),
                    ("/machine/tim1", "clock-hz")]
            values = qom_get(qmp, tim4 + rest)
        finally:
            qemu.kill()
    us = APB1_TIMER_HZ // 1_000_000
    assert values[:4] == [w * us for w in (1000, 1250, 1500, 2000)]
    assert values[4:6] == [2041 * us, APB1_TIMER_HZ]
    assert values[6:] == [1500 * 21, 4000 * 21, APB2_TIMER_HZ]
