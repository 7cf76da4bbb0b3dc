"""A farm's benches on one machine: a real `dask scheduler` on 127.0.0.1, two `rig bench-host`s (each a
Dask worker in its own process, with a virtual bridge probed at start, and labels) and `rig serve
--engine`. A bench run's selector lands it on the bench with those labels; a selector no bench matches
is refused at once with the labels known; a bench taken out (`rig bench disable`) keeps its runs
queued while the other bench's go on, and takes them once put back; a bench host killed mid-run leaves
that run interrupted (never flown again) while the other bench's run passes."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.service.test_api import Service, start, stop, until_line
from tests.sweep.test_sweep_cli import end, start_scheduler

pytestmark = pytest.mark.slow  # (~90 s: bench runs fly in real time)

QUICK = "gust_rejection"  # (1 s of flight: a bench run is real time)


@dataclass
class Farm:
    address: str
    hosts: dict[str, subprocess.Popen[str]]
    procs: list[subprocess.Popen[bytes]]
    svc: Service


def bench_host(address: str, name: str, private: Path, *labels: str) -> subprocess.Popen[str]:
    args = [sys.executable, "-m", "rig.cli", "bench-host", "--engine", address, "--bridge", "virtual",
            "--name", name, "--host", "127.0.0.1"]
    for label in labels:
        args += ["--label", label]
    proc = subprocess.Popen(args, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True,
                            start_new_session=True, env={**os.environ, "TMPDIR": str(private)})
    until_line(proc, "joined")
    drain(proc)
    return proc


def drain(proc: subprocess.Popen[str]) -> None:
    """Its stderr read to the end in a thread of its own: Dask's log lines never fill the pipe."""
    assert proc.stderr is not None
    threading.Thread(target=proc.stderr.read, daemon=True).start()


@pytest.fixture
def farm(tmp_path: Path) -> Iterator[Farm]:
    private = Path(tempfile.mkdtemp(prefix="rig-farm-", dir="/tmp"))
    procs: list[subprocess.Popen[bytes]] = []
    hosts: dict[str, subprocess.Popen[str]] = {}
    svc = None
    try:
        address, scheduler = start_scheduler(tmp_path / "scheduler.json", private)
        procs.append(scheduler)
        hosts["a"] = bench_host(address, "a", private, "site=x", "kind=f4")
        hosts["b"] = bench_host(address, "b", private, "site=y,kind=f4")
        svc = start(tmp_path / "data", "--engine", address)
        yield Farm(address, hosts, procs, svc)
    finally:
        if svc is not None:
            stop(svc)
        for p in hosts.values():
            p.kill()
            p.wait()
        end(procs)
        shutil.rmtree(private, ignore_errors=True)


def rig(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rig.cli", *args], capture_output=True, text=True,
                          timeout=60)


def test_selectors_maintenance_and_a_bench_host_killed_mid_run(farm: Farm) -> None:
    svc = farm.svc
    status, body = svc.call("POST", "/api/runs", {"scenarios": [QUICK], "mode": "bridge",
                                                  "bench": {"site": "z"}})
    assert status == 422, body
    [problem] = body["detail"]["problems"]
    assert "no bench has the labels site=z" in problem and "a: kind=f4,site=x; b: kind=f4,site=y" in problem
    r = rig("submit", "--server", svc.url, QUICK, "--bench", "site=y", "--wait")
    assert r.returncode == 0, r.stderr
    run_id = int(r.stdout)
    done = svc.call("GET", f"/api/runs/{run_id}")[1]
    assert done["status"] == "passed" and done["bench_name"] == "b" and done["bench"] == {"site": "y"}
    # a taken out: its run waits (position 1) while b's, queued after it, flies
    r = rig("bench", "--server", svc.url, "disable", "a")
    assert r.returncode == 0 and r.stdout.startswith("a: maintenance"), r.stdout + r.stderr
    _, waits = svc.call("POST", "/api/runs", {"scenarios": [QUICK], "mode": "bridge", "bench": {"site": "x"}})
    _, goes = svc.call("POST", "/api/runs", {"scenarios": [QUICK], "mode": "bridge", "bench": {"kind": "f4"}})
    assert svc.follow(goes["id"])["bench_name"] == "b"
    queued = svc.call("GET", f"/api/runs/{waits['id']}")[1]
    assert queued["status"] == "queued" and queued["position"] == 1
    with urllib.request.urlopen(svc.url + "/", timeout=30) as page:
        html = page.read().decode()
    assert "<td>a</td><td class=\"\">maintenance" in html and "put back" in html
    # its page: its place, its selector, and the bench it waits for with that bench's state
    with urllib.request.urlopen(f"{svc.url}/runs/{waits['id']}", timeout=30) as page:
        html = page.read().decode()
    assert "position 1 in the bench queue" in html and '<code id="selector">site=x</code>' in html
    assert 'waits for <span id="waits">a bench: a (maintenance)</span>' in html
    assert rig("bench", "--server", svc.url, "enable", "a").returncode == 0
    back = svc.follow(waits["id"])
    assert back["status"] == "passed" and back["bench_name"] == "a", back
    # a's host dies mid-run: that run is interrupted, b's goes on
    _, doomed = svc.call("POST", "/api/runs", {"scenarios": ["step_roll"], "mode": "bridge",
                                               "bench": {"site": "x"}})
    _, other = svc.call("POST", "/api/runs", {"scenarios": ["step_roll"], "mode": "bridge",
                                              "bench": {"site": "y"}})
    svc.until(doomed["id"], "running")
    farm.hosts["a"].send_signal(signal.SIGKILL)
    gone = svc.follow(doomed["id"])
    assert gone["status"] == "interrupted" and "not run again" in gone["error"], gone
    assert svc.follow(other["id"])["status"] == "passed"
    benches = {b["name"]: b["state"] for b in svc.call("GET", "/api/benches")[1]}
    assert benches == {"a": "offline", "b": "free"}
    # a second bench host under a name taken: one line naming the clash and --name, exit 2
    clash = rig("bench-host", "--engine", farm.address, "--bridge", "virtual", "--name", "b")
    assert clash.returncode == 2 and clash.stderr.count("\n") == 1, clash.stderr
    assert "a bench named 'b' already" in clash.stderr and "--name" in clash.stderr
    # the scheduler dies: what was seen of the benches is no news of them now
    _, last = svc.call("POST", "/api/runs", {"scenarios": ["step_roll"], "mode": "bridge",
                                             "bench": {"site": "y"}})
    svc.until(last["id"], "running")
    farm.procs[0].send_signal(signal.SIGKILL)
    assert svc.follow(last["id"])["status"] == "interrupted"
    assert svc.call("GET", "/api/health")[1]["status"] == "degraded"
    benches = {b["name"]: b["state"] for b in svc.call("GET", "/api/benches")[1]}
    assert benches == {"a": "unknown", "b": "unknown"}
    listed = rig("bench", "--server", svc.url, "list")
    assert listed.returncode == 0 and [line.split(":")[1].split()[0] for line in listed.stdout.splitlines()] \
        == ["unknown", "unknown"] and "free" not in listed.stdout, listed.stdout
    with urllib.request.urlopen(svc.url + "/", timeout=30) as page:
        html = page.read().decode()
    assert ">unknown<" in html.replace("\n", "") and ">free<" not in html.replace("\n", "")
