"""The USART model (qemu/hw/rig_stm32_usart.c) with tests/stm32/firmware/usart.c through the link: the
registers against RM0090 table 146 and section 30.6, the frame times against 30.3.4's baud formula
measured with DWT_CYCCNT, TXE/TC timing (30.3.2), bytes the session sends at SBUS's 100000 baud 8E2 and
at 115200 8N1 read by the receiver set up for SBUS (30.3.3 sampling, 30.6.1 flags), overrun and IDLE,
and each on USART1's NVIC line 37. The core runs at the 16 MHz HSI: every clock is 16 MHz except
USART2's PCLK1 (HCLK / 2)."""

from __future__ import annotations

import functools

from rig.mcu import board as boards
from rig.mcu.stm32_link import Stm32Config, Stm32Engine
from tests.stm32.conftest import REPORT_LINE, engine_or_skip, firmware, reports

MS = 1_000_000
HCLK = 16_000_000
#: RM0090 30.6.1 (USART_SR)
PE, FE, NF, ORE, IDLE, RXNE, TC, TXE = (1 << n for n in range(8))
ERRORS_AND_RX = 0x3F  # PE, FE, NF, ORE, IDLE, RXNE: what the receiver sets
SBUS = bytes([0x0F, *range(1, 23), 0x00, 0x00])
#: RM0090 30.3.3: RXNE comes at the stop bit's sampling, its middle: 10.5 bits of a 12-bit 8E2 frame
SBUS_BIT_CYCLES = HCLK // 100_000
#: what the session sends and when (ms): SBUS 8E2 at 100000, a lone 0xFF and the burst FF 00 00 at 115200
#: 8N1, SBUS 8E2 3 % slow and 0x00 5 % slow, then three bytes at 22 ms, after the firmware stopped reading
SCHEDULE = [(5, SBUS, 100_000, "E", 2), (10, b"\xff", 115_200, "N", 1),
            (12, b"\xff\x00\x00", 115_200, "N", 1), (14, SBUS, 97_000, "E", 2), (18, b"\x00", 95_000, "E", 2),
            (22, b"\x11\x22\x33", 100_000, "E", 2)]


@functools.cache
def run() -> tuple[str, bytes, bytes]:
    """usart.elf through the link with SCHEDULE's bytes: its output and what USART1 and USART2 sent."""
    cfg = Stm32Config(boards.load("stm32f405-gy86"), firmware("usart"), engine_or_skip())
    engine = Stm32Engine(cfg, None)
    sent1, sent2 = bytearray(), bytearray()
    try:
        stop = None
        for t_ms in range(1, 40):
            stop = engine.run_until(t_ms * MS)
            sent1 += engine.uart_take(1)
            sent2 += engine.uart_take(2)
            if stop.kind != "reached":
                break
            for at, data, baud, parity, stops in SCHEDULE:
                if at == t_ms:
                    engine.uart_send(1, data, baud, parity, stops)
        assert stop is not None and stop.kind == "exited", stop
        return engine.output(), bytes(sent1), bytes(sent2)
    finally:
        engine.close()


def log() -> list[tuple[int, int, int]]:
    """The receive interrupts' log: (SR, DR, CYCCNT) in order."""
    lines = [(m.group(1), int(m.group(2), 16)) for m in REPORT_LINE.finditer(run()[0])]
    values = [v for name, v in lines if name in ("log_sr", "log_dr", "log_at")]
    return [(values[i], values[i + 1], values[i + 2]) for i in range(0, len(values), 3)]


def test_registers_at_reset_with_ones_and_after_an_rcc_reset() -> None:
    r = reports(run()[0])
    # RM0090 table 146: SR resets to 0x00C0 (TXE, TC), the others to 0
    for prefix in ("reset_", "rst_"):
        values = [r[prefix + n] for n in ("sr", "dr", "brr", "cr1", "cr2", "cr3", "gtpr")]
        assert values == [0xC0, 0, 0, 0, 0, 0, 0]
    assert r["w0_sr"] == TXE  # 30.6.1: TC is rc_w0, TXE read only
    # writable bits (30.6.3-30.6.7): BRR 16 bits; CR1 all but bit 14 (TXEIE, TCIE left 0 by the
    # firmware; SBK, bit 0, ends at once: the model sends no break); CR2 bits 14:8, 6:5, 3:0; CR3 bits
    # 11:0; GTPR 16 bits
    assert (r["ones_brr"], r["ones_cr1"], r["ones_cr2"], r["ones_cr3"], r["ones_gtpr"]) == \
        (0xFFFF, 0xBFFF & ~(TXE | TC | 1), 0x7F6F, 0x0FFF, 0xFFFF)
    # UART4: no CLKEN/CPOL/CPHA/LBCL, no CTSIE/CTSE/RTSE/SCEN/NACK, no GTPR (30.6: "not available")
    assert (r["uart4_ones_cr2"], r["uart4_ones_cr3"], r["uart4_ones_gtpr"]) == (0x706F, 0x08CF, 0)


def test_frame_times_follow_brr_and_the_apb_clock() -> None:
    """30.3.4: baud = f_PCLK / (8 x (2 - OVER8) x USARTDIV); a frame is start + data (+ parity) + stops."""
    r = reports(run()[0])
    frame_8e2 = 12 * 160  # BRR 160 = 16 x USARTDIV at 16 MHz: 100000 baud, 12 bits
    assert abs(r["idle_frame"] - frame_8e2) <= 4  # 30.3.2: TE sends an idle frame first
    assert abs(r["over8_frame"] - 10 * (8 * 17 + 3)) <= 4  # OVER8: USARTDIV 17 + 3/8, 8N1
    assert abs(r["apb1_frame"] - 10 * 80 * 2) <= 4  # USART2: BRR 80 at PCLK1 = 8 MHz, 2 HCLK cycles a tick


def test_txe_at_once_into_a_free_shift_register_tc_at_the_frame_end() -> None:
    r = reports(run()[0])
    frame = 12 * 160
    assert r["te_txe"] & (TXE | TC) == TXE
    assert r["write_sr"] & (TXE | TC) == TXE  # the byte moved on at once; TC cleared by SR read, DR write
    assert r["write2_sr"] & (TXE | TC) == 0  # the second waits in DR
    assert abs(r["txe_at"] - frame) <= 4 and abs(r["tc_at"] - 2 * frame) <= 4


def test_transmit_interrupts_and_the_bytes_sent() -> None:
    r = reports(run()[0])
    assert (r["txe_irqs"], r["tc_irqs"]) == (5, 1)  # four bytes and the one that turns TXEIE off; one TC
    assert 0 <= r["tc_irq_at"] - 4 * 12 * 160 <= 16  # TC at the fourth frame's end (and the ISR's entry)
    _, sent1, sent2 = run()
    assert sent1 == b"\x55\xa5\x3cTXIR"
    assert sent2 == b"\x42"


def test_sbus_frames_arrive_without_error_then_idle() -> None:
    entries = log()
    rx = entries[:25]
    for byte, (sr, dr, _) in zip(SBUS, rx, strict=True):
        # 30.3.7: with PCE and M = 1 the ninth bit read is the parity bit, even parity by PS = 0
        assert (sr & ERRORS_AND_RX, dr) == (RXNE, byte | (bin(byte).count("1") & 1) << 8)
    # one byte each 120 us frame (exact to the cycle, the interrupt's latency being the same each time)
    assert all(abs(b[2] - a[2] - 12 * SBUS_BIT_CYCLES) <= 1 for a, b in zip(rx, rx[1:], strict=False))
    # the first at 5 ms + 10.5 bits (less the cycles before main enabled DWT's counter)
    assert 0 <= (5 * MS * HCLK // 1_000_000_000 + 105 * SBUS_BIT_CYCLES // 10) - rx[0][2] < 200
    # IDLE (30.6.1): a whole frame of idle line after the last frame's end (which is 1.5 bits after RXNE)
    sr, _, at = entries[25]
    assert sr & ERRORS_AND_RX == IDLE
    assert abs(at - rx[-1][2] - (15 + 120) * SBUS_BIT_CYCLES // 10) <= 1


def test_bytes_at_another_baud_and_framing_give_the_chips_errors() -> None:
    """115200 8N1 into the 100000 8E2 receiver (bit times 8.68 and 10 us), RM0090 30.3.3: each bit is
    sampled at its middle (10 us x (k + 0.5) after the falling edge), the ninth the parity bit, then the
    stop bit.
    A lone 0xFF: the start bit is low until 8.68 us, every later sample high: DR 0x1FF, nine ones under
    even parity: PE (30.3.7), the stop bit high: no FE.
    FF 00 00 back to back: the first frame's data samples (15-85 us) see 0xFF's ones, its parity sample
    (95 us) the next byte's start bit: DR 0x0FF, eight ones: no PE; its stop bit sample (105 us) falls
    in the second byte's data bit 1, low: FE (30.6.1: de-synchronisation). The line stays low through the
    second byte's zeros, so the next frame starts at the third byte's start bit (173.6 us): samples up to
    248.6 us low, 258.6 us in its stop bit, 268.6 us idle: DR 0x180, two ones, stop high: no error."""
    entries = log()[26:31]
    flags = [(sr & ERRORS_AND_RX, dr) for sr, dr, _ in entries]
    assert flags == [(RXNE | PE, 0x1FF), (IDLE, 0x1FF), (RXNE | FE, 0x0FF), (RXNE, 0x180), (IDLE, 0x180)]
    assert not any(sr & NF for sr, _, _ in entries)  # every sample group falls within one bit


def test_the_baud_tolerance_is_the_sampling_points() -> None:
    """30.3.5 (receiver's tolerance to clock deviation): a sender 3 % slow (97000 baud, bit 10.31 us)
    still has every sample group inside one bit (the last, the stop bit's 10.56 bit times, falls before
    10.31 x 11 us and after 10.31 x 10): SBUS arrives clean, within RM0090's 3.41 % for 9-bit words.
    5 % slow (95000, bit 10.53 us), 0x00 (its even parity bit 0): the stop bit's samples at 104.4, 105
    and 105.6 us fall in the parity bit (low, to 105.3 us) twice and in the stop bit once: FE by the
    majority, NF as they differ."""
    entries = log()[31:]
    assert [(sr & ERRORS_AND_RX, dr) for sr, dr, _ in entries[:25]] == \
        [(RXNE, b | (bin(b).count("1") & 1) << 8) for b in SBUS]
    assert [(sr & ERRORS_AND_RX, dr) for sr, dr, _ in entries[25:]] == \
        [(IDLE, 0), (RXNE | FE | NF, 0), (IDLE, 0)]


def test_a_byte_not_read_is_overrun() -> None:
    """30.6.1: ORE when a byte comes while RXNE is set (DR keeps the first); SR then DR read clears ORE
    and IDLE, the DR read RXNE."""
    r = reports(run()[0])
    assert r["ore_sr"] & ERRORS_AND_RX == RXNE | ORE | IDLE
    assert r["ore_dr"] == 0x11  # two ones: the even parity bit 0
    assert r["ore_sr_after"] & ERRORS_AND_RX == 0


def test_two_runs_give_the_same_bytes() -> None:
    first = run()
    run.cache_clear()
    assert run() == first
