"""Shared fixtures: the plant FMU is built once if `make` has not built it already. The tests run the
compiled hot modules (rig/compiled.py) as the CLI does: the hook is installed here, before any test
module imports one."""

from __future__ import annotations

import signal
from pathlib import Path

import pytest

from plant import DEFAULT_FMU
from rig import compiled

compiled.install()  # (plant is not among the hot modules; nothing hot is imported before this)

# A suite started in the background by a non-interactive shell (`make test &`, a CI step run so)
# inherits SIGINT ignored, and so would every command a test starts: a test pressing Ctrl-C on `rig
# submit` would see it ignored. Handled here, it is the default again in every child, as from a terminal.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture(scope="session")
def fmu_path() -> Path:
    if not DEFAULT_FMU.is_file():
        from plant.build import build

        build()
    return DEFAULT_FMU
