"""Shared fixtures: the plant FMU is built once if `make` has not built it already."""

from __future__ import annotations

from pathlib import Path

import pytest

from plant import DEFAULT_FMU


@pytest.fixture(scope="session")
def fmu_path() -> Path:
    if not DEFAULT_FMU.is_file():
        from plant.build import build

        build()
    return DEFAULT_FMU
