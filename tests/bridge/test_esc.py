"""The ESC protocols: a captured width becomes the plant's standard-PWM command (OneShot125 is PWM
divided by eight, by its definition), an unknown protocol is refused by name, and --esc is a bench
option the command line checks before anything runs."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from rig.bridge.esc import ESC_PROTOCOLS, esc_protocol


@pytest.mark.parametrize("name, tenth_us, pwm_us", [
    ("pwm", 15003, 1500.3), ("pwm", 0, 0.0),
    ("oneshot125", 1250, 1000.0), ("oneshot125", 2500, 2000.0), ("oneshot125", 1875, 1500.0),
])
def test_a_width_is_the_plants_pwm_microseconds(name: str, tenth_us: int, pwm_us: float) -> None:
    assert esc_protocol(name).motor_us(tenth_us) == pytest.approx(pwm_us)


def test_each_protocols_limits_hold_its_whole_range_and_nothing_twice_as_long() -> None:
    fastest_hz = {"pwm": 490, "oneshot125": 4000}
    for p in ESC_PROTOCOLS.values():
        lo, hi = 1000 / p.to_pwm_us, 2000 / p.to_pwm_us  # idle and full throttle, in its own microseconds
        assert p.pulse_min_us < lo and hi < p.pulse_max_us < 2 * hi
        assert 0 < p.period_min_us <= 1e6 / fastest_hz[p.name]  # its fastest update rate passes


def test_an_unknown_protocol_is_refused_with_the_known_ones() -> None:
    with pytest.raises(ValueError, match="dshot600.*pwm, oneshot125"):
        esc_protocol("dshot600")


def test_esc_without_a_bridge_is_bad_usage() -> None:
    r = subprocess.run([sys.executable, "-m", "rig.cli", "run", "--esc", "oneshot125", "seed000_roll_stand"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "--esc oneshot125" in r.stderr and "--bridge" in r.stderr


def test_pwm_pulses_captured_as_oneshot125_are_said_to_be_outside_its_window(tmp_path: Path) -> None:
    """The reference FC sends standard PWM; the bridge told oneshot125 counts every pulse a glitch. The
    run is an error that says so, not "the DUT never drove a motor" beside thousands of glitches."""
    from tests.bridge.tools import vbridge

    vbridge()
    scenario = tmp_path / "short.toml"
    scenario.write_text('[scenario]\nname = "short"\nduration = 2.0\n\n[vehicle]\nstand = 1\n\n'
                        '[[timeline]]\nt = 1.2\nsticks = { arm = true, throttle = 0.2 }\n\n'
                        '[[criteria]]\nmetric = "max"\nsignal = "tilt"\nmax = 90.0\n')  # (armed: pulses)
    r = subprocess.run([sys.executable, "-m", "rig.cli", "run", "--bridge", "virtual", "--esc", "oneshot125",
                        str(scenario), "--out", str(tmp_path / "out")],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 3, r.stderr
    result = json.loads((tmp_path / "out" / "short" / "result.json").read_text())
    glitches = result["metadata"]["bridge"]["bridge_status"]["pulse_glitches"]
    assert glitches > 0
    said = result["error"]
    assert "never drove a motor" not in said, said
    assert "no pulse within the oneshot125 protocol's window (62..313 us" in said
    assert "pulses outside it (pulse glitches): is the board's ESC protocol oneshot125?" in said
