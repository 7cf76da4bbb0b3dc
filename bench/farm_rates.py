"""The farm's rates (bench, not a test): lockstep runs per minute through `rig serve --engine` with 1 and
2 worker hosts (a `dask worker` of one thread each, on 127.0.0.1: on one machine a "host" is a process),
and the time from submit to start of a bench run on a free bench (`rig bench-host --bridge virtual`):
the run's `started` minus its `created`, which is the service's dispatch (its look every second at the
scheduler) and not the bench's own start-up. Wall-clock figures: they vary with the machine.

    .venv/bin/python bench/farm_rates.py
"""

from __future__ import annotations

import json
import os
import select
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
DASK = Path(sys.executable).parent / "dask"
SCENARIO = "step_roll"
RUNS = 8
BENCH_RUNS = 5


def port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def until(proc: subprocess.Popen[str], words: str, timeout: float = 120) -> None:
    assert proc.stderr is not None
    seen = ""
    while words not in seen:
        ready, _, _ = select.select([proc.stderr], [], [], timeout)
        line = proc.stderr.readline() if ready else ""
        if not line:
            raise SystemExit(f"{proc.args!r} never said {words!r}: {seen}")
        seen += line


def call(url: str, method: str = "GET", body: object = None) -> Any:
    req = urllib.request.Request(url, method=method, data=None if body is None else json.dumps(body).encode(),
                                 headers={"content-type": "application/json"})
    with urllib.request.urlopen(req, timeout=120) as r:
        return json.loads(r.read())


def ended(url: str, run_id: int) -> dict[str, Any]:
    while True:
        run = call(f"{url}/api/runs/{run_id}?wait=30")
        if run["status"] not in ("queued", "running"):
            return dict(run)


def spawn(args: list[str], tmp: Path, log: bool = False) -> subprocess.Popen[str]:
    return subprocess.Popen(args, cwd=REPO, text=True, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE if log else subprocess.DEVNULL,
                            env={**os.environ, "TMPDIR": str(tmp)}, start_new_session=True)


def main() -> int:
    tmp = Path(tempfile.mkdtemp(prefix="farm-bench-", dir="/tmp"))
    procs: list[subprocess.Popen[str]] = []
    try:
        info = tmp / "scheduler.json"
        procs.append(spawn([str(DASK), "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                            "--scheduler-file", str(info)], tmp))
        while not info.exists():
            time.sleep(0.1)
        address = json.loads(info.read_text())["address"]
        http = port()
        svc = spawn([sys.executable, "-m", "rig.cli", "serve", "--port", str(http), "--data",
                     str(tmp / "data"), "--engine", address], tmp, log=True)
        procs.append(svc)
        until(svc, "listening on")
        url = f"http://127.0.0.1:{http}"
        print(f"farm_rates: {RUNS} lockstep runs of {SCENARIO} through rig serve --engine "
              f"({os.cpu_count()} cores)")
        rates = {}
        for hosts in (1, 2):
            procs.append(spawn([str(DASK), "worker", address, "--nthreads", "1", "--no-nanny",
                                "--no-dashboard", "--host", "127.0.0.1"], tmp))
            while call(f"{url}/api/health")["engine"]["threads"] < hosts:
                time.sleep(0.2)
            t0 = time.perf_counter()
            ids = [call(f"{url}/api/runs", "POST", {"scenarios": [SCENARIO], "seed": s})["id"]
                   for s in range(RUNS)]
            statuses = [ended(url, i)["status"] for i in ids]
            wall = time.perf_counter() - t0
            rates[hosts] = RUNS / wall * 60
            passed = statuses.count("passed")
            print(f"  {hosts} worker host(s): {rates[hosts]:6.1f} runs/min ({wall:.1f} s; {passed}/{RUNS} "
                  "passed)")
        print(f"  2 hosts / 1 host: {rates[2] / rates[1]:.2f}x")
        host = spawn([sys.executable, "-m", "rig.cli", "bench-host", "--engine", address, "--bridge",
                      "virtual", "--name", "bench", "--label", "site=here"], tmp, log=True)
        procs.append(host)
        until(host, "joined")
        waits = []
        for _ in range(BENCH_RUNS):
            run_id = call(f"{url}/api/runs", "POST", {"scenarios": ["gust_rejection"], "mode": "bridge",
                                                       "bench": {"site": "here"}})["id"]
            run = ended(url, run_id)
            waits.append(run["started"] - run["created"])
        waits.sort()
        print(f"  submit to start on a free bench: median {waits[len(waits) // 2]:.2f} s, "
              f"max {waits[-1]:.2f} s ({BENCH_RUNS} runs)")
    finally:
        for p in reversed(procs):
            os.killpg(p.pid, signal.SIGTERM)
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
