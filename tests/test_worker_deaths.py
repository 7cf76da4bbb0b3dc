"""tests/worker_deaths.py: a pytest-xdist worker that dies says how, and where it was, in the log (in a
child pytest on two workers, whose test ends its own worker)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.api.test_pytest_plugin import own_env

REPO = Path(__file__).resolve().parents[1]

DYING = '''
import os, signal

def test_a_worker_that_ends_itself():
    os.kill(os.getpid(), signal.{sig})

def test_another_one_that_passes():
    pass
'''


@pytest.mark.parametrize("sig", ["SIGTERM", "SIGKILL"])
def test_a_dead_workers_signal_and_stack_are_in_the_log(tmp_path: Path, sig: str) -> None:
    (tmp_path / "test_dying.py").write_text(DYING.format(sig=sig))
    env = {**own_env(), "PYTHONPATH": str(REPO)}
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "tests.worker_deaths",
           "--rootdir", str(tmp_path), "-n", "2", "test_dying.py"]
    done = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    log = done.stdout + done.stderr
    assert done.returncode == 1, log
    assert "1 failed, 1 passed" in log, log
    assert f") was killed by {sig}: Not properly terminated" in log, log
    # a signal that can be caught shows where the worker was; SIGKILL cannot be
    assert ('in test_a_worker_that_ends_itself' in log) == (sig == "SIGTERM"), log
    assert not [p for p in os.listdir(tmp_path) if p.startswith("core")]
