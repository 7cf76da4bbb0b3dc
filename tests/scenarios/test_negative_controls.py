"""Negative controls: DUTs with a defect must fail the library's scenarios on the right criterion or
end in error, so a green suite means something. The defects are reference-FC options (dut/src/config.h)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from rig.runner import run
from rig.scenarios.result import RunResult
from rig.scenarios.schema import load

LIB = Path(__file__).resolve().parents[2] / "scenarios" / "library"


def run_with(name: str, tmp_path: Path, **fc: object) -> RunResult:
    sc = load(LIB / f"{name}.toml")
    sc = dataclasses.replace(sc, fc={**sc.fc, **{k: str(v) for k, v in fc.items()}})
    return run(sc, work_dir=tmp_path)


def failed(r: RunResult) -> set[str]:
    return {m.name for m in r.measurements if m.outcome == "fail"}


def test_the_healthy_reference_fc_passes_the_scenarios_used_below(tmp_path: Path) -> None:
    for name in ("step_roll", "hover_turbulence", "fault_gyro_stuck"):
        r = run_with(name, tmp_path / name)
        assert r.verdict == "pass", (name, failed(r), r.error)


def test_a_roll_sign_error_fails_the_roll_step(tmp_path: Path) -> None:
    r = run_with("step_roll", tmp_path, defect_mixer_sign=1)
    assert r.verdict == "fail"
    assert {"overshoot of roll", "steady_state_error of roll", "settling_time of roll"} <= failed(r)


def test_a_dut_that_never_arms_fails_take_off(tmp_path: Path) -> None:
    r = run_with("hover_turbulence", tmp_path, defect_never_arm=1)
    assert r.verdict == "fail"
    assert "no ground contact after take-off" in failed(r)
    assert r.signals["armed"][-1] == 0


def test_a_stuck_gyro_without_fault_handling_fails(tmp_path: Path) -> None:
    r = run_with("fault_gyro_stuck", tmp_path, gyro_fault_check=0)
    assert r.verdict == "fail"
    assert failed(r) & {"no flip during the fault", "level again after the fault"}


def test_a_dut_that_crashes_mid_run_ends_in_error(tmp_path: Path) -> None:
    r = run_with("hover_turbulence", tmp_path, defect_crash_at=5)
    assert r.verdict == "error"
    assert "SIGABRT" in (r.error or "") or "signal 6" in (r.error or "")
    assert 5.0 <= r.metadata["sim_time"] < 6.5


def test_a_dut_that_ignores_the_altitude_setpoint_fails_the_altitude_step(tmp_path: Path) -> None:
    r = run_with("step_altitude", tmp_path, alt_sp_range_m=0)
    assert r.verdict == "fail"
    assert {"rise_time of alt", "steady_state_error of alt"} <= failed(r)


def test_a_half_size_altitude_step_fails_on_its_final_value(tmp_path: Path) -> None:
    """The step is measured from where the vehicle held (relative target): 0.5 m instead of 1 m must
    show as a steady-state error, not pass as "a step happened"."""
    r = run_with("step_altitude", tmp_path, alt_sp_range_m=2.5)
    assert r.verdict == "fail"
    assert "steady_state_error of alt" in failed(r)
    sse = next(m for m in r.measurements if m.name == "steady_state_error of alt")
    assert 0.3 < sse.value < 0.7
