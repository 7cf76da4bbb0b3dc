"""Debian's Chromium through Playwright (never a downloaded browser) for the tests of the pages the rig
writes and serves: one way to open it, so every such test runs headless with the same flags and fails
on a JavaScript error the page raised."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from playwright.sync_api import Page

CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync", "--no-first-run"]


@contextlib.contextmanager
def chromium_page(url: str, width: int = 1280, height: int = 720) -> Iterator[tuple[Page, list[str]]]:
    """A page opened at ``url`` and the JavaScript errors it raises (the test asserts there are none
    where it means it); the browser is closed however the test ends. ``page.context`` opens more tabs
    beside it, ``page.context.browser`` more contexts (one without JavaScript, say)."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_FLAGS)
        try:
            page = browser.new_context(viewport={"width": width, "height": height}).new_page()
            errors: list[str] = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(url)
            yield page, errors
        finally:
            browser.close()
