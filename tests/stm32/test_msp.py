"""RC by MSP on the STM32 tier: MSP v1 SET_RAW_RC frames on USART1 at 115200 baud 8N1 (the engine's
uart_send through the link and the USART model's receiver), decoded by tests/stm32/firmware/msp_rx.c,
which answers MSP_RC (105) with the channels it holds and reports them through semihosting.

Independent truth: MSP v1 as MultiWii and Betaflight define it, written here byte by byte ("$M<" or "$M>",
the payload's size, the command, the payload, the XOR of size, command and payload; SET_RAW_RC is 200,
its payload the channels as u16 little-endian microseconds; MSP_RC is 105; "$M!" refuses a command),
and the widths the test sends. The firmware's parser and encoder are ours in C; the rig's are
rig/telemetry/msp.py, which reads the replies of a run's USART for the msp_reply criterion."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from rig.emulators import sbus
from rig.mcu import board as boards
from rig.mcu.board import Board, BoardError
from rig.mcu.session import McuConfig, McuSession
from rig.mcu.stm32_link import Stm32Config, Stm32Engine
from rig.telemetry.msp import ReplyReader
from rig.world import World
from tests.stm32.conftest import REPO, board_with_rc, engine_or_skip, firmware, reports
from tests.stm32.test_link import level_world

STEP_NS = 1_000_000
BAUD = 115_200
RC, TEL = "/dev/ttyRC0", "/dev/ttyTEL0"
#: three SET_RAW_RC frames: MultiWii's 8 channels, 4, and Betaflight's 18 (microseconds)
FRAMES = [
    [1000, 1100, 1234, 1500, 1777, 1900, 2000, 1050],
    [1500, 1500, 1000, 1999],
    [988, 1012, 1500, 1500, 2012, 1000, 1100, 1200, 1300, 1400, 1600, 1700, 1800, 1900, 2000, 1001, 1002,
     1003],
]
#: SBUS values as a scenario's sticks send them (172..1811; 16 channels, of which MSP carries 8)
SBUS_CHANNELS = [172, 992, 1811, 500, 1500, 992, 300, 1700, 992, 992, 992, 992, 992, 992, 992, 992]


def frame(direction: str, command: int, payload: bytes = b"") -> bytes:
    """An MSP v1 frame, written out as the protocol gives it (not with the rig's encoder)."""
    check = len(payload) ^ command
    for b in payload:
        check ^= b
    return b"$M" + direction.encode() + bytes([len(payload), command]) + payload + bytes([check])


def channels(us: list[int]) -> bytes:
    return b"".join(bytes([u & 0xFF, u >> 8]) for u in us)


def msp_board(tmp_path: Path, rc: str = 'protocol = "msp"\nuart = 1\nbaud = 115_200\n') -> Path:
    """The shipped STM32F405 board with MSP on USART1 (RX PA10, TX PA9) instead of SBUS."""
    return board_with_rc(tmp_path, rc, "msp")


def drive(board: Board, sends: list[bytes], until_ns: int) -> tuple[str, bytes]:
    """msp_rx on ``board`` with a level world's chip core: each of ``sends`` onto USART1's RX line at
    115200 8N1 at the start of its own 10 ms; QEMU's semihosting output and what the firmware sent on
    USART1 TX."""
    chips = level_world()
    engine = Stm32Engine(Stm32Config(board, firmware("msp_rx"), engine_or_skip()), chips)
    sent = bytearray()

    def step(t: int) -> None:
        stop = engine.run_until(t)
        while stop.kind == "need":
            chips.serve(stop.need)
            stop = engine.run_until(t)
        assert stop.kind == "reached", stop.describe()
        sent.extend(engine.uart_take(1))

    try:
        t = 0
        for k, data in enumerate(sends):
            while t < (k + 1) * 10 * STEP_NS:
                t += STEP_NS
                step(t)
            engine.uart_send(1, data, BAUD)
        while t < until_ns:
            t += STEP_NS
            step(t)
        return engine.output(), bytes(sent)
    finally:
        engine.close()


def set_raw_rc(us: list[int]) -> bytes:
    return frame("<", 200, channels(us))


def test_the_channels_sent_arrive_exactly_and_msp_rc_gives_them_back(tmp_path: Path) -> None:
    board = boards.load(msp_board(tmp_path))
    assert board.rc is not None and (board.rc.protocol, board.rc.uart, board.rc.baud) == ("msp", 1, BAUD)
    corrupt = bytearray(set_raw_rc([1500] * 8))
    corrupt[-1] ^= 0x01  # (a checksum one bit off: dropped, counted)
    sends = [set_raw_rc(FRAMES[0]), bytes(corrupt), set_raw_rc(FRAMES[1]), set_raw_rc(FRAMES[2]),
             frame("<", 105), frame("<", 101)]
    out, sent = drive(board, sends, 70 * STEP_NS)
    got = reports(out)
    assert got["who_am_i"] == 0x68  # (the MPU-6050's register map: WHO_AM_I reads 0x68)
    for f, us in enumerate(FRAMES):
        assert got[f"msp_{f}_n"] == len(us), out
        assert [got[f"msp_{f}_{c + 1:02d}"] for c in range(len(us))] == us, out
    assert "msp_3_n" not in got and got["msp_bad"] == 1, out
    # each SET_RAW_RC acknowledged by an empty reply, MSP_RC with the channels last set, 101 refused
    ack = frame(">", 200)
    assert sent == ack * 3 + frame(">", 105, channels(FRAMES[2])) + frame("!", 101), sent


def test_two_runs_give_the_same_bytes(tmp_path: Path) -> None:
    board = boards.load(msp_board(tmp_path))
    sends = [set_raw_rc(FRAMES[0]), frame("<", 105)]
    first = drive(board, sends, 30 * STEP_NS)
    assert "msp_0_08=" in first[0] and first[1].endswith(frame(">", 105, channels(FRAMES[0])))
    assert drive(board, sends, 30 * STEP_NS) == first


def test_the_sessions_rc_frames_reach_the_firmware_as_set_raw_rc(tmp_path: Path) -> None:
    """The MCU session with the MSP board: the scenario's RC frames (SBUS, as the scenarios write them)
    become SET_RAW_RC frames on USART1 (rig/mcu/session.py), and an MSP_RC request on the same port (at the
    board's baud for it) is answered with the channels exactly, each as a receiver maps SBUS to
    microseconds; rig/telemetry/msp.py reads the replies and checks their checksums."""
    engine_or_skip()
    board = boards.load(msp_board(tmp_path))
    world = World.at_rest(seed=0, topology=board.topology)
    session = McuSession(McuConfig(board, firmware("msp_rx"), 0.1, RC, TEL, listen=frozenset({1})), world)
    rc_frame = sbus.encode(SBUS_CHANNELS)
    for t in (0.02, 0.04, 0.06):
        session.at(t, lambda s: s.serial_write(RC, rc_frame))
    session.at(0.08, lambda s: s.serial_write(s.serial_port(1, None), frame("<", 105)))
    outcome = session.run()
    world.close()
    assert outcome.verdict == "ok", outcome.error
    reader = ReplyReader()
    replies = [r for _, data in session.uart_log[1] for r in reader.feed(data)]
    assert (reader.skipped, reader.bad) == (0, 0)
    assert [(r.command, r.error) for r in replies] == [(200, False)] * 3 + [(105, False)]
    # the receiver's line through its two ends, written here: 172 -> 1000 us, 1811 -> 2000 us
    want = [round(1000 + (c - 172) * (2000 - 1000) / (1811 - 172)) for c in SBUS_CHANNELS[:8]]
    assert replies[-1].payload == channels(want)
    assert session.figures.rc_bytes == 3 * 25


SCENARIO = """
[scenario]
name = "msp on usart1"
duration = 0.5
[sensors]
noise = false
[[serial]]
t = 0.3
uart = 1
msp = 105
[[serial]]
t = 0.4
uart = 1
msp = 101
[[criteria]]
uart = 1
msp_reply = 105
start = 0.3
end = 0.31
[[criteria]]
name = "refused"
uart = 1
msp_reply = 101
"""


def test_a_scenarios_msp_step_gets_its_reply_through_rig_run(tmp_path: Path) -> None:
    """`rig run` with the MSP board: the sticks go in as SET_RAW_RC all along, the scenario's `msp = 105`
    step at 0.3 s gets its reply (the msp_reply criterion), and the firmware's "$M!" to 101 is no reply."""
    engine_or_skip()
    scenario = tmp_path / "msp.toml"
    scenario.write_text(SCENARIO)
    done = subprocess.run([sys.executable, "-m", "rig.cli", "run", "--mcu", str(msp_board(tmp_path)),
                           "--firmware", str(firmware("msp_rx")), str(scenario),
                           "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, cwd=REPO, timeout=300)
    assert done.returncode == 1, done.stdout + done.stderr  # (only "refused" fails)
    result = json.loads((tmp_path / "out" / "msp" / "result.json").read_text())
    by_name = {m["name"]: m for m in result["measurements"]}
    assert [m["outcome"] for m in result["measurements"]] == ["pass", "fail"]
    # at most a sticks' SET_RAW_RC (6 + 2 x 8 bytes) on the line before the request (6), its ack (6) and
    # the reply (6 + 2 x 8) before it, 10 bits a byte at 115200 baud, taken at the next 1 ms step's end
    latest = 0.3 + (22 + 6 + 6 + 22) * 10 / BAUD + 0.001
    assert 0.3 < by_name["an MSP reply to 105 on USART1"]["value"] <= latest
    assert "no MSP reply to command 101 on USART 1" in by_name["refused"]["reason"]


@pytest.mark.parametrize(("rc", "key", "words"), [
    ('protocol = "msp"\nuart = 4\n', "rc.uart", "has USART 1, 2, 3, 6 only"),
    ('protocol = "msp"\nuart = 1\nbaud = 100\n', "rc.baud", "expected an integer in 300..2000000"),
], ids=["uart", "baud"])
def test_a_board_puts_msp_on_a_usart_the_mcu_has(tmp_path: Path, rc: str, key: str, words: str) -> None:
    with pytest.raises(BoardError, match=f"{key}.*{words}"):
        boards.load(msp_board(tmp_path, rc))
