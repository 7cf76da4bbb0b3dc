"""run.mcap's channels in Foxglove's well-known schemas, read back with Foxglove's ``mcap`` reader: the
schemas against the definitions Foxglove publishes (written here from foxglove-sdk's
schemas/jsonschema/FrameTransform.json and Log.json, not taken from the code under test), every
message valid under them, the vehicle's rotation against the attitude by a formula of its own, the
log holding the rig's words, and docs/foxglove-layout.json naming only what a run.mcap holds."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rig.reports import foxglove
from rig.reports import mcap as rig_mcap
from tests.scenarios.test_mcap import SCENARIO, read

LAYOUT = Path(__file__).resolve().parents[2] / "docs" / "foxglove-layout.json"

_TIME = {"type": "object", "title": "time",
         "properties": {"sec": {"type": "integer", "minimum": 0},
                        "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}}
#: Foxglove's published JSON schemas (foxglove-sdk, schemas/jsonschema), the fields a message needs
PUBLISHED: dict[str, dict[str, Any]] = {
    "foxglove.FrameTransform": {
        "type": "object",
        "properties": {
            "timestamp": _TIME,
            "parent_frame_id": {"type": "string"},
            "child_frame_id": {"type": "string"},
            "translation": {"title": "foxglove.Vector3", "type": "object",
                            "properties": {k: {"type": "number"} for k in "xyz"},
                            "required": ["x", "y", "z"]},
            "rotation": {"title": "foxglove.Quaternion", "type": "object",
                         "properties": {k: {"type": "number"} for k in "xyzw"},
                         "required": ["x", "y", "z", "w"]},
        },
        "required": ["timestamp", "parent_frame_id", "child_frame_id", "translation", "rotation"],
    },
    "foxglove.Log": {
        "type": "object",
        "properties": {
            "timestamp": _TIME,
            "level": {"title": "foxglove.LogLevel",
                      "oneOf": [{"title": t, "const": k} for k, t in
                                enumerate(["UNKNOWN", "DEBUG", "INFO", "WARNING", "ERROR", "FATAL"])]},
            "message": {"type": "string"},
            "name": {"type": "string"},
            "file": {"type": "string"},
            "line": {"type": "integer", "minimum": 0},
        },
        "required": ["timestamp", "level", "message", "name", "file", "line"],
    },
}
PY_TYPES: dict[str, type | tuple[type, ...]] = {"object": dict, "string": str, "integer": int,
                                                "number": (int, float)}


def problems(value: Any, schema: dict[str, Any], where: str = "") -> list[str]:
    """Where ``value`` breaks ``schema`` (the keywords Foxglove's definitions use), [] when valid."""
    out: list[str] = []
    kind = schema.get("type")
    if kind is not None and (not isinstance(value, PY_TYPES[kind]) or isinstance(value, bool)):
        return [f"{where}: {value!r} is not {kind}"]
    if "oneOf" in schema and sum(value == c["const"] for c in schema["oneOf"]) != 1:
        out.append(f"{where}: {value!r} is none of {[c['const'] for c in schema['oneOf']]}")
    if "minimum" in schema and value < schema["minimum"] or "maximum" in schema and value > schema["maximum"]:
        out.append(f"{where}: {value!r} out of range")
    for name in schema.get("required", []):
        if name not in value:
            out.append(f"{where}.{name}: missing")
    for name, sub in schema.get("properties", {}).items():
        if isinstance(value, dict) and name in value:
            out += problems(value[name], sub, f"{where}.{name}")
    return out


def same_shape(ours: dict[str, Any], published: dict[str, Any], where: str = "") -> None:
    """Our schema declares every published field with the published type, title, range and values."""
    for key in ("type", "title", "minimum", "maximum", "required"):
        if key in published:
            assert ours.get(key) == published[key], (where, key)
    if "oneOf" in published:
        assert [(c["title"], c["const"]) for c in ours["oneOf"]] == \
            [(c["title"], c["const"]) for c in published["oneOf"]], where
    for name, sub in published.get("properties", {}).items():
        assert name in ours["properties"], f"{where}.{name}"
        same_shape(ours["properties"][name], sub, f"{where}.{name}")


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    tmp = tmp_path_factory.mktemp("foxglove")
    (tmp / "mcap_check.toml").write_text(SCENARIO)
    p = subprocess.run([sys.executable, "-m", "rig.cli", "run", str(tmp / "mcap_check.toml"), "--out",
                        str(tmp / "out")], capture_output=True, text=True, timeout=300)
    assert p.returncode in (0, 1), p.stderr
    return tmp / "out" / "mcap_check"


def test_the_foxglove_channels_carry_foxglove_s_published_schemas(run_dir: Path) -> None:
    summary, by_topic, _ = read(run_dir / "run.mcap")
    titles = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
    assert titles["/vehicle/transform"] == titles["/vehicle/target"] == "foxglove.FrameTransform"
    assert titles["/log"] == "foxglove.Log"
    for c in summary.channels.values():
        schema = summary.schemas[c.schema_id]
        if schema.name in PUBLISHED:
            doc = json.loads(schema.data)
            assert doc["title"] == schema.name
            same_shape(doc, PUBLISHED[schema.name])
            for _, msg in by_topic[c.topic]:
                assert problems(msg, PUBLISHED[schema.name]) == [], c.topic
    att = by_topic["/attitude"]
    assert len(by_topic["/vehicle/transform"]) == len(by_topic["/vehicle/target"]) == len(att)
    for t_ns, msg in by_topic["/vehicle/transform"]:
        assert msg["timestamp"]["sec"] * 10**9 + msg["timestamp"]["nsec"] == t_ns
        assert (msg["parent_frame_id"], msg["child_frame_id"]) == ("world", "vehicle")


def rotate(q: dict[str, float], v: tuple[float, float, float]) -> tuple[float, ...]:
    """v turned by the unit quaternion q (v' = q v q*, written out)."""
    x, y, z, w = q["x"], q["y"], q["z"], q["w"]
    tx, ty, tz = 2 * (y * v[2] - z * v[1]), 2 * (z * v[0] - x * v[2]), 2 * (x * v[1] - y * v[0])
    return (v[0] + w * tx + y * tz - z * ty, v[1] + w * ty + z * tx - x * tz, v[2] + w * tz + x * ty - y * tx)


def assert_points_as(q: dict[str, float], roll: float, pitch: float, yaw: float) -> None:
    """The nose and the left wing in north-west-up, from roll, pitch and yaw (deg; north-east-down,
    z-y-x): the nose is (cos θ cos ψ, -cos θ sin ψ, sin θ); the right wing in NED is (cos ψ sin θ sin φ -
    sin ψ cos φ, sin ψ sin θ sin φ + cos ψ cos φ, cos θ sin φ), the left wing in NWU its opposite with y
    and z turned."""
    phi, theta, psi = (math.radians(a) for a in (roll, pitch, yaw))
    nose = (math.cos(theta) * math.cos(psi), -math.cos(theta) * math.sin(psi), math.sin(theta))
    right = (math.cos(psi) * math.sin(theta) * math.sin(phi) - math.sin(psi) * math.cos(phi),
             math.sin(psi) * math.sin(theta) * math.sin(phi) + math.cos(psi) * math.cos(phi),
             math.cos(theta) * math.sin(phi))
    assert rotate(q, (1, 0, 0)) == pytest.approx(nose, abs=1e-9)
    assert rotate(q, (0, 1, 0)) == pytest.approx((-right[0], right[1], right[2]), abs=1e-9)


def test_the_quaternion_turns_the_body_as_roll_pitch_and_yaw_say() -> None:
    angles = [(r, p, y) for r in (-170.0, -30.0, 0.0, 45.0) for p in (-80.0, 0.0, 20.0)
              for y in (-135.0, 0.0, 90.0)]
    rows = foxglove.quaternion(*(np.array(col) for col in zip(*angles, strict=True)))
    for (r, p, y), q in zip(angles, rows.tolist(), strict=True):
        assert_points_as(dict(zip("xyzw", q, strict=True)), r, p, y)


def test_the_vehicle_frame_is_the_runs_attitude_and_altitude(run_dir: Path) -> None:
    _, by_topic, _ = read(run_dir / "run.mcap")
    att = {t: m for t, m in by_topic["/attitude"]}
    for t_ns, msg in by_topic["/vehicle/transform"]:
        a = att[t_ns]
        assert_points_as(msg["rotation"], a["roll"], a["pitch"], a["yaw"])
        assert msg["translation"] == {"x": 0.0, "y": 0.0, "z": pytest.approx(a["alt"], abs=1e-12)}
    for t_ns, msg in by_topic["/vehicle/target"]:
        a = att[t_ns]
        assert_points_as(msg["rotation"], a["roll_sp"], a["pitch_sp"], a["yaw"])


def test_the_log_holds_the_faults_the_notes_and_the_verdict(run_dir: Path) -> None:
    _, by_topic, _ = read(run_dir / "run.mcap")
    result = json.loads((run_dir / "result.json").read_text())
    logs = by_topic["/log"]
    faults = [(t, m["level"], m["message"]) for t, m in logs if m["name"] == "rig/faults"]
    assert faults == [(2_000_000_000, 3, "fault active: gyro stuck 2..2.5 s"),
                      (2_500_000_000, 3, "fault cleared: gyro stuck 2..2.5 s")]
    rig_lines = [m["message"] for _, m in logs if m["name"] == "rig"]
    assert rig_lines[-1] == f"verdict: {result['verdict']}"
    assert all(note in rig_lines for note in result["notes"])


def _message_paths(config: Any) -> list[str]:
    if isinstance(config, dict):
        found = [v for k, v in config.items()
                 if k in ("value", "topicPath", "topicToRender") and isinstance(v, str)]
        return found + [p for v in config.values() for p in _message_paths(v)]
    if isinstance(config, list):
        return [p for v in config for p in _message_paths(v)]
    return []


def _panels(node: Any) -> list[str]:
    return [node] if isinstance(node, str) else _panels(node["first"]) + _panels(node["second"])


def test_the_layout_shows_only_what_a_run_holds() -> None:
    layout = json.loads(LAYOUT.read_text())
    assert sorted(_panels(layout["layout"])) == sorted(layout["configById"])
    kinds = {p.split("!")[0] for p in layout["configById"]}
    assert {"Plot", "3D", "StateTransitions", "Log"} <= kinds
    paths = _message_paths(layout["configById"])
    assert len(paths) > 10
    for path in paths:
        topic, _, field = path.partition(".")
        assert topic in rig_mcap.TOPICS, path
        assert not field or field in rig_mcap.SCHEMAS[topic]["properties"], path
    shown = {p.partition(".")[0] for p in paths}
    assert {"/attitude", "/motors", "/i2c", "/faults", "/log"} <= shown
    assert layout["configById"]["3D!vehicle"]["followTf"] == "vehicle"
