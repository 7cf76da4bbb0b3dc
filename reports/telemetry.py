"""The recorded signals as CSV (RFC 4180): one column per signal, one row per 10 ms of sim time, a
header of ``name[units]``. CSV is columnar enough for every plotting tool and spreadsheet and needs no
library to read; NaN (a DUT value not yet reported) is written as an empty field."""

from __future__ import annotations

import csv
import io
import math

import numpy as np

from rig.scenarios.signals import SIGNALS


def render(signals: dict[str, np.ndarray]) -> str:
    names = ["t"] + [n for n in SIGNALS if n in signals]
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(["t[s]"] + [f"{n}[{SIGNALS[n].units}]" for n in names[1:]])
    # the rows' fields need no quoting (numbers, empty); as plain floats, not numpy's scalars (formatting
    # those one at a time was 40 % of writing the file)
    cols = [np.asarray(signals[n], dtype=np.float64).tolist() for n in names]
    write = out.write
    for row in zip(*cols, strict=True):
        write(",".join(["" if v != v else f"{v:.6g}" for v in row]) + "\n")
    return out.getvalue()


def read(text: str) -> dict[str, np.ndarray]:
    """The inverse of render (for tests and users' scripts): name (without units) to column."""
    rows = list(csv.reader(io.StringIO(text)))
    names = [h.split("[")[0] for h in rows[0]]
    data = np.array([[float(v) if v else math.nan for v in r] for r in rows[1:]], dtype=float)
    data = data.reshape(-1, len(names))  # (no rows: a run that recorded nothing)
    return {n: data[:, k] for k, n in enumerate(names)}
