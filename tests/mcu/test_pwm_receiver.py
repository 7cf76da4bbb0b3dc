"""A parallel PWM receiver (4-8 channels, each on its own pin with a pin change interrupt) and a PPM sum
on any pin change pin, beside SBUS and MSP: the board file names the pins, the session puts each
channel's pulse on its pin every 20 ms, one after the other as receivers do. The widths expected are
the rig's stick convention written out: SBUS raw = round(992 + x * 819) for x in -1..1 (throttle
x = 2t - 1), and a receiver's microseconds 1000 + (raw - 172) * 1000 / 1639."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from rig.mcu import board
from rig.mcu.board import BoardError
from tests.mcu.conftest import REPO, firmware

STICKS = "roll=0,pitch=0.5,throttle=1,yaw=-1"


def receiver_us(x: float) -> int:
    raw = max(172, min(1811, round(992 + x * (1811 - 992))))
    return round(1000 + (raw - 172) * 1000 / (1811 - 172))


WANT = [receiver_us(0), receiver_us(0.5), receiver_us(1), receiver_us(-1)]  # (AETR)


def exec_sticks(tmp_path: Path, text: str, fw: Path) -> bytes:
    path = tmp_path / "board.toml"
    path.write_text(text)
    done = subprocess.run([sys.executable, "-m", "rig.cli", "exec", "--mcu", str(path), "--firmware", str(fw),
                           "--duration", "0.5", "--allow-no-devices", "--sticks", STICKS],
                          capture_output=True, cwd=REPO, timeout=300)
    assert done.returncode == 0, done.stderr
    return done.stdout


NANO_PWM = (board.find("nano328-gy521").read_text() +
            '\n[rc]\nprotocol = "pwm"\npins = ["PD4", "PD5", "PD6", "PD7"]\n'
            "\n[telemetry]\nuart = 0\nbaud = 115_200\n")
MEGA_PWM = board.find("mega2560-gy86").read_text().replace(
    'protocol = "sbus"    # RX1 D19 (PD2)\nuart = 1', 'protocol = "pwm"\npins = ["PK0", "PK1", "PK2", "PK3"]')


@pytest.mark.parametrize(("mcu", "text"), [("atmega328p", NANO_PWM), ("atmega2560", MEGA_PWM)])
def test_a_parallel_pwm_receiver_gives_each_channel_on_its_pin(tmp_path: Path, mcu: str, text: str) -> None:
    out = exec_sticks(tmp_path, text, firmware("pwm_rx", mcu))
    frames = [out[k + 2:k + 10] for k in range(len(out) - 9) if out[k:k + 2] == b"\xe3\x04"]
    widths = [[f[2 * i] | f[2 * i + 1] << 8 for i in range(4)] for f in frames]
    assert len(widths) >= 20  # (0.5 s at 50 Hz, the first frames before the sticks' first SBUS frame)
    assert all(abs(g - w) <= 1 for g, w in zip(widths[-1], WANT, strict=True)), (widths[-1], WANT)
    assert widths[-10:] == [widths[-1]] * 10


def test_a_ppm_sum_on_a_pin_change_pin(tmp_path: Path) -> None:
    """pcint_rc times the high pulses on PK3 (PCINT19): in a PPM sum (300 us low pulses) each channel's
    high part is its width less 300 us."""
    text = board.find("mega2560-gy86").read_text().replace(
        'protocol = "sbus"    # RX1 D19 (PD2)\nuart = 1', 'protocol = "ppm"\npin = "PK3"')
    out = exec_sticks(tmp_path, text, firmware("pcint_rc", "atmega2560"))
    highs = [out[i] | out[i + 1] << 8 for i in range(0, len(out) - 1, 2)]
    want = [w - 300 for w in WANT]
    found = [k for k in range(len(highs) - 3)
             if all(abs(highs[k + i] - want[i]) <= 1 for i in range(4))]
    assert len(found) >= 10, highs[-12:]


@pytest.mark.parametrize(
    ("rc", "words"),
    [('protocol = "pwm"\npins = ["PK0", "PK1", "PK2"]', "expected 4 to 8 pins"),
     ('protocol = "pwm"\npins = ["PK0", "PK1", "PK2", "PA0"]', "PA0 has no external or pin change interrupt"),
     ('protocol = "pwm"\npins = ["PK0", "PK1", "PK2", "PK0"]', "pin PK0 is two channels"),
     ('protocol = "ppm"\npin = "PA0"', "PA0 has no external or pin change interrupt"),
     ('protocol = "ppm"\npin = "PE4"', "pin PE4 drives motor 1")],  # (INT4, the board's motor 1)
)
def test_receiver_pin_mistakes_name_the_key(tmp_path: Path, rc: str, words: str) -> None:
    path = tmp_path / "b.toml"
    path.write_text(board.find("mega2560-gy86").read_text().replace(
        'protocol = "sbus"    # RX1 D19 (PD2)\nuart = 1', rc))
    with pytest.raises(BoardError) as e:
        board.load(path)
    assert e.value.key.startswith("rc.pin") and words in str(e.value)
