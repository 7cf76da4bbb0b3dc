"""Shared fixtures: the plant FMU is built once if `make` has not built it already. The tests run the
compiled hot modules (rig/compiled.py) as the CLI does: the hook is installed here, before any test
module imports one."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

from rig import compiled
from rig.plant import DEFAULT_FMU

# why a pytest-xdist worker died, said in the log; the suite's rules (slow markers, inconclusive tests
# counted at the end of the run)
pytest_plugins = ["tests.worker_deaths", "tests.suite_rules"]

compiled.install()  # (plant is not among the hot modules; nothing hot is imported before this)

# A suite started in the background by a non-interactive shell (`make test &`, a CI step run so)
# inherits SIGINT ignored, and so would every command a test starts: a test pressing Ctrl-C on `rig
# submit` would see it ignored. Handled here, it is the default again in every child, as from a terminal.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


# Under pytest-xdist (make test runs the suite on every core) each worker holds a core of its own. A
# lockstep session pins itself and its DUT to the highest core it may use (rig/session.py): with every
# core allowed, every worker's sessions would share that one core while the others idle.
_WORKER = os.environ.get("PYTEST_XDIST_WORKER", "")
if _WORKER.startswith("gw") and _WORKER[2:].isdigit():
    _allowed = sorted(os.sched_getaffinity(0))
    os.sched_setaffinity(0, {_allowed[int(_WORKER[2:]) % len(_allowed)]})


@pytest.fixture(scope="session")
def fmu_path() -> Path:
    if not DEFAULT_FMU.is_file():
        from rig.plant.build import build

        build()
    return DEFAULT_FMU
