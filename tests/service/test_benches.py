"""A farm's benches on one machine: a real `dask scheduler` on 127.0.0.1, two `rig bench-host`s (each a
Dask worker in its own process, with a virtual bridge probed at start, and labels) and `rig serve
--engine`. A bench run's selector lands it on the bench with those labels; a selector no bench matches
is refused at once with the labels known; a bench taken out (`rig bench disable`) keeps its runs
queued while the other bench's go on, and takes them once put back; a bench host killed mid-run leaves
that run interrupted (never flown again) while the other bench's run passes.

Where a run goes is judged in the default run: a bench run's flight is real time, so those tests take
any verdict of a flight that ended. That a bench run through the farm passes is judged only by the
paced test, after the host's lateness (tests/realtime.py)."""

from __future__ import annotations

import json
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
from typing import Any

import pytest

from tests.realtime import realtime
from tests.service.test_api import Service, post_bytes, start, stop, until_line
from tests.short_scenario import SHORT_BENCH
from tests.sweep.test_sweep_cli import end, start_scheduler

#: the scenario the bench runs fly (a bench run is real time: 2.5 s of flight), uploaded by the fixture
QUICK = "short_bench"


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
        assert post_bytes(svc, f"/api/scenarios?name={QUICK}", SHORT_BENCH.encode())[0] == 201
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


def ended_on(svc: Service, run_id: int, bench: str) -> dict[str, Any]:
    """The run, followed to its end, which must be a flight on ``bench`` that ended with its verdicts
    (pass or fail: the host's pace is not judged here, the paced test below judges the verdict)."""
    run = svc.follow(run_id)
    assert run["bench_name"] == bench, run
    assert run["status"] in ("passed", "failed") and [r["verdict"] for r in run["results"]] in (
        [["pass"], ["fail"]]), run
    return run


def judged_bench_run(svc: Service, scenario: str, selector: dict[str, str],
                     first: int | None = None) -> dict[str, Any]:
    """A bench run of ``scenario`` on the bench ``selector`` names, followed to its end, judged only when
    the host kept pace (tests/realtime.py): ``first`` is a run already queued, flown again if it was
    starved."""
    queued = [] if first is None else [first]
    body = {"scenarios": [scenario], "mode": "bridge", "bench": selector}

    def fly() -> dict[str, Any]:
        run_id = queued.pop() if queued else svc.call("POST", "/api/runs", body)[1]["id"]
        return svc.follow(run_id)

    def lateness(run: dict[str, Any]) -> dict[str, dict[str, Any]]:
        f = svc.data / "runs" / str(run["id"]) / scenario / "result.json"
        if not f.is_file():
            return {}  # no result: the caller's assertions say what the run did
        return {f"bench run {run['id']}": json.loads(f.read_text())["metadata"].get("realtime_lateness", {})}

    return realtime(fly, lateness)


def test_selectors_choose_the_bench_and_a_disabled_bench_keeps_its_runs_queued(farm: Farm) -> None:
    svc = farm.svc
    status, body = svc.call("POST", "/api/runs", {"scenarios": [QUICK], "mode": "bridge",
                                                  "bench": {"site": "z"}})
    assert status == 422, body
    [problem] = body["detail"]["problems"]
    assert "no bench has the labels site=z" in problem and "a: kind=f4,site=x; b: kind=f4,site=y" in problem
    assert svc.call("GET", "/api/runs")[1] == []  # nothing was queued
    assert rig("submit", "--server", svc.url, QUICK, "--bench", "site=z").returncode == 2
    # a taken out: its run (given by rig submit --bench) waits while the run queued after it flies on b
    r = rig("bench", "--server", svc.url, "disable", "a")
    assert r.returncode == 0 and r.stdout.startswith("a: maintenance"), r.stdout + r.stderr
    r = rig("submit", "--server", svc.url, QUICK, "--bench", "site=x")
    assert r.returncode == 0, r.stderr
    waits = int(r.stdout)
    _, goes = svc.call("POST", "/api/runs", {"scenarios": [QUICK], "mode": "bridge", "bench": {"kind": "f4"}})
    assert svc.until(goes["id"], "running")["bench_name"] == "b"
    queued = svc.call("GET", f"/api/runs/{waits}")[1]
    assert queued["status"] == "queued" and queued["position"] == 1 and queued["bench"] == {"site": "x"}
    assert {b["name"]: b["state"] for b in svc.call("GET", "/api/benches")[1]}["a"] == "maintenance"
    with urllib.request.urlopen(svc.url + "/", timeout=30) as page:
        html = page.read().decode()
    assert "<td>a</td><td class=\"\">maintenance" in html and "put back" in html
    # its page: its place, its selector, and the bench it waits for with that bench's state
    with urllib.request.urlopen(f"{svc.url}/runs/{waits}", timeout=30) as page:
        html = page.read().decode()
    assert "position 1 in the bench queue" in html and '<code id="selector">site=x</code>' in html
    assert 'waits for <span id="waits">a bench: a (maintenance)</span>' in html
    r = rig("bench", "--server", svc.url, "enable", "a")
    assert r.returncode == 0, r.stdout + r.stderr
    assert ended_on(svc, waits, "a")["mode"] == "bridge"  # put back, it takes its run
    ended_on(svc, goes["id"], "b")


# paced: its bench runs' verdicts are judged, so it runs in make test's second part, alone; a bench run
# starved by the host (twice) makes the test inconclusive, never a failure of the run
@pytest.mark.paced
def test_a_bench_host_killed_mid_run_interrupts_its_run_and_the_other_bench_passes(farm: Farm) -> None:
    svc = farm.svc
    _, doomed = svc.call("POST", "/api/runs", {"scenarios": ["step_roll"], "mode": "bridge",
                                               "bench": {"site": "x"}})
    _, other = svc.call("POST", "/api/runs", {"scenarios": [QUICK], "mode": "bridge", "bench": {"site": "y"}})
    svc.flying(doomed["id"])
    farm.hosts["a"].send_signal(signal.SIGKILL)  # (its run has 10 s of flight in real time)
    gone = svc.follow(doomed["id"])
    assert gone["status"] == "interrupted" and "not run again" in gone["error"], gone
    done = judged_bench_run(svc, QUICK, {"site": "y"}, other["id"])
    assert done["status"] == "passed" and done["bench_name"] == "b", done
    benches = {b["name"]: b["state"] for b in svc.call("GET", "/api/benches")[1]}
    assert benches == {"a": "offline", "b": "free"}


def test_a_scheduler_gone_leaves_the_benches_unknown(farm: Farm) -> None:
    svc = farm.svc
    # the scheduler dies: what was seen of the benches is no news of them now
    _, last = svc.call("POST", "/api/runs", {"scenarios": ["step_roll"], "mode": "bridge",
                                             "bench": {"site": "y"}})  # (10 s of flight in real time)
    svc.flying(last["id"])
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


def test_a_bench_name_taken_is_one_line(farm: Farm) -> None:
    """The refusal must leave the farm as it was: while this was written the scheduler was once seen
    gone after it, under a heavily loaded host (not reproduced since: 4 of 4 runs), hence the checks
    after the refusal."""
    # a second bench host under a name taken: one line naming the clash and --name, exit 2
    clash = rig("bench-host", "--engine", farm.address, "--bridge", "virtual", "--name", "b")
    assert clash.returncode == 2 and clash.stderr.count("\n") == 1, clash.stderr
    assert "a bench named 'b' already" in clash.stderr and "--name" in clash.stderr
    # and the farm is as it was: the scheduler answers, both benches are there and free
    health = farm.svc.call("GET", "/api/health")[1]
    assert health["status"] == "ok", health
    benches = {b["name"]: b["state"] for b in farm.svc.call("GET", "/api/benches")[1]}
    assert benches == {"a": "free", "b": "free"}, benches
