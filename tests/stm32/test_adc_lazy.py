"""The ADC's lazy DMA scan (qemu/hw/rig_stm32_adc.c): a continuous scan feeding a DMA stream makes its
conversions and transfers when something looks (an ADC or DMA register access, the link's stop, an input
set), a QEMU timer only for the stream's interrupt instants and, after each change, for each conversion
until every item of the buffer was written again. What the firmware sees must not tell it from the ADC
eager (the model's property "eager": a QEMU timer for every conversion): tests/stm32/firmware/adc_lazy.c
copies the buffer with no register access, reads the stream's flags and NDTR, and takes the half- and
transfer-complete interrupts, then copies a buffer of four items (no whole number of three-channel
sequences: each round puts other channels at each place, so each conversion keeps its QEMU timer), while
the rig sets channel 11 to new volts at every 1 ms stop; both runs print the same bytes.

Independent truth, written here: each item is the code of its channel's volts (V / 3.3 V x 4095,
rounded; RM0090 13.3.4's scan order SQ1, SQ2, SQ3 into consecutive half-words, 10.3.9's circular mode),
channel 11's code one the rig set; a conversion takes (480 + 12) ADC cycles at 16 MHz / 2 (13.5, 13.13.17),
984 CPU cycles, so the six-item buffer's HTIF (10.3.11: half the items) and TCIF come three conversions
apart, with NDTR 3 and 6 (reloaded) when they come."""

from __future__ import annotations

import functools
from fractions import Fraction

from rig.mcu import board as boards
from rig.mcu.stm32_link import Stm32Config, Stm32Engine
from tests.stm32.conftest import engine_or_skip, firmware, reports

STEP_NS = 1_000_000
VDDA = Fraction(33, 10)
#: channels 10 and 12 fixed; channel 11 at the n-th stop
FIXED = {10: Fraction(1), 12: Fraction(1, 2)}


def ch11_volts(stop: int) -> Fraction:
    return Fraction(1 + (7 * stop) % 23, 10)


CONVERSION_CYCLES = (480 + 12) * 2  # ADC cycles at PCLK2 / 2, in 16 MHz CPU cycles
ITEMS, SAMPLES, SAMPLE_CYCLES, INTERRUPTS, ROTATING_SAMPLES = 6, 48, 2500, 12, 16
HTIF, TCIF = 1 << 4, 1 << 5  # RM0090 10.5.1: stream 0's flags in LISR


def code(volts: Fraction) -> int:
    return int(min(volts, VDDA) / VDDA * 4095 + Fraction(1, 2))


@functools.cache
def output(*qemu_args: str) -> str:
    """adc_lazy.elf through the link in 1 ms stops, channel 11 set anew at each: QEMU's output."""
    analog = tuple((ch, float(v)) for ch, v in {**FIXED, 11: ch11_volts(0)}.items())
    cfg = Stm32Config(boards.load("stm32f405-gy86"), firmware("adc_lazy"), engine_or_skip(), analog=analog,
                      qemu_args=qemu_args)
    engine = Stm32Engine(cfg, None)
    try:
        t = stop = 0
        while (reached := engine.run_until(t := t + STEP_NS)).kind == "reached":
            assert t < 100 * STEP_NS, "adc_lazy.elf did not end"
            stop += 1
            engine.analog_input(11, float(ch11_volts(stop)))
        assert reached.kind == "exited", reached.describe()
        return engine.output()
    finally:
        engine.close()


def test_lazy_and_eager_scans_show_the_firmware_the_same_bytes() -> None:
    lazy, eager = output(), output("-global", "rig-stm32f4-adc.eager=on")
    assert lazy.endswith("done\n"), lazy
    assert lazy == eager


def test_the_buffer_holds_each_channels_code_in_scan_order() -> None:
    """Between register accesses too: the memory copied with none holds channel 10's and 12's codes at
    their places, and channel 11's a code of volts the rig set; the samples see it change."""
    r = reports(output())
    set_codes = {code(ch11_volts(n)) for n in range(100)}
    seen11 = []
    for k in range(SAMPLES):
        items = [r[f"sample{k:02d}_{i}"] for i in range(ITEMS)]
        if (k + 1) * SAMPLE_CYCLES < ITEMS * CONVERSION_CYCLES:
            continue  # (before the first round is written)
        assert items[0] == items[3] == code(FIXED[10]), (k, items)
        assert items[2] == items[5] == code(FIXED[12]), (k, items)
        assert items[1] in set_codes and items[4] in set_codes, (k, items)
        seen11.append(items[1])
    assert len(set(seen11)) >= 5  # (the rig's changes reached the buffer between register accesses)


def test_the_flags_and_ndtr_between_samples() -> None:
    """Every fourth sample (10000 cycles, over 3 rounds of 2952) the stream has been through both HTIF and
    TCIF since the last look, its NDTR one of the round's."""
    r = reports(output())
    for k in range(3, SAMPLES, 4):
        assert r[f"sample{k:02d}_6"] == HTIF | TCIF
        assert 1 <= r[f"sample{k:02d}_7"] <= ITEMS


def test_half_and_transfer_complete_interrupts_three_conversions_apart() -> None:
    r = reports(output())
    cycles = [r[f"irq{k:02d}_8"] for k in range(INTERRUPTS)]
    assert {b - a for a, b in zip(cycles, cycles[1:], strict=False)} == {3 * CONVERSION_CYCLES}
    kinds = [r[f"irq{k:02d}_6"] for k in range(INTERRUPTS)]
    ndtrs = [r[f"irq{k:02d}_7"] for k in range(INTERRUPTS)]
    first = 0 if kinds[0] == HTIF else 1
    assert kinds[first::2] == [HTIF] * len(kinds[first::2])
    assert kinds[1 - first::2] == [TCIF] * len(kinds[1 - first::2])
    assert [n for n, f in zip(ndtrs, kinds, strict=True) if f == HTIF] == [3] * kinds.count(HTIF)
    assert [n for n, f in zip(ndtrs, kinds, strict=True) if f == TCIF] == [ITEMS] * kinds.count(TCIF)
    for k in range(INTERRUPTS):
        items = [r[f"irq{k:02d}_{i}"] for i in range(ITEMS)]
        assert items[0] == items[3] == code(FIXED[10]) and items[2] == items[5] == code(FIXED[12])


def test_a_buffer_of_no_whole_number_of_sequences_rotates_the_channels() -> None:
    """Four items of a three-channel scan: round r puts rank (4 r + i) mod 3 at place i, so the first place
    sees channel 10's, 12's and 11's codes in turn, as copied with no register access."""
    r = reports(output())
    fixed = {code(FIXED[10]), code(FIXED[12])}
    firsts = [r[f"rotating{k:02d}_0"] for k in range(ROTATING_SAMPLES)]
    assert fixed <= set(firsts)
    assert len(set(firsts) - fixed) >= 1  # (channel 11's)
