"""What a run's plots show, once for every renderer (the static SVG of report.html and the PDF, and the
interactive uPlot charts): which signals each plot draws, and the intervals to mark (sensor faults, RC
link lost). A trace the run never recorded (the DUT sent no telemetry) is left out with its legend."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.plant.variables import MOTORS


@dataclass(frozen=True)
class Trace:
    label: str
    signal: str
    dash: str = ""  # SVG stroke-dasharray: "" solid, "4 3" dashed (setpoints), "1 2" dotted (the DUT's)
    zero_is_gap: bool = False  # a pulse width of 0 is no pulse (the channel not enabled yet): not drawn


@dataclass(frozen=True)
class Plot:
    key: str
    title: str
    units: str
    traces: tuple[Trace, ...]
    lanes: bool = False  # one lane per trace, each with its own scale (four motors would overlap)


@dataclass(frozen=True)
class Mark:
    """Intervals [start, end) of sim time when something was wrong on purpose."""

    label: str
    colour: str
    spans: tuple[tuple[float, float], ...]


PLOTS = (
    Plot(
        "attitude",
        "roll and pitch against setpoint",
        "deg",
        (
            Trace("roll", "roll"),
            Trace("roll sp", "roll_sp", "4 3"),
            Trace("pitch", "pitch"),
            Trace("pitch sp", "pitch_sp", "4 3"),
            Trace("roll (DUT)", "est_roll", "1 2"),
            Trace("pitch (DUT)", "est_pitch", "1 2"),
        ),
    ),
    Plot("yaw", "yaw", "deg", (Trace("yaw", "yaw"), Trace("yaw (DUT)", "est_yaw", "1 2"))),
    Plot("altitude", "altitude", "m", (Trace("alt", "alt"), Trace("alt (DUT)", "est_alt", "1 2"))),
    Plot(
        "motors",
        "motor commands",
        "µs",
        tuple(Trace(f"motor {m}", f"pwm{m}", zero_is_gap=True) for m in range(1, MOTORS + 1)),
        lanes=True,
    ),
)


def values(signals: dict[str, np.ndarray], trace: Trace) -> np.ndarray:
    """What the plot draws of the trace's signal (NaN: nothing drawn there)."""
    v = signals[trace.signal]
    return np.where(v <= 0, np.nan, v) if trace.zero_is_gap else v


def recorded(signals: dict[str, np.ndarray], trace: Trace) -> bool:
    v = signals.get(trace.signal)
    return v is not None and bool(np.isfinite(v).any())


def plots(signals: dict[str, np.ndarray]) -> list[Plot]:
    """The plots with only the traces that hold at least one value."""
    return [
        Plot(
            p.key,
            p.title,
            p.units,
            tuple(tr for tr in p.traces if recorded(signals, tr)) or p.traces[:1],
            p.lanes,
        )
        for p in PLOTS
    ]


def spans(t: np.ndarray, on: np.ndarray) -> tuple[tuple[float, float], ...]:
    """The [start, end) intervals where ``on`` is set, in the times of ``t`` (an interval still open at
    the end closes one sample period after the last sample)."""
    if not len(t):
        return ()
    edges = np.diff(np.concatenate([[0], (on > 0.5).astype(int), [0]]))
    dt = float(t[1] - t[0]) if len(t) > 1 else 0.01
    ends = [float(t[b]) if b < len(t) else float(t[-1]) + dt for b in np.nonzero(edges == -1)[0]]
    return tuple(zip((float(t[a]) for a in np.nonzero(edges == 1)[0]), ends, strict=True))


def marks(signals: dict[str, np.ndarray]) -> list[Mark]:
    """Sensor faults and RC loss, each only when the run had one."""
    t = signals["t"]
    out = []
    for label, colour, on in (
        ("sensor fault", "#f4cccc", signals["fault"]),
        ("RC link lost", "#cfe2f3", 1 - signals["rc_link"]),
    ):
        s = spans(t, on) if len(on) else ()
        if s:
            out.append(Mark(label, colour, s))
    return out
