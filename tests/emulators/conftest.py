"""Every emulator test runs twice: against the Python chips (the reference, emulators/*.py) and
against the chip core in C (emulators/chips/), through the boards of tests/emulators/boards.py. The
core's own tests (test_chip_core.py) build both themselves and run once."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from tests.emulators import boards

ONCE = ("tests.emulators.test_chip_core",)


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    if "chips" in metafunc.fixturenames and metafunc.module.__name__ not in ONCE:
        metafunc.parametrize("chips", boards.IMPLS, indirect=True)


@pytest.fixture(autouse=True)
def chips(request: pytest.FixtureRequest) -> Iterator[str]:
    """Which chips the test's boards are made of: "python" or "core"."""
    saved = boards.IMPL
    boards.IMPL = getattr(request, "param", "python")
    yield boards.IMPL
    boards.IMPL = saved
