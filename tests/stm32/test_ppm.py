"""RC by PPM on the STM32 tier: the engine's pin_drive (rig/mcu/stm32_link.py) puts a PPM sum on PA0
through the link (qemu/hw/rig_link.c's PIN message, the GPIO port's outside driver), and
tests/stm32/firmware/ppm_rx.c decodes it with TIM2 channel 1's input capture at 1 MHz (the 16 MHz HSI,
PSC 15: RM0090 18.3.1, CK_CNT = f_CK_PSC / (PSC + 1)) on the falling edges.

Independent truth: the widths the test puts on the pin. Each channel's width is the time between two
falling edges (the receiver's PPM_PULSE_NS low pulse starts each channel), so at a 1 MHz count the
captures differ by exactly the width in microseconds; the sync gap before a frame is the frame period
(PPM_FRAME_NS) less the previous frame's channels."""

from __future__ import annotations

from pathlib import Path

import pytest

from rig.mcu import board as boards
from rig.mcu.board import Board, BoardError
from rig.mcu.session import PPM_FRAME_NS, ppm_edges
from rig.mcu.stm32_link import Stm32Config, Stm32Engine
from tests.stm32.conftest import (
    RC_FRAMES,
    RC_SBUS_CHANNELS,
    board_with_rc,
    drive_rc_frames,
    engine_or_skip,
    firmware,
    receiver_session_lines,
    reports,
)

STEP_NS = 1_000_000


def drive_ppm(board: Board) -> str:
    """ppm_rx on ``board``, RC_FRAMES as PPM sums on its receiver's pin; QEMU's output."""
    pin = board.rc.pin if board.rc is not None else None
    assert pin is not None
    return drive_rc_frames(board, "ppm_rx", PPM_FRAME_NS,
                           lambda start, widths: {pin: ppm_edges(start, widths)})


def ppm_board(tmp_path: Path, pin: str) -> Path:
    """The shipped STM32F405 board with its receiver's PPM sum on ``pin`` instead of SBUS on USART1."""
    return board_with_rc(tmp_path, f'protocol = "ppm"\npin = "{pin}"', "ppm")


def test_the_firmware_decodes_each_channel_to_the_microsecond(tmp_path: Path) -> None:
    out = drive_ppm(boards.load(ppm_board(tmp_path, "PA0")))
    got = reports(out)
    for f, channels in enumerate(RC_FRAMES):
        assert [got[f"ppm_{f}_{c + 1}"] for c in range(8)] == channels, out
    # (the first capture starts the first frame; each later one follows the previous frame's gap)
    assert got["ppm_0_sync"] == 0
    for f in (1, 2):
        assert got[f"ppm_{f}_sync"] == PPM_FRAME_NS // 1000 - sum(RC_FRAMES[f - 1])


def test_two_runs_print_the_same_bytes(tmp_path: Path) -> None:
    board = boards.load(ppm_board(tmp_path, "PA0"))
    first = drive_ppm(board)
    assert "ppm_2_8=" in first
    assert drive_ppm(board) == first


def test_a_board_puts_ppm_on_a_timer_channel_pin_only(tmp_path: Path) -> None:
    """DS8626 table 9: PA0 is TIM2_CH1 (and TIM5_CH1); PC13 is no timer's channel."""
    board = boards.load(ppm_board(tmp_path, "pa0"))
    assert board.rc is not None and (board.rc.protocol, board.rc.pin) == ("ppm", "PA0")
    with pytest.raises(BoardError, match="rc.pin.*timer channel"):
        boards.load(ppm_board(tmp_path, "PC13"))


def test_pin_drive_refuses_what_no_wire_can_do(tmp_path: Path) -> None:
    """Edges that go back in time, a port the chip lacks (the F405 has A..I) and a 17th pin number are
    refused before anything reaches QEMU, which runs on."""
    board = boards.load(ppm_board(tmp_path, "PA0"))
    engine = Stm32Engine(Stm32Config(board, firmware("ppm_rx"), engine_or_skip()), None)
    try:
        assert engine.run_until(STEP_NS).kind == "reached"
        with pytest.raises(ValueError, match="ascend"):
            engine.pin_drive("PA0", [(2 * STEP_NS, 0), (STEP_NS + 1, 1)])
        with pytest.raises(ValueError, match="ascend"):
            engine.pin_drive("PA0", [(STEP_NS - 1, 0)])
        with pytest.raises(ValueError, match="port letter"):
            engine.pin_drive("PJ0", [(2 * STEP_NS, 0)])
        with pytest.raises(ValueError, match="port letter"):
            engine.pin_drive("PA16", [(2 * STEP_NS, 0)])
        assert engine.run_until(2 * STEP_NS).kind == "reached"
    finally:
        engine.close()


def test_the_sessions_rc_frames_reach_the_firmware_as_ppm(tmp_path: Path) -> None:
    """The MCU session with the PPM board: the scenario's RC frames (SBUS, as the scenarios write them)
    become a PPM sum on the board's pin every PPM_FRAME_NS (rig/mcu/session.py), and ppm_rx's telemetry
    lines on USART6 carry the widths back exactly, each as a receiver maps SBUS to microseconds."""
    engine_or_skip()
    lines, want = receiver_session_lines(ppm_board(tmp_path, "PA0"), "ppm_rx", RC_SBUS_CHANNELS)
    assert lines and all(line == "PPM " + " ".join(map(str, want)) for line in lines), lines
    # one PPM frame a period from the first period after the first RC frame (20 ms): at 22.5, 45, ...
    # 180 ms, each over within the 0.2 s run
    assert len(lines) == 180_000_000 // PPM_FRAME_NS


@pytest.mark.parametrize(("payload", "why"), [
    (bytes([0, 0, 0, 0]) + (5 * STEP_NS).to_bytes(8, "little") + bytes([2]), "a level other than 0 or 1"),
    (bytes([9, 0, 0, 0]), "a malformed pin"),
    (bytes([0, 0, 0, 0, 1]), "a malformed pin or edge list"),
], ids=["level", "port", "length"])
def test_the_link_ends_qemu_on_a_malformed_pin_message(tmp_path: Path, payload: bytes, why: str) -> None:
    """QEMU checks the PIN message as any input (qemu/hw/rig_link.c): a bad one ends it with a message,
    which the engine's stop carries, and never reaches a pin."""
    board = boards.load(ppm_board(tmp_path, "PA0"))
    engine = Stm32Engine(Stm32Config(board, firmware("ppm_rx"), engine_or_skip()), None)
    try:
        assert engine.run_until(STEP_NS).kind == "reached"
        engine._send(ord("I"), payload)  # (what pin_drive refuses to send)
        stop = engine.run_until(2 * STEP_NS)
    finally:
        engine.close()
    assert stop.kind == "crashed" and "rig-link: PIN: " + why in stop.what, stop.what
