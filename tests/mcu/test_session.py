"""The MCU session's side of the tier (rig/mcu/session.py): the scenario's RC frames reach a board's RC
input as its board file wires it (SBUS bytes, a PPM sum on an interrupt pin, MSP SET_RAW_RC), read back
by the RC echo firmware; and an ESC that stops getting pulses stops its motor, as on the bench."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from rig.emulators import sbus
from rig.mcu import board as boards
from rig.mcu.session import ESC_TIMEOUT_S, McuConfig, McuSession
from rig.plant.variables import PWM_INPUTS
from rig.world import World
from tests.mcu.conftest import firmware
from tests.mcu.test_rc import echoes

RC, TEL = "/dev/ttyRC0", "/dev/ttyTEL0"
#: an ATmega2560 board for the RC echo: its RC input as the test says, motors on timers 1 and 5
ECHO_BOARD = """
[board]
mcu = "atmega2560"
clock_hz = 16_000_000
[[motors]]
motor = 1
pin = "PB5"
timer = 1
channel = "A"
[[motors]]
motor = 2
pin = "PB6"
timer = 1
channel = "B"
[[motors]]
motor = 3
pin = "PL3"
timer = 5
channel = "A"
[[motors]]
motor = 4
pin = "PL4"
timer = 5
channel = "B"
[rc]
{rc}
[telemetry]
uart = 0
baud = 115_200
"""
CHANNELS = [172, 992, 1811, 500, 1500, 992, 300, 1700, 992, 992, 992, 992, 992, 992, 992, 992]


def send(data: bytes) -> Callable[[McuSession], None]:
    def event(s: McuSession) -> None:
        s.serial_write(RC, data)

    return event


def fly(board: boards.Board, fw: Path, duration: float, events: dict[float, bytes]) -> McuSession:
    world = World.at_rest(seed=0, topology=board.topology)
    session = McuSession(McuConfig(board, fw, duration, RC, TEL), world)
    for t, data in events.items():
        session.at(t, send(data))
    outcome = session.run()
    world.close()
    assert outcome.verdict == "ok", outcome.error
    return session


@pytest.mark.parametrize(
    ("rc", "source"),
    [('protocol = "sbus"\nuart = 1', 0), ('protocol = "msp"\nuart = 0\nbaud = 115_200', 1),
     ('protocol = "ppm"\npin = "PE4"', 2)],
    ids=["sbus", "msp", "ppm"],
)
def test_the_scenarios_rc_frames_reach_the_boards_rc_input(tmp_path: Path, rc: str, source: int) -> None:
    path = tmp_path / "echo.toml"
    path.write_text(ECHO_BOARD.format(rc=rc))
    frame = sbus.encode(CHANNELS)
    session = fly(boards.load(str(path)), firmware("rc_echo", "atmega2560"), 0.2,
                     {0.02: frame, 0.04: frame, 0.06: frame})
    got = [channels for src, channels in echoes(session.serial_output(TEL)) if src == source]
    assert got, echoes(session.serial_output(TEL))
    if source == 0:  # SBUS: the raw 11-bit values as they were sent
        assert got[0] == CHANNELS
    else:  # MSP and PPM: microseconds, as a receiver maps SBUS (172 -> 1000, 1811 -> 2000)
        # the receiver's line through its two ends, written here: 172 -> 1000 us, 1811 -> 2000 us
        want = [round(1000 + (c - 172) * (2000 - 1000) / (1811 - 172)) for c in CHANNELS[:8]]
        slack = 1 if source == 2 else 0  # (PPM: timed by the firmware's 0.5 us timer)
        for g in got:
            assert len(g) == 8 and all(abs(a - b) <= slack for a, b in zip(g, want, strict=True)), (got, want)


def test_an_esc_without_pulses_stops_its_motor() -> None:
    """pulse_stop pulses motor 1 at 1500 us for 0.5 s, then its pin goes quiet: the motor holds 1500 us
    until ESC_TIMEOUT_S after the last pulse, then stops; the motors never pulsed stay off."""
    board = boards.load("mega2560-gy86")
    seen: dict[float, list[float]] = {}

    def look(s: McuSession) -> None:
        seen[s.now_ns / 1e9] = [s.world.plant.u[s.world.plant.u_index[n]] for n in PWM_INPUTS[:4]]

    world = World.at_rest(seed=0, topology=board.topology)
    session = McuSession(McuConfig(board, firmware("pulse_stop", "atmega2560"), 0.9, RC, TEL), world)
    for t in (0.3, 0.5 + ESC_TIMEOUT_S / 2, 0.5 + ESC_TIMEOUT_S + 0.05):
        session.at(t, look)
    outcome = session.run()
    world.close()
    assert outcome.verdict == "ok", outcome.error
    (t1, during), (t2, just_after), (t3, later) = sorted(seen.items())
    assert during == [1500.0, 0.0, 0.0, 0.0]
    assert just_after == [1500.0, 0.0, 0.0, 0.0]  # the ESC keeps its last pulse until its timeout
    assert later == [0.0, 0.0, 0.0, 0.0]
    assert session.figures.motors[0].pulses == pytest.approx(0.5 / 0.00204, abs=2)
