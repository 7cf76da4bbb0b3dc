"""A bench run with a supply: `rig run --bridge virtual --psu riden:PTY` against a simulated RD6006 on a
real pty. The supply is set, switched off, then on once the bridge is configured, and read while the
run lasts; its volts and amps are in telemetry.csv on the run's sim-time grid; a board that draws over
`[bench] max_current` ends the run as an error, and a supply that does not answer is a clear error."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.bridge.tools import vbridge
from tests.power.sim_supplies import SimRiden
from tests.realtime import of_results, realtime

SCENARIO = """
[scenario]
name = "bench power"
duration = {duration}

[vehicle]
stand = 1

[bench]
volts = 11.1
current_limit = 2.0
max_current = 1.0
off_s = 0.0

[[criteria]]
name = "the board draws under 0.5 A"
metric = "max"
signal = "psu_amps"
start = 1.0
max = 0.5
"""


def bench_run(tmp_path: Path, supply: SimRiden, duration: float = 2.0,
              paced: bool = False) -> tuple[int, str, dict[str, Any], Path]:
    """The run; ``paced``: the test judges what the wall clock paced (the readings' share of the
    record), so a run the host starved is flown again, then inconclusive (tests/realtime.py)."""
    vbridge()
    scenario = tmp_path / "bench_power.toml"
    scenario.write_text(SCENARIO.format(duration=duration))
    out = tmp_path / "out"

    def fly() -> subprocess.CompletedProcess[str]:
        supply.log.clear()  # (a second try is judged on its own exchanges)
        return subprocess.run([sys.executable, "-m", "rig.cli", "run", str(scenario), "--bridge", "virtual",
                               "--psu", f"riden:{supply.path}", "--out", str(out)],
                              capture_output=True, text=True, timeout=300)

    r = realtime(fly, of_results(out, ["bench_power"])) if paced else fly()
    result = json.loads((out / "bench_power" / "result.json").read_text())
    return r.returncode, r.stderr, result, out / "bench_power" / "telemetry.csv"


@pytest.fixture
def supply() -> Iterator[SimRiden]:
    s = SimRiden()
    yield s
    s.close()


@pytest.mark.paced
def test_power_cycled_before_the_run_and_recorded_in_the_telemetry(tmp_path: Path, supply: SimRiden) -> None:
    code, stderr, result, telemetry = bench_run(tmp_path, supply, paced=True)
    assert code == 0, stderr
    assert result["verdict"] == "pass"
    # set, off, on — in that order, before anything is read while the run lasts
    assert supply.writes() == [(8, 1110), (9, 2000), (18, 0), (18, 1)]
    on_at = supply.log.index(("write", (18, 1)))
    assert ("read", (10, 2)) not in supply.log[:on_at] and ("read", (10, 2)) in supply.log[on_at:]
    power = result["metadata"]["bench_power"]
    assert power["sequence"] == ["off", "on", "up"] and power["supply"] == "Riden RD6006"
    assert power["peak_amps"] == pytest.approx(0.35) and power["samples"] > 0
    assert result["metadata"]["bridge"]["bridge_id"]  # the link was up before the board was switched on
    rows = list(csv.DictReader(telemetry.open()))
    volts = [float(r["psu_volts[V]"]) for r in rows if r["psu_volts[V]"] not in ("", "nan")]
    amps = {float(r["psu_amps[A]"]) for r in rows if r["psu_amps[A]"] not in ("", "nan")}
    assert set(volts) == {11.1} and amps == {0.35}
    # the readings join the 100 Hz record at 10 Hz of sim time: most of the 2 s carry one
    assert len(volts) >= 0.9 * len(rows)
    measured = {m["name"]: m for m in result["measurements"]}
    assert measured["the board draws under 0.5 A"]["value"] == pytest.approx(0.35)


def test_over_current_ends_the_run_as_an_error(tmp_path: Path, supply: SimRiden) -> None:
    supply.load.amps = 1.4  # under the supply's 2 A limit, over the scenario's 1 A
    code, stderr, result, _ = bench_run(tmp_path, supply, duration=5.0)
    assert code == 3 and result["verdict"] == "error"
    assert "over-current: the board drew 1.400 A, over the limit of 1 A" in result["error"]
    assert result["metadata"]["sim_time"] < 5.0  # ended by the reading, not by the scenario's end


def test_a_supply_that_does_not_answer_is_a_clear_error(tmp_path: Path, supply: SimRiden) -> None:
    supply.mode = "silent"
    code, stderr, result, _ = bench_run(tmp_path, supply)
    assert code == 3 and result["verdict"] == "error"
    assert f"bench supply: riden:{supply.path}: no valid answer" in result["error"]
    assert "Traceback" not in stderr
