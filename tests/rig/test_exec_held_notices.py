"""In lockstep the shim holds a process's notices (PWM writes, a sleep that went ahead) until its next
message, so a control loop's cycle wakes the session once. A process may never send another: it ends,
becomes another program, or starts one and waits. Each way of leaving right after a PWM write must
still deliver that write, stamped as when it was made: the same log as a program that sends a request
after it (``sleep``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.rig.helpers import build_client, rig_exec

LEAVINGS = ["return", "_exit", "execl", "execle", "execvp", "posix_spawnp", "fork", "vfork", "system"]


@pytest.fixture(scope="module")
def dut(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_client(tmp_path_factory, "pwm_then_leave")


def pwm_lines(tmp_path: Path, dut: Path, how: str) -> list[str]:
    log = tmp_path / f"log-{how}"
    run = rig_exec(tmp_path, str(dut), how, options=("--log", str(log)))
    assert run.returncode == 0, run.stderr
    return [line for line in log.read_text().splitlines() if " pwm0 " in line]


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory, dut: Path) -> list[str]:
    lines = pwm_lines(tmp_path_factory.mktemp("reference"), dut, "sleep")
    assert lines[-1] == "0.010000000 c1 pwm0 duty_cycle 1700000"  # after the 10 ms sleep
    assert len(lines) == 5
    return lines


@pytest.mark.parametrize("how", LEAVINGS)
def test_a_pwm_write_reaches_the_session_however_the_process_leaves(
        tmp_path: Path, dut: Path, reference: list[str], how: str) -> None:
    assert pwm_lines(tmp_path, dut, how) == reference
