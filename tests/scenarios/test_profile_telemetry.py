"""Every profile path flown by a firmware the project builds: the reference FC configured by the shipped
profiles reference-msp (MSP polled), reference-mavlink (MAVLink read) and reference-sticks (arms by the
stick gesture, reads SBUS as MultiWii does, flies X, MSP) gives the same verdicts as under `reference`
on library scenarios, with the criteria on its estimates measured from that telemetry; on Linux and, for
MSP and stick arming, on the AVR under the MCU tier.

The independent truth for the estimates is the FC's own text lines: the same flight (same seed, same
gains) under `reference` gives est_roll from ``T … roll=…``, which the MSP/MAVLink columns must match
within their resolution and the poll's timing."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from rig.runner import run
from rig.scenarios import LIBRARY
from rig.scenarios import profile as profiles
from rig.scenarios.criteria import NOT_MEASURED
from rig.scenarios.result import RunResult
from rig.scenarios.schema import load
from rig.targets import Target

REPO = Path(__file__).resolve().parents[2]
BINARY = ("reference-msp", "reference-mavlink", "reference-sticks")
SCENARIOS = ("step_roll", "hover_turbulence", "mag_disturbance")


def flown(name: str, fc: str, seed: int = 0, target: Target | None = None) -> RunResult:
    return run(load(LIBRARY / f"{name}.toml"), target, seed=seed, profile=profiles.load(fc))


def verdicts(r: RunResult) -> dict[str, str]:
    return {m.name: m.outcome for m in r.measurements}


@pytest.fixture(scope="module")
def reference() -> dict[str, RunResult]:
    return {name: flown(name, "reference") for name in SCENARIOS}


@pytest.mark.parametrize("fc", BINARY)
def test_each_profile_flies_as_the_reference_and_measures_the_estimates(
        fc: str, reference: dict[str, RunResult]) -> None:
    for name in SCENARIOS:
        r, ref = flown(name, fc), reference[name]
        assert r.verdict == ref.verdict == "pass", (name, r.error, r.notes, verdicts(r))
        assert verdicts(r) == verdicts(ref), name
        est = [m for m in r.measurements if m.signal.endswith("_est_error")]
        assert all(m.outcome != NOT_MEASURED and math.isfinite(m.value) for m in est), name
        tel = r.metadata["telemetry"]
        assert isinstance(tel, dict) and tel["bad_frames"] == 0 and tel["first_valid_s"] is not None
        assert not any("ready" in n or "never" in n for n in r.notes), r.notes
    # hover_turbulence and mag_disturbance judge est_* (roll, and yaw in mag_disturbance)
    assert any(m.signal == "yaw_est_error" for m in reference["mag_disturbance"].measurements)


@pytest.mark.parametrize("fc", ["reference-msp", "reference-mavlink"])
def test_the_binary_estimates_are_the_text_lines_estimates(fc: str, reference: dict[str, RunResult]) -> None:
    r, ref = flown("hover_turbulence", fc), reference["hover_turbulence"]
    # the same flight: the telemetry's protocol changes nothing the FC does
    assert np.array_equal(r.signals["roll"], ref.signals["roll"])
    after = (r.signals["t"] > 3.0) & np.isfinite(r.signals["est_roll"]) & np.isfinite(ref.signals["est_roll"])
    assert after.sum() > 500
    # MSP: 0.1 deg steps; MAVLink: float radians; both up to one poll/watch period late (20 / 10 ms), in
    # which a turbulent hover's roll moves well under a degree
    diff = np.abs(r.signals["est_roll"][after] - ref.signals["est_roll"][after])
    assert float(diff.max()) < 1.0, float(diff.max())
    d_alt = np.abs(r.signals["est_alt"][after] - ref.signals["est_alt"][after])
    assert float(d_alt.max()) < 0.1  # MSP_ALTITUDE in cm; VFR_HUD in m
    armed = r.signals["armed"][np.isfinite(r.signals["armed"])]
    assert armed[0] == 0.0 and armed[-1] == 1.0  # disarmed at its first reply, armed by the end


def test_a_stick_armed_x_frame_fc_that_never_arms_says_so_by_its_msp_flag(tmp_path: Path) -> None:
    text = (profiles.PROFILES / "reference-sticks.toml").read_text()
    assert "arm_hold_s = 0.5" in text
    path = tmp_path / "late.toml"  # the FC wants the gesture 2 s; the rig holds it 1 s
    path.write_text(text.replace("arm_hold_s = 0.5", "arm_hold_s = 2"))
    r = run(load(LIBRARY / "step_roll.toml"), seed=0, profile=profiles.load(path))
    assert r.verdict == "fail"
    assert all("its telemetry never said armed" in m.reason for m in r.measurements), verdicts(r)


def test_the_avr_flies_msp_and_stick_arming(tmp_path: Path) -> None:
    import subprocess

    from rig.targets.mcu import McuTarget

    subprocess.run(["make", "-s", "-C", str(REPO / "dut"), "avr"], capture_output=True, check=True)
    target = McuTarget("mega2560-gy86", REPO / "build" / "avr" / "fc.elf")
    # the "+" frame: the AVR's 75 Hz loop with the X mixer overshoots step_roll's 10 deg by 26 %
    # (the gains are tuned on "+"; Linux at 250 Hz flies X within 2 %), which is not what this tests
    text = (profiles.PROFILES / "reference-sticks.toml").read_text()
    plus = tmp_path / "sticks-plus.toml"
    plus.write_text(text.replace(", mixer = 1 }", " }").replace('frame = "x"', 'frame = "+"'))
    for name in ("step_roll", "hover_turbulence"):
        ref = flown(name, "reference", target=target)
        r = flown(name, str(plus), target=target)
        assert r.verdict == ref.verdict == "pass", (name, r.error, r.notes, verdicts(r))
        assert verdicts(r) == verdicts(ref)
        fc = r.metadata["fc_config"]
        assert isinstance(fc, dict) and fc["arming"] == "1" and fc["sbus_map"] == "1"
        tel = r.metadata["telemetry"]
        assert isinstance(tel, dict) and tel["messages"]["MSP_ATTITUDE"] > 100
        assert all(m.outcome != NOT_MEASURED for m in r.measurements if m.signal.endswith("_est_error"))
        assert not any("never" in n for n in r.notes), r.notes


def test_an_fc_acting_before_its_first_reply_is_noted(tmp_path: Path) -> None:
    # the reference FC answers its first MSP poll after its 1 s calibration (first_valid_s ~1.1);
    # a scenario that arms at 0.6 s under a profile claiming no start-up time acts before that
    text = (LIBRARY / "step_roll.toml").read_text()
    assert "t = 1.2\narm = true" in text
    early = tmp_path / "early.toml"
    early.write_text(text.replace("t = 1.2\narm = true", "t = 0.6\narm = true"))
    fc = tmp_path / "fc.toml"
    shipped = (profiles.PROFILES / "reference-msp.toml").read_text()
    fc.write_text(shipped.replace("seconds = 1.2", "seconds = 0"))
    r = run(load(early), seed=0, profile=profiles.load(fc))
    tel = r.metadata["telemetry"]
    assert isinstance(tel, dict) and isinstance(tel["first_valid_s"], float) and tel["first_valid_s"] > 0.6
    assert any("after the scenario's first action at 0.6 s" in n for n in r.notes), r.notes
    # the same under the shipped profile: shifted to its 1.2 s start-up, no such note
    r = run(load(early), seed=0, profile=profiles.load("reference-msp"))
    assert not any("first action" in n and "MSP reply" in n for n in r.notes), r.notes
