"""result.json: every measurement with its limits and outcome, the verdict and the run's metadata."""

from __future__ import annotations

import dataclasses
import json

from rig.reports.values import json_number
from rig.scenarios.result import RunResult

FORMAT = "rig-result/1"


def to_dict(r: RunResult) -> dict[str, object]:
    return {
        "format": FORMAT,
        "scenario": r.scenario.stem,
        "name": r.scenario.name,
        "description": r.scenario.description,
        "verdict": r.verdict,
        # passes within MARGINAL_PCT of a limit (each measurement says so too, with its margin)
        "marginal": [m.name for m in r.measurements if m.marginal],
        "error": r.error,
        "metadata": r.metadata,
        "notes": r.notes,
        "measurements": [{**dataclasses.asdict(m), **json_number(m.value)} for m in r.measurements],
    }


def render(r: RunResult) -> str:
    return json.dumps(to_dict(r), indent=2, allow_nan=False) + "\n"
