"""Bad scenario files fail before anything runs, naming the file, the key and what was expected; the
whole library is valid; `rig validate` reports without a traceback."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from scenarios.schema import ScenarioError, load

LIB = Path(__file__).resolve().parents[2] / "scenarios" / "library"
GOOD = """
[scenario]
name = "x"
duration = 5.0

[[criteria]]
metric = "max"
signal = "tilt"
max = 5.0
"""


def write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "s.toml"
    p.write_text(text)
    return p


def test_a_minimal_file_loads(tmp_path: Path) -> None:
    sc = load(write(tmp_path, GOOD))
    assert sc.duration == 5.0 and sc.criteria[0].units == "deg" and sc.capture.transport == "direct"


@pytest.mark.parametrize(
    "edit, key, expected",
    [
        (("duration = 5.0", "duraton = 5.0"), "scenario.duraton", "unknown key"),
        (("duration = 5.0", 'duration = "5"'), "scenario.duration", "expected a finite number, got a string"),
        (("duration = 5.0", "duration = -1.0"), "scenario.duration", "expected a number > 0"),
        (('signal = "tilt"', 'signal = "tilt_angle"'), "criteria[0].signal", "expected one of"),
        (('metric = "max"', 'metric = "maximum"'), "criteria[0].metric", "expected one of"),
        (("max = 5.0", ""), "criteria[0]", "expected a limit"),
        (("[[criteria]]", "[vehicle]\nmas = 1.0\n[[criteria]]"), "vehicle.mas", "unknown key"),
        (
            ("[[criteria]]", '[[faults]]\ntarget = "gyro"\nkind = "stuk"\nstart = 1.0\n[[criteria]]'),
            "faults[0].kind",
            "expected one of",
        ),
        (("[[criteria]]", "[[timeline]]\nt = 9.0\n[[criteria]]"), "timeline[0].t", "in 0..5"),
        (
            ("[[criteria]]", "[[timeline]]\nt = 1.0\nsticks = { roll = 2.0 }\n[[criteria]]"),
            "timeline[0].sticks.roll",
            "in -1..1",
        ),
        (
            ("[[criteria]]", '[capture]\ntransport = "usb"\n[[criteria]]'),
            "capture.transport",
            "expected one of",
        ),
        (
            ("[[criteria]]", '[capture]\ntransport = "can"\ncan_interface = "socketcan"\n[[criteria]]'),
            "capture.can_channel",
            "needs a channel",
        ),
        (("max = 5.0", "max = 5.0\nbaseline_at = 1.0"), "criteria[0].baseline_at", "needs a target"),
        (("max = 5.0", "max = 5.0\ntarget = 1.0\nbaseline_at = 7.0"), "criteria[0].baseline_at", "in 0..5"),
    ],
)
def test_bad_files_name_the_file_the_key_and_what_was_expected(
    tmp_path: Path, edit: tuple[str, str], key: str, expected: str
) -> None:
    p = write(tmp_path, GOOD.replace(*edit))
    with pytest.raises(ScenarioError) as e:
        load(p)
    assert str(e.value).startswith(f"{p}: {key}: ")
    assert expected in str(e.value)


def test_not_toml_and_missing_files(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match="not valid TOML"):
        load(write(tmp_path, "[scenario\n"))
    with pytest.raises(ScenarioError, match="cannot read"):
        load(tmp_path / "none.toml")


def test_every_library_scenario_is_valid() -> None:
    files = sorted(LIB.glob("*.toml"))
    assert len(files) >= 14
    for f in files:
        load(f)


def test_rig_validate_reports_without_a_traceback(tmp_path: Path) -> None:
    bad = write(tmp_path, GOOD.replace("duration = 5.0", "duration = -2"))
    done = subprocess.run(
        [sys.executable, "-m", "rig.cli", "validate", str(bad)], capture_output=True, text=True
    )
    assert done.returncode == 2
    assert "scenario.duration: expected a number > 0" in done.stderr and "Traceback" not in done.stderr
    done = subprocess.run(
        [sys.executable, "-m", "rig.cli", "run", str(bad), "--out", str(tmp_path / "o")],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 2 and "Traceback" not in done.stderr
