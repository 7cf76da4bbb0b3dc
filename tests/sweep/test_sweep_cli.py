"""rig sweep end to end: the Show's 2 masses × 3 wind speeds × 4 seeds (of an 8 s hover) through the
local pool and through a Dask cluster the test starts (`dask scheduler`, two `dask worker`s, on
127.0.0.1), one worker killed mid-sweep; a sweep interrupted by Ctrl-C and resumed; errors retried; a
bad spec refused. The runs are lockstep and seeded, so both engines must give the same table, value for
value."""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from rig.run_cmd import LIBRARY
from rig.scenarios.sweep import load_sweep
from rig.sweep import store
from rig.sweep.work import ROW, row_files, run_dir
from tests.sweep import SHOW
from tests.waits import wait_file

TIMEOUT_S = 300


def sweep(*args: str | Path, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "rig.cli", "sweep", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=TIMEOUT_S,
        env=env,
    )


def start(*args: str | Path, env: dict[str, str] | None = None) -> subprocess.Popen[str]:
    """The sweep in its own process group, as a terminal runs it (a Ctrl-C reaches the whole group)."""
    return subprocess.Popen(
        [sys.executable, "-m", "rig.cli", "sweep", *map(str, args)],
        text=True,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,
    )


#: the hover the sweeps here fly: the library's, 8 s instead of 20 (its criteria judge from 5 s on), as the
#: Show's 24 runs are flown four times over in this file
SHORT_HOVER = "duration = 8.0"


@pytest.fixture(scope="module")
def show(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    tmp = tmp_path_factory.mktemp("sweep")
    hover = (LIBRARY / "hover_turbulence.toml").read_text()
    assert "duration = 20.0" in hover
    (tmp / "hover_short.toml").write_text(hover.replace("duration = 20.0", SHORT_HOVER))
    assert 'scenario = "hover_turbulence"' in SHOW
    spec = SHOW.replace('scenario = "hover_turbulence"', 'scenario = "hover_short.toml"')
    (tmp / "show.toml").write_text(spec)
    r = sweep(tmp / "show.toml", "--out", tmp / "local", "--jobs", "2")
    return {"dir": tmp, "spec": tmp / "show.toml", "local": tmp / "local", "run": r}


def table(folder: Path) -> dict[str, list[Any]]:
    t = store.read(folder / store.TABLE)
    return {k: v for k, v in t.items() if k not in ("wall_s", "host")}


def same(a: dict[str, list[Any]], b: dict[str, list[Any]]) -> bool:
    if a.keys() != b.keys():
        return False
    return all(
        x == y or (isinstance(x, float) and math.isnan(x) and math.isnan(y))
        for k in a
        for x, y in zip(a[k], b[k], strict=True)
    )


def test_the_local_pool_writes_the_table_the_summary_and_junit(show: dict[str, Any]) -> None:
    r, out = show["run"], show["local"]
    assert r.returncode in (0, 1), r.stderr
    t = store.read(out / store.TABLE)
    assert len(t["id"]) == 24
    assert list(t)[:8] == [
        "id",
        "vehicle.mass",
        "environment.wind[0]",
        "seed",
        "verdict",
        "error",
        "wall_s",
        "host",
    ]
    assert sorted(zip(t["vehicle.mass"], t["environment.wind[0]"], t["seed"], strict=True)) == sorted(
        (m, w, s) for m in (1.1, 1.3) for w in (0.0, 2.0, 4.0) for s in range(4)
    )
    sw = load_sweep(show["spec"], LIBRARY)
    names = [c.name for c in sw.scenario.criteria]
    assert all(n in t for n in names)  # every measurement is a column
    for i, run_id in enumerate(t["id"]):  # each row is its run's result.json
        res = __import__("json").loads((run_dir(out, run_id) / "result.json").read_text())
        assert res["verdict"] == t["verdict"][i] and res["metadata"]["seed"] == t["seed"][i]
        assert {m["name"]: m["value"] for m in res["measurements"]}[names[0]] == pytest.approx(t[names[0]][i])
    # wind makes a difference: the same mass and seed, another wind, another roll RMS
    by = {
        (m, w, s): v
        for m, w, s, v in zip(
            t["vehicle.mass"], t["environment.wind[0]"], t["seed"], t["roll RMS"], strict=True
        )
    }
    assert by[(1.1, 0.0, 0)] != by[(1.1, 4.0, 0)]
    cases = ET.parse(out / "junit.xml").getroot().iter("testcase")
    assert sorted(c.get("name") or "" for c in cases) == sorted(
        f"vehicle.mass={m} environment.wind[0]={w} seed={s}"
        for m in (1.1, 1.3)
        for w in ("0", "2", "4")
        for s in range(4)
    )
    page = (out / "summary.html").read_text()
    assert "pass rate against <code>vehicle.mass</code>" in page and page.count("<svg") == len(names)
    for link in [x.split('"')[0] for x in page.split('href="runs/')[1:]]:
        assert (out / "runs" / link).is_file(), link
    assert not (out / ".slots").exists()  # the core-slot locks went with the sweep


DASK = Path(sys.executable).parent / "dask"


def scheduler_file_written(info: Path) -> bool:
    """The scheduler file is created before its JSON is written: it is there once the JSON is whole."""
    try:
        return "address" in json.loads(info.read_text())
    except (FileNotFoundError, ValueError):
        return False


def start_scheduler(info: Path, private: Path, port: int = 0) -> tuple[str, subprocess.Popen[bytes]]:
    """A Dask scheduler on loopback (its address from its scheduler file)."""
    info.unlink(missing_ok=True)
    proc = subprocess.Popen(
        [DASK, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard", "--scheduler-file",
         info],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env={**os.environ, "TMPDIR": str(private)},
    )
    if wait_file([info], ready=scheduler_file_written) != info:
        proc.kill()
        proc.wait()
        raise AssertionError("the scheduler did not start")
    address = json.loads(info.read_text())["address"]
    assert address.startswith("tcp://127.0.0.1:")
    return address, proc


def start_worker(address: str, name: str, private: Path, cwd: Path | None = None) -> subprocess.Popen[bytes]:
    """A single-thread worker, no nanny (a killed worker stays dead); ``cwd``: where it runs."""
    return subprocess.Popen(
        [DASK, "worker", address, "--nthreads", "1", "--no-nanny", "--no-dashboard", "--host", "127.0.0.1",
         "--name", name],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env={**os.environ, "TMPDIR": str(private)},
        cwd=cwd,
    )


def end(procs: list[subprocess.Popen[bytes]]) -> None:
    """The workers first (a worker whose scheduler is gone waits for it before it stops)."""
    for p in reversed(procs):
        p.terminate()
        try:
            p.wait(timeout=30)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait(timeout=30)


@pytest.fixture
def cluster(tmp_path: Path) -> Iterator[tuple[str, list[subprocess.Popen[bytes]]]]:
    """A Dask scheduler and two single-thread workers (no nanny: a killed worker stays dead) on loopback."""
    # the cluster's temporary files (its scratch space too), removed at the end: the worker the test
    # kills cannot remove its run's session folder (in /tmp: a session's socket path must stay under
    # AF_UNIX's 108 bytes)
    private = Path(tempfile.mkdtemp(prefix="rig-dask-", dir="/tmp"))
    procs: list[subprocess.Popen[bytes]] = []
    try:
        address, scheduler = start_scheduler(tmp_path / "scheduler.json", private)
        procs.append(scheduler)
        procs += [start_worker(address, f"w{n}", private) for n in range(2)]
        from distributed import Client

        with Client(address, timeout=60) as c:
            c.wait_for_workers(2, timeout=60)
        yield address, procs
    finally:
        end(procs)
        shutil.rmtree(private, ignore_errors=True)


def test_a_dask_cluster_gives_the_same_table_with_a_worker_killed_mid_sweep(
    show: dict[str, Any], cluster: tuple[str, list[subprocess.Popen[bytes]]], tmp_path: Path
) -> None:
    address, procs = cluster
    out = tmp_path / "dask"
    first = [run_dir(out, v.id) / ROW for v in load_sweep(show["spec"], LIBRARY).variants[:2]]
    for f in first:
        f.parent.mkdir(parents=True)
    p = start(show["spec"], "--out", out, "--engine", address)
    try:
        assert wait_file(first) is not None, "no run finished"
        procs[1].kill()  # a worker dies mid-sweep: the scheduler gives its runs to the other one
        stdout, stderr = p.communicate(timeout=TIMEOUT_S)
    finally:
        p.kill()
    assert p.returncode == show["run"].returncode, stderr
    assert "24/24 runs" in stderr and address in stderr
    assert same(table(out), table(show["local"]))


def test_an_interrupted_sweep_keeps_what_finished_and_a_resume_runs_only_the_rest(
    show: dict[str, Any], tmp_path: Path
) -> None:
    out = tmp_path / "resume"
    variants = load_sweep(show["spec"], LIBRARY).variants
    first = [run_dir(out, v.id) / ROW for v in variants[:2]]
    for f in first:
        f.parent.mkdir(parents=True)
    # the sweep's temporary files land here, to see that none is left (in /tmp: a session's socket path
    # must stay under AF_UNIX's 108 bytes)
    private = Path(tempfile.mkdtemp(prefix="rig-test-", dir="/tmp"))
    p = start(show["spec"], "--out", out, "--jobs", "2", env={**os.environ, "TMPDIR": str(private)})
    try:
        assert wait_file(first) is not None, "no run finished"
        os.killpg(p.pid, signal.SIGINT)  # Ctrl-C: the terminal signals the whole group
        _, stderr = p.communicate(timeout=TIMEOUT_S)
    finally:
        p.kill()
    assert p.returncode == 130, stderr
    kept = {
        v.id: (run_dir(out, v.id) / ROW).stat().st_mtime_ns
        for v in variants
        if (run_dir(out, v.id) / ROW).exists()
    }
    assert 1 <= len(kept) < 24 and len(store.read(out / store.TABLE)["id"]) == len(kept)
    assert "Traceback" not in stderr and "runs not done" in (out / "summary.html").read_text()
    assert list(private.iterdir()) == []
    private.rmdir()
    r = sweep(show["spec"], "--out", out, "--jobs", "2")
    assert r.returncode == show["run"].returncode, r.stderr
    assert f"{len(kept)} done already, {24 - len(kept)} to run" in r.stderr
    assert {k: (run_dir(out, k) / ROW).stat().st_mtime_ns for k in kept} == kept  # not flown again
    assert same(table(out), table(show["local"]))


def test_errors_are_kept_and_flown_again_with_retry_errors(tmp_path: Path) -> None:
    spec = tmp_path / "s.toml"
    spec.write_text('[sweep]\nscenario = "step_roll"\nseeds = [3, 5]\n')
    out = tmp_path / "out"
    r = sweep(spec, "--out", out, "--dut", "/bin/false")  # a DUT that never flies: an error each
    assert r.returncode == 3 and "2 error" in r.stderr
    t = store.read(out / store.TABLE)
    assert t["verdict"] == ["error", "error"] and t["seed"] == [3, 5] and all(t["error"])
    rows = {f: f.stat().st_mtime_ns for f in row_files(out)}
    r = sweep(spec, "--out", out, "--dut", "/bin/false")
    assert "2 done already, 0 to run" in r.stderr and r.returncode == 3
    r = sweep(spec, "--out", out, "--dut", "/bin/false", "--retry-errors")
    assert "0 done already, 2 to run" in r.stderr and r.returncode == 3, r.stderr
    assert all(f.stat().st_mtime_ns != t for f, t in rows.items())  # flown again
    # another DUT (the reference FC) needs --fresh (tests/sweep/test_sweep_dut.py)
    r = sweep(spec, "--out", out, "--fresh")
    assert "0 done already, 2 to run" in r.stderr and r.returncode == 0, r.stderr
    assert store.read(out / store.TABLE)["verdict"] == ["pass", "pass"]


def test_a_bad_spec_is_exit_2_with_nothing_written(tmp_path: Path) -> None:
    spec = tmp_path / "s.toml"
    spec.write_text(
        '[sweep]\nscenario = "step_roll"\n[[sweep.vary]]\nkey = "vehicle.mass"\nvalues = [1.2, -1]\n'
    )
    r = sweep(spec, "--out", tmp_path / "out")
    assert r.returncode == 2 and "variant vehicle.mass = -1" in r.stderr and not (tmp_path / "out").exists()
    r = sweep(spec, "--out", tmp_path / "out", "--jobs", "0")
    assert r.returncode == 2 and "--jobs" in r.stderr


def test_an_engine_that_is_not_there_is_a_clear_error(tmp_path: Path) -> None:
    spec = tmp_path / "s.toml"
    spec.write_text('[sweep]\nscenario = "step_roll"\n')
    import socket

    with socket.socket() as s:  # a loopback port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    r = sweep(spec, "--out", tmp_path / "out", "--engine", f"tcp://127.0.0.1:{port}")
    assert r.returncode == 3 and "no Dask scheduler at" in r.stderr and "Traceback" not in r.stderr
    # the same through the environment, as Dask's own tools take it
    r = sweep(spec, "--out", tmp_path / "out", env={**os.environ, "DASK_SCHEDULER_ADDRESS": f"tcp://127.0.0.1:{port}"})
    assert r.returncode == 3 and f"no Dask scheduler at tcp://127.0.0.1:{port}" in r.stderr
