"""What a sweep's folder keeps besides its runs' own folders.

runs.parquet: one row per finished run, in the spec's order: ``id``, each varied key as a column named
by its path, ``seed``, ``verdict``, ``error``, ``wall_s``, ``host``, ``dut_command``, ``dut_sha256``,
then every measurement by name (NaN: not measured). Written from the rows the runs left in their
folders, so it is rebuilt whole at the end of every sweep, interrupted or not.

sweep.json: the DUT the folder's runs fly against (its command and the SHA-256 of its firmware, as
``rig run`` records them). A run's id says which variant it is, not what flew it: without this, a resume
with another DUT, or a firmware rebuilt at the same path, counted the first DUT's rows as its own."""

from __future__ import annotations

import json
import math
import shlex
from collections.abc import Sequence
from pathlib import Path
from typing import Any

TABLE = "runs.parquet"
FIXED = ("id", "seed", "verdict", "error", "wall_s", "host", "dut_command", "dut_sha256")
SWEEP = "sweep.json"
#: what identifies a DUT (the other keys of sweep.json say it in words)
DUT_KEYS = ("dut_command", "dut_sha256", "fc_profile_sha256")
#: what a sweep writes in its folder (beside .slots/, gone at its end): --fresh removes these
WRITTEN = ("runs", TABLE, "summary.html", "junit.xml", SWEEP)


def dut_identity(dut: list[str] | None, cwd: Path | None = None, fc: str | None = None) -> dict[str, Any]:
    """The DUT a sweep flies: ``dut_command`` (``--dut`` with its relative paths made absolute, or the
    reference FC's program), ``dut_sha256`` (of its firmware: rig/firmware.py), ``dut_firmware``
    (what was hashed, in words) and the FC profile it is flown by (``fc``: its file; None: the
    reference FC's), by name and SHA-256."""
    from rig import firmware
    from rig.scenarios import profile as profiles
    from rig.targets import REFERENCE_FC
    from rig.targets.process import absolute_command

    cwd = cwd or Path.cwd()
    command = list(dut) if dut is not None else [str(REFERENCE_FC)]
    info = firmware.identify(command, cwd)
    text = shlex.join(absolute_command(command, cwd))
    fc_profile = profiles.load(fc or profiles.DEFAULT)
    return {
        "dut_command": text if dut is not None else f"reference FC {text}",
        "dut_sha256": info.get("dut_firmware_sha256"),
        "dut_firmware": info.get("dut_firmware"),
        "fc_profile": fc_profile.name,
        "fc_profile_sha256": fc_profile.sha256,
    }


def same_dut(a: dict[str, Any], b: dict[str, Any]) -> bool:
    return all(a.get(k) == b.get(k) for k in DUT_KEYS)


def describe(dut: dict[str, Any]) -> str:
    """A DUT in words, for a message: its command and hash."""
    if dut.get("dut_command") is None:
        return "a DUT this folder does not record (runs from before sweeps recorded their DUT)"
    return f"{dut['dut_command']} (SHA-256 {dut.get('dut_sha256') or 'none: not hashed'})"


def read_dut(folder: Path) -> dict[str, Any] | None:
    """The DUT sweep.json records, or None (no file, or not one of ours)."""
    try:
        data = json.loads((folder / SWEEP).read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) and isinstance(data.get("dut_command"), str) else None


def write_dut(folder: Path, dut: dict[str, Any]) -> None:
    tmp = folder / f".{SWEEP}.tmp"
    tmp.write_text(json.dumps(dut, indent=1) + "\n")
    tmp.replace(folder / SWEEP)


def _cell(v: Any) -> Any:
    """A varied value as a column cell: numbers and strings as they are, anything else (a vector) as
    its JSON text, so one column keeps one type."""
    if isinstance(v, bool | int | float | str):
        return v
    return json.dumps(v)


def columns(rows: Sequence[dict[str, Any]], keys: Sequence[str]) -> dict[str, list[Any]]:
    names: list[str] = []
    for r in rows:
        names += [n for n in r.get("measurements", {}) if n not in names]
    out: dict[str, list[Any]] = {"id": [r["id"] for r in rows]}
    for k in keys:
        out[k] = [_cell(r["values"].get(k)) for r in rows]
    for k in FIXED[1:]:
        out[k] = [r.get(k) for r in rows]
    for n in names:
        out[n] = [_float(r.get("measurements", {}).get(n)) for r in rows]
    return out


def _float(v: Any) -> float:
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else math.nan


def write(path: Path, rows: Sequence[dict[str, Any]], keys: Sequence[str]) -> Path:
    import pyarrow as pa
    import pyarrow.parquet as pq

    cols = columns(rows, keys)
    fields = []
    for name, values in cols.items():
        kinds = {type(v) for v in values if v is not None}
        if kinds <= {int} and name != "wall_s":
            t = pa.int64()
        elif kinds <= {int, float}:
            t = pa.float64()
        elif kinds <= {bool}:
            t = pa.bool_()
        else:
            t = pa.string()
            cols[name] = [None if v is None else str(v) for v in values]
        fields.append(pa.field(name, t))
    table = pa.table(cols, schema=pa.schema(fields))
    tmp = path.with_name(f".{path.name}.tmp")
    pq.write_table(table, tmp)
    tmp.replace(path)
    return path


def read(path: Path) -> dict[str, list[Any]]:
    import pyarrow.parquet as pq

    return pq.read_table(path).to_pydict()
