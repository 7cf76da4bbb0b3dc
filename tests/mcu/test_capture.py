"""A motor on a timer's compare-output pin whose compare output is disconnected (COMnx = 0): the
datasheets' "normal port operation, OCnx disconnected", so the pin follows PORTx writes and a firmware
that bit-bangs its ESC pulses there drives the motor; result.json's ``capture`` says how each motor was
measured. The bitbang firmware drives one pin by the timer (fast PWM, TOP = ICR = 4999 at clk/8, OCR =
2199) and the next by PORT writes (1500 us high, 1000 us low, with avr-libc's _delay_us)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from rig.mcu.engine import AvrEngine, EngineConfig, Motor
from tests.mcu.conftest import MCUS, REPO, firmware

CLOCK = 16_000_000
MOTORS = {"atmega2560": (Motor("PE4", 3, "B"), Motor("PE5", 3, "C")),
          "atmega328p": (Motor("PB1", 1, "A"), Motor("PB2", 1, "B"))}
#: fast PWM (the datasheets' formulas): width (OCR + 1) N / f, period (TOP + 1) N / f, N = 8
TIMED_WIDTH_NS = (2199 + 1) * 8 * 10**9 // CLOCK
TIMED_PERIOD_NS = (4999 + 1) * 8 * 10**9 // CLOCK
#: the port writes: _delay_us's exact cycles plus the instructions around them (a few cycles, < 1 us)
BANGED_WIDTH_NS, BANGED_PERIOD_NS, INSTRUCTIONS_NS = 1_500_000, 2_500_000, 1_000


@pytest.mark.parametrize("mcu", MCUS)
def test_a_timer_pin_with_its_compare_output_disconnected_follows_port_writes(mcu: str) -> None:
    cfg = EngineConfig(mcu, CLOCK, firmware("bitbang", mcu), motors=MOTORS[mcu], hang_ns=0)
    with AvrEngine(cfg, None) as e:
        assert e.run_until(30_000_000).kind == "reached"
        timed, banged = e.pulses()
        capture = e.capture()
    assert len(timed) >= 10 and {(w, p) for _, w, p in timed} == {(TIMED_WIDTH_NS, TIMED_PERIOD_NS)}
    assert len(banged) >= 10
    assert all(BANGED_WIDTH_NS <= w < BANGED_WIDTH_NS + INSTRUCTIONS_NS for _, w, _ in banged)
    assert all(BANGED_PERIOD_NS <= p < BANGED_PERIOD_NS + INSTRUCTIONS_NS for _, _, p in banged[1:])
    assert capture == [{"timer": len(timed), "edges": 0}, {"timer": 0, "edges": len(banged)}]


def test_the_summary_says_how_each_motor_was_measured(tmp_path: Path) -> None:
    """On the shipped Mega board (motors 1-4 on OC3B PE4, OC3C PE5, OC3A PE3, OC4A PH3)."""
    summary = tmp_path / "s.json"
    done = subprocess.run([sys.executable, "-m", "rig.cli", "exec", "--mcu", "mega2560-gy86", "--firmware",
                           str(firmware("bitbang", "atmega2560")), "--duration", "0.1", "--allow-no-devices",
                           "--summary", str(summary)], capture_output=True, text=True, cwd=REPO, timeout=120)
    assert done.returncode == 0, done.stderr
    said = json.loads(summary.read_text())
    assert said["capture"] == ("m1 PE4: OC3B registers; m2 PE5: pin edges (OC3C disconnected); "
                               "m3 PE3: no pulse; m4 PH3: no pulse")
    # the pulses ended in 0.1 s, one each 2.5 ms from the start: (100 - 1.5) // 2.5 + 1 = 40 (the banged
    # one, 1.5 ms, ends latest)
    assert said["mcu"]["motor_pulses"] == [40, 40, 0, 0]


def test_a_board_motor_without_a_timer_is_measured_from_its_edges(tmp_path: Path) -> None:
    """The Mega board with its motor 2 named by pin only (PE5, no timer): software PWM."""
    shipped = (REPO / "rig" / "mcu" / "boards" / "mega2560-gy86.toml").read_text()
    motor2 = 'pin = "PE5"\ntimer = 3\nchannel = "C"'
    assert motor2 in shipped
    board = tmp_path / "soft.toml"
    board.write_text(shipped.replace(motor2, 'pin = "PE5"'))
    summary = tmp_path / "s.json"
    done = subprocess.run([sys.executable, "-m", "rig.cli", "exec", "--mcu", board, "--firmware",
                           str(firmware("bitbang", "atmega2560")), "--duration", "0.1", "--allow-no-devices",
                           "--summary", str(summary)], capture_output=True, text=True, cwd=REPO, timeout=120)
    assert done.returncode == 0, done.stderr
    said = json.loads(summary.read_text())
    assert said["capture"].startswith("m1 PE4: OC3B registers; m2 PE5: pin edges; m3 PE3: no pulse")
    assert said["mcu"]["motor_pulses"] == [40, 40, 0, 0]
