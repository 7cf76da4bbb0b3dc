"""Metrics over a recorded signal, and criteria: a measurement with limits and an outcome (after
OpenHTF's model). Every metric works on samples inside a window [start, end] of sim time; a metric that
cannot be measured (a step never reached, a signal the DUT did not report) measures as NaN or infinity
and fails its limit, never passes by default."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

Metric = Callable[[np.ndarray, np.ndarray, "Params"], float]


@dataclass(frozen=True)
class Params:
    target: float | None
    band: float | None
    start: float


@dataclass(frozen=True)
class MetricDef:
    fn: Metric
    needs: tuple[str, ...]
    units: str | None  # None: the signal's units
    text: str


class Unmeasurable(ValueError):
    """A metric that has no value for this response; the message says why (it becomes the reason)."""


def _err(x: np.ndarray, p: Params) -> np.ndarray:
    return x - (p.target if p.target is not None else 0.0)


#: A step counts as reached once the response has covered this fraction of it (the rise time's 90 %)
REACHED = 0.9


def overshoot(t: np.ndarray, x: np.ndarray, p: Params) -> float:
    """Percent of the step (from the value at the window start to the target) passed beyond it. A
    step never reached has no overshoot to speak of: 0 % would pass a DUT that never moved."""
    step = p.target - x[0]
    if abs(step) < 1e-9:
        raise Unmeasurable("no step: the signal starts at the target")
    covered = float(np.max((x - x[0]) / step))
    if covered < REACHED:
        raise Unmeasurable(f"the step was never reached (at most {covered * 100:.0f} % of it)")
    beyond = np.max((x - p.target) * math.copysign(1.0, step))
    return max(0.0, float(beyond)) / abs(step) * 100.0


def rise_time(t: np.ndarray, x: np.ndarray, p: Params) -> float:
    """10 % to 90 % of the step; infinity when 90 % is never reached."""
    step = p.target - x[0]
    frac = (x - x[0]) / step if abs(step) > 1e-9 else np.zeros_like(x)
    lo, hi = np.nonzero(frac >= 0.1)[0], np.nonzero(frac >= 0.9)[0]
    if not len(hi):
        return math.inf
    return float(t[hi[0]] - t[lo[0]])


def settling_time(t: np.ndarray, x: np.ndarray, p: Params) -> float:
    """From the window start until the signal enters the band around the target for good;
    infinity when it is outside the band at the end."""
    out = np.nonzero(np.abs(x - p.target) > p.band)[0]
    if not len(out):
        return 0.0
    if out[-1] == len(x) - 1:
        return math.inf
    return float(t[out[-1] + 1] - p.start)


def steady_state_error(t: np.ndarray, x: np.ndarray, p: Params) -> float:
    """|mean error| over the window (put the window at the end of the response)."""
    return abs(float(np.mean(_err(x, p))))


def peak_error(t: np.ndarray, x: np.ndarray, p: Params) -> float:
    return float(np.max(np.abs(_err(x, p))))


def rms_error(t: np.ndarray, x: np.ndarray, p: Params) -> float:
    return float(np.sqrt(np.mean(_err(x, p) ** 2)))


def time_in_band(t: np.ndarray, x: np.ndarray, p: Params) -> float:
    """Percent of the window's samples within the band around the target."""
    return float(np.mean(np.abs(_err(x, p)) <= p.band)) * 100.0


def time_above(t: np.ndarray, x: np.ndarray, p: Params) -> float:
    """Percent of the window's samples at or above the target (motor saturation: pwm_max >= 1950)."""
    return float(np.mean(x >= p.target)) * 100.0


def maximum(t: np.ndarray, x: np.ndarray, p: Params) -> float:
    return float(np.max(x))


def minimum(t: np.ndarray, x: np.ndarray, p: Params) -> float:
    return float(np.min(x))


def final(t: np.ndarray, x: np.ndarray, p: Params) -> float:
    return float(x[-1])


METRICS: dict[str, MetricDef] = {
    "overshoot": MetricDef(overshoot, ("target",), "%", "percent of the step beyond the target"),
    "rise_time": MetricDef(rise_time, ("target",), "s", "10 % to 90 % of the step"),
    "settling_time": MetricDef(settling_time, ("target", "band"), "s", "until inside the band for good"),
    "steady_state_error": MetricDef(steady_state_error, ("target",), None, "|mean error| in the window"),
    "peak_error": MetricDef(peak_error, (), None, "largest |signal - target| (target 0 if not given)"),
    "rms_error": MetricDef(rms_error, (), None, "RMS of signal - target (target 0 if not given)"),
    "time_in_band": MetricDef(time_in_band, ("band",), "%", "percent of samples within the band"),
    "time_above": MetricDef(time_above, ("target",), "%", "percent of samples at or above the target"),
    "max": MetricDef(maximum, (), None, "largest value"),
    "min": MetricDef(minimum, (), None, "smallest value"),
    "final": MetricDef(final, (), None, "value at the end of the window"),
}


#: A measurement's outcome when its run ended in error: the value may exist, but nothing was judged
NOT_JUDGED = "not judged"
#: A measurement's outcome when the FC under test cannot give the signal (no telemetry the rig reads):
#: shown with the reason, never counted as a pass
NOT_MEASURED = "not measured"
#: The outcome (and verdict) of a scenario the FC cannot fly (a mode or feature its profile lacks)
SKIPPED = "skipped"

#: A pass closer than this to a limit (in % of the limit) is marginal, after OpenHTF's marginal limits
MARGINAL_PCT = 10.0

#: Signals that are states (0 or 1): their max, min or final is a yes or no, which has no margin
STATES = frozenset({"on_ground", "rc_link", "fault", "armed"})


def margin_pct(value: float, lo: float | None, hi: float | None) -> float | None:
    """How far ``value`` lies inside its limits, in % of the nearer limit (negative: outside). A
    limit of 0 has no percentage: with two limits the band's width stands in for it, with one the
    margin is None, as it is for a value that is not finite."""
    if not math.isfinite(value):
        return None
    found: list[float] = []
    width = hi - lo if lo is not None and hi is not None else None
    for limit, inside in ((lo, None if lo is None else value - lo), (hi, None if hi is None else hi - value)):
        if limit is None or inside is None:
            continue
        scale = abs(limit) if limit != 0 else width
        if scale:
            found.append(inside / scale * 100.0)
    return min(found) if found else None


@dataclass(frozen=True)
class Measurement:
    name: str
    metric: str
    signal: str
    value: float
    units: str
    min: float | None
    max: float | None
    start: float
    end: float
    outcome: str  # "pass" | "fail" | NOT_JUDGED | NOT_MEASURED | SKIPPED
    reason: str = ""
    target: float | None = None  # the target the metric used (after baseline_at), if it has one
    band: float | None = None
    margin: float | None = None  # % of the nearer limit inside it (margin_pct); None: no margin
    marginal: bool = False  # a pass within MARGINAL_PCT of a limit


def measure(
    name: str,
    metric: str,
    signal: str,
    t: np.ndarray,
    x: np.ndarray,
    start: float,
    end: float,
    target: float | None,
    band: float | None,
    lo: float | None,
    hi: float | None,
    units: str,
    baseline_at: float | None = None,
    marginal_pct: float = MARGINAL_PCT,
) -> Measurement:
    """Evaluates one criterion over the samples of ``x`` with ``start <= t <= end``. With
    ``baseline_at`` the target counts from the signal's value at that time (a step of 1 m from
    wherever the vehicle was holding, when the DUT chose that altitude itself). A pass less than
    ``marginal_pct`` inside a limit (margin_pct) is marginal."""
    sel = (t >= start - 1e-9) & (t <= end + 1e-9)
    xs, ts = x[sel], t[sel]
    if metric == "final":  # only the last sample counts (a DUT value unreported early is fine)
        xs, ts = xs[-1:], ts[-1:]
    reason = ""
    if not len(xs):
        value, reason = math.nan, "no samples in the window"
    elif np.isnan(xs).any():
        value, reason = math.nan, f"{signal} was not reported for the whole window"
    else:
        if baseline_at is not None and target is not None:
            target = float(np.interp(baseline_at, t, x)) + target
        try:
            value = METRICS[metric].fn(ts, xs, Params(target, band, start))
        except Unmeasurable as e:
            value, reason = math.nan, str(e)
    ok = bool(math.isfinite(value) and (lo is None or value >= lo) and (hi is None or value <= hi))
    if not ok and not reason:
        reason = "not measurable" if math.isnan(value) else "outside the limits"
    margin = None if signal in STATES and metric in ("max", "min", "final") else margin_pct(value, lo, hi)
    marginal = bool(ok and margin is not None and margin < marginal_pct)
    if marginal:
        reason = f"marginal: {margin:.1f} % inside the limit (under {marginal_pct:g} %)"
    return Measurement(
        name, metric, signal, value, units, lo, hi, start, end, "pass" if ok else "fail", reason,
        target, band, margin, marginal,
    )
