"""How a measurement and its limits read, the same in every report."""

from __future__ import annotations

import math

from scenarios.criteria import Measurement


def fmt_value(v: float, units: str) -> str:
    if math.isnan(v):
        return "not measured"
    if math.isinf(v):
        return "never" if units == "s" else ("+inf" if v > 0 else "-inf")
    return f"{v:.4g} {units}".strip()


def fmt_limits(m: Measurement) -> str:
    lo = "" if m.min is None else f"{m.min:g}"
    hi = "" if m.max is None else f"{m.max:g}"
    if lo and hi:
        return f"{lo} .. {hi} {m.units}".strip()
    return (f">= {lo}" if lo else f"<= {hi}") + (f" {m.units}" if m.units else "")


def json_number(v: float) -> float | str:
    """JSON has no NaN or infinity: they are written as strings a reader cannot mistake for numbers."""
    return v if math.isfinite(v) else ("nan" if math.isnan(v) else ("inf" if v > 0 else "-inf"))
