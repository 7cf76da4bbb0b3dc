"""Scenarios, as data: the file format and its checker, the recorded signals, the metrics and criteria,
what a run produced (``result.py``), and the scenario library (``scenarios/library/*.toml``). The runner
that flies a scenario in a session is the rig's (rig/runner.py)."""

from pathlib import Path

#: the scenario library, the acceptance suite (``rig list``), shipped inside the package
LIBRARY = Path(__file__).resolve().parent / "library"
