"""Bad scenario files fail before anything runs, naming the file, the key and what was expected; the
whole library is valid; `rig validate` reports without a traceback."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from rig.scenarios.schema import ScenarioError, load

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
        (("[[criteria]]", "[vehicle]\nmass = -1\n[[criteria]]"), "vehicle.mass",
         "the plant refuses it: mass must be > 0"),
        (("[[criteria]]", "[vehicle]\nstand = 9\n[[criteria]]"), "vehicle.stand", "stand must be 0..4"),
        (("[[criteria]]", "[vehicle]\nstand = 1.5\n[[criteria]]"), "vehicle.stand", "takes a whole number"),
        (("[[criteria]]", "[vehicle]\nesc_max_us = 900\n[[criteria]]"), "vehicle.esc_max_us",
         "esc_max_us must be > esc_min_us"),
        (("[[criteria]]", "[fc]\nestimater = 1\n[[criteria]]"), "fc.estimater",
         "unknown key; did you mean 'estimator'?"),
        (("[[criteria]]", "[fc]\nestimator = 3\n[[criteria]]"), "fc.estimator", "3 is outside 0..2"),
        (("[[criteria]]", '[fc]\nestimator = "one"\n[[criteria]]'), "fc.estimator", "expected an integer"),
        (("[[criteria]]", "[fc]\nalpha = [1, 1, 1]\n[[criteria]]"), "fc.alpha", "expected 4 numbers"),
        (("[[criteria]]", '[fc]\nprofile = "fast"\n[[criteria]]'), "fc.profile", "one of default, seed002"),
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


@pytest.mark.parametrize(
    "edit, key, said",
    [
        (("max = 5.0", "max = nan"), "criteria[0].max", "expected a finite number, got nan"),
        (("max = 5.0", "max = -inf"), "criteria[0].max", "expected a finite number, got -inf"),
        (("duration = 5.0", "duration = 1e12"), "scenario.duration",
         "expected a number > 0 and at most 3600, got 1e+12"),
        (("max = 5.0", "min = 10\nmax = 5"), "criteria[0].max",
         "expected a limit at least min (10), got 5: no value could pass"),
    ],
)
def test_the_message_says_what_the_value_is_and_what_was_expected(
    tmp_path: Path, edit: tuple[str, str], key: str, said: str
) -> None:
    p = write(tmp_path, GOOD.replace(*edit))
    with pytest.raises(ScenarioError) as e:
        load(p)
    assert str(e.value) == f"{p}: {key}: {said}"
    assert "-inf.." not in str(e.value) and "got a number" not in str(e.value)


def test_min_equal_to_max_is_an_exact_value_and_passes_the_check(tmp_path: Path) -> None:
    assert load(write(tmp_path, GOOD.replace("max = 5.0", "min = 5\nmax = 5"))).criteria[0].min == 5


THREE_BAD = GOOD.replace("duration = 5.0", "duration = 5.0\ndescripton = 1").replace(
    "max = 5.0", "min = 10\nmax = 5\nband = -1"
) + '\n[[timeline]]\nt = 99\n\n[environment]\nturbulence = 50\n'


def test_every_problem_of_a_file_is_reported_not_only_the_first(tmp_path: Path) -> None:
    p = write(tmp_path, THREE_BAD)
    with pytest.raises(ScenarioError) as e:
        load(p)
    keys = [x.key for x in e.value.problems]
    assert keys == ["scenario.descripton", "timeline[0].t", "criteria[0].max", "criteria[0].band",
                    "environment.turbulence"], str(e.value)
    assert str(e.value).splitlines() == [str(x) for x in e.value.problems]
    done = subprocess.run([sys.executable, "-m", "rig.cli", "validate", str(p)], capture_output=True,
                          text=True)
    assert done.returncode == 2
    assert [line.split(": ")[1] for line in done.stderr.splitlines() if line.startswith("FAIL ")] == keys


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


def test_fc_values_reach_the_config_file_as_the_fc_reads_them(tmp_path: Path) -> None:
    from rig.targets import reference_config

    sc = load(write(tmp_path, GOOD.replace("[[criteria]]", '[fc]\nalpha = [1, 1.5, 1, 1]\nmpu_addr = "0x69"\n'
                                                           'profile = "seed002"\n[[criteria]]')))
    conf = reference_config(sc)
    assert "alpha = 1.0, 1.5, 1.0, 1.0" in conf and "mpu_addr = 105" in conf and "profile = seed002" in conf


def test_the_fc_key_table_is_the_one_the_fc_compiles(tmp_path: Path) -> None:
    """scenarios/fc_keys.py reads dut/src/config_keys.h; the built FC takes every key it finds there at a
    value inside the table's range, refuses one outside it, and refuses a key the table lacks."""
    from rig.scenarios import fc_keys
    from rig.targets import REFERENCE_FC

    keys = fc_keys.keys()
    assert {"estimator", "alpha", "alt_i_band_m", "i2c_path"} <= set(keys) and len(keys) > 40
    assert keys["alpha"].count == 4 and fc_keys.profiles() == ("default", "seed002")

    def fc_says(line: str) -> str:
        conf = tmp_path / "fc.conf"
        conf.write_text(line + "\n")
        done = subprocess.run([str(REFERENCE_FC), str(conf)], capture_output=True, text=True, timeout=30,
                              env={"PATH": "/usr/bin:/bin"})
        return done.stderr

    for k in keys.values():
        value = "/nowhere" if k.kind == "S" else ", ".join([str(int(max(k.low, 0)))] * k.count)
        if k.name in ("ctrl_rate_hz", "est_rate_hz"):
            value = "250"  # (their defaults: ctrl at most est is a rule between two keys)
        said = fc_says(f"{k.name} = {value}")
        assert "unknown key" not in said and "must be" not in said, (k.name, said)
    assert "estimator must be in 0..2" in fc_says("estimator = 3")
    assert "unknown key 'estimater'" in fc_says("estimater = 1")


@pytest.mark.parametrize("stem", ["mag_disturbance", "hover_turbulence"])
def test_the_disturbance_window_is_where_mag_disturbance_at_acts(stem: str) -> None:
    """What the recorder and the fast path read once (mag_disturbance_window) says what the scenario's
    mag_disturbance_at gives at every instant of the run: the field inside [start, end), none outside."""
    sc = load(LIB / f"{stem}.toml")
    vec, start, end = sc.mag_disturbance_window
    inside = 0
    for k in range(round(sc.duration * 1000) + 1):
        t = k / 1000
        acting = start <= t < end
        inside += acting
        assert sc.mag_disturbance_at(t) == (vec if acting else (0.0, 0.0, 0.0))
    assert (inside > 100) == (stem == "mag_disturbance")
