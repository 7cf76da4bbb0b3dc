"""The hang check: a firmware is hung when, for the board's limit (1 s unless the board file or the
command line says otherwise), it made no TWI transaction, no motor pulse, sent no USART byte and changed
no output pin; the error then says what it was polling (its receiver's USART, the EEPROM). The
idle_ways firmware does one of these by its EEPROM byte 0."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from rig.mcu.engine import AvrEngine, EngineConfig
from tests.mcu.conftest import MCUS, REPO, firmware

CLOCK = 16_000_000
SECOND = 1_000_000_000


def run(mcu: str, mode: int, until_ns: int = 1_500_000_000, eeprom: bytes = b"",
        send_at: int | None = None) -> str:
    """The stop's kind and words after running idle_ways in ``mode`` (hang limit 1 s)."""
    cfg = EngineConfig(mcu, CLOCK, firmware("idle_ways", mcu), eeprom=bytes([mode]) + eeprom, twi=False,
                       hang_ns=SECOND)
    with AvrEngine(cfg, None) as e:
        if send_at is not None:
            assert e.run_until(send_at).kind == "reached"
            e.uart_send(0, b"go", 115_200)
        stop = e.run_until(until_ns)
        return f"{stop.kind}: {stop.what}"


@pytest.mark.parametrize("mcu", MCUS)
def test_a_blinking_or_talking_firmware_is_not_hung(mcu: str) -> None:
    """Before USART bytes and output pins counted, both were 'hung' at 1 s."""
    assert run(mcu, 0).startswith("reached")
    assert run(mcu, 1).startswith("reached")


@pytest.mark.parametrize("mcu", MCUS)
def test_a_firmware_waiting_for_its_receiver_says_so(mcu: str) -> None:
    said = run(mcu, 2)
    assert said.startswith("hung: no TWI transaction, motor pulse, USART byte sent or output pin change for "
                           "1000 ms"), said
    assert "polling UCSR0A" in said and "waiting on USART0, bytes from a receiver or a host" in said
    assert run(mcu, 2, send_at=SECOND // 2).startswith("reached")  # (a byte came: it blinks)


@pytest.mark.parametrize("mcu", MCUS)
def test_a_firmware_waiting_for_eeprom_contents_says_so(mcu: str) -> None:
    said = run(mcu, 3)
    assert said.startswith("hung") and "EECR" in said and "waiting on the EEPROM" in said, said
    assert run(mcu, 3, eeprom=bytes([0x5A])).startswith("reached")


def rig(*args: object) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rig.cli", *map(str, args)], capture_output=True, text=True,
                          cwd=REPO, timeout=300)


def test_the_limit_comes_from_the_board_file_or_the_command_line(tmp_path: Path) -> None:
    """idle_ways waiting for a byte: hung at the board's 0.3 s, or at the command line's 0.2 s."""
    eeprom = tmp_path / "mode.bin"
    eeprom.write_bytes(bytes([2]))
    board = tmp_path / "board.toml"
    board.write_text((REPO / "rig/mcu/boards/nano328-gy521.toml").read_text() + "\n[limits]\nhang_s = 0.3\n")
    fw = firmware("idle_ways", "atmega328p")
    base = ["exec", "--mcu", board, "--firmware", fw, "--duration", "2", "--eeprom", eeprom]
    done = rig(*base)
    assert done.returncode == 125 and "for 300 ms" in done.stderr, done.stderr
    done = rig(*base, "--hang-limit", "0.2")
    assert done.returncode == 125 and "for 200 ms" in done.stderr, done.stderr
    done = rig(*base, "--hang-limit", "0")  # (off: the duration ends it)
    assert done.returncode == 125 and "never read a sensor" in done.stderr, done.stderr
    done = rig(*base, "--hang-limit", "-1")
    assert done.returncode == 2 and "--hang-limit" in done.stderr


def echoed_channels(stdout: bytes) -> list[list[int]]:
    """The rc_echo firmware's SBUS echoes (0xE0, 16, the channels little-endian) in its output."""
    frames, at = [], stdout.find(b"\xe0\x10")
    while at >= 0 and at + 34 <= len(stdout):
        body = stdout[at + 2:at + 34]
        frames.append([body[2 * i] | body[2 * i + 1] << 8 for i in range(16)])
        at = stdout.find(b"\xe0\x10", at + 34)
    return frames


def test_rig_exec_gives_sticks_constant_or_as_a_timeline(tmp_path: Path) -> None:
    """SBUS channels (AETR, channel 5 arm) are 992 + x * (1811 - 992) for x in -1..1, throttle 0..1 as
    x = 2 * throttle - 1: throttle 0 is 173, full 1811; the arm switch is 1811 on, 172 off (the rig's
    stick convention, docs/scenarios.md). rc_echo sends back each SBUS frame it decoded."""
    low = 992 - (1811 - 992)
    fw = firmware("rc_echo", "atmega2560")
    base = ["exec", "--mcu", "mega2560-gy86", "--firmware", fw, "--duration", "1", "--allow-no-devices"]
    done = subprocess.run([sys.executable, "-m", "rig.cli", *map(str, base), "--sticks", "throttle=1,arm=on"],
                          capture_output=True, cwd=REPO, timeout=300)
    assert done.returncode == 0, done.stderr
    frames = echoed_channels(done.stdout)
    assert len(frames) > 50 and all(f[2] == 1811 and f[4] == 1811 and f[0] == 992 for f in frames)
    done = subprocess.run([sys.executable, "-m", "rig.cli", *map(str, base),
                           "--sticks", "0:throttle=0,arm=off; 0.5:throttle=1"],
                          capture_output=True, cwd=REPO, timeout=300)
    frames = echoed_channels(done.stdout)
    assert {f[2] for f in frames[:20]} == {low} and {f[2] for f in frames[-20:]} == {1811}
    assert {f[4] for f in frames} == {172}
    for sticks, words in (("throttle=2", "--sticks: [0].sticks.throttle: expected a number in 0..1"),
                          ("x:throttle=1", "expected a time in seconds"), ("rol=1", "did you mean 'roll'")):
        done = subprocess.run([sys.executable, "-m", "rig.cli", *map(str, base), "--sticks", sticks],
                              capture_output=True, cwd=REPO, timeout=300)
        assert done.returncode == 2 and words in done.stderr.decode(), done.stderr
    refused = rig("exec", "--mcu", "nano328-gy521", "--firmware", firmware("rc_echo", "atmega328p"),
                  "--duration", "1", "--sticks", "throttle=1")
    assert refused.returncode == 2 and "has no [rc]" in refused.stderr
