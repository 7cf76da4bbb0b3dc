"""Shared fixtures: the plant FMU is built once if `make` has not built it already. The tests run the
compiled hot modules (rig/compiled.py) as the CLI does: the hook is installed here, before any test
module imports one."""

from __future__ import annotations

from pathlib import Path

import pytest

from plant import DEFAULT_FMU
from rig import compiled

compiled.install()  # (plant is not among the hot modules; nothing hot is imported before this)


@pytest.fixture(scope="session")
def fmu_path() -> Path:
    if not DEFAULT_FMU.is_file():
        from plant.build import build

        build()
    return DEFAULT_FMU
