"""What one scenario run produced, as plain data: the verdict, every measurement, the recorded signals
and the run's metadata. The runner (rig/runner.py) makes it; the reports (reports/) render it."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from scenarios.criteria import Measurement
from scenarios.schema import Scenario


@dataclass
class RunResult:
    scenario: Scenario
    verdict: str  # "pass" | "fail" | "error" | "interrupted" (a signal stopped the rig mid-run)
    error: str | None
    measurements: list[Measurement]
    signals: dict[str, np.ndarray]
    metadata: dict[str, Any]  # JSON-like: result.json's "metadata"
    exit_code: int | None = None  # the session's (rig exec's) exit status; 128 + N for signal N
    stderr: str = ""
    notes: list[str] = field(default_factory=list)
