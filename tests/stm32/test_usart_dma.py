"""The USARTs' DMA requests (qemu/hw/rig_stm32_usart.c into rig_stm32_dma.c) with
tests/stm32/firmware/usart_dma.c: SBUS received through a circular DMA with the IDLE interrupt marking each
frame's end (Betaflight's receiver), and a 64-byte block sent by DMA and then from the TXE interrupt. The
instants on the line come from the engine's byte trace (-global rig-stm32f4-usart.trace-bytes=on: each
byte with its frame's end in ns), those the firmware saw from DWT_CYCCNT at HCLK = PCLK2 = 16 MHz; the
expected ones are RM0090's baud formula (30.3.4), the TXE/TC sequence (30.3.2) and the request mapping
(tables 42/43: USART1_RX on DMA2 stream 5 channel 4, USART6_TX on DMA2 stream 6 channel 5)."""

from __future__ import annotations

import functools
import re

from rig.mcu import board as boards
from rig.mcu.stm32_link import Stm32Config, Stm32Engine
from tests.stm32.conftest import engine_or_skip, firmware, reports, run_to_done

MS = 1_000_000
HCLK = 16_000_000
#: RM0090 30.3.4: baud = f_PCLK / (8 x (2 - OVER8) x USARTDIV); BRR 32 at OVER8 = 0 is USARTDIV 2
BAUD = HCLK // (16 * 2)
#: 8N1: start, 8 data bits, stop
FRAME_NS = 10 * 1_000_000_000 // BAUD
FRAME_CYCLES = 10 * HCLK // BAUD
BLOCK = bytes((i * 37 + 11) & 0xFF for i in range(64))
#: three SBUS frames (25 bytes: 0x0F, 22 bytes of channels, flags, 0x00), each its own bytes, sent at these
#: ms at 100000 baud 8E2; the firmware's circular buffer is 32 bytes, so the second and third wrap
SBUS_AT = [6, 13, 20]
SBUS = [bytes([0x0F, *((40 * k + i) & 0xFF for i in range(22)), 0x00, 0x00]) for k in range(3)]
TRACE = ("-global", "rig-stm32f4-usart.trace-bytes=on")
TRACE_LINE = re.compile(r"t_ns=(\d+) USART(\d) byte=0x([0-9a-f]{2})")
#: the cycles from the CYCCNT read before the stream's EN write to the write itself, and an interrupt's
#: entry (the ISR's CYCCNT read): a few instructions, at 1.34 cycles each under icount shift 3 at 16 MHz
LATENCY = 16


@functools.cache
def standalone() -> tuple[dict[str, int], list[tuple[int, int, int]]]:
    """usart_dma.elf alone with the byte trace: its reports and the (t_ns, USART, byte) trace."""
    done = run_to_done("usart_dma", *TRACE)
    trace = [(int(t), int(u), int(b, 16)) for t, u, b in TRACE_LINE.findall(done.stderr)]
    return reports(done.stdout), trace


@functools.cache
def linked() -> tuple[dict[str, int], bytes]:
    """usart_dma.elf through the link with the SBUS frames: its reports and what USART6 sent."""
    cfg = Stm32Config(boards.load("stm32f405-gy86"), firmware("usart_dma"), engine_or_skip())
    engine = Stm32Engine(cfg, None)
    sent = bytearray()
    try:
        stop = None
        for t_ms in range(1, 40):
            stop = engine.run_until(t_ms * MS)
            sent += engine.uart_take(6)
            if stop.kind != "reached":
                break
            if t_ms in SBUS_AT:
                engine.uart_send(1, SBUS[SBUS_AT.index(t_ms)], 100_000, "E", 2)
        assert stop is not None and stop.kind == "exited", stop
        return reports(engine.output()), bytes(sent)
    finally:
        engine.close()


def test_sbus_frames_land_in_the_circular_buffer_exactly() -> None:
    """Each RXNE is a request the DMA serves by reading DR; at each IDLE (a frame's time of idle line after
    the last stop bit, 30.6.1) the firmware takes the bytes from its last position to 32 - NDTR."""
    r, _ = linked()
    assert r["n_frames"] == 3
    for k, frame in enumerate(SBUS):
        assert r[f"f{k}_len"] == len(frame)
        assert bytes(r[f"f{k}_b{i:02d}"] for i in range(len(frame))) == frame
    assert r["rx_sr"] & 0x2F == 0  # no RXNE left for the core, no overrun, parity, framing or noise error


def test_the_block_goes_out_by_dma_a_frame_apart() -> None:
    _, trace = standalone()
    dma = trace[:64]
    assert {u for _, u, _ in dma} == {6}
    assert bytes(b for _, _, b in dma) == BLOCK
    assert all(b[0] - a[0] == FRAME_NS for a, b in zip(dma, dma[1:], strict=False))


def test_stream_flags_and_tc_at_their_bytes() -> None:
    """The DMA fills DR at each TXE: the first two bytes at the stream's enable (the shift register and DR
    both empty), byte k (k >= 3) when byte k - 2 has left, so its transfer is at k - 2 frames. HTIF at the
    32nd transfer, TCIF at the 64th, USART TC at the end of the 64th frame; NDTR after 10.5 frames is the
    64 less the 12 transferred."""
    r, _ = standalone()
    assert 0 <= r["tx_ht_at"] - 30 * FRAME_CYCLES <= LATENCY
    assert 0 <= r["tx_tcif_at"] - 62 * FRAME_CYCLES <= LATENCY
    assert 0 <= r["tx_tc_at"] - 64 * FRAME_CYCLES <= LATENCY
    assert (r["tx_ht_irqs"], r["tx_tcif_irqs"]) == (1, 1)
    assert r["ndtr_mid"] == 64 - 12
    assert r["tx_ndtr_after"] == 0
    assert r["tx_scr_after"] & 1 == 0  # EN cleared at the end (10.5.5)


def test_dma_and_the_txe_interrupt_put_the_same_bytes_at_the_same_instants() -> None:
    """The interrupt-fed path (a byte written at each TXE interrupt) against the DMA's: the same bytes,
    each at the same time after the transfer's start, and TC as long after it."""
    r, trace = standalone()
    dma, eager = trace[:64], trace[64:]
    assert len(eager) == 64
    assert [b for _, _, b in eager] == [b for _, _, b in dma]
    assert [t - eager[0][0] for t, _, _ in eager] == [t - dma[0][0] for t, _, _ in dma]
    assert r["eager_tc_at"] == r["tx_tc_at"]


def test_the_link_gets_the_bytes() -> None:
    _, sent = linked()
    assert sent == BLOCK + BLOCK


def test_two_runs_give_the_same_bytes() -> None:
    first = run_to_done("usart_dma", *TRACE)
    second = run_to_done("usart_dma", *TRACE)
    assert (first.stdout, first.stderr) == (second.stdout, second.stderr)
