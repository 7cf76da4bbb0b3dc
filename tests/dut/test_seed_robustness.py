"""The acceptance suite must not depend on the noise seed. Flying the library over 20 seeds found two
weaknesses of the reference FC, not of the limits (the distributions are in docs/scenarios.md, "The suite
over many seeds"): the initial heading came from one noisy magnetometer sample, and seed 000's eq. 1
carries a heading error into roll (0.43 of it at a 60 deg dip), so the roll step's steady-state error
spread to 0.64 deg at some seeds; and the altitude integral wound up while hold engaged on a climb,
leaving a creep that the 1 m step measured as settling time. The fast tests pin both at the seeds that
showed them; the slow one flies the whole library over 20 seeds."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest

from rig.runner import run
from rig.scenarios.schema import load

LIB = Path(__file__).resolve().parents[2] / "scenarios" / "library"
SEEDS = 20


@pytest.mark.parametrize("seed", [1, 2, 4, 7])
def test_the_roll_estimate_is_true_before_the_roll_step(seed: int, tmp_path: Path) -> None:
    """At these seeds the estimate sat 0.38-0.53 deg off the true roll (with the estimate held at 0,
    the vehicle flew tilted), from a heading error of 2 deg at alignment."""
    r = run(load(LIB / "step_roll.toml"), seed=seed, work_dir=tmp_path)
    t = r.signals["t"]
    before = (t >= 5.0) & (t <= 6.0)
    assert abs(float(np.mean(r.signals["roll_est_error"][before]))) < 0.15
    assert r.verdict == "pass", [(m.name, m.value) for m in r.measurements if m.outcome != "pass"]


def test_an_altitude_hold_engaged_while_climbing_does_not_wind_up(tmp_path: Path) -> None:
    """Seed 7 settled only after 5.3 s (limit 5 s) while the median seed took 2.5 s: the outer altitude
    integral had summed the metre of overshoot after engaging and was still unwinding."""
    r = run(load(LIB / "step_altitude.toml"), seed=7, work_dir=tmp_path)
    settling = next(m for m in r.measurements if m.metric == "settling_time")
    assert settling.value < 3.5
    assert r.verdict == "pass"


@pytest.mark.slow(reason="a soak: 20 seeds of what the default run flies at one, "
                  "tests/scenarios/test_library_and_reports.py::test_rig_run_passes_the_library_and_writes_every_report")
@pytest.mark.parametrize("name", sorted(p.stem for p in LIB.glob("*.toml")))
def test_the_library_passes_at_every_seed(name: str) -> None:
    """`make test-slow` (or `pytest -m slow tests/dut/test_seed_robustness.py`): each scenario of the
    library at seeds 0..19 against the reference FC; every run must pass."""
    sc = load(LIB / f"{name}.toml")
    failures = []
    for seed in range(SEEDS):
        with tempfile.TemporaryDirectory(prefix="rig-seeds-") as work:
            r = run(sc, seed=seed, work_dir=Path(work))
        if r.verdict != "pass":
            failures.append((seed, r.verdict, r.error, [(m.name, m.value) for m in r.measurements
                                                        if m.outcome != "pass"]))
    assert not failures, failures
