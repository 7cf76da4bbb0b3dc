"""rig sweep stopped by SIGTERM or SIGHUP to its process group (`timeout 5 rig sweep …`, a closed
terminal, `rig serve` cancelling a sweep with killpg): the sweep exits 128+N with every process it
started gone, no run cut short is a row (not then, not later), and a resume flies what is missing into
the table an uninterrupted sweep writes. The Ctrl-C case is in test_sweep_cli.py; step_roll keeps these
short (a run is about a second), and the stopped sweep has one core for its two workers, so that one
of them is waiting for a core when the signal comes."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import pytest

from rig.run_cmd import LIBRARY
from rig.scenarios.sweep import load_sweep
from rig.sweep import store
from rig.sweep.work import ROW, row_files, run_dir
from tests.sweep.test_sweep_cli import TIMEOUT_S, same, sweep, table
from tests.waits import wait_file, wait_gone

SPEC = '[sweep]\nscenario = "step_roll"\nseeds = 8\n'


@pytest.fixture(scope="module")
def whole(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The spec flown without interruption: the table a stopped and resumed sweep must end with."""
    tmp = tmp_path_factory.mktemp("stop")
    (tmp / "spec.toml").write_text(SPEC)
    r = sweep(tmp / "spec.toml", "--out", tmp / "whole", "--jobs", "2")
    assert r.returncode == 0, r.stderr
    return {"spec": tmp / "spec.toml", "table": table(tmp / "whole")}


def group(pgid: int) -> list[int]:
    """The processes of a process group, from /proc (the field after the command's closing bracket)."""
    pids = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        if int(fields[2]) == pgid:
            pids.append(int(stat.parent.name))
    return pids


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP], ids=["SIGTERM", "SIGHUP"])
def test_a_signal_to_the_group_ends_every_worker_and_keeps_no_cut_run(
    whole: dict[str, Any], tmp_path: Path, signum: int
) -> None:
    out = tmp_path / "out"
    variants = load_sweep(whole["spec"], LIBRARY).variants
    rows = [run_dir(out, v.id) / ROW for v in variants]
    for f in rows:
        f.parent.mkdir(parents=True)
    # the sweep's temporary files land here, to see that none is left (in /tmp: a session's socket path
    # must stay under AF_UNIX's 108 bytes); its stderr goes to a file, which a process left behind
    # cannot hold open as it would a pipe
    private = Path(tempfile.mkdtemp(prefix="rig-test-", dir="/tmp"))
    log = tmp_path / "stderr.txt"
    with open(log, "wb") as err:
        p = subprocess.Popen(
            [sys.executable, "-m", "rig.cli", "sweep", whole["spec"], "--out", out, "--jobs", "2"],
            stdout=subprocess.DEVNULL,
            stderr=err,
            start_new_session=True,
            env={**os.environ, "TMPDIR": str(private)},
            # one core for two workers: while one flies, the other waits for the core (a state the
            # signal must end too)
            preexec_fn=lambda: os.sched_setaffinity(0, {min(os.sched_getaffinity(0))}),
        )
    left: list[int] = []
    try:
        assert wait_file(rows) is not None, "no run finished"
        os.killpg(p.pid, signum)  # as `timeout` does, and rig serve's cancel
        assert p.wait(timeout=TIMEOUT_S) == 128 + signum, log.read_text()
        kept = {f: f.stat().st_mtime_ns for f in row_files(out)}
        # every process of the sweep ends by itself (the workers were left blocked until SIGKILL)
        left = [pid for pid in group(p.pid) if not wait_gone(pid)]
        assert left == [], f"processes of the sweep still there: {left}"
        assert list(private.iterdir()) == []
    finally:
        for pid in left:
            os.kill(pid, signal.SIGKILL)
        p.kill()
        p.wait()
        shutil.rmtree(private, ignore_errors=True)
    stderr = log.read_text()
    assert "Traceback" not in stderr and "Error" not in stderr, stderr
    # no row came after the sweep ended, and every row is a run that finished: its report beside it
    assert {f: f.stat().st_mtime_ns for f in row_files(out)} == kept
    assert 1 <= len(kept) < len(variants)
    assert all((f.parent / "result.json").is_file() and (f.parent / "report.html").is_file() for f in kept)
    assert store.read(out / store.TABLE)["verdict"] == ["pass"] * len(kept)
    r = sweep(whole["spec"], "--out", out, "--jobs", "2")
    assert r.returncode == 0, r.stderr
    assert f"{len(kept)} done already, {len(variants) - len(kept)} to run" in r.stderr
    assert same(table(out), whole["table"])
