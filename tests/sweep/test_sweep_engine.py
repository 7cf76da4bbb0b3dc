"""rig sweep's cluster engine at its edges: an address that cannot be one is refused before anything
(it made a half-built Dask Client hang 20 s on its way out, then print a traceback), and a scheduler
with no workers is waited for with a count on stderr, up to --wait-workers (it was waited for forever,
the progress bar saying ×1), then a worker that arrives meanwhile is used."""

from __future__ import annotations

import os
import select
import shutil
import subprocess
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.sweep.test_sweep_cli import end, start, start_scheduler, start_worker, sweep
from tests.waits import BOUND_S

SPEC = '[sweep]\nscenario = "step_roll"\n'


@pytest.mark.parametrize("address", ["banana", "tcp://127.0.0.1:0", "udp://127.0.0.1:8786",
                                     "tcp://127.0.0.1:x", "tcp://:8786", "tcp://h:1/path"])
def test_an_address_that_cannot_be_one_is_exit_2_at_once(tmp_path: Path, address: str) -> None:
    (tmp_path / "s.toml").write_text(SPEC)
    r = sweep(tmp_path / "s.toml", "--out", tmp_path / "out", "--engine", address)
    said = f"--engine: expected tcp://HOST:PORT (or tls://), got {address!r}"
    assert r.returncode == 2 and said in r.stderr
    assert "Traceback" not in r.stderr and not (tmp_path / "out").exists()
    env = {**os.environ, "DASK_SCHEDULER_ADDRESS": address}
    r = sweep(tmp_path / "s.toml", "--out", tmp_path / "out", env=env)
    assert r.returncode == 2 and "DASK_SCHEDULER_ADDRESS: expected tcp://HOST:PORT" in r.stderr


def test_wait_workers_goes_with_a_cluster(tmp_path: Path) -> None:
    (tmp_path / "s.toml").write_text(SPEC)
    r = sweep(tmp_path / "s.toml", "--out", tmp_path / "out", "--wait-workers", "5")
    assert r.returncode == 2 and "--wait-workers goes with a Dask cluster" in r.stderr
    r = sweep(tmp_path / "s.toml", "--out", tmp_path / "out", "--engine", "tcp://127.0.0.1:1",
              "--wait-workers", "-1")
    assert r.returncode == 2 and "--wait-workers" in r.stderr and not (tmp_path / "out").exists()


@pytest.fixture
def scheduler(tmp_path: Path) -> Iterator[tuple[str, Path, list[subprocess.Popen[bytes]]]]:
    """A scheduler with no workers; the test may add some to the list (all ended after)."""
    private = Path(tempfile.mkdtemp(prefix="rig-dask-", dir="/tmp"))
    procs: list[subprocess.Popen[bytes]] = []
    try:
        address, proc = start_scheduler(tmp_path / "scheduler.json", private)
        procs.append(proc)
        yield address, private, procs
    finally:
        end(procs)
        shutil.rmtree(private, ignore_errors=True)


def test_no_workers_is_said_and_waited_for_up_to_the_timeout(
    tmp_path: Path, scheduler: tuple[str, Path, list[subprocess.Popen[bytes]]]
) -> None:
    address = scheduler[0]
    (tmp_path / "s.toml").write_text(SPEC)
    r = sweep(tmp_path / "s.toml", "--out", tmp_path / "out", "--engine", address, "--wait-workers", "1")
    assert r.returncode == 3, r.stderr
    assert f"the Dask scheduler at {address} has no workers: waiting up to 1 s for one" in r.stderr
    assert f"no worker joined the Dask scheduler at {address} in 1 s" in r.stderr
    assert "Traceback" not in r.stderr and "×1" not in r.stderr


def _stderr_until(p: subprocess.Popen[str], marker: str) -> str:
    """What the process wrote on stderr, read until ``marker`` appears (bounded: BOUND_S)."""
    assert p.stderr is not None
    fd, seen, end_at = p.stderr.fileno(), b"", time.monotonic() + BOUND_S
    while marker.encode() not in seen:
        left = end_at - time.monotonic()
        assert left > 0, f"no {marker!r} on stderr: {seen.decode(errors='replace')}"
        if select.select([fd], [], [], left)[0]:
            chunk = os.read(fd, 65536)
            assert chunk, f"stderr closed before {marker!r}: {seen.decode(errors='replace')}"
            seen += chunk
    return seen.decode(errors="replace")


def test_a_worker_that_comes_during_the_wait_flies_the_sweep(
    tmp_path: Path, scheduler: tuple[str, Path, list[subprocess.Popen[bytes]]]
) -> None:
    address, private, procs = scheduler
    (tmp_path / "s.toml").write_text(SPEC)
    p = start(tmp_path / "s.toml", "--out", tmp_path / "out", "--engine", address, "--wait-workers", "300")
    try:
        before = _stderr_until(p, "has no workers: waiting up to 300 s")
        procs.append(start_worker(address, "late", private))
        _, rest = p.communicate(timeout=300)
    finally:
        p.kill()
        p.wait()
    stderr = before + rest
    assert p.returncode == 0, stderr
    assert f"1 worker(s) at {address}: starting" in stderr and "1/1 runs" in stderr
