"""`rig serve`'s pages as they change while they are open (Debian's chromium through Playwright, a real
uvicorn on 127.0.0.1): a bench run's progress moves on its page during its real-time flight and the
page turns to its verdict, the front page's queue and history follow, all without a reload (a mark
set in the page survives). Run pages say what the API knows: an errored run the scenario's reason, a
queued one its place and what it waits for, and only the artifacts that are there are linked."""

from __future__ import annotations

import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.browser import chromium_page
from tests.service.test_api import Service, blocked_dut, post_bytes, start, stop
from tests.short_scenario import SHORT_BENCH
from tests.waits import BOUND_S, read_pid

MS = BOUND_S * 1000  # (Playwright's waits: for a condition, bounded)


@pytest.fixture
def service(tmp_path: Path) -> Iterator[Service]:
    svc = start(tmp_path / "data", "--slots", "1")
    yield svc
    stop(svc)


def test_a_bench_runs_progress_moves_on_an_open_page(service: Service) -> None:
    from playwright.sync_api import expect

    assert post_bytes(service, "/api/scenarios?name=short", SHORT_BENCH.encode())[0] == 201
    with chromium_page(service.url + "/") as (front, errors):
        page = front.context.new_page()
        page.on("pageerror", lambda e: errors.append(str(e)))
        expect(front.locator("#history")).to_contain_text("no runs")
        _, body = service.call("POST", "/api/runs", {"scenarios": ["short"], "mode": "bridge"})
        page.goto(f"{service.url}/runs/{body['id']}")
        for tab in (front, page):
            tab.evaluate("window.stillThisPage = true")  # a reload would lose it
        # mid-flight: between 0 and 100 % (real time: the wall clock since the scenario started)
        page.wait_for_function("""() => {
            const p = parseFloat(document.querySelector('#progress').textContent);
            return document.querySelector('#status').textContent === 'running' && p > 0 && p < 100; }""",
                               timeout=MS)
        expect(front.locator("#queue")).to_contain_text("running", timeout=MS)
        expect(page.locator("#status")).to_have_text("passed", timeout=MS)
        expect(page.locator("#progress")).to_have_text("100 % done")
        expect(page.locator("table.criteria")).to_contain_text("level")
        expect(page.locator("#artifacts a")).to_have_count(2)
        expect(front.locator("#history tr.run")).to_have_count(1, timeout=MS)
        expect(front.locator("#history tr.run").first).to_contain_text("passed")
        expect(front.locator("#queue")).to_contain_text("nothing queued or running", timeout=MS)
        for tab in (front, page):
            assert tab.evaluate("window.stillThisPage") is True
        assert not errors, errors


def html(svc: Service, path: str) -> str:
    """The page as served, its character references read (a reason's quotes are &#39; there)."""
    import html as markup

    with urllib.request.urlopen(svc.url + path, timeout=BOUND_S) as r:
        return markup.unescape(r.read().decode())


def test_run_pages_say_what_the_api_knows(service: Service, tmp_path: Path) -> None:
    from rig.service.db import Db

    # an errored run: the scenario's reason, as its result.json gives it, not rig run's last line
    _, failing = service.call("POST", "/api/runs", {"scenarios": ["step_roll"],
                                                    "dut": {"command": "sh -c 'exit 3'"}})
    run = service.follow(failing["id"])
    reason = run["results"][0]["error"]
    assert run["status"] == "error" and "status 3" in reason, run
    assert run["error"] == f"step_roll: {reason}"
    text = html(service, f"/runs/{failing['id']}")
    assert reason in text and "rig run exited" not in text and "reports in" not in text
    # a queued run (the only slot held): its position, no links to what it has not written
    command, fifo = blocked_dut(tmp_path)
    _, holder = service.call("POST", "/api/runs", {"scenarios": ["step_roll"], "dut": {"command": command}})
    read_pid(fifo)
    _, waiting = service.call("POST", "/api/runs", {"scenarios": ["step_roll"]})
    text = html(service, f"/runs/{waiting['id']}")
    assert "position 1 in the lockstep queue" in text and 'id="artifacts"' not in text
    assert service.call("DELETE", f"/api/runs/{waiting['id']}")[0] == 200  # cancelled: never ran
    assert 'id="artifacts"' not in html(service, f"/runs/{waiting['id']}")
    # a queued bench run: its place and what it waits for (another holder has the service's bench)
    assert post_bytes(service, "/api/scenarios?name=short", SHORT_BENCH.encode())[0] == 201
    other = Db(tmp_path / "data" / "rig.sqlite")
    try:
        assert other.acquire("bench", "another-service", ttl=3600)
        _, bench_run = service.call("POST", "/api/runs", {"scenarios": ["short"], "mode": "bridge"})
        text = html(service, f"/runs/{bench_run['id']}")
        assert "position 1 in the bench queue" in text
        assert "waits for <span id=\"waits\">the service's bench (held by another-service)" in text
        assert "the service's bench (held by another-service)" in html(service, "/")
    finally:
        other.close()
    assert service.call("DELETE", f"/api/runs/{bench_run['id']}")[0] == 200
    assert service.call("DELETE", f"/api/runs/{holder['id']}")[0] == 200
