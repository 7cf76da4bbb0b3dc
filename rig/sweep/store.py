"""The sweep's table, runs.parquet: one row per finished run, in the spec's order: ``id``, each varied
key as a column named by its path, ``seed``, ``verdict``, ``error``, ``wall_s``, ``host``, then every
measurement by name (NaN: not measured). Written from the rows the runs left in their folders, so it
is rebuilt whole at the end of every sweep, interrupted or not."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

TABLE = "runs.parquet"
FIXED = ("id", "seed", "verdict", "error", "wall_s", "host")


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
