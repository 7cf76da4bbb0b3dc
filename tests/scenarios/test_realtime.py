"""Real-time (bench) mode of the scenario runner: the session paced by the wall clock."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from rig.runner import run
from rig.scenarios.schema import load
from rig.targets.process import ProcessTarget
from tests.realtime import realtime

LIB = Path(__file__).resolve().parents[2] / "scenarios" / "library"

pytestmark = pytest.mark.paced  # (make test runs these alone: tests/realtime.py)


def test_a_real_time_run_flies_and_reports_its_lateness(tmp_path: Path) -> None:
    """The bench mode: the same scenario paced by the wall clock. The FC arms from the SBUS frames and
    flies; the result says it was not lockstep and how late the scheduled events ran (numbers are
    reported, not judged: timing belongs in bench/). A run the host starved is flown again, then
    inconclusive (tests/realtime.py).

    The FC arms only while the throttle stick is low, and in real time its start-up (1 s of gyro
    calibration in real sleeps) takes as long as the wall clock makes it: the throttle goes up at 3 s, not
    at the library's 1.5 s, so a slow machine does not make the FC miss the arming window."""
    step_roll = load(LIB / "step_roll.toml")
    arm, climb = (ev for ev in step_roll.timeline if ev.t < 6.0)   # arm at 1.2 s; throttle up at 1.5 s
    assert (arm.arm, arm.mode, arm.sticks) == (True, "angle", {"throttle": 0.0})
    assert climb.sticks == {"throttle": 0.5}
    sc = dataclasses.replace(step_roll, duration=5.0, criteria=(),
                             timeline=(arm, dataclasses.replace(climb, t=3.0)))
    tries = iter(range(2))
    r = realtime(lambda: run(sc, ProcessTarget(realtime=True), work_dir=tmp_path / f"try{next(tries)}"),
                 lambda r: {"step_roll": r.metadata.get("realtime_lateness", {})})
    assert r.verdict == "pass", r.error
    md = r.metadata
    assert md["lockstep"] is False and md["sim_time"] >= 5.0
    late = md["realtime_lateness"]
    assert late["events"] > 5.0 / 0.01  # at least the recorder's 100 Hz ticks ran
    assert 0.0 <= late["p50_s"] <= late["p99_s"] <= late["max_s"]
    # how the paced loop ran (rig/pace): SCHED_FIFO and mlockall, or why not
    assert late["sched_fifo"] or any(w.startswith("SCHED_FIFO") for w in late["not_taken"])
    assert late["mlockall"] or any(w.startswith("mlockall") for w in late["not_taken"])
    # the host's own figures beside the events': the waits that ran to their deadline, how late they
    # woke (never before it), and the machine's steal time over the run
    assert 0 < late["waits"] and 0.0 <= late["wait_p99_s"] <= late["wait_max_s"]
    assert late.get("steal_s", 0.0) >= 0.0
    assert sum(late["late_causes"].values()) == late["late_over_1ms"]  # each late event has a cause
    assert r.signals["armed"][-1] == 1 and r.signals["pwm1"][-1] > 1100
