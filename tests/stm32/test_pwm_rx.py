"""A parallel PWM receiver on the STM32 tier: a pulse per channel on its own pin, the engine's pin_drive
(rig/mcu/stm32_link.py) putting each on its pin through the link, and tests/stm32/firmware/pwm_rx.c
timing each by a timer channel's input capture (rising edge, then falling: CCxP turned at each capture),
as Betaflight's PWM input does, at 1 MHz (the 16 MHz HSI, PSC 15: RM0090 17.3.1, CK_CNT = f_CK_PSC /
(PSC + 1)). So the board check wants a timer channel's pin for each channel, as for a PPM sum
(rig/mcu/mcus.py, rc_timing).

Independent truth: the widths the test puts on the pins, and DS8626 table 9 for which pins are timer
channels. At a 1 MHz count the two captures of a pulse differ by exactly its width in microseconds."""

from __future__ import annotations

from pathlib import Path

import pytest

from rig.mcu import board as boards
from rig.mcu.board import Board, BoardError
from rig.mcu.session import PWM_FRAME_NS
from tests.stm32.conftest import (
    RC_FRAMES,
    RC_SBUS_CHANNELS,
    board_with_rc,
    drive_rc_frames,
    engine_or_skip,
    receiver_session_lines,
    reports,
)

STEP_NS = 1_000_000
#: pwm_rx's channels in order (DS8626 table 9): TIM1_CH1, TIM1_CH4, TIM3_CH1, TIM3_CH2, TIM5_CH1,
#: TIM5_CH2, TIM8_CH3, TIM8_CH4
PINS = ["PA8", "PA11", "PA6", "PA7", "PA0", "PA1", "PC8", "PC9"]


def pwm_board(tmp_path: Path, pins: list[str]) -> Path:
    """The shipped STM32F405 board with a parallel PWM receiver on ``pins`` instead of SBUS on USART1."""
    return board_with_rc(tmp_path, pwm_rc(pins), "pwm")


def pwm_rc(pins: list[str]) -> str:
    """An [rc] table's body: a parallel PWM receiver on ``pins``."""
    return 'protocol = "pwm"\npins = [' + ", ".join(f'"{p}"' for p in pins) + "]"


def frame_edges(start_ns: int, widths_us: list[int]) -> dict[str, list[tuple[int, int]]]:
    """One frame from ``start_ns``: each channel's pulse on its pin, the next rising as one falls."""
    edges: dict[str, list[tuple[int, int]]] = {}
    t = start_ns
    for pin, us in zip(PINS, widths_us, strict=True):
        edges[pin] = [(t, 1), (t + us * 1000, 0)]
        t += us * 1000
    return edges


def drive_pwm(board: Board) -> str:
    """pwm_rx on ``board``, RC_FRAMES as a pulse per channel on PINS; QEMU's output."""
    return drive_rc_frames(board, "pwm_rx", PWM_FRAME_NS, frame_edges)


def test_the_firmware_times_each_channel_to_the_microsecond(tmp_path: Path) -> None:
    out = drive_pwm(boards.load(pwm_board(tmp_path, PINS)))
    got = reports(out)
    for f, widths in enumerate(RC_FRAMES):
        assert [got[f"pwm_{f}_{c + 1}"] for c in range(8)] == widths, out
    assert "pwm_3_1" not in got


def test_two_runs_print_the_same_bytes(tmp_path: Path) -> None:
    board = boards.load(pwm_board(tmp_path, PINS))
    first = drive_pwm(board)
    assert "pwm_2_8=" in first
    assert drive_pwm(board) == first


def test_the_sessions_rc_frames_reach_the_firmware_as_pulses(tmp_path: Path) -> None:
    """The MCU session with the PWM board: the scenario's RC frames (SBUS, as the scenarios write them)
    become a pulse on each channel's pin every PWM_FRAME_NS (rig/mcu/session.py), and pwm_rx's telemetry
    lines on USART6 carry the widths back exactly, each as a receiver maps SBUS to microseconds."""
    engine_or_skip()
    lines, want = receiver_session_lines(pwm_board(tmp_path, PINS), "pwm_rx", RC_SBUS_CHANNELS)
    assert lines and all(line == "PWM " + " ".join(map(str, want)) for line in lines), lines
    # a frame each period from the first period after the first RC frame (20 ms): at 40, 60, ... 180 ms
    # (the one at 200 ms ends after the run), each over within its 20 ms
    assert len(lines) == 8


@pytest.mark.parametrize(("pins", "words"), [
    (["PA8", "PA11", "PA6", "PC13"], "rc.pins: the stm32f405's PC13 has no timer channel"),
    (["PA8", "PA11", "PA6", "PB0"], "rc.pins: pin PB0 drives motor 1"),
    (["PA8", "PA11", "PA6", "PA8"], "rc.pins: pin PA8 is two channels"),
    (["PA8", "PA11", "PA6"], "rc.pins: expected 4 to 8 pins"),
], ids=["no-timer", "motor", "twice", "three"])
def test_a_board_puts_each_channel_on_a_free_timer_channel_pin(tmp_path: Path, pins: list[str],
                                                                words: str) -> None:
    """DS8626 table 9: PC13 is no timer's channel; PB0 is TIM3_CH3, the board's motor 1."""
    with pytest.raises(BoardError, match=words):
        boards.load(pwm_board(tmp_path, pins))


def test_four_to_eight_timer_channel_pins_are_a_receiver(tmp_path: Path) -> None:
    board = boards.load(pwm_board(tmp_path, [p.lower() for p in PINS[:4]]))
    assert board.rc is not None and (board.rc.protocol, board.rc.pins) == ("pwm", tuple(PINS[:4]))
    board = boards.load(pwm_board(tmp_path, PINS))
    assert board.rc is not None and board.rc.pins == tuple(PINS)


def test_the_f411s_own_timer_channels_are_its_receiver_pins(tmp_path: Path) -> None:
    """DS10314 table 9: the F411 has TIM9 (CH1 PA2, CH2 PA3, USART2's TX and RX, the Black Pill's
    telemetry) and no TIM8, so PC8 (the F405's TIM8_CH3) is no receiver pin on the Black Pill; PA6 is
    TIM3_CH1, the board's motor 1; PA0 and PA1 are TIM2's or TIM5's CH1 and CH2, PA8 TIM1_CH1."""
    def board_with(pins: list[str]) -> Board:
        return boards.load(board_with_rc(tmp_path, pwm_rc(pins), "pwm", "stm32f411-blackpill-gy86"))

    board = board_with(["PA8", "PA0", "PA1", "PB6"])
    assert board.rc is not None and board.rc.pins == ("PA8", "PA0", "PA1", "PB6")
    with pytest.raises(BoardError, match="rc.pins: pin PA2 is USART2's TX, the telemetry's"):
        board_with(["PA8", "PA0", "PA1", "PA2"])
    with pytest.raises(BoardError, match="rc.pins: the stm32f411's PC8 has no timer channel"):
        board_with(["PA8", "PA0", "PA1", "PC8"])
    with pytest.raises(BoardError, match="rc.pins: pin PA6 drives motor 1"):
        board_with(["PA8", "PA0", "PA1", "PA6"])
