"""Every emulator test runs twice: against the Python chips (the reference, emulators/*.py) and
against the chip core in C (emulators/chips/), through the boards of tests/emulators/boards.py."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from tests.emulators import boards


@pytest.fixture(autouse=True, params=boards.IMPLS)
def chips(request: pytest.FixtureRequest) -> Iterator[str]:
    """Which chips the test's boards are made of: "python" or "core"."""
    saved = boards.IMPL
    boards.IMPL = request.param
    yield request.param
    boards.IMPL = saved
