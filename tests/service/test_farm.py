"""`rig serve --engine`: lockstep runs go to a real Dask cluster on 127.0.0.1 (`dask scheduler`, a `dask
worker` in a process of its own, with another working folder and another TMPDIR), and each run's folder
comes back into the service's data folder as bytes (nothing shared but the machine: the worker's run
lives in its own temporary folder, gone afterwards). A cancelled run stops its DUT on the worker. A
scheduler killed mid-run interrupts that run, says so at /api/health and on the page, and keeps what is
queued queued, across a restart of the service too, until a scheduler is back."""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import sys
import tempfile
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.service.test_api import Service, blocked_dut, post_bytes, start, stop
from tests.sweep.test_sweep_cli import end, start_scheduler, start_worker
from tests.waits import read_pid, wait_file, wait_gone


@dataclass
class Cluster:
    address: str
    port: int
    info: Path
    private: Path  # the cluster's TMPDIR
    elsewhere: Path  # the worker's working folder
    procs: list[subprocess.Popen[bytes]]

    def worker(self, name: str) -> subprocess.Popen[bytes]:
        proc = start_worker(self.address, name, self.private, cwd=self.elsewhere)
        self.procs.append(proc)
        from distributed import Client

        with Client(self.address, timeout=60) as c:
            c.wait_for_workers(sum(p.poll() is None for p in self.procs[1:]), timeout=60)
        return proc


@pytest.fixture
def cluster(tmp_path: Path) -> Iterator[Cluster]:
    """A scheduler and one single-thread worker whose working folder and TMPDIR are not the service's."""
    private = Path(tempfile.mkdtemp(prefix="rig-farm-", dir="/tmp"))  # (AF_UNIX paths stay short)
    elsewhere = tmp_path / "worker-cwd"
    elsewhere.mkdir()
    procs: list[subprocess.Popen[bytes]] = []
    try:
        address, scheduler = start_scheduler(tmp_path / "scheduler.json", private)
        procs.append(scheduler)
        c = Cluster(address, int(address.rsplit(":", 1)[1]), tmp_path / "scheduler.json", private, elsewhere,
                    procs)
        c.worker("w0")
        yield c
    finally:
        end(procs)
        shutil.rmtree(private, ignore_errors=True)


def page(svc: Service) -> str:
    with urllib.request.urlopen(svc.url + "/", timeout=30) as r:
        return str(r.read().decode())


def test_a_service_killed_mid_run_re_attaches_and_the_clusters_results_equal_a_plain_run(
    cluster: Cluster, tmp_path: Path
) -> None:
    """One service killed outright while its run flies on the cluster; the next one re-attaches to it.
    What comes back equals a plain ``rig run`` of the same seed (lockstep: the same values), and a sweep
    submitted to the restarted service flies on the same cluster."""
    svc = start(tmp_path / "data", "--engine", cluster.address)
    try:
        _, body = svc.call("POST", "/api/runs", {"scenarios": ["seed000_roll_stand", "step_roll"], "seed": 3})
        svc.flying(body["id"])  # (published on the cluster: a restart can re-attach to it)
    finally:
        stop(svc, signal.SIGKILL)  # the service dies outright; the run flies on
    svc = start(tmp_path / "data", "--engine", cluster.address)
    try:
        _, sweep = post_bytes(svc, "/api/sweeps", b'[sweep]\nscenario = "step_roll"\nseeds = [0, 1]\n')
        seen = []  # the progress it showed, each change (the long poll answers at each)
        for _ in range(100):
            run = svc.call("GET", f"/api/runs/{body['id']}?wait=30")[1]
            seen.append(run["progress"])
            if run["status"] not in ("queued", "running"):
                break
        assert run["status"] == "passed" and [r["verdict"] for r in run["results"]] == ["pass", "pass"], run
        assert seen == sorted(seen) and seen[-1] == 100.0, seen
        folder = tmp_path / "data" / "runs" / str(body["id"])
        result = json.loads((folder / "step_roll" / "result.json").read_text())
        # flown in the worker's temporary folder, not here: no file system is shared
        assert result["metadata"]["scenario_file"].startswith(str(cluster.private)), result["metadata"]
        plain = subprocess.run([sys.executable, "-m", "rig.cli", "run", "seed000_roll_stand", "step_roll",
                                "--seed", "3", "--out", str(tmp_path / "plain")],
                               capture_output=True, text=True)
        assert plain.returncode == 0, plain.stderr
        for r in run["results"]:
            expected = json.loads((tmp_path / "plain" / r["scenario"] / "result.json").read_text())
            assert [(m["name"], m["value"]) for m in r["measurements"]] == \
                [(m["name"], m["value"]) for m in expected["measurements"]]  # lockstep: the same values
        files = svc.call("GET", f"/api/runs/{body['id']}/artifacts")[1]
        assert {"junit.xml", "rig-run.log", "step_roll/result.json", "step_roll/telemetry.csv"} <= set(files)
        assert not any(f.startswith(".") for f in files)
        swept = svc.follow(sweep["id"])
        assert swept["status"] == "passed", swept
        assert swept["results"][0]["sweep"] == {"pass": 2, "fail": 0, "error": 0}
        swept_files = svc.call("GET", f"/api/runs/{sweep['id']}/artifacts")[1]
        assert {"summary.html", "runs.parquet"} <= set(swept_files)
        health = svc.call("GET", "/api/health")[1]
        engine = health["engine"]
        assert health["status"] == "ok" and engine["connected"] and engine["workers"] == 1
        assert f"the Dask cluster at\n{cluster.address}: 1 worker(s)" in page(svc)
    finally:
        stop(svc)
    assert list(cluster.private.glob("rig-farm-*")) == [] and list(cluster.elsewhere.iterdir()) == []


def test_a_cancelled_run_stops_its_dut_on_the_worker(cluster: Cluster, tmp_path: Path) -> None:
    svc = start(tmp_path / "data", "--engine", cluster.address)
    try:
        command, fifo = blocked_dut(tmp_path)
        _, body = svc.call("POST", "/api/runs", {"scenarios": ["step_roll"], "dut": {"command": command}})
        dut = read_pid(fifo)
        assert svc.call("DELETE", f"/api/runs/{body['id']}")[1]["status"] == "cancelled"
        assert wait_gone(dut)
        assert svc.follow(body["id"])["status"] == "cancelled"
        log = tmp_path / "data" / "runs" / str(body["id"]) / "rig-run.log"
        assert wait_file([log]) == log  # what the stopped run left came back
    finally:
        stop(svc)


def test_a_scheduler_gone_stops_dispatch_and_the_queue_waits_across_a_restart(
    cluster: Cluster, tmp_path: Path
) -> None:
    svc = start(tmp_path / "data", "--engine", cluster.address)
    try:
        command, fifo = blocked_dut(tmp_path)
        _, first = svc.call("POST", "/api/runs", {"scenarios": ["step_roll"], "dut": {"command": command}})
        dut = read_pid(fifo)
        cluster.procs[0].send_signal(signal.SIGKILL)  # the scheduler dies
        cluster.procs[0].wait()
        run = svc.follow(first["id"])
        assert run["status"] == "interrupted" and "Dask scheduler" in run["error"], run
        health = svc.call("GET", "/api/health")[1]
        assert health["status"] == "degraded" and not health["engine"]["connected"], health
        assert health["engine"]["problem"] and cluster.address in health["engine"]["problem"]
        assert "nothing is dispatched, the queue waits" in page(svc)
        _, second = svc.call("POST", "/api/runs", {"scenarios": ["step_roll"]})
        assert svc.call("GET", f"/api/runs/{second['id']}")[1]["position"] == 1
    finally:
        stop(svc)
    cluster.procs[1].kill()  # (the old worker: it may be waiting for its scheduler still)
    assert wait_gone(dut)
    svc = start(tmp_path / "data", "--engine", cluster.address)  # the service restarts meanwhile
    try:
        queued = svc.call("GET", f"/api/runs/{second['id']}")[1]
        assert queued["status"] == "queued" and queued["position"] == 1
        address, scheduler = start_scheduler(cluster.info, cluster.private, cluster.port)
        assert address == cluster.address
        cluster.procs[0] = scheduler
        cluster.worker("w1")
        assert svc.follow(second["id"])["status"] == "passed"  # re-attached: the queue went on
        assert svc.call("GET", "/api/health")[1]["status"] == "ok"
    finally:
        stop(svc)


def test_an_avr_image_on_an_uploaded_board_and_an_errors_words_on_the_cluster(cluster: Cluster,
                                                                             tmp_path: Path) -> None:
    import hashlib

    from tests.service.test_firmware_kinds import avr_image, board_and_image
    from tests.short_scenario import SHORT_BENCH

    image = avr_image()
    svc = start(tmp_path / "data", "--engine", cluster.address)
    try:
        assert post_bytes(svc, "/api/scenarios?name=short", SHORT_BENCH.encode())[0] == 201
        board, fw = board_and_image(svc, image)
        _, body = svc.call("POST", "/api/runs", {"scenarios": ["short"],
                                                 "dut": {"firmware": fw, "board": board}})
        # a program whose interpreter is nowhere: the reason names the service's copy, not the worker's
        script = post_bytes(svc, "/api/firmware", b"#!/nonexistent/interpreter\n")[1]["sha256"]
        _, bad = svc.call("POST", "/api/runs", {"scenarios": ["step_roll"], "dut": {"firmware": script}})
        run = svc.follow(body["id"])
        assert run["status"] == "passed", run
        folder = tmp_path / "data" / "runs" / str(body["id"])
        result = json.loads((folder / "short" / "result.json").read_text())
        assert result["metadata"]["dut_firmware_sha256"] == hashlib.sha256(image.read_bytes()).hexdigest()
        assert result["metadata"]["board"].startswith("my ")  # the uploaded board went with the task
        failed = svc.follow(bad["id"])
        assert failed["status"] == "error", failed
        assert failed["error"] == f"step_roll: command not found: {tmp_path / 'data' / 'firmware' / script}"
        assert str(cluster.private) not in json.dumps(failed)
    finally:
        stop(svc)
