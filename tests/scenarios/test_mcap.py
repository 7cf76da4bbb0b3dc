"""run.mcap read back with Foxglove's own reader (``mcap.reader.make_reader``), not with our writer:
the channels and their JSON schemas, the attitude channel against telemetry.csv sample for sample, the
I2C channel against the run's bus transaction count, the metadata against result.json's, and
``rig report --mcap`` writing the file for a run that never had one."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader

from rig.reports import mcap as rig_mcap
from rig.reports import telemetry

PY = sys.executable
SCENARIO = """[scenario]
name = "mcap check"
duration = 3.0
[[faults]]
target = "gyro"
kind = "stuck"
start = 2.0
end = 2.5
[[timeline]]
t = 1.2
sticks = { arm = true, throttle = 0.0 }
[[timeline]]
t = 1.6
link = "failsafe"
[[criteria]]
name = "level"
metric = "max"
signal = "tilt"
max = 5.0
"""


def read(path: Path) -> tuple[Any, dict[str, list[tuple[int, dict[str, Any]]]], dict[str, dict[str, str]]]:
    """The file's summary, its messages by topic (log time, decoded JSON) and its metadata records."""
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        by_topic: dict[str, list[tuple[int, dict[str, Any]]]] = {}
        for _, channel, message in reader.iter_messages(log_time_order=False):
            by_topic.setdefault(channel.topic, []).append((message.log_time, json.loads(message.data)))
        meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
    return summary, by_topic, meta


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    tmp = tmp_path_factory.mktemp("mcap")
    (tmp / "mcap_check.toml").write_text(SCENARIO)
    p = subprocess.run([PY, "-m", "rig.cli", "run", str(tmp / "mcap_check.toml"), "--out", str(tmp / "out")],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode in (0, 1), p.stderr
    return tmp / "out" / "mcap_check"


def test_every_group_has_its_channel_with_a_json_schema(run_dir: Path) -> None:
    summary, by_topic, _ = read(run_dir / "run.mcap")
    channels = summary.channels.values()
    assert sorted(c.topic for c in channels) == sorted(rig_mcap.TOPICS)
    assert len(summary.schemas) == len({s["title"] for s in rig_mcap.SCHEMAS.values()}) == 9
    for c in channels:
        schema = summary.schemas[c.schema_id]
        assert c.message_encoding == "json" and schema.encoding == "jsonschema"
        doc = json.loads(schema.data)
        assert doc["type"] == "object" and doc["properties"]
        for _, msg in by_topic.get(c.topic, [])[:50]:  # each message has what its schema requires
            assert set(doc["required"]) <= set(msg), c.topic
    # every group was written: the run read its sensors, flew RC frames, switched a fault
    assert {t for t, msgs in by_topic.items() if msgs} == set(rig_mcap.TOPICS)


def test_the_attitude_channel_is_telemetry_csv_sample_for_sample(run_dir: Path) -> None:
    _, by_topic, _ = read(run_dir / "run.mcap")
    csv = telemetry.read((run_dir / "telemetry.csv").read_text())
    att = by_topic["/attitude"]
    assert len(att) == len(csv["t"]) == 301
    for k, (t_ns, msg) in enumerate(att):
        assert t_ns == round(csv["t"][k] * 1e9)
        for name in ("t", *rig_mcap.ATTITUDE):
            v, want = msg[name], csv[name][k]
            if math.isnan(want):
                assert v is None, (name, k)
            else:  # (telemetry.csv holds 6 significant digits of the same number)
                assert f"{v:.6g}" == f"{want:.6g}", (name, k, v, want)
    motors = by_topic["/motors"]
    assert [m["pwm1"] for _, m in motors][-1] == pytest.approx(csv["pwm1"][-1], rel=1e-5)


def test_the_i2c_channel_holds_every_bus_transaction(run_dir: Path) -> None:
    _, by_topic, meta = read(run_dir / "run.mcap")
    result = json.loads((run_dir / "result.json").read_text())
    i2c = by_topic["/i2c"]
    assert len(i2c) == result["metadata"]["bus_transactions"] > 1000
    times = [t for t, _ in i2c]
    assert times == sorted(times) and times[-1] <= 3.0e9
    assert all(m["t_ns"] == t for t, m in i2c)
    assert {m["address"] for _, m in i2c} >= {0x68}
    # the MPU-6050's data burst, decoded on /sensors, is the bytes /i2c carries
    burst = next(m for _, m in i2c if m["address"] == 0x68 and m["register"] == 0x3B and m["read"])
    sensors = [m for _, m in by_topic["/sensors"] if m["chip"] == "MPU-6050"]
    raw = bytes.fromhex(burst["read"])
    assert sensors[0]["values"]["az"] == int.from_bytes(raw[4:6], "big", signed=True)
    assert "note /i2c" not in meta["mcap"]


def test_the_metadata_is_result_json_s(run_dir: Path) -> None:
    _, by_topic, meta = read(run_dir / "run.mcap")
    result = json.loads((run_dir / "result.json").read_text())
    assert {k: json.loads(v) for k, v in meta["result"].items()} == result["metadata"]
    assert meta["run"]["verdict"] == result["verdict"]
    (t_last, criteria), = by_topic["/criteria"]
    assert criteria["measurements"] == result["measurements"]
    assert t_last == max(t for msgs in by_topic.values() for t, _ in msgs)


def test_rc_frames_and_fault_events_are_at_their_sim_times(run_dir: Path) -> None:
    _, by_topic, _ = read(run_dir / "run.mcap")
    rc = by_topic["/rc"]
    assert len(rc) == math.ceil(3.0 / 0.014)  # an SBUS frame every 14 ms, the failsafe ones included
    assert not rc[0][1]["failsafe"] and rc[-1][1]["failsafe"]
    first_failsafe = next(t for t, m in rc if m["failsafe"])
    assert 1.6e9 <= first_failsafe < 1.6e9 + 14e6
    events = [(t, m["event"]) for t, m in by_topic["/faults"]]
    assert events == [(2_000_000_000, "active"), (2_500_000_000, "cleared")]  # the fault's [start, end)
    assert by_topic["/faults"][0][1]["what"] == "gyro stuck 2..2.5 s"


def test_rig_report_mcap_writes_it_for_an_old_run(run_dir: Path, tmp_path: Path) -> None:
    import shutil

    old = tmp_path / "old"
    shutil.copytree(run_dir.parent, old)
    (old / "mcap_check" / "run.mcap").unlink()  # as a run made before the rig wrote it
    p = subprocess.run([PY, "-m", "rig.cli", "report", str(old), "--mcap"], capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 0, p.stderr
    _, by_topic, meta = read(old / "mcap_check" / "run.mcap")
    _, fresh, _ = read(run_dir / "run.mcap")
    result = json.loads((old / "mcap_check" / "result.json").read_text())
    assert {k: json.loads(v) for k, v in meta["result"].items()} == result["metadata"]
    # the flight is what telemetry.csv kept (6 digits); the bus and the RC frames were never kept
    assert len(by_topic["/attitude"]) == len(fresh["/attitude"])
    for (_, a), (_, b) in zip(by_topic["/attitude"], fresh["/attitude"], strict=True):
        assert a["roll"] == pytest.approx(b["roll"], rel=1e-5, abs=1e-9)
    assert "/i2c" not in by_topic and "/rc" not in by_topic
    assert "rig report --mcap" in meta["mcap"]["note /i2c"]
    assert "rig report --mcap" in meta["mcap"]["note /rc"]
    assert [(t, m["event"]) for t, m in by_topic["/faults"]] == [(t, m["event"]) for t, m in fresh["/faults"]]


def test_a_target_that_cannot_see_the_bus_says_so(run_dir: Path, tmp_path: Path) -> None:
    from rig.reports.load import read_run

    r = read_run(run_dir)  # (i2c and rc_frames None: as a bridge run's result has them)
    r.metadata["mode"] = "bridge"
    summary, by_topic, meta = read(rig_mcap.write_run(tmp_path, r))
    assert len(summary.channels) == len(rig_mcap.TOPICS)
    assert "/i2c" not in by_topic and "/sensors" not in by_topic
    assert "this target (bridge) cannot see" in meta["mcap"]["note /i2c"]
    assert meta["mcap"]["messages /i2c"] == "0"
    assert [p.name for p in tmp_path.iterdir()] == ["run.mcap"]  # (no temporary file left)


def test_a_capped_transaction_log_is_said_in_the_metadata(run_dir: Path, tmp_path: Path) -> None:
    from rig.reports.load import read_run
    from rig.scenarios.result import I2CRecord

    r = read_run(run_dir)
    r.i2c = [I2CRecord(1000 * k, 0x68, None, b"", b"\x00", True) for k in range(3)]
    r.metadata["bus_transactions"] = 5
    _, by_topic, meta = read(rig_mcap.write_run(tmp_path, r))
    assert len(by_topic["/i2c"]) == 3
    assert "the first 3 of the run's 5 transfers" in meta["mcap"]["note /i2c"]
