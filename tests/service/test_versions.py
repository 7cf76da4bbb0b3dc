"""Uploaded scenarios are versions, on a real `rig serve` (uvicorn on 127.0.0.1): a name points at a
version (its SHA-256); a different file under a taken name is a 409 unless `?replace=true`, the same
bytes again are no error; a run, or a sweep, queued before the name is pointed elsewhere flies the
version it was queued with; a sweep of an uploaded name flies it; history and trends tell versions
apart. Runs stay queued behind a run whose DUT blocks on the only slot until it is cancelled (no
sleeps)."""

from __future__ import annotations

import hashlib
import json
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from rig.service.db import Db
from rig.service.store import Store
from rig.sweep import store as sweep_store
from tests.browser import chromium_page
from tests.service.test_api import SHORT, Service, blocked_dut, post_bytes, start, stop
from tests.waits import BOUND_S, read_pid, wait_gone

FIRST = SHORT.encode()
SECOND = SHORT.replace("a short bench check", "a short bench check, edited").encode()
SPEC = b'[sweep]\nscenario = "ver"\nseeds = [0]\n[[sweep.vary]]\nkey = "vehicle.mass"\nvalues = [1.1, 1.3]\n'


def sha(text: bytes) -> str:
    return hashlib.sha256(text).hexdigest()


@pytest.fixture
def service(tmp_path: Path) -> Iterator[Service]:
    svc = start(tmp_path / "data", "--slots", "1")
    yield svc
    stop(svc)


def occupy(svc: Service, tmp_path: Path) -> tuple[int, int]:
    """The only lockstep slot taken by a run whose DUT blocks until it is stopped: (its id, the DUT's
    pid). What is queued after it stays queued until it is cancelled."""
    command, fifo = blocked_dut(tmp_path)
    _, body = svc.call("POST", "/api/runs", {"scenarios": ["step_roll"], "dut": {"command": command}})
    return body["id"], read_pid(fifo)


def release(svc: Service, run_id: int, dut: int) -> None:
    assert svc.call("DELETE", f"/api/runs/{run_id}")[0] == 200
    assert wait_gone(dut)


def artifact(svc: Service, run_id: int, name: str) -> bytes:
    with urllib.request.urlopen(f"{svc.url}/api/runs/{run_id}/artifacts/{name}", timeout=BOUND_S) as r:
        data: bytes = r.read()
        return data


def page(svc: Service, path: str) -> str:
    with urllib.request.urlopen(svc.url + path, timeout=BOUND_S) as r:
        return str(r.read().decode())


def test_a_queued_run_flies_the_version_it_was_queued_with(service: Service, tmp_path: Path) -> None:
    blocker, dut = occupy(service, tmp_path)
    status, body = post_bytes(service, "/api/scenarios?name=ver", FIRST)
    assert status == 201, body
    _, queued = service.call("POST", "/api/runs", {"scenarios": ["ver"]})
    # another file under the taken name: refused, and nothing changes
    status, body = post_bytes(service, "/api/scenarios?name=ver", SECOND)
    assert status == 409 and "?replace=true" in body["detail"] and sha(FIRST)[:12] in body["detail"], body
    status, body = post_bytes(service, "/api/scenarios?name=ver", FIRST)  # the same bytes again: no error
    assert status == 200 and body["sha256"] == sha(FIRST) and body["new"] is False, body
    run = service.call("GET", f"/api/runs/{queued['id']}")[1]
    assert run["status"] == "queued" and run["versions"] == {"ver": sha(FIRST)}, run
    listed = {s["name"]: s for s in service.call("GET", "/api/scenarios")[1]}
    assert listed["ver"]["sha256"] == sha(FIRST) and listed["ver"]["origin"] == "uploaded"
    # ... unless the request says replace: the name points at the new version, the queued run keeps its
    status, body = post_bytes(service, "/api/scenarios?name=ver&replace=true", SECOND)
    assert status == 201 and body == {"name": "ver", "sha256": sha(SECOND), "replaced": sha(FIRST),
                                      "new": True}, body
    _, later = service.call("POST", "/api/runs", {"scenarios": ["ver"]})
    assert service.call("GET", f"/api/runs/{queued['id']}")[1]["status"] == "queued"
    assert [v["sha256"] for v in service.call("GET", "/api/scenarios/ver/versions")[1]] == \
        [sha(FIRST), sha(SECOND)]
    release(service, blocker, dut)
    for run_id, text in ((queued["id"], FIRST), (later["id"], SECOND)):
        run = service.follow(run_id)
        assert run["status"] == "passed", run["error"]
        assert run["versions"] == {"ver": sha(text)} and run["results"][0]["sha256"] == sha(text)
        flown = json.loads(artifact(service, run_id, "ver/result.json"))["metadata"]
        assert flown["scenario"] == "ver" and flown["scenario_sha256"] == sha(text), flown
        assert flown["scenario_file"].endswith(f"{sha(text)}.toml")
    # history and trends tell the versions apart
    history = {r["id"]: r["versions"] for r in service.call("GET", "/api/runs?scenario=ver")[1]}
    assert history == {queued["id"]: {"ver": sha(FIRST)}, later["id"]: {"ver": sha(SECOND)}}
    trend = service.call("GET", "/api/trend?scenario=ver&measurement=level")[1]
    assert [(p["run"], p["version"]) for p in trend] == \
        [(queued["id"], sha(FIRST)), (later["id"], sha(SECOND))]
    only = service.call("GET", f"/api/trend?scenario=ver&measurement=level&version={sha(SECOND)[:8]}")[1]
    assert [p["run"] for p in only] == [later["id"]]
    index = page(service, "/")
    assert f"ver@{sha(FIRST)[:8]}" in index and f"ver@{sha(SECOND)[:8]}" in index
    assert f"@{sha(FIRST)[:8]}" in page(service, f"/runs/{queued['id']}")
    compared = page(service, f"/compare?a={queued['id']}&b={later['id']}&scenario=ver")
    assert 'id="versions-differ"' in compared and sha(SECOND)[:8] in compared
    itself = page(service, f"/compare?a={queued['id']}&b={queued['id']}&scenario=ver")
    assert 'id="versions-differ"' not in itself
    trend_page = page(service, "/trend?scenario=ver&measurement=level")
    assert trend_page.count("version-changed") == 1 and sha(SECOND)[:8] in trend_page
    from playwright.sync_api import expect

    # the plot draws a series per version
    with chromium_page(f"{service.url}/trend?scenario=ver&measurement=level") as (tab, errors):
        expect(tab.locator("#trend[data-versions='2'] canvas").first).to_be_visible()
        expect(tab.locator("#trend")).to_contain_text(f"ver@{sha(SECOND)[:8]}")  # (the legend)
        assert not errors, errors


def test_a_sweep_of_an_uploaded_scenario_flies_the_version_it_was_queued_with(service: Service,
                                                                                tmp_path: Path) -> None:
    assert post_bytes(service, "/api/scenarios?name=ver", FIRST)[0] == 201
    blocker, dut = occupy(service, tmp_path)
    status, body = post_bytes(service, "/api/sweeps", SPEC)
    assert status == 201 and body["runs"] == 2 and body["scenario"] == "ver", body
    status, replaced = post_bytes(service, "/api/scenarios?name=ver&replace=true", SECOND)
    release(service, blocker, dut)
    run = service.follow(body["id"])
    assert run["status"] == "passed", run["error"]
    assert status == 201 and body["sha256"] == sha(FIRST), (body, replaced)
    assert run["results"][0]["scenario"] == "ver" and run["results"][0]["sha256"] == sha(FIRST)
    assert run["results"][0]["sweep"] == {"pass": 2, "fail": 0, "error": 0}
    (tmp_path / "served.parquet").write_bytes(artifact(service, body["id"], "runs.parquet"))
    table = sweep_store.read(tmp_path / "served.parquet")
    assert len(table["verdict"]) == 2 and set(table["verdict"]) == {"pass"}
    _, names = service.call("GET", f"/api/runs/{body['id']}/artifacts")
    results = [n for n in names if n.endswith("/result.json")]
    assert len(results) == 2
    for name in results:  # every run of the sweep flew the first version
        flown = json.loads(artifact(service, body["id"], name))["metadata"]
        assert flown["scenario"] == "ver" and flown["scenario_file"].endswith(f"{sha(FIRST)}.toml"), flown
    assert [r["id"] for r in service.call("GET", "/api/runs?scenario=ver")[1]] == [body["id"]]
    assert f"sweep of ver@{sha(FIRST)[:8]}" in page(service, "/")


def test_an_older_data_folder_is_brought_over(tmp_path: Path) -> None:
    """A data folder from before versions (schema 3, uploads kept as scenarios/NAME.toml, a run queued
    by name): each upload becomes the version its name points at when the service starts, nothing else
    there is touched, and the queued run flies the version its name points at when it starts."""
    import sqlite3

    from rig.service.db import MIGRATIONS
    from rig.service.worker import PINNED, command

    data = tmp_path / "data"
    (data / "scenarios").mkdir(parents=True)
    (data / "scenarios" / "legacy.toml").write_bytes(FIRST)
    (data / "scenarios" / "Not A Name.toml").write_bytes(SECOND)
    old = sqlite3.connect(data / "rig.sqlite")
    for migration in MIGRATIONS[:3]:
        old.executescript(migration)
    old.execute("PRAGMA user_version = 3")
    old.execute("INSERT INTO runs (created, status, priority, mode, seed, scenarios, dut) "
                "VALUES (0, 'queued', 0, 'lockstep', 0, '[\"legacy\"]', '{}')")
    old.commit()
    old.close()
    db = Db(data / "rig.sqlite")
    try:
        store = Store(data, db)
        assert store.uploaded_scenarios() == {"legacy": sha(FIRST)}
        kept = sorted(p.name for p in (data / "scenarios").iterdir())
        assert kept == ["Not A Name.toml", f"{sha(FIRST)}.toml"]
        assert Store(data, db).uploaded_scenarios() == {"legacy": sha(FIRST)}  # (again: nothing changes)
        run = db.claim("lockstep")
        assert run is not None and run["versions"] == {}
        cmd, flown = command(run, tmp_path / "out", store)
        assert flown == {"legacy": sha(FIRST)} and str(tmp_path / "out" / PINNED / "legacy.toml") in cmd
        assert (tmp_path / "out" / PINNED / "legacy.toml").read_bytes() == FIRST
    finally:
        db.close()


@pytest.mark.parametrize("value", [
    "text with \"quotes\", a \\ and a\ttab\u007f", 1.5e300, -0.0, float("inf"), [1, [2.5, "x"]],
    {"a b": {"c": True}}, "ünïcödé 🚁",
])
def test_a_spec_is_restated_with_every_value_it_had(tmp_path: Path, value: Any) -> None:
    """A sweep's spec, as rig sweep reads it, names the scenario's version file instead of its name and
    keeps every other value as it was (rig sweep has no TOML writer to lean on: ours is checked here)."""
    import tomllib

    from rig.service.store import SWEEP_SPEC, _toml

    data = tmp_path / "data"
    db = Db(tmp_path / "rig.sqlite")
    try:
        store = Store(data, db)
        store.put_scenario("ver", FIRST)
        spec = tmp_path / "spec.toml"
        text = f'[sweep]\nscenario = "ver"\n[[sweep.vary]]\nkey = "x"\nvalues = [{_toml(value)}]\n'
        spec.write_text(text)
        path, flown = store.sweep_spec(spec, tmp_path / "pinned", {})
        assert path.name == SWEEP_SPEC and flown == {"ver": sha(FIRST)}
        restated = tomllib.loads(path.read_text())["sweep"]
        assert restated["scenario"] == "ver.toml" and (path.parent / "ver.toml").read_bytes() == FIRST
        assert restated["vary"] == tomllib.loads(text)["sweep"]["vary"] == [{"key": "x", "values": [value]}]
    finally:
        db.close()
