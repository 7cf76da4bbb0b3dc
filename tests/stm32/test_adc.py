"""The rig's STM32F4 ADCs (qemu/hw/rig_stm32_adc.c) against RM0090 section 13, and a board's battery
reaching the firmware: tests/stm32/firmware/adc.c runs on the F405 board file with a ``[battery]`` on PC0
(ADC123_IN10), the engine opened as the MCU session opens it (rig/mcu/engines.py: the board's analog
inputs over the link's ADC message, qemu/hw/rig_link.c), and two more inputs set through the engine.

Independent truth, written here: a conversion's code is V / VDDA x (2^bits - 1) rounded, halves up (VDDA
= VREF+ = 3.3 V on the boards); its time is (sampling cycles + the resolution's bits) ADC clock cycles
(RM0090 13.5), the ADC clock PCLK2 / ADCPRE's 2, 4, 6, 8 (13.13.17); the data alignment of 13.7; the
internal channels' volts of DS8626 (temperature sensor V25 0.76 V, VREFINT 1.21 V typical) and RM0090
13.11 (VBAT / 2 on the F405), RM0383 11.11 (VBAT / 4 on the F411, its sensor on channel 18), with the
model's fixed 3.0 V backup battery."""

from __future__ import annotations

import functools
from fractions import Fraction
from pathlib import Path

import pytest

from rig.mcu import board as boards
from rig.mcu.board import BoardError
from rig.mcu.engines import open_engine
from rig.mcu.stm32_link import Stm32Engine
from tests.stm32.conftest import engine_or_skip, firmware, reports, run_to_done

SHIPPED = boards.BOARDS / "stm32f405-gy86.toml"
#: the board's battery: a 3S pack at 12.6 V through 10 k / 1 k onto PC0
BATTERY = '[battery]\npin = "PC0"\ndivider = [10_000, 1_000]\nvolts = 12.6\n'
PACK_VOLTS, TOP, BOTTOM = Fraction(126, 10), 10_000, 1_000
#: what the test sets through the engine: ADC channel -> volts
INPUTS = {11: Fraction(2), 12: Fraction(1, 2)}
VDDA = Fraction(33, 10)
CPU_HZ = PCLK2_HZ = 16_000_000  # the reset clock: HSI, APB2 undivided
STEP_NS = 1_000_000
#: RM0090 13.13.4/13.13.5: SMPx -> sampling cycles
SAMPLING = [3, 15, 28, 56, 84, 112, 144, 480]
#: adc.c's scan: channels 10, 11, 12 at 480 cycles each, ADCPRE /2, over this many CPU cycles
SCAN_WINDOW_CYCLES = 295_200
SR_AWD, SR_EOC, SR_STRT, SR_OVR = 1 << 0, 1 << 1, 1 << 4, 1 << 5


def code(volts: Fraction, bits: int = 12) -> int:
    """The ideal converter: V / VDDA x full scale, rounded (halves up), full scale above VDDA."""
    return int(min(volts, VDDA) / VDDA * ((1 << bits) - 1) + Fraction(1, 2))


def pin_volts() -> Fraction:
    return PACK_VOLTS * BOTTOM / (TOP + BOTTOM)


def battery_board(tmp_path: Path, battery: str = BATTERY) -> Path:
    """The shipped F405 board with ``battery`` for its own [battery] table."""
    text = SHIPPED.read_text()
    start = text.index("[battery]")
    end = text.index("\n[", start) + 1
    path = tmp_path / "stm32f405-gy86-battery.toml"
    path.write_text(text[:start] + battery + "\n" + text[end:])
    return path


@functools.cache
def output(tmp: Path) -> str:
    """adc.elf on the battery board through the link, with INPUTS set: QEMU's output."""
    board = boards.load(battery_board(tmp))
    engine_or_skip()
    engine = open_engine(board, firmware("adc"), None)
    try:
        assert isinstance(engine, Stm32Engine)
        for channel, volts in INPUTS.items():
            engine.analog_input(channel, float(volts))
        t = 0
        while (stop := engine.run_until(t := t + STEP_NS)).kind == "reached":
            assert t < 200 * STEP_NS, "adc.elf did not end"
        assert stop.kind == "exited", stop.describe()
        return engine.output()
    finally:
        engine.close()


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("adc")


@pytest.fixture(scope="module")
def r(run_dir: Path) -> dict[str, int]:
    out = output(run_dir)
    assert out.endswith("done\n"), out
    return reports(out)


def test_registers_at_reset_and_writable_bits(r: dict[str, int]) -> None:
    """13.13: every register resets to 0 but HTR (0xFFF); without RCC_APB2ENR.ADC1EN writes are lost;
    all ones written keep the writable bits of the register map (table 71)."""
    assert r["cr1_unclocked"] == 0
    assert r["or_of_reset"] == 0
    assert r["htr_reset"] == 0xFFF
    writable = {0x04: 0x07C0FFFF, 0x0C: 0x07FFFFFF, 0x10: 0x3FFFFFFF, 0x14: 0xFFF, 0x24: 0xFFF, 0x28: 0xFFF,
                0x2C: 0x00FFFFFF, 0x30: 0x3FFFFFFF, 0x34: 0x3FFFFFFF, 0x38: 0x003FFFFF, 0x3C: 0, 0x4C: 0}
    assert {off: r[f"ones_{off:02d}"] for off in writable} == writable
    # CR2 (13.13.3) less SWSTART, which hardware clears as the conversion starts (JSWSTART not written)
    assert r["ones_cr2"] == 0x7F7F0F03 & ~(1 << 30) & ~(1 << 22)
    assert r["ccr_ones"] == 0x00C3EF00  # 13.13.17: TSVREFE, VBATE, ADCPRE, DMA, DDS, DELAY


def test_the_battery_and_the_engines_inputs_read_at_each_resolution(r: dict[str, int]) -> None:
    """The board's battery on PC0 (ADC123_IN10) and the inputs set on 11 and 12; RES 12, 10, 8, 6 bits
    (13.13.2); a channel nobody set reads 0 V."""
    assert [r[f"ch10_res{k:02d}"] for k in range(4)] == [code(pin_volts(), b) for b in (12, 10, 8, 6)]
    assert r["ch11"] == code(INPUTS[11]) and r["ch12"] == code(INPUTS[12])
    assert r["ch0"] == 0
    assert r["sr_after"] == SR_STRT  # EOC cleared by each DR read, STRT kept until software clears it


def test_left_alignment(r: dict[str, int]) -> None:
    """13.7: left aligned, 12 bits fill the half-word's top; 6 bits sit on a byte (bits 7:2)."""
    assert r["ch10_left"] == code(pin_volts()) << 4
    assert r["ch10_left6"] == code(pin_volts(), 6) << 2


@pytest.mark.parametrize(("smp", "pre"), [(0, 0), (7, 0), (0, 3), (7, 3), (4, 1)])
def test_conversion_time(r: dict[str, int], smp: int, pre: int) -> None:
    """13.5: Tconv = (sampling cycles + 12) ADC clock cycles, the ADC clock PCLK2 / (2 (pre + 1)); from
    SWSTART to the EOC seen, within one polling loop of SR (measured by the firmware) and a cycle."""
    adc_cycles = SAMPLING[smp] + 12
    expected = adc_cycles * 2 * (pre + 1) * CPU_HZ // PCLK2_HZ
    loop = -(-r["poll_100"] // 100)
    assert 0 <= r[f"time_smp{smp}_pre{pre}"] - expected <= loop + 1, (r[f"time_smp{smp}_pre{pre}"], expected)


def test_scan_by_dma_into_a_circular_buffer(r: dict[str, int]) -> None:
    """Betaflight's pattern: SCAN of SQ1-SQ3 (10, 11, 12), CONT, DMA with DDS into a 3-half-word circular
    buffer by DMA2 stream 0 channel 0 (RM0090 table 43); each round of three conversions ends in one
    transfer-complete interrupt, so the window holds its length over a round's cycles (the last one may
    fall just past it), and no overrun."""
    round_cycles = 3 * (SAMPLING[7] + 12) * 2
    assert r["scan_rounds"] in (SCAN_WINDOW_CYCLES // round_cycles - 1, SCAN_WINDOW_CYCLES // round_cycles)
    assert [r["scan_0"], r["scan_1"], r["scan_2"]] == [code(pin_volts()), code(INPUTS[11]), code(INPUTS[12])]
    assert 1 <= r["scan_ndtr"] <= 3
    assert not r["scan_sr"] & SR_OVR


def test_overrun(r: dict[str, int]) -> None:
    """13.8.1: with EOCS set, a conversion ending while DR is unread sets OVR and stops the regular
    conversions (DR keeps the first); triggers are ignored until OVR is cleared. Without DMA and with EOCS
    clear no overrun is detected: continuous conversions go on unread."""
    assert r["ovr_sr"] == SR_EOC | SR_STRT | SR_OVR
    assert r["ovr_dr"] == code(pin_volts())
    assert r["ovr_sr_ignored"] == SR_STRT | SR_OVR
    assert r["ovr_cleared"] == code(INPUTS[11])
    assert r["ovr_dma_sr"] == SR_EOC | SR_STRT | SR_OVR  # (with DMA, the same with nobody to take DR)
    assert r["cont_sr"] == SR_EOC | SR_STRT
    assert r["cont_dr"] == code(pin_volts())


def test_the_analog_watchdog(r: dict[str, int]) -> None:
    """13.3.7: AWDEN with AWDSGL watches AWDCH (10) alone; its code (1421) over HTR (1000) sets AWD, channel
    12's code (621) under it on an unwatched channel does not."""
    assert code(INPUTS[12]) < 1000 < code(pin_volts())
    assert r["awd_sr_12"] == SR_STRT
    assert r["awd_sr_10"] == SR_STRT | SR_AWD


def test_injected_conversions_less_their_offset(r: dict[str, int]) -> None:
    """13.3.4, 13.13.12: JL = 1 converts JSQ3 then JSQ4 into JDR1, JDR2, less JOFR1 (100) and JOFR2 (0)."""
    assert r["jdr1"] == code(pin_volts()) - 100
    assert r["jdr2"] == code(INPUTS[11])


def test_internal_channels(r: dict[str, int]) -> None:
    """13.10, 13.11 on the F405: the sensor on 16 and VREFINT on 17 with TSVREFE, VBAT / 2 on 18 with
    VBATE; 0 without them."""
    assert r["ch17_off"] == 0
    assert r["ch16_temp"] == code(Fraction(76, 100))
    assert r["ch17_vrefint"] == code(Fraction(121, 100))
    assert r["ch18_no_vbate"] == 0
    assert r["ch18_vbat"] == code(Fraction(3) / 2)


def test_the_eoc_interrupt(r: dict[str, int]) -> None:
    """EOCIE raises NVIC line 18 (RM0090 table 61) once a conversion; the handler's DR read clears it."""
    assert r["eoc_interrupts"] == 1
    assert r["eoc_value"] == code(pin_volts())


def test_the_f411s_internal_channels() -> None:
    """RM0383 11.10, 11.11: the F411's sensor and VBAT share channel 18 (VBAT wins), VBAT / 4; its
    channel 16 is no sensor. (Run without the link: its external inputs read 0 V.)"""
    r = reports(run_to_done("adc", machine="rig-stm32f411").stdout)
    assert r["ch16_temp"] == 0
    assert r["ch17_vrefint"] == code(Fraction(121, 100))
    assert r["ch18_no_vbate"] == code(Fraction(76, 100))
    assert r["ch18_vbat"] == code(Fraction(3) / 4)
    assert r["scan_rounds"] >= SCAN_WINDOW_CYCLES // (3 * (SAMPLING[7] + 12) * 2) - 1


def test_two_runs_print_the_same_bytes(run_dir: Path, tmp_path: Path) -> None:
    assert output(tmp_path) == output(run_dir)


def test_a_battery_needs_an_analog_pin(tmp_path: Path) -> None:
    """The board check takes the STM32's ADC pins (rig/mcu/mcus.py): PD0 has none."""
    with pytest.raises(BoardError, match="battery.pin.*analog inputs are PA0"):
        boards.load(battery_board(tmp_path, BATTERY.replace("PC0", "PD0")))
    assert boards.load(battery_board(tmp_path)).battery is not None


def test_the_shipped_board_measures_its_battery_on_pc2() -> None:
    """The Omnibus F4's battery pin (Betaflight's OMNIBUSF4 target) is ADC123_IN12 (DS8626's pin table);
    its 10 k / 1 k divider puts 12.6 V at 1.145 V, 1421 of 4095."""
    battery = boards.load("stm32f405-gy86").battery
    assert battery is not None and (battery.pin, battery.channel) == ("PC2", 12)
    assert code(Fraction(battery.pin_volts).limit_denominator(10**6)) == code(pin_volts()) == 1421


def test_the_link_refuses_an_input_the_chip_lacks(run_dir: Path) -> None:
    """A channel with no pin is refused by the engine before QEMU hears of it."""
    board = boards.load(battery_board(run_dir))
    engine_or_skip()
    engine = open_engine(board, firmware("adc"), None)
    try:
        assert isinstance(engine, Stm32Engine)
        with pytest.raises(ValueError, match="no analog input 16"):
            engine.analog_input(16, 1.0)
        with pytest.raises(ValueError, match="outside"):
            engine.analog_input(10, -1.0)
    finally:
        engine.close()


@pytest.mark.parametrize(("payload", "why"), [
    (bytes([4, 10, 0, 0, 0, 0, 0, 0]), "ADC 4"),
    (bytes([1, 16, 0, 0, 0, 0, 0, 0]), "channel 16 (an internal one)"),
    (bytes([1, 10, 0, 0, 0, 0, 0]), "a short message"),
    (bytes([1, 10, 1, 0, 0, 0, 0, 0]), "padding not zero"),
], ids=["adc", "channel", "length", "padding"])
def test_the_link_ends_qemu_on_a_malformed_adc_message(run_dir: Path, payload: bytes, why: str) -> None:
    """QEMU checks the ADC message as any input (qemu/hw/rig_link.c): a bad one ends it with a message,
    which the engine's stop carries."""
    engine_or_skip()
    engine = open_engine(boards.load(battery_board(run_dir)), firmware("adc"), None)
    try:
        assert isinstance(engine, Stm32Engine)
        engine._send(ord("A"), payload)  # (what analog_input refuses to send)
        stop = engine.run_until(STEP_NS)
    finally:
        engine.close()
    assert stop.kind == "crashed" and "rig-link: ADC: " in stop.what, (why, stop.what)

