"""What one scenario run produced, as plain data: the verdict, every measurement, the recorded signals
and the run's metadata. The runner (rig/runner.py) makes it; the reports (reports/) render it."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from scenarios.criteria import Measurement
from scenarios.schema import Scenario


class ScenarioInfo(Protocol):
    """What a report needs of a scenario: a loaded Scenario, or a ScenarioRecord read back from a
    result.json whose scenario file may be gone."""

    @property
    def path(self) -> Path: ...
    @property
    def name(self) -> str: ...
    @property
    def description(self) -> str: ...
    @property
    def sha256(self) -> str: ...
    @property
    def stem(self) -> str: ...


@dataclass(frozen=True)
class ScenarioRecord:
    path: Path
    name: str
    description: str
    sha256: str

    @property
    def stem(self) -> str:
        return self.path.stem


_: type[ScenarioInfo] = Scenario  # (both kinds are ScenarioInfo: mypy checks it here)
__: type[ScenarioInfo] = ScenarioRecord


@dataclass
class RunResult:
    scenario: ScenarioInfo
    verdict: str  # "pass" | "fail" | "error" | "interrupted" (a signal stopped the rig mid-run)
    error: str | None
    measurements: list[Measurement]
    signals: dict[str, np.ndarray]
    metadata: dict[str, Any]  # JSON-like: result.json's "metadata"
    exit_code: int | None = None  # the session's (rig exec's) exit status; 128 + N for signal N
    stderr: str = ""
    notes: list[str] = field(default_factory=list)
