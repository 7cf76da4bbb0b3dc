"""rig.api against the command line: the same run, the same files; validate's problems; sweep's table."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pyarrow as pa
import pytest

from rig import api
from tests.api import SHORT, failing_copy

#: result.json's fields that say when, where and how fast a run was made, not what it did
VOLATILE = {"started", "host", "wall_time", "realtime_factor", "scenario_file"}


def _result_json(path: Path) -> dict[str, object]:
    """result.json without what differs between two runs of one scenario (the run's own folder: the
    reference FC's configuration file is in it)."""
    data = json.loads(path.read_text().replace(str(path.parents[1]), "OUT"))
    data["metadata"] = {k: v for k, v in data["metadata"].items() if k not in VOLATILE}
    return data


def test_run_writes_what_rig_run_writes(tmp_path):
    cli = subprocess.run([sys.executable, "-m", "rig.cli", "run", str(SHORT), "--out", str(tmp_path / "cli"),
                          "--seed", "3"], capture_output=True, text=True, timeout=120)
    assert cli.returncode == 0, cli.stderr
    r = api.run(SHORT, seed=3, out=tmp_path / "api")
    a, b = tmp_path / "cli" / "seed000_roll_stand", tmp_path / "api" / "seed000_roll_stand"
    assert r.run_dir == b and r.verdict == "pass" and r.passed and r.seed == 3
    assert (b / "telemetry.csv").read_text() == (a / "telemetry.csv").read_text()
    assert _result_json(b / "result.json") == _result_json(a / "result.json")
    assert sorted(p.name for p in b.iterdir()) == sorted(p.name for p in a.iterdir())
    assert set(r.artifacts) >= {"result", "telemetry", "report", "junit"}
    assert all(p.is_file() and p.parent == b for p in r.artifacts.values())
    assert r.artifacts["mcap"] == b / "run.mcap"  # (rig run writes it: docs/mcap.md)
    assert (b / "run.mcap").read_bytes().startswith(b"\x89MCAP0\r\n")  # the format's magic
    # the result object says what result.json says
    doc = json.loads((b / "result.json").read_text())
    assert r.metadata["scenario_sha256"] == doc["metadata"]["scenario_sha256"]
    assert [c.name for c in r.criteria] == [m["name"] for m in doc["measurements"]]
    assert all(c.outcome == "pass" and c.max is not None and c.margin is not None for c in r.criteria)
    # the telemetry table is telemetry.csv's columns, sample for sample
    from rig.reports import telemetry

    csv = telemetry.read((b / "telemetry.csv").read_text())
    table = r.telemetry
    assert isinstance(table, pa.Table)
    assert table.column_names == list(csv)
    assert table.num_rows == len(csv["t"]) > 700
    assert table.schema.field("roll").metadata == {b"units": b"deg"}
    roll = table.column("roll").to_numpy()
    assert [f"{v:.6g}" for v in roll[:50]] == [f"{v:.6g}" for v in csv["roll"][:50]]


def test_failing_run_names_its_criterion(tmp_path):
    r = api.run(failing_copy(tmp_path), out=tmp_path / "out")
    assert r.verdict == "fail" and not r.passed
    assert [c.name for c in r.failed_criteria] == ["overshoot after release"]
    bad = r.failed_criteria[0]
    assert bad.max == 0.001 and bad.value > bad.max and bad.units == "%"
    assert type(bad.value) is float and type(bad.margin) is float  # plain numbers, not numpy's


def test_load_scenario_by_name_and_file():
    by_name = api.load_scenario("seed000_roll_stand")
    assert by_name == api.load_scenario(SHORT)
    assert by_name.stem == "seed000_roll_stand" and by_name.duration == 8.0
    with pytest.raises(api.ScenarioError, match="no_such_scenario"):
        api.load_scenario("no_such_scenario")


def test_validate_names_every_problem(tmp_path):
    assert api.validate(SHORT) == []
    text = SHORT.read_text().replace("roll0 = ", "rol0 = ").replace("max = 25.0", "mxa = 25.0")
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("duration = 8.0", "duration = 8.0\ncolour = 1"))
    problems = api.validate(bad)
    assert all(p.startswith(f"{bad}: ") for p in problems)
    keys = [p.removeprefix(f"{bad}: ").split(":")[0] for p in problems]
    # (the criterion whose misspelt limit is taken out is then left without one: a fourth problem)
    assert keys == ["scenario.colour", "vehicle.rol0", "criteria[1].mxa", "criteria[1]"], problems
    (tmp_path / "syntax.toml").write_text("[scenario\n")
    assert len(api.validate(tmp_path / "syntax.toml")) == 1


def test_bad_options_raise_before_anything_runs(tmp_path):
    # the API's own argument names, never the command line's flags
    with pytest.raises(api.RigError, match="^dut is empty") as raised:
        api.run(SHORT, dut="", out=tmp_path / "out")
    assert "--" not in str(raised.value)
    with pytest.raises(api.RigError, match="^mcu: ") as raised:
        api.run(SHORT, mcu=("no-such-board", tmp_path / "none.hex"), out=tmp_path / "out")
    assert "--mcu" not in str(raised.value)
    was = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {min(was)})
    try:
        with pytest.raises(api.RigError, match="^spin takes two CPU cores; this process may use 1"):
            api.run(SHORT, spin=True, out=tmp_path / "out")
    finally:
        os.sched_setaffinity(0, was)
    assert not (tmp_path / "out" / "seed000_roll_stand").exists()


def test_sweep_returns_the_runs_table(tmp_path):
    """In a process of its own: a sweep's local pool (spawned workers, multiprocessing's resource
    tracker, signal masks) is not left in the test runner's process. (A make test run once died of
    SIGPIPE after the in-process version: vcdvcd's import had set SIGPIPE to SIG_DFL in every xdist
    worker, since fixed and checked by tests/test_sigpipe.py.)"""
    spec = tmp_path / "sweep.toml"
    spec.write_text('[sweep]\nscenario = "seed000_roll_stand"\nseeds = [1, 2]\n')
    code = (
        "import sys, json\nfrom pathlib import Path\nimport pyarrow as pa\nfrom rig import api\n"
        "t = api.sweep(Path(sys.argv[1]), out=Path(sys.argv[2]), jobs=2)\n"
        "assert isinstance(t, pa.Table)\n"
        "print(json.dumps({'rows': t.num_rows, 'seed': t.column('seed').to_pylist(),"
        " 'verdict': t.column('verdict').to_pylist()}))\n"
        "try:\n    api.sweep(Path(sys.argv[3]), out=Path(sys.argv[2]) / 'x')\n"
        "except api.RigError as e:\n    print(json.dumps({'error': str(e)}))\n"
    )
    bad = tmp_path / "bad.toml"
    bad.write_text('[sweep]\nscenario = "no_such"\n')
    done = subprocess.run([sys.executable, "-c", code, str(spec), str(tmp_path / "sweep"), str(bad)],
                          capture_output=True, text=True, timeout=300, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, done.stderr
    table, refused = (json.loads(line) for line in done.stdout.splitlines()[-2:])
    assert table["rows"] == 2 and sorted(table["seed"]) == [1, 2]
    assert table["verdict"] == ["pass", "pass"]
    assert "sweep.scenario" in refused["error"]
