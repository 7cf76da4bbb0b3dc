"""run.mcap's channels in Foxglove's well-known schemas, beside the plot-only ``rig.*`` ones
(reports/mcap.py): Foxglove's 3D panel shows the vehicle's attitude and altitude, and its Log panel
the rig's words and the DUT's, with no configuration (docs/foxglove-layout.json opens a run as a
dashboard).

Why these: ``foxglove.FrameTransform`` is what the 3D panel places frames with (the vehicle, and the
attitude it is asked for, beside it); ``foxglove.Log`` what the Log panel lists. Both as JSON with the
JSON schemas Foxglove publishes (their ``title`` is the name Foxglove recognises), field for field.

Frames: ``world`` is north-west-up (the plant's north-east-down turned so that up is up, as the 3D
panel draws), ``vehicle`` the body front-left-up, at the true altitude over the start point (the plant
has no horizontal position); ``target`` the same place turned to the setpoints (roll and pitch sticks
as angles, the true yaw: the sticks set a yaw rate, not a heading).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any, Final

import numpy as np

#: the topics, after reports/mcap.py's own
TRANSFORM_TOPIC: Final = "/vehicle/transform"
TARGET_TOPIC: Final = "/vehicle/target"
LOG_TOPIC: Final = "/log"
TOPICS: Final = (TRANSFORM_TOPIC, TARGET_TOPIC, LOG_TOPIC)
WORLD: Final = "world"
#: foxglove.LogLevel's names, by value
LEVELS: Final = ("UNKNOWN", "DEBUG", "INFO", "WARNING", "ERROR", "FATAL")
INFO, WARNING, ERROR = (LEVELS.index(n) for n in ("INFO", "WARNING", "ERROR"))

_TIME: Final[dict[str, Any]] = {
    "type": "object", "title": "time",
    "properties": {"sec": {"type": "integer", "minimum": 0},
                   "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}},
}


def _xyz(title: str, names: str) -> dict[str, Any]:
    return {"title": title, "type": "object", "properties": {n: {"type": "number"} for n in names},
            "required": list(names)}


FRAME_TRANSFORM: Final[dict[str, Any]] = {
    "title": "foxglove.FrameTransform",
    "description": "A transform between two reference frames in 3D space",
    "type": "object",
    "properties": {
        "timestamp": {**_TIME, "description": "Timestamp of transform"},
        "parent_frame_id": {"type": "string", "description": "Name of the parent frame"},
        "child_frame_id": {"type": "string", "description": "Name of the child frame"},
        "translation": _xyz("foxglove.Vector3", "xyz"),
        "rotation": _xyz("foxglove.Quaternion", "xyzw"),
    },
    "required": ["timestamp", "parent_frame_id", "child_frame_id", "translation", "rotation"],
}
LOG: Final[dict[str, Any]] = {
    "title": "foxglove.Log",
    "description": "A log message",
    "type": "object",
    "properties": {
        "timestamp": {**_TIME, "description": "Timestamp of log message"},
        "level": {"title": "foxglove.LogLevel", "description": "Log level",
                  "oneOf": [{"title": name, "const": k} for k, name in enumerate(LEVELS)]},
        "message": {"type": "string", "description": "Log message"},
        "name": {"type": "string", "description": "Process or node name"},
        "file": {"type": "string", "description": "Filename"},
        "line": {"type": "integer", "minimum": 0, "description": "Line number in the file"},
    },
    "required": ["timestamp", "level", "message", "name", "file", "line"],
}
SCHEMAS: Final[dict[str, dict[str, Any]]] = {TRANSFORM_TOPIC: FRAME_TRANSFORM, TARGET_TOPIC: FRAME_TRANSFORM,
                                             LOG_TOPIC: LOG}

_TRANSFORM: Final = ('{"timestamp":{"sec":%d,"nsec":%d},"parent_frame_id":"world","child_frame_id":"%s",'
                     '"translation":{"x":0.0,"y":0.0,"z":%r},"rotation":{"x":%r,"y":%r,"z":%r,"w":%r}}')


def quaternion(roll_deg: np.ndarray, pitch_deg: np.ndarray, yaw_deg: np.ndarray) -> np.ndarray:
    """(x, y, z, w) of the front-left-up body in the north-west-up world, per row, from the plant's
    roll, pitch and yaw (north-east-down, z-y-x): about x by roll, about y by -pitch, about z by -yaw."""
    r, p, y = (np.radians(a) / 2 for a in (roll_deg, -pitch_deg, -yaw_deg))
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.column_stack([sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
                            cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy])


def transforms(signals: dict[str, np.ndarray], child: str, roll: str,
               pitch: str) -> Iterator[tuple[int, bytes]]:
    """(sim time ns, message) of the ``child`` frame at each recorder row where all it needs is known."""
    names = ("t", "alt", roll, pitch, "yaw")
    if any(n not in signals for n in names):
        return
    t, alt, rr, pp, yy = (np.asarray(signals[n], dtype=np.float64) for n in names)
    q = quaternion(rr, pp, yy)
    finite = np.isfinite(np.column_stack([t, alt, q])).all(axis=1) & (t >= 0)
    for k in np.flatnonzero(finite).tolist():
        t_ns = round(float(t[k]) * 1e9)
        x, y, z, w = q[k].tolist()
        yield t_ns, (_TRANSFORM % (t_ns // 1_000_000_000, t_ns % 1_000_000_000, child, float(alt[k]),
                                   x, y, z, w)).encode()


def log(t_ns: int, level: int, name: str, message: str) -> dict[str, Any]:
    """One foxglove.Log message (the rig has no source file or line to give: empty and 0)."""
    t_ns = max(0, t_ns)
    return {"timestamp": {"sec": t_ns // 1_000_000_000, "nsec": t_ns % 1_000_000_000}, "level": level,
            "message": message, "name": name, "file": "", "line": 0}


def logs(end_ns: int, notes: list[str], faults: list[tuple[int, dict[str, Any]]], stderr: str,
         verdict: str, error: str | None) -> Iterator[tuple[int, dict[str, Any]]]:
    """The run's words as foxglove.Log, in time order: the fault events as they switch (WARNING), then
    at the run's end (the rig keeps no time for them) the DUT's lines on stderr (``dut``, INFO), the
    rig's notes (``rig``, INFO), its error (ERROR) and the verdict."""
    for t_ns, ev in faults:
        yield t_ns, log(t_ns, WARNING, "rig/faults", f"fault {ev['event']}: {ev['what']}")
    for line in stderr.splitlines():
        if line.strip():
            yield end_ns, log(end_ns, INFO, "dut", line)
    for note in notes:
        yield end_ns, log(end_ns, INFO, "rig", note)
    if error:
        yield end_ns, log(end_ns, ERROR, "rig", error)
    yield end_ns, log(end_ns, ERROR if verdict in ("fail", "error") else INFO, "rig", f"verdict: {verdict}")

