"""The sandbox every DUT the service starts runs in (rig/sandbox.py): a hostile DUT (hostile_dut.py)
tries each way out, through the service and through ``rig run --sandbox``, and every try fails, while
a normal run under the sandbox still passes."""

from __future__ import annotations

import os
import re
import secrets
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from rig.sandbox import Limits
from tests.service.test_api import start, stop

HOSTILE = Path(__file__).resolve().parent / "hostile_dut.py"
#: the processes the hostile DUT tries to start: more than the sandbox allows
FORKS = 3 * Limits().processes

pytestmark = pytest.mark.skipif(shutil.which("bwrap") is None, reason="needs bubblewrap (make test-packages)")


def listener() -> socket.socket:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    s.listen()
    s.setblocking(False)
    return s


def escapes(stdout: str) -> dict[str, str]:
    return dict(re.findall(r"^escape ([\w-]+): (.*)$", stdout, re.M))


def assert_nothing_escaped(stdout: str, outside: Path, net: socket.socket, token: str) -> None:
    tried = escapes(stdout)
    assert tried["write-outside"].startswith("blocked") and not (outside / "escaped").exists()
    assert tried["network"].startswith("blocked")
    with pytest.raises(BlockingIOError):  # nobody came through
        net.accept()
    started = int(re.search(r"^forks (\d+)$", stdout, re.M).group(1))  # type: ignore[union-attr]
    assert 0 < started < Limits().processes
    assert "seen " in stdout and token not in stdout
    # the limits as the kernel reports them (/proc/self/limits: name, soft limit, hard limit, units)
    limits = {m[0]: int(m[1]) for m in re.findall(r"^limit (Max [a-z ]+?)\s+(\d+)\s", stdout, re.M)}
    want = Limits()
    assert limits["Max cpu time"] == want.cpu_s and limits["Max file size"] == want.file_bytes
    assert limits["Max address space"] == want.memory_bytes and limits["Max processes"] == want.processes
    assert limits["Max realtime timeout"] == want.rt_us


def test_a_hostile_dut_reaches_nothing_through_the_service(tmp_path: Path) -> None:
    data, outside = tmp_path / "data", tmp_path / "outside"
    outside.mkdir()
    token = f"token-{secrets.token_hex(16)}"
    net = listener()
    svc = start(data, "--slots", "1", token=token)
    try:
        first = svc.call("POST", "/api/runs", {"scenarios": ["step_roll"]})[1]
        assert svc.follow(first["id"])["status"] == "passed"  # a normal run passes in the sandbox
        command = f"{sys.executable} {HOSTILE} {data} {outside} {net.getsockname()[1]} {FORKS}"
        body = svc.call("POST", "/api/runs", {"scenarios": ["step_roll"], "dut": {"command": command}})[1]
        svc.follow(body["id"])
    finally:
        stop(svc)
    stdout = (data / "runs" / str(body["id"]) / "step_roll" / "dut-stdout.txt").read_text()
    tried = escapes(stdout)
    assert tried["read-database"].startswith("blocked") and (data / "rig.sqlite").stat().st_size > 0
    assert tried["write-database"].startswith("blocked")
    # only the mount points of its own run folder and of the scenario version it flies
    assert tried["list-data"] in ("['runs']", "['runs', 'scenarios']")
    assert tried["list-runs"] == repr([str(body["id"])])  # the first run's folder is out of sight
    assert_nothing_escaped(stdout, outside, net, token)


def test_rig_run_sandbox_passes_a_normal_run_and_blocks_a_hostile_dut(tmp_path: Path) -> None:
    outside = tmp_path / "outside"
    outside.mkdir()
    token = f"token-{secrets.token_hex(16)}"
    env = {**os.environ, "RIG_TOKEN": token}
    rig = [sys.executable, "-m", "rig.cli", "run", "--sandbox", "step_roll"]
    normal = subprocess.run([*rig, "--out", str(tmp_path / "normal")], capture_output=True, text=True,
                            env=env)
    assert normal.returncode == 0, normal.stderr
    net = listener()
    command = f"{sys.executable} {HOSTILE} {tmp_path / 'data'} {outside} {net.getsockname()[1]} {FORKS}"
    subprocess.run([*rig, "--out", str(tmp_path / "hostile"), "--dut", command], capture_output=True, env=env)
    assert_nothing_escaped((tmp_path / "hostile" / "step_roll" / "dut-stdout.txt").read_text(), outside, net,
                           token)


def test_without_bubblewrap_serve_and_run_sandbox_refuse_with_exit_2(tmp_path: Path) -> None:
    env = {**os.environ, "PATH": str(tmp_path)}  # (no bwrap on it)
    serve = subprocess.run([sys.executable, "-m", "rig.cli", "serve", "--data", str(tmp_path / "data")],
                           capture_output=True, text=True, env=env, timeout=60)
    assert serve.returncode == 2 and "bubblewrap" in serve.stderr and "--no-sandbox" in serve.stderr
    run = subprocess.run([sys.executable, "-m", "rig.cli", "run", "--sandbox", "step_roll", "--out",
                          str(tmp_path / "out")], capture_output=True, text=True, env=env, timeout=60)
    assert run.returncode == 2 and "rig run: --sandbox: the sandbox needs bubblewrap" in run.stderr
    assert not (tmp_path / "out" / "step_roll").exists()
