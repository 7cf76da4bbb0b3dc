"""`rig serve`'s page in a real browser: Debian's chromium driven by Playwright (executable_path, never a
downloaded browser), against a real uvicorn on 127.0.0.1. A run appears in the history, a filter
narrows the list, the form starts a run, and a run's page plots its telemetry with the right series
beside its criteria."""

from __future__ import annotations

import hashlib
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.browser import chromium_page
from tests.service.test_api import Service, start, stop

HTMX = Path(__file__).resolve().parents[2] / "rig" / "service" / "static" / "htmx" / "htmx.min.js"


@pytest.fixture
def service(tmp_path: Path) -> Iterator[Service]:
    svc = start(tmp_path / "data", "--slots", "2")
    yield svc
    stop(svc)


def test_the_vendored_htmx_is_the_pinned_one() -> None:
    pinned = (HTMX.parent / "README.md").read_text()
    assert hashlib.sha256(HTMX.read_bytes()).hexdigest() in pinned and "2.0.4" in pinned


def test_the_page_lists_filters_starts_and_plots_runs(service: Service, tmp_path: Path) -> None:
    from playwright.sync_api import expect

    _, body = service.call("POST", "/api/runs", {"scenarios": ["step_roll"]})
    first = service.follow(body["id"])
    assert first["status"] == "passed"
    with chromium_page(service.url + "/", 1100, 1300) as (page, errors):
        history = page.locator("#history tr.run")
        expect(history).to_have_count(1)
        expect(history.first).to_contain_text("step_roll")
        expect(history.first).to_contain_text("passed")
        # a filter narrows the list (htmx swaps the table)
        page.select_option("#filters select[name=status]", "failed")
        expect(page.locator("#history")).to_contain_text("no runs")
        page.select_option("#filters select[name=status]", "passed")
        expect(history).to_have_count(1)
        # the form starts a run
        page.select_option("#start select[name=scenarios]", ["seed000_roll_stand"])
        page.click("#start button")
        expect(page.locator("#started")).to_contain_text("queued run")
        started = int(page.locator("#started a").inner_text().split()[-1])
        assert service.follow(started)["status"] == "passed"
        assert service.call("GET", f"/api/runs/{started}")[1]["scenarios"] == ["seed000_roll_stand"]
        # a run's page: its criteria and its plot with the attitude's series
        page.goto(f"{service.url}/runs/{first['id']}")
        expect(page.locator("#status")).to_have_text("passed")
        expect(page.locator("table.criteria")).to_contain_text("overshoot of roll")
        plot = page.locator("div.plot[data-series]")
        expect(plot).to_have_count(1)
        assert plot.get_attribute("data-series") == "roll,roll_sp,pitch,pitch_sp,est_roll"
        assert page.locator("div.plot canvas").count() >= 1
        assert page.locator("div.plot .u-legend").inner_text().count("roll") >= 3
        page.screenshot(path=str(tmp_path / "run-page.png"), full_page=True)
        assert (tmp_path / "run-page.png").stat().st_size > 10_000
        assert not errors, errors


def test_two_runs_overlaid_and_a_measurements_trend(service: Service) -> None:
    from playwright.sync_api import expect

    ids = []
    for seed in (0, 1):
        _, body = service.call("POST", "/api/runs", {"scenarios": ["step_roll"], "seed": seed})
        assert service.follow(body["id"])["status"] == "passed"
        ids.append(body["id"])
    a, b = ids
    values = [service.call("GET", f"/api/runs/{i}")[1]["results"][0]["measurements"][0]["value"]
              for i in ids]
    _, points = service.call("GET", "/api/trend?scenario=step_roll&measurement=overshoot%20of%20roll")
    assert [(p["run"], p["value"], p["firmware"]) for p in points] == \
        [(a, values[0], "reference FC"), (b, values[1], "reference FC")]
    assert values[0] != values[1]  # two seeds: two flights
    # what sets a series apart, in each point: the seed, the mode, the DUT, the version and its number
    assert [(p["seed"], p["mode"], p["version_number"]) for p in points] == \
        [(0, "lockstep", 1), (1, "lockstep", 1)]
    assert len({p["series"] for p in points}) == 2  # two seeds: never one line
    _, one = service.call("GET", "/api/trend?scenario=step_roll&measurement=overshoot%20of%20roll&seed=1")
    assert [p["run"] for p in one] == [b]
    with chromium_page(f"{service.url}/compare?a={a}&b={b}&scenario=step_roll", 1100, 1000) as (page, errors):
        overlay = page.locator("#overlay[data-series]")
        expect(overlay).to_have_count(1)
        named = f"run {a} roll,run {a} pitch,run {b} roll,run {b} pitch"
        assert overlay.get_attribute("data-series") == named
        expect(page.locator("table.criteria")).to_contain_text("overshoot of roll")
        page.goto(f"{service.url}/trend?scenario=step_roll&measurement=overshoot%20of%20roll")
        expect(page.locator("tr.point")).to_have_count(2)
        expect(page.locator("#trend[data-points='2'][data-series='2'] canvas").first).to_be_visible()
        assert page.locator("tr.point td:nth-child(6)").all_inner_texts()[0].startswith("v1 ")
        # the x axis: run numbers, whole (the labels uPlot drew at the first axis's ticks, on its canvas)
        ticks = page.evaluate("document.getElementById('trend').uplot.axes[0]._values")
        assert ticks and all(t == "" or t.isdigit() for t in ticks) and f"{b}" in ticks, ticks
        # a filter keeps one seed (a form the page submits)
        page.select_option("#trend-filters select[name=seed]", "1")
        expect(page.locator("tr.point")).to_have_count(1)
        expect(page.locator("tr.point td").first).to_have_text(str(b))
        assert not errors, errors
    assert service.call("GET", f"/compare?a={a}&b=999&scenario=step_roll")[0] == 404


def test_the_form_shows_why_a_run_was_not_started(service: Service) -> None:
    from playwright.sync_api import expect

    with chromium_page(service.url + "/") as (page, errors):
        page.select_option("#start select[name=scenarios]", ["step_roll"])
        refused = page.locator("#started #refused")
        # a seed the service refuses (the browser lets it through): the service's words, by the form
        page.fill("#start input[name=seed]", "3000000000")
        page.click("#start button")
        expect(refused).to_contain_text("not started: seed: Input should be less than 2147483648")
        # a seed the browser refuses (htmx then sends nothing): its words, by the form
        page.fill("#start input[name=seed]", "-1")
        page.click("#start button")
        expect(refused).to_contain_text("not started: seed: ")
        expect(refused).not_to_contain_text("2147483648")
        # and a good one still starts a run
        page.fill("#start input[name=seed]", "2")
        page.click("#start button")
        expect(page.locator("#started")).to_contain_text("queued run")
        assert not errors, errors
    queued = service.call("GET", "/api/runs")[1]
    assert [r["seed"] for r in queued] == [2]  # the refused ones were not queued
