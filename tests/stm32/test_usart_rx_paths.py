"""USART1's receiver fed by the RXNE interrupt and by the DMA (qemu/hw/rig_stm32_usart_rx.c: with DMAR, the
RXNE interrupt off and the stream enabled, the bytes go into the DMA lazily, with no QEMU timer of their
own) with tests/stm32/firmware/usart_rx_paths.c: the same SBUS frames through the link give the same bytes
in memory, the same IDLE instants and the same error flags. IDLE comes a whole frame's time of idle line
after the last stop bit (RM0090 30.6.1); at 100000 baud 8E2 a frame is 12 bits (30.3.3), so the IDLE of a
frame of 25 bytes sent back to back is 26 frames after its start. PE is set for a byte with the wrong
parity (30.3.7, 30.6.1). With the DMA's HTIE and TCIE the stream's HTIF and TCIF come at the bytes that
set them (RM0090 10.3.9), each at its RXNE: the stop bit's middle, 10.5 bits after the byte's start
(30.3.3) with 9-bit words (M = 1, the parity the ninth)."""

from __future__ import annotations

import functools

from rig.mcu import board as boards
from rig.mcu.stm32_link import Stm32Config, Stm32Engine
from tests.stm32.conftest import engine_or_skip, firmware, reports

MS = 1_000_000
HCLK = 16_000_000
BAUD = 100_000
#: 8E2: start, 8 data bits, parity, 2 stop bits
FRAME_CYCLES = 12 * HCLK // BAUD
SBUS = [bytes([0x0F, *((40 * k + i) & 0xFF for i in range(22)), 0x00, 0x00]) for k in range(3)]
PARITY = ["E", "E", "O"]  # the third frame with the parity the receiver does not expect
#: the ms each frame is sent at, by phase (the RXNE interrupt, then the DMA)
SENT_AT = [[4, 11, 18], [30, 37, 44]]
SR_PE = 1 << 0
#: CYCCNT counts from the firmware's start (a few instructions after reset), the ISR reads it a few
#: instructions after its entry (1.34 cycles each under icount shift 3 at 16 MHz)
LATENCY = 40


def run() -> dict[str, int]:
    """usart_rx_paths.elf through the link with the frames sent at SENT_AT: its reports."""
    cfg = Stm32Config(boards.load("stm32f405-gy86"), firmware("usart_rx_paths"), engine_or_skip())
    engine = Stm32Engine(cfg, None)
    try:
        stop = None
        for t_ms in range(1, 70):
            stop = engine.run_until(t_ms * MS)
            if stop.kind != "reached":
                break
            for phase in SENT_AT:
                if t_ms in phase:
                    k = phase.index(t_ms)
                    engine.uart_send(1, SBUS[k], BAUD, PARITY[k], 2)
        assert stop is not None and stop.kind == "exited", stop
        return reports(engine.output())
    finally:
        engine.close()


linked = functools.cache(run)


def received(r: dict[str, int], phase: int) -> bytes:
    return bytes(r[f"p{phase}_b{i:02d}"] for i in range(r[f"p{phase}_n"]))


def test_both_paths_put_the_frames_in_memory() -> None:
    r = linked()
    assert received(r, 0) == b"".join(SBUS)
    assert received(r, 1) == b"".join(SBUS)


def test_idle_comes_a_frame_after_the_last_stop_bit_on_both_paths() -> None:
    r = linked()
    for phase, sent in enumerate(SENT_AT):
        for k, t_ms in enumerate(sent):
            after = r[f"p{phase}_idle{k}"] - t_ms * HCLK // 1000
            assert abs(after - 26 * FRAME_CYCLES) <= LATENCY, (phase, k, after)
    offsets = [[r[f"p{p}_idle{k}"] - t * HCLK // 1000 for k, t in enumerate(sent)]
               for p, sent in enumerate(SENT_AT)]
    assert offsets[0] == offsets[1]


def test_the_same_error_flags() -> None:
    r = linked()
    for phase in range(2):
        assert [r[f"p{phase}_err{k}"] for k in range(3)] == [0, 0, SR_PE]


def test_two_runs_give_the_same_reports() -> None:
    assert run() == linked()


def test_the_streams_half_and_full_at_their_bytes() -> None:
    """The 32-byte ring fills from the DMA phase's first frame: HTIF at its 16th byte, TCIF at the 32nd,
    the 7th of the second frame."""
    r = linked()
    bit = HCLK // BAUD
    ht = SENT_AT[1][0] * HCLK // 1000 + 15 * FRAME_CYCLES + 21 * bit // 2
    tc = SENT_AT[1][1] * HCLK // 1000 + 6 * FRAME_CYCLES + 21 * bit // 2
    assert abs(r["ht_at"] - ht) <= LATENCY, r["ht_at"] - ht
    assert abs(r["tc_at"] - tc) <= LATENCY, r["tc_at"] - tc
