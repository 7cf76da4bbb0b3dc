"""`rig run --bridge virtual`: the reference FC flies the whole bench path in real time (the host's
session streaming samples over the link's pty to build/vbridge, the chip core there answering the
FC's I2C, its PWM captured by the bridge as pulse widths, its sticks sent as SBUS by the bridge), and
each measurement agrees with the lockstep run of the same scenario and seed within the tolerance
tools/derive_bench_tolerance.py derives (docs/bench.md): the capture path's timing, measured in
lockstep, plus 4·√2 σ of the measurement over lockstep seeds, plus the recorder's grid for times.

Faults through the bridge (a NACKing magnetometer, a stuck gyro) act as in lockstep. A bridge that dies
or stops answering ends the run as an error within a second of sim time (real time here: the same)."""

from __future__ import annotations

import json
import math
import os
import re
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from rig.bridge.messages import PROTOCOL_VERSION
from rig.bridge.session import BenchConfig, BenchSession
from rig.scenarios.schema import load
from rig.targets import REFERENCE_FC, reference_config
from rig.world import World
from tests.bridge.tools import REPO, vbridge
from tests.realtime import fly_each, inconclusive_if_starved, of_outcome, of_results, realtime
from tests.short_scenario import SHORT_BENCH

pytestmark = pytest.mark.paced  # (make test runs these alone: tests/realtime.py)

SHOW = ["seed000_roll_stand", "step_roll", "hover_turbulence", "rc_loss_failsafe"]
FAULTS = ["fault_gyro_stuck", "fault_mag_nack"]
TOLERANCE = json.loads((Path(__file__).parent / "bench_tolerance.json").read_text())


def rig_run(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rig.cli", "run", *map(str, args)], capture_output=True,
                          text=True, timeout=600)


@pytest.fixture(scope="module")
def lockstep(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The Show's scenarios and the fault scenarios in lockstep (seed 0): each one's folder."""
    out = tmp_path_factory.mktemp("lockstep")
    lock = rig_run(*SHOW, *FAULTS, "--out", out)
    assert lock.returncode == 0, lock.stderr
    return {name: out / name for name in SHOW + FAULTS}


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory, lockstep: dict[str, Path]) -> dict[str, Any]:
    """The Show's scenarios and the fault scenarios, through the virtual bridge (seed 0). "bench" is each
    ``rig run`` of the bridge with the folder it wrote; "folders" each kind's folder of each scenario
    (a run starved twice: its last flight's); "starved" the runs the host starved twice, which make
    inconclusive only the tests that judge them (``judged``)."""
    vbridge()  # built when a source is newer
    tmp = tmp_path_factory.mktemp("bench")

    def fly(names: list[str], attempt: int) -> tuple[subprocess.CompletedProcess[str], Path]:
        out = tmp / f"bench-{attempt}"
        return rig_run("--bridge", "virtual", *names, "--out", out), out

    # (the runs the host starved of real time are flown again: tests/realtime.py)
    flights, starved_twice = fly_each(SHOW + FAULTS, fly, lambda got: of_results(got[1], SHOW + FAULTS)(None))
    bench = {name: out / name for (_, out), kept in flights for name in kept}
    bench.update({name: flights[-1][0][1] / name for name in starved_twice})
    return {"bench": [got for got, _ in flights], "folders": {"lockstep": lockstep, "bench": bench},
            "starved": starved_twice}


def judged(runs: dict[str, Any], *names: str) -> None:
    """The test judges these bench runs: inconclusive if the host starved one of them twice."""
    inconclusive_if_starved(runs["starved"], *names)


def folder(runs: dict[str, Any], kind: str, name: str) -> Path:
    path: Path = runs["folders"][kind][name]
    return path


def result(runs: dict[str, Any], kind: str, name: str) -> dict[str, Any]:
    return json.loads((folder(runs, kind, name) / "result.json").read_text())


#: fault_gyro_stuck's "level again after the fault" (max tilt 10-14 s under 3 deg) is not required on the
#: bench: the reference FC's recovery has little margin against the motor path's latency — 2.23 deg in
#: lockstep, 2.5-2.8 through the lockstep capture model of the bridge's path, 2.1-4.8 on the bench
#: (docs/bench.md). It is reported; the FC's response to the fault is held to lockstep below.
NOT_REQUIRED = {("fault_gyro_stuck", "level again after the fault")}


@pytest.mark.parametrize("name", SHOW + FAULTS)
def test_the_show_and_the_faults_pass_through_the_virtual_bridge(runs: dict[str, Any], name: str) -> None:
    judged(runs, name)
    r = result(runs, "bench", name)
    assert r["error"] is None and r["metadata"]["mode"] == "bridge", (name, r["error"])
    failed = [m["name"] for m in r["measurements"] if m["outcome"] != "pass"]
    assert not [f for f in failed if (name, f) not in NOT_REQUIRED], (name, r["measurements"])


def test_each_rig_run_says_with_its_exit_status_whether_a_measurement_failed(runs: dict[str, Any]) -> None:
    """(Whatever the host's pace: a starved flight's exit status says its outcomes too.)"""
    for done, out in runs["bench"]:
        files = [out / name / "result.json" for name in SHOW + FAULTS]
        flown = [json.loads(f.read_text()) for f in files if f.is_file()]
        assert flown, done.stderr
        outcomes = [m["outcome"] for r in flown for m in r["measurements"]]
        assert done.returncode == (0 if set(outcomes) == {"pass"} else 1), done.stderr


@pytest.mark.parametrize("name", SHOW)
def test_each_measurement_agrees_with_lockstep_within_its_derived_tolerance(runs: dict[str, Any],
                                                                             name: str) -> None:
    judged(runs, name)
    bench, lock = result(runs, "bench", name), result(runs, "lockstep", name)
    table = TOLERANCE["scenarios"][name]
    assert [m["name"] for m in bench["measurements"]] == list(table)
    for mb, ml in zip(bench["measurements"], lock["measurements"], strict=True):
        row = table[mb["name"]]
        # the tolerance was derived from this lockstep value: a lockstep run that moved more than the
        # tolerance itself means the derivation is stale (rerun tools/derive_bench_tolerance.py)
        assert abs(ml["value"] - row["lockstep"]) <= row["tolerance"], (mb["name"], ml["value"], row)
        assert abs(mb["value"] - ml["value"]) <= row["tolerance"], (name, mb["name"], mb["value"],
                                                                   ml["value"], row["tolerance"])


def fc_says(runs: dict[str, Any], kind: str, name: str) -> dict[str, float]:
    """The sim times at which the FC said each of its words on stderr ("gyro stuck ... at t=…")."""
    base = result(runs, kind, name)["metadata"]["dut_clock_base_s"]
    said: dict[str, float] = {}
    for line in (folder(runs, kind, name) / "dut-stderr.txt").read_text().splitlines():
        m = re.match(r"fc: gyro (stuck|recovered).* at t=([0-9.]+)$", line)
        if m:
            said.setdefault(m.group(1), float(m.group(2)) - base)
    return said


def test_a_stuck_gyro_is_declared_and_recovered_when_it_is_in_lockstep(runs: dict[str, Any]) -> None:
    """The stuck gyro acts on the host's samples (a signal fault): the FC sees the repeated sample and
    declares it after GYRO_STUCK_N = 10 cycles, then sees it move again, at the same sim times as in
    lockstep within 5 of its 4 ms cycles (its loop's phase on the wall clock, the lead, the link)."""
    judged(runs, "fault_gyro_stuck")
    bench, lock = fc_says(runs, "bench", "fault_gyro_stuck"), fc_says(runs, "lockstep", "fault_gyro_stuck")
    assert set(lock) == {"stuck", "recovered"} and set(bench) == set(lock), (bench, lock)
    for word in lock:
        assert abs(bench[word] - lock[word]) <= 0.02, (word, bench[word], lock[word])


def test_a_nacking_magnetometer_nacks_on_the_bridge(runs: dict[str, Any]) -> None:
    """The HMC5883L 'off' from 6 s to 8 s is a bus fault: the bridge's chip core does not acknowledge it
    then (the FC's reads of it fail and are counted), and the FC flies on as in lockstep."""
    judged(runs, "fault_mag_nack", "step_roll")
    status = result(runs, "bench", "fault_mag_nack")["metadata"]["bridge"]["bridge_status"]
    assert status["i2c_errors"] > 0
    assert result(runs, "bench", "step_roll")["metadata"]["bridge"]["bridge_status"]["i2c_errors"] == 0


def test_result_json_carries_the_bridge_and_the_links_figures(runs: dict[str, Any]) -> None:
    judged(runs, "step_roll")
    meta = result(runs, "bench", "step_roll")["metadata"]
    b = meta["bridge"]
    assert (b["bridge"], b["bridge_id"], b["protocol"]) == ("virtual", "vbridge", PROTOCOL_VERSION)
    assert b["lead_s"] == pytest.approx(0.003)
    status = b["bridge_status"]
    assert len(status["underruns"]) == 3 and status["frames_bad"] == 0 and status["refused"] == 0
    # the FC's 250 Hz loop reads the MPU-6050 (a pointer write and a read: two STARTs) for about 8.9 s
    assert status["i2c_acked"] > 2 * 250 * 8
    assert b["link"]["frames_bad"] == 0 and b["link"]["seq_gaps"] == 0
    # the bridge saw every frame the host sent but the last few in flight at the end
    assert 0 <= b["link"]["frames_sent"] - status["frames_ok"] < 50
    s = b["samples"]
    assert s["imu"] >= 9_000 and s["mag"] >= 1_900 and s["baro"] >= 4_900  # 1 kHz, 200 Hz, 500 Hz
    assert b["time_sync"]["exchanges"] >= 90  # 10 Hz over 10 s
    assert abs(b["time_sync"]["drift_ppm"]) < 1000  # one machine, one clock: no drift to speak of
    assert meta["realtime_lateness"]["events"] > 10_000
    # the host loop waits to a deadline before most of its events (about 1.8 k a second)
    assert meta["realtime_lateness"]["waits"] > 5_000
    late = meta["realtime_lateness"]
    assert sum(late["late_causes"].values()) == late["late_over_1ms"]  # each late event has a cause
    assert meta["bus_transactions"] == status["i2c_acked"]


def test_the_index_and_the_report_name_the_bridge(runs: dict[str, Any]) -> None:
    html = (folder(runs, "bench", "step_roll") / "report.html").read_text()
    assert "bridge (bench: port virtual, id vbridge" in html


def _session(name: str, tmp: Path) -> tuple[BenchSession, World]:
    sc = load(REPO / "scenarios" / "library" / f"{name}.toml")
    conf = tmp / "fc.conf"
    conf.write_text(reference_config(sc))
    world = World.at_rest(seed=0)
    cfg = BenchConfig(bridge="virtual", command=[str(REFERENCE_FC), str(conf)], serial=["/dev/ttyTEL0"],
                      duration=6.0, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return BenchSession(cfg, world), world


@pytest.mark.parametrize("how", [signal.SIGKILL, signal.SIGSTOP])
def test_a_bridge_that_dies_or_stops_answering_ends_the_run_as_an_error_within_a_second(
        tmp_path: Path, how: signal.Signals) -> None:
    vbridge()
    victim: list[int] = []

    def fly() -> tuple[Any, BenchSession]:
        session, world = _session("hover_turbulence", tmp_path)
        victim.clear()

        def hit(s: BenchSession) -> None:
            assert s.vbridge is not None
            victim.append(s.vbridge.proc.pid)
            os.kill(s.vbridge.proc.pid, how)

        session.at(2.0, hit)
        try:
            # (a stopped bridge is killed like any other: SIGKILL needs no SIGCONT)
            return session.run(), session
        finally:
            world.close()

    outcome, session = realtime(fly, lambda got: {"hover_turbulence": of_outcome(got[0])})
    assert outcome.verdict == "error"
    assert outcome.error is not None and "bridge" in outcome.error
    assert 2.0 <= outcome.sim_time < 3.0, outcome.sim_time  # sim time is the wall clock's here
    assert not math.isnan(outcome.sim_time)
    with pytest.raises(ProcessLookupError):  # nothing left behind
        os.kill(victim[0], 0)
    assert session.vbridge is not None and not Path(session.vbridge.endpoints.board).parent.exists()


def test_bad_bridge_options_are_refused_before_anything_runs(tmp_path: Path) -> None:
    r = rig_run("--bridge", tmp_path / "no-such-port", "step_roll", "--out", tmp_path / "out")
    assert r.returncode == 2
    assert "no such port" in r.stderr
    r = rig_run("--bridge", "/dev/null", "--dut", "true", "step_roll", "--out", tmp_path / "out")
    assert r.returncode == 2
    assert "the DUT is the board" in r.stderr


def test_the_motors_can_come_from_the_bridges_can_frames_over_slcan(tmp_path: Path,
                                                                    lockstep: dict[str, Path]) -> None:
    """The virtual bridge's capture frames (the DBC's, built by the core from the generated layout) read
    with python-can's slcan interface on its pty: every frame passes the CodecCan's CRC and layout
    checks, none is lost, and the flight agrees with lockstep as the link's pulses do."""
    r = realtime(lambda: rig_run("--bridge", "virtual", "--can", "slcan:vbridge", "step_roll", "--out",
                                 tmp_path / "can"), of_results(tmp_path / "can", ["step_roll"]))
    assert r.returncode == 0, r.stderr
    res = json.loads((tmp_path / "can" / "step_roll" / "result.json").read_text())
    cap = res["metadata"]["bridge"]["capture"]
    assert cap["interface"] == "slcan" and cap["channel"].startswith("/dev/pts/")
    assert cap["frames"] > 2 * 3000 and cap["applied"] == cap["frames"]  # two frames a report, 400 Hz PWM
    assert cap["rejected"] == 0 and cap["seq_gaps"] == 0
    assert res["metadata"]["capture"] == "can (slcan:vbridge)"
    lock = json.loads((lockstep["step_roll"] / "result.json").read_text())
    table = TOLERANCE["scenarios"]["step_roll"]
    for mb, ml in zip(res["measurements"], lock["measurements"], strict=True):
        assert abs(mb["value"] - ml["value"]) <= table[mb["name"]]["tolerance"], mb["name"]


@pytest.mark.parametrize("mode", [["--bridge", "virtual"], ["--realtime"]], ids=["bridge", "realtime"])
def test_a_paced_run_on_a_one_core_host_ends(tmp_path: Path, mode: list[str]) -> None:
    """Everything on one core: the paced loop (SCHED_FIFO), the virtual bridge, the keeper and the DUT.
    Once the run was over, the bench loop kept waking for the link's unread bytes, at a priority above
    the keeper's, so the keeper stopping the DUT never ran again and the run never ended. Whether the
    flight keeps pace on one core is not judged here: only that the run ends, with its result."""
    (tmp_path / "short_bench.toml").write_text(SHORT_BENCH)
    core = max(os.sched_getaffinity(0))
    r = subprocess.run([sys.executable, "-m", "rig.cli", "run", *mode, str(tmp_path / "short_bench.toml"),
                        "--out", str(tmp_path / "out")], capture_output=True, text=True, timeout=120,
                       preexec_fn=lambda: os.sched_setaffinity(0, {core}))
    assert r.returncode in (0, 1), r.stderr
    ended = json.loads((tmp_path / "out" / "short_bench" / "result.json").read_text())
    assert ended["verdict"] in ("pass", "fail")
