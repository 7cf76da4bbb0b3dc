"""A report folder read back (``rig report DIR``): each run's result.json, telemetry.csv and the DUT's
stderr as the RunResults the renderers take, so an archived run's pages and PDF can be made again from
what it wrote, even when its scenario files have moved or changed since."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from rig.reports import telemetry
from rig.reports.values import from_json_number
from rig.scenarios.criteria import Measurement
from rig.scenarios.result import RunResult, ScenarioRecord
from rig.scenarios.signals import SIGNALS

MANIFEST = ".rig-run.json"  # (rig/run_cmd.py's ReportFolder writes it: the run's scenario folders in order)
FIELDS = {f.name for f in dataclasses.fields(Measurement)}


class NotAReportFolder(ValueError):
    pass


def read_run(folder: Path) -> RunResult:
    data = json.loads((folder / "result.json").read_text())
    meta = data.get("metadata") or {}
    scenario = ScenarioRecord(
        Path(str(meta.get("scenario_file") or f"{data['scenario']}.toml")),
        str(data.get("name") or data["scenario"]),
        str(data.get("description") or ""),
        str(meta.get("scenario_sha256") or ""),
    )
    measurements = [
        Measurement(**{**{k: v for k, v in m.items() if k in FIELDS},
                       "value": from_json_number(m.get("value"), m.get("value_reason"))})
        for m in data.get("measurements", [])
    ]
    csv = folder / "telemetry.csv"
    signals = telemetry.read(csv.read_text()) if csv.is_file() else {}
    n = len(signals.get("t", ()))
    for name in ("t", *SIGNALS):
        signals.setdefault(name, np.full(n, math.nan))
    stderr_file = folder / "dut-stderr.txt"
    stderr = stderr_file.read_text(errors="replace") if stderr_file.is_file() else ""
    return RunResult(
        scenario,
        str(data["verdict"]),
        data.get("error"),
        measurements,
        signals,
        meta,
        None,
        stderr,
        list(data.get("notes") or []),
    )


def read_folder(out: Path) -> tuple[list[RunResult], list[str]]:
    """The runs of the folder in the order they ran, and the scenarios listed but never run."""
    try:
        stems = json.loads((out / MANIFEST).read_text())
    except (OSError, ValueError):
        stems = sorted(p.parent.name for p in out.glob("*/result.json"))
    stems = [s for s in stems if isinstance(s, str) and s and "/" not in s]
    runs = [read_run(out / s) for s in stems if (out / s / "result.json").is_file()]
    if not runs:
        raise NotAReportFolder(f"{out}: no run's result.json in it (is it a `rig run --out` folder?)")
    return runs, [s for s in stems if not (out / s / "result.json").is_file()]
