"""docs/service-run-page.png: `rig serve`'s page of a run (step_roll at seed 0), as Debian's chromium
shows it. Starts a service on a free loopback port with a data folder of its own, runs the scenario,
takes the screenshot, stops the service. `make docs-images` runs it."""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tests.scenarios.test_library_and_reports import CHROMIUM_FLAGS  # noqa: E402
from tests.service.test_api import start, stop  # noqa: E402

OUT = REPO / "docs" / "service-run-page.png"


def main() -> None:
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory(prefix="rig-serve-shot-") as tmp:
        svc = start(Path(tmp) / "data", "--slots", "1")
        try:
            _, body = svc.call("POST", "/api/runs", {"scenarios": ["step_roll"]})
            svc.follow(body["id"])
            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_FLAGS)
                page = browser.new_page(viewport={"width": 1000, "height": 900})
                page.goto(f"{svc.url}/runs/{body['id']}")
                page.wait_for_selector("div.plot[data-series]")
                page.screenshot(path=str(OUT), full_page=True)
                browser.close()
        finally:
            stop(svc)
    print(OUT)


if __name__ == "__main__":
    main()
