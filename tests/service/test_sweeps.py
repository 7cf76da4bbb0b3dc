"""POST /api/sweeps on a real `rig serve` (uvicorn on 127.0.0.1): a spec is checked whole before it is
queued (the checker's words in a 422; a scenario only by name, never a path), runs as one job of a
lockstep slot, and gives the same table as `rig sweep` of the same spec; its page shows the summary."""

from __future__ import annotations

import json
import subprocess
import sys
import urllib.error
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from rig.sweep import store
from tests.service.test_api import Service, post_bytes, start, stop
from tests.waits import BOUND_S

SPEC = """
[sweep]
scenario = "step_roll"
seeds = [0, 1]

[[sweep.vary]]
key = "vehicle.mass"
values = [1.1, 1.3]
"""


@pytest.fixture
def service(tmp_path: Path) -> Iterator[Service]:
    svc = start(tmp_path / "data", "--slots", "1")
    yield svc
    stop(svc)


def get(svc: Service, path: str) -> tuple[int, bytes]:
    try:
        with urllib.request.urlopen(svc.url + path, timeout=BOUND_S) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as e:
        return e.code, e.read()


def test_a_sweep_runs_as_a_job_and_equals_rig_sweep(service: Service, tmp_path: Path) -> None:
    status, body = post_bytes(service, "/api/sweeps", SPEC.encode())
    assert status == 201 and body["runs"] == 4 and body["scenario"] == "step_roll", body
    run = service.follow(body["id"])
    assert run["status"] == "passed" and run["mode"] == "sweep" and run["progress"] == 100.0, run
    assert run["results"][0]["sweep"] == {"pass": 4, "fail": 0, "error": 0}
    assert [s["id"] for s in service.call("GET", "/api/sweeps")[1]] == [body["id"]]
    code, parquet = get(service, f"/api/runs/{body['id']}/artifacts/runs.parquet")
    assert code == 200
    (tmp_path / "served.parquet").write_bytes(parquet)
    (tmp_path / "spec.toml").write_text(SPEC)
    plain = subprocess.run([sys.executable, "-m", "rig.cli", "sweep", str(tmp_path / "spec.toml"), "--out",
                            str(tmp_path / "plain")], capture_output=True, text=True, timeout=300)
    assert plain.returncode == 0, plain.stderr

    def table(p: Path) -> dict[str, list[Any]]:
        return {k: v for k, v in store.read(p).items() if k not in ("wall_s", "host")}

    assert table(tmp_path / "served.parquet") == table(tmp_path / "plain" / store.TABLE)
    code, summary = get(service, f"/api/runs/{body['id']}/artifacts/summary.html")
    assert code == 200 and b"pass rate against <code>vehicle.mass</code>" in summary
    code, page = get(service, f"/runs/{body['id']}")
    assert code == 200 and f'src="/api/runs/{body["id"]}/artifacts/summary.html"'.encode() in page
    assert b"4 pass, 0 fail, 0 error" in page
    # a sweep reads as what it sweeps, never as its spec's path on the server, nor as "seed 0"
    label = f"sweep of step_roll@{body['sha256'][:8]}"
    assert run["label"] == label and label.encode() in page and b"seed 0" not in page
    code, index = get(service, "/")
    assert code == 200 and label.encode() in index and b"/sweeps/" not in index
    assert f'{label}</td><td></td>'.encode() in index  # (no seed: the spec's seeds)
    listed = subprocess.run([sys.executable, "-m", "rig.cli", "status", "--server", service.url,
                             str(body["id"])], capture_output=True, text=True, timeout=60)
    assert listed.stdout.strip() == f"run {body['id']}: passed 100 % — {label}: 4 pass, 0 fail, 0 error"


@pytest.mark.parametrize("spec, words", [
    (b'[sweep]\nscenario = "step_roll"\n[[sweep.vary]]\nkey = "vehicle.mass"\nvalues = [1.2, -1]\n',
     "variant vehicle.mass = -1"),
    (b'[sweep]\nscenario = "../../../etc/passwd.toml"\n', "no scenario named"),
    (b'[sweep]\nscenario = "no_such_scenario"\n', "no scenario named"),
    (b"[sweep\n", "not valid TOML"),
    (b"", "sweep"),
])
def test_a_bad_spec_is_refused_before_it_is_queued(service: Service, spec: bytes, words: str) -> None:
    status, body = post_bytes(service, "/api/sweeps", spec)
    assert status == 422 and words in json.dumps(body), body
    assert service.call("GET", "/api/sweeps")[1] == []
    stored = service.data / "sweeps"
    assert not stored.exists() or list(stored.iterdir()) == []  # a refused spec is not kept
