"""Every client sequence of docs/sensors.md §7, stored as a trace file, replays against the emulators
with the bytes the real chips would give."""

from __future__ import annotations

import json

import pytest

from rig.emulators.mpu6050 import ImuTruth
from rig.emulators.ms5611 import BaroTruth
from rig.emulators.trace import TRACE_DIR, TraceError, load, parse_msg, replay
from tests.emulators.boards import make_board

TRACES = sorted(TRACE_DIR.glob("*.json"))


def board_for(trace):
    tr = trace["truth"]
    return make_board(
        lambda t: ImuTruth(tuple(tr["accel"]), tuple(tr["gyro"]), tr["temperature"]),
        lambda t: tuple(tr["field"]),
        lambda t: BaroTruth(tr["pressure"], tr["temperature"]),
        trace["topology"], dlpf=False)


def test_the_library_has_the_clients_of_specs_section_7():
    names = {p.stem for p in TRACES}
    assert {"i2c_tools", "mpu6050_raspberrypi", "adafruit_mpu6050", "crazyflie_cf1", "ardupilot_ms5611",
            "multiwii_gy86", "linux_iio", "te_generic_ms5611", "micropython_ms5611", "ardupilot_hmc5843",
            "ardupilot_invensense"} <= names


@pytest.mark.parametrize("path", TRACES, ids=[p.stem for p in TRACES])
def test_trace_replays_without_a_mismatch(path):
    trace = load(path)
    checked = sum(1 for s in trace["steps"] for e in s.get("expect", []) if e is not None)
    assert checked >= 3  # a trace that checks nothing proves nothing
    problems = replay(trace, board_for(trace).bus)
    assert problems == []


def test_a_wrong_expectation_is_reported():
    trace = load(TRACE_DIR / "i2c_tools.json")
    trace["steps"][4]["expect"] = ["69"]  # WHO_AM_I is 0x68
    problems = replay(trace, board_for(trace).bus)
    assert len(problems) == 1 and problems[0].expected == "69" and problems[0].got == "68"


def test_malformed_traces_fail_with_the_file_named(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(TraceError, match="bad.json: not JSON"):
        load(bad)
    bad.write_text(json.dumps({"name": "x", "truth": {}, "steps": []}))
    with pytest.raises(TraceError, match="missing key 'topology'"):
        load(bad)
    with pytest.raises(TraceError, match="expected 'w ADDR"):
        parse_msg("x 68")
