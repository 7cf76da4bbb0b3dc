"""Real-time priorities and mlockall: in lockstep accepted and recorded (the run's log and notes), not
applied, since the rig's rule decides which thread runs; in real time applied as the kernel permits."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from tests.rig.helpers import build_client, rig_exec

RECORDED = "priority recorded, not applied (lockstep schedules the threads): "


@pytest.fixture(scope="module")
def dut(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_client(tmp_path_factory, "priorities", "-pthread")


def lines(text: str) -> dict[str, str]:
    return dict(line.split(" ", 1) for line in text.splitlines())


def test_lockstep_accepts_and_records_but_does_not_apply(tmp_path: Path, dut: Path) -> None:
    log = tmp_path / "log"
    run = rig_exec(tmp_path, str(dut), options=("--allow-no-devices", "--log", str(log)))
    assert run.returncode == 0, run.stderr
    out = lines(run.stdout)
    assert out["mlockall"] == out["sched_setscheduler"] == out["pthread_create_fifo"] == "0"
    assert out["pthread_setschedparam_rr"] == "0"
    assert out["sched_setscheduler_out_of_range"] == "EINVAL"    # SCHED_FIFO's range is 1..99
    assert out["main_policy"] == out["timer_thread_policy"] == "SCHED_OTHER"   # not applied
    assert run.summary["notes"] == [
        "mlockall recorded, not applied (lockstep: no real deadline to miss)",
        RECORDED + "sched_setscheduler SCHED_FIFO priority 12 for thread 'main-loop'",
        RECORDED + "pthread_create SCHED_FIFO priority 15 for a thread created by 'main-loop'",
        RECORDED + "pthread_setschedparam SCHED_RR priority 10 for thread 'main-loop'"]
    logged = [line.split(" note: ", 1)[1] for line in log.read_text().splitlines() if " note: " in line]
    assert logged == run.summary["notes"]


def test_real_time_applies_them_as_the_kernel_does(tmp_path: Path, dut: Path) -> None:
    without_rig = subprocess.run([str(dut)], capture_output=True, text=True, check=True).stdout
    run = rig_exec(tmp_path, str(dut), options=("--allow-no-devices", "--realtime"))
    assert run.returncode == 0, run.stderr
    assert lines(run.stdout) == lines(without_rig)
    assert run.summary["notes"] == []
