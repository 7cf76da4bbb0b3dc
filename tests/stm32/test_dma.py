"""The rig's STM32F405 DMA controllers (qemu/hw/rig_stm32_dma.c) against RM0090 section 10: the test
firmware tests/stm32/firmware/dma.c reports registers, copies, flags and interrupt counts; the engine's pulse
trace (-global rig-stm32f4-timer.trace-pulses=on) shows TIM4 channel 1's width each period as TIM4's update
requests wrote it through DMA1 stream 6. Expected values are RM0090's register descriptions (10.5), its
request mapping (table 42) and the timer's formulas (18.3), written here; the I2C1 read through DMA1 stream
0 is compared with the same registers read by polling (the chip core answers both)."""

from __future__ import annotations

import itertools

import pytest

from tests.stm32.conftest import engine_or_skip, firmware, reports, run_firmware
from tests.stm32.test_timers import TRACE, TRACE_PULSES, checked_run

#: the reset clock: HSI 16 MHz, APB1 undivided, so TIM4's clock is 16 MHz (RM0090 7.2: doubled only when
#: the APB prescaler is not 1)
TIM4_HZ = 16_000_000
TIM4_PSC, TIM4_ARR = 15, 99
TABLE = [10, 25, 40, 55, 70, 85, 30, 60]  # dma.c's compare values
#: RM0090 10.5.1: a stream's flags in LISR/HISR from its offset there (streams 0/4: 0, 1/5: 6, 2/6: 16,
#: 3/7: 22): FEIF 0, DMEIF 2, TEIF 3, HTIF 4, TCIF 5
FLAG_OFFSET = [0, 6, 16, 22]
TEIF, HTIF, TCIF = 1 << 3, 1 << 4, 1 << 5
#: 10.5.5 SxCR fields
EN, TEIE, HTIE, TCIE = 1, 1 << 2, 1 << 3, 1 << 4
M2M, PINC, MINC = 2 << 6, 1 << 9, 1 << 10


def psize(n: int) -> int:
    return n << 11


def msize(n: int) -> int:
    return n << 13


def run() -> str:
    done = checked_run("dma", *TRACE_PULSES)
    return done.stdout + done.stderr


@pytest.fixture(scope="module")
def r() -> dict[str, int]:
    return reports(checked_run("dma", *TRACE_PULSES).stdout)


def test_registers_at_reset(r: dict[str, int]) -> None:
    """10.5: every register resets to 0 but SxFCR, 0x21 (FS = 100, the FIFO empty; FTH = 01); with
    RCC_AHB1ENR.DMA1EN off (7.3.10) writes are lost."""
    assert r["dma1_s0cr_unclocked"] == 0
    for d in (1, 2):
        assert r[f"dma{d}_or_of_registers"] == 0
        assert r[f"dma{d}_fcr_and"] == r[f"dma{d}_fcr_or"] == 0x21


def test_writable_bits(r: dict[str, int]) -> None:
    """All ones written: SxCR's bits 0-19 and 21-27 (20 and 28-31 reserved; EN left out), NDT[15:0], the
    addresses' 32 bits, SxFCR's FTH, DMDIS and FEIE with FS read-only at 100; LISR read-only, LIFCR
    reads 0."""
    assert r["cr_ones"] == 0x0FEF_FFFE
    assert r["ndtr_ones"] == 0xFFFF
    assert r["par_ones"] == r["m0ar_ones"] == r["m1ar_ones"] == 0xFFFF_FFFF
    assert r["fcr_ones"] == 0x80 | 0x20 | 0x04 | 0x03
    assert r["lisr_ones"] == 0
    assert r["lifcr_read"] == 0


def test_configuration_locked_while_enabled(r: dict[str, int]) -> None:
    """10.5.5-10.5.10: with EN set, SxCR's configuration, NDTR, PAR and FCR's FTH/DMDIS are write-protected
    (the interrupt enables and FEIE are not); in direct mode MSIZE follows PSIZE. Cleared by software under
    way, the stream stops with TCIF (10.3.17) and NDTR keeps what was left."""
    assert r["enabled_cr"] == EN | MINC  # MSIZE (word, written) forced to PSIZE (byte)
    assert r["locked_cr"] == EN | MINC | TCIE  # PSIZE and CIRC not taken
    assert r["locked_ndtr"] == 5
    assert r["locked_par"] == 0x4000_5410
    assert r["locked_fcr"] == 0x21 | 0x80
    assert r["disabled_cr"] == MINC | TCIE
    assert r["disabled_lisr"] == TCIF << FLAG_OFFSET[2]
    assert r["disabled_ndtr"] == 5
    assert r["cleared_lisr"] == 0


SOURCE = bytes((i * 7 + 3) & 0xFF for i in range(32))  # dma.c's source bytes


def word(data: bytes, at: int) -> int:
    return int.from_bytes(data[at:at + 4], "little")


#: name: PSIZE, MSIZE, PINC/MINC, items; the bytes written
COPIES = {
    "m2m8": (0, 0, PINC | MINC, 32, SOURCE),
    "m2m16": (1, 1, PINC | MINC, 16, SOURCE),
    "m2m32": (2, 2, PINC | MINC, 8, SOURCE),
    "pack": (0, 2, PINC | MINC, 16, SOURCE[:16]),  # 16 bytes read, four words written (FIFO packing)
    "fill": (2, 2, MINC, 4, (0xA5C3E10F).to_bytes(4, "little") * 4),  # a fixed source
}


@pytest.mark.parametrize("name", sorted(COPIES))
def test_memory_to_memory(r: dict[str, int], name: str) -> None:
    """10.3.6: DMA2 copies NDTR items of PSIZE from PAR to M0AR at once; the addresses increment by the
    sizes; NDTR ends at 0, EN cleared (10.5.5), HTIF and TCIF set (10.3.11) and the stream's interrupt
    taken (both flags in one entry: the copy is done before the core runs again)."""
    p, m, inc, items, written = COPIES[name]
    assert len(written) == items << p
    assert r[f"{name}_first"] == word(written, 0)
    assert r[f"{name}_last"] == word(written, len(written) - 4)
    assert r[f"{name}_after"] == 0  # nothing past NDTR items
    assert r[f"{name}_cr"] == M2M | psize(p) | msize(m) | inc | TCIE | HTIE
    assert r[f"{name}_ndtr"] == 0
    assert r[f"{name}_flags"] == HTIF | TCIF
    assert r[f"{name}_irqs"] == 1


def test_memory_to_memory_sets_dmdis(r: dict[str, int]) -> None:
    """10.5.10: DMDIS is set by hardware when a memory-to-memory stream is enabled."""
    assert r["m2m_fcr"] == 0x21 | 0x04


def test_transfer_error(r: dict[str, int]) -> None:
    """10.3.16: a transfer to an address nothing answers sets TEIF and disables the stream; the item was
    not counted."""
    assert r["error_lisr"] == TEIF << FLAG_OFFSET[1]
    assert r["error_cr"] & EN == 0
    assert r["error_ndtr"] == 4


def test_a_peripheral_transfer_error(r: dict[str, int]) -> None:
    """10.3.16: TIM6_UP's request (DMA1 stream 1, channel 7) on a stream reading memory nothing answers
    (FIFO mode, bytes into words) stops the stream with TEIF, NDTR untouched."""
    assert r["m2p_error_lisr"] == TEIF << FLAG_OFFSET[1]
    assert r["m2p_error_cr_en"] == 0
    assert r["m2p_error_ndtr"] == 2


def test_memory_to_memory_on_dma1_is_a_transfer_error(r: dict[str, int]) -> None:
    """10.3.6: only DMA2 copies memory to memory (DMA1's peripheral port is not on the bus matrix): on DMA1
    the stream stops with TEIF and nothing moves, whatever its (here reserved) sizes and count."""
    assert r["dma1_m2m_lisr"] == TEIF << FLAG_OFFSET[1]
    assert r["dma1_m2m_cr_en"] == 0
    assert r["dma1_m2m_ndtr"] == 0xFFFF
    assert r["dma1_m2m_destination"] == 0


def test_timer_update_requests_write_ccr1_each_period(r: dict[str, int]) -> None:
    """Table 42: TIM4_UP is DMA1 stream 6, channel 2. UG's request writes the first value into CCR1's
    preload, and each update event after takes the preload into the shadow register (the period's pulse,
    latched then) and requests the next: the widths follow the table period by period, circular (10.3.9).
    The firmware stops TIM4 at the second TCIF, the update that requested the last value of round two:
    15 periods latched, each (PSC + 1)(ARR + 1) ticks apart (18.3.1)."""
    lines = [m for m in TRACE.finditer(run()) if (int(m[2]), int(m[3])) == (4, 1)]
    period_ticks = (TIM4_PSC + 1) * (TIM4_ARR + 1)
    assert [int(m[4]) for m in lines] == [v * (TIM4_PSC + 1) for v in (TABLE * 2)[:15]]
    assert {(int(m[5]), int(m[6])) for m in lines} == {(period_ticks, TIM4_HZ)}
    times = [int(m[1]) for m in lines]
    assert {b - a for a, b in itertools.pairwise(times)} == {period_ticks * 1_000_000_000 // TIM4_HZ}
    assert r["tim_rounds"] == 2
    assert r["tim_halves"] == 2  # HTIF at the fourth item of each round
    assert r["tim_ccr1"] == TABLE[7]
    assert r["tim_ndtr"] == len(TABLE)  # reloaded (circular)
    assert r["tim_cr_en"] == 1


#: dma.c's frames for TIM1's DMA burst (CCR1-CCR4 each period)
FRAMES = [[100, 200, 300, 400], [150, 250, 350, 450], [120, 220, 320, 420]]
TIM1_ARR = 499


def test_timer_dma_burst_writes_four_ccrs_each_period(r: dict[str, int]) -> None:
    """17.3.19, 17.4.20-21: TIM1_UP's request (DMA2 stream 5, channel 6, table 43) with DCR.DBA = 13 (CCR1)
    and DBL = 3 writes CCR1..CCR4 through DMAR, four transfers an update event. UG sends frame 0, each
    update latches a frame and sends the next; TIM1 stops at the second TC (frame 2 of round two sent at
    the fifth update): five periods latched, frames 0, 1, 2, 0, 1 on the four channels, 500 ticks of
    (PSC + 1) apart (TIM1 on APB2, 16 MHz at reset)."""
    trace = list(TRACE.finditer(run()))
    period_ticks = (TIM4_PSC + 1) * (TIM1_ARR + 1)
    for ch in range(1, 5):
        lines = [m for m in trace if (int(m[2]), int(m[3])) == (1, ch)]
        assert [int(m[4]) for m in lines] == [FRAMES[k][ch - 1] * (TIM4_PSC + 1) for k in (0, 1, 2, 0, 1)], ch
        assert {(int(m[5]), int(m[6])) for m in lines} == {(period_ticks, TIM4_HZ)}
        times = [int(m[1]) for m in lines]
        assert {b - a for a, b in itertools.pairwise(times)} == {period_ticks * 1_000_000_000 // TIM4_HZ}
        assert r[f"burst_ccr{ch}"] == FRAMES[2][ch - 1]  # the last frame sent, in the preloads
    assert r["burst_dcr"] == 13 | 3 << 8


def test_double_buffer_mode(r: dict[str, int]) -> None:
    """10.3.10: with DBM each round of NDTR items goes to the memory CT names, and CT switches at its end
    (set after rounds one and three, clear after two); the address of the memory not in use can be written
    while the stream runs (10.5.8, 10.5.9: M0AR while CT = 1), the one in use cannot. The source's words
    are 0x1000 (i + 1), 0x10 more after each round."""
    for b in range(3):
        assert r[f"db_buffer{b}_first"] == 0x1000 + 0x10 * b, b
        assert r[f"db_buffer{b}_last"] == 0x4000 + 0x10 * b, b
    assert [r[f"db_ct{k}"] for k in range(3)] == [1 << 19, 0, 1 << 19]
    assert r["db_m0ar_is_buffer2"] == 1
    assert r["db_m1ar_is_buffer1"] == 1


def test_a_request_storm_lets_the_core_run(r: dict[str, int]) -> None:
    """TIM7's update DMA writing UG into its own EGR requests again at every item (circular): the engine
    must not serve that forever at one instant; the firmware, still running, disables the stream."""
    assert r["storm_stopped_cr_en"] == 0
    assert r["storm_tcif"] == TCIF  # stream 4: HISR bits 0-5


def test_i2c_read_by_dma_with_last(r: dict[str, int]) -> None:
    """27.3.8: I2C1's RXNE requests (DMA1 stream 0, channel 1, table 42) move the MPU-6050's 14-byte burst
    into memory; with LAST the controller NACKs the byte after the DMA's EOT_1, the last, so nothing more
    comes after the STOP the complete interrupt sends (SR1 clear, the bus goes on: WHO_AM_I 0x68). The bytes
    are those the polled read got, and the burst is the power-on sample of a still world: az 0 and the die
    at 0 degrees C by the register map's formula (TEMP / 340 + 36.53)."""
    assert r["polled_result"] == 0
    for k in range(4):
        assert r[f"dma_{k}"] == r[f"polled_{k}"], k
    assert r["dma_differ"] == 0
    assert r["dma_after"] == 0xEEEE
    temp = (r["dma_1"] & 0xFFFF) - 0x10000 * bool(r["dma_1"] & 0x8000)
    assert round(temp / 340 + 36.53, 2) == 0.0
    assert r["dma_i2c_ndtr"] == 0
    assert r["dma_i2c_cr_en"] == 0
    assert r["i2c_sr1_after_dma"] == 0
    assert r["who_am_i_after_dma"] == 0x68


def test_two_runs_print_the_same_bytes() -> None:
    again = run_firmware(engine_or_skip(), firmware("dma"), *TRACE_PULSES)
    assert again.returncode == 0
    assert again.stdout + again.stderr == run()


def test_i2c_write_by_dma(r: dict[str, int]) -> None:
    """27.3.8: TXE's requests (DMA1 stream 7, channel 1, table 42) give DR the MPU-6050's register address
    and value; the register reads back what was written (SMPLRT_DIV resets to 0, MPU-6000/6050 register
    map 4.2)."""
    assert r["smplrt_div_before"] == 0
    assert r["dma_write_hisr"] == (HTIF | TCIF) << FLAG_OFFSET[3]  # the flags set whatever the enables
    assert r["smplrt_div_after"] == 0x07
