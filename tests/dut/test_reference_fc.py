"""The reference flight controller (dut/): its C algorithm tests, and the real binary under ``rig exec``
against the emulated board, including the bad inputs it must refuse without driving a motor."""

from __future__ import annotations

import itertools
import math
import subprocess
from collections.abc import Callable, Sequence
from pathlib import Path

import pytest

from rig.emulators.ms5611 import DEFAULT_PROM
from rig.rc import StickEmulator
from rig.scheduler import MONO_BASE_NS, NS
from rig.session import Outcome, Session, SessionConfig
from rig.world import World

REPO = Path(__file__).resolve().parents[2]
BUILD = REPO / "build" / "dut"


@pytest.fixture(scope="module")
def fc() -> Path:
    subprocess.run(["make", "-s", "-C", str(REPO / "dut")], check=True)
    return BUILD / "fc"


@pytest.mark.parametrize("program", ["test_fc", "test_fc32"])
def test_algorithms_against_independent_truth(fc: Path, program: str) -> None:
    """In double (the Linux FC) and in single precision (test_fc32: what the AVR computes)."""
    done = subprocess.run([str(BUILD / program)], capture_output=True, text=True)
    lines = done.stdout.splitlines()
    assert done.returncode == 0, done.stdout
    assert not [line for line in lines if not line.startswith("ok ")]
    assert len(lines) >= 20


def telemetry(session: Session, path: str) -> list[dict[str, float]]:
    rows = []
    for line in session.serial_output(path).decode().splitlines():
        if line.startswith("T "):
            rows.append({k: float(v) for k, v in (kv.split("=") for kv in line.split()[1:])})
    return rows


def run_fc(tmp_path: Path, fc: Path, config: str, world_setup: Callable[[World], None] | None = None,
           duration: float = 3.0, serial: tuple[str, ...] = ("/dev/ttyTEL0",),
           events: Sequence[tuple[float, Callable[[Session], None]]] = (),
           ) -> tuple[Session, Outcome, str, str]:
    conf = tmp_path / "fc.conf"
    conf.write_text(config)
    log = tmp_path / "tx.log"
    err = tmp_path / "stderr.txt"
    with open(err, "w") as ferr:
        cfg = SessionConfig(command=[str(fc), str(conf)], serial=list(serial), duration=duration,
                            log_path=log, stderr=ferr)
        session = Session(cfg, World.at_rest())
        if world_setup:
            world_setup(session.world)
        for t, fn in events:
            session.at(t, fn)
        outcome = session.run()
    return session, outcome, log.read_text(), err.read_text()


@pytest.mark.parametrize("estimator", [0, 1, 2], ids=["seed000-quaternion", "seed002-mahony", "ekf"])
def test_fc_at_rest_estimates_level_and_keeps_motors_idle(tmp_path: Path, fc: Path, estimator: int) -> None:
    conf = f"telemetry_path = /dev/ttyTEL0\nestimator = {estimator}\n"
    session, outcome, log, err = run_fc(tmp_path, fc, conf)
    assert outcome.verdict == "ok", (outcome.error, err)
    rows = telemetry(session, "/dev/ttyTEL0")
    assert len(rows) > 50
    last = rows[-1]
    assert abs(last["roll"]) < 0.5 and abs(last["pitch"]) < 0.5 and abs(last["yaw"]) < 2.0
    assert last["armed"] == 0
    duties = {line.split()[-1] for line in log.splitlines() if " duty_cycle " in line}
    assert duties == {"1000000"}                                  # disarmed: idle on every motor
    # lockstep: the loop's work takes a few clock quanta of its 4 ms, so no cycle overruns (the loop's
    # deadlines once started before the 1 s calibration, and 250 cycles ran back to back to catch up)
    assert last["overruns"] == 0
    t = [r["t"] for r in rows]
    assert min(b - a for a, b in itertools.pairwise(t)) == pytest.approx(0.02, abs=1e-6)  # every 5th cycle


@pytest.mark.parametrize("config, message", [
    ("mpu_addr = 0x69\n", "MPU-6050: no answer at 0x69"),
    ("mpu_addr = 0x77\n", "MPU-6050: wrong WHO_AM_I"),
    ("hmc_addr = 0x1f\n", "HMC5883L: no answer at 0x1f"),
    ("estimatr = 1\n", "unknown key 'estimatr'"),
    ("est_rate_hz = fast\n", "est_rate_hz expects a number"),
    ("telemetry_every = 0\n", "telemetry_every must be in 1..100000"),
])
def test_bad_sensors_and_config_are_refused_without_motor_output(tmp_path: Path, fc: Path, config: str,
                                                                message: str) -> None:
    _, outcome, log, err = run_fc(tmp_path, fc, config)
    assert message in err
    assert outcome.dut_returncode == 2 and outcome.verdict == "error"   # it exited before the duration
    assert " pwm" not in log


def test_a_prom_with_a_bad_crc_is_refused(tmp_path: Path, fc: Path) -> None:
    bad = (*DEFAULT_PROM[:7], DEFAULT_PROM[7] ^ 0x1)

    def corrupt(world: World) -> None:
        world.board.baro.prom = bad

    _, outcome, log, err = run_fc(tmp_path, fc, "", world_setup=corrupt)
    assert "MS5611: PROM CRC-4 mismatch (computed 0x3, stored 0x2)" in err
    assert " pwm" not in log


def test_garbage_on_the_rc_port_is_reported_and_the_motors_stay_idle(tmp_path: Path, fc: Path) -> None:
    junk = bytes((i * 37 + 11) % 256 for i in range(200)).replace(b"\x0f", b"\x10")
    def garbage(s: Session) -> None:
        s.serial_write("/dev/ttyRC0", junk)

    events = [(1.5 + 0.1 * k, garbage) for k in range(10)]
    conf = "rc_path = /dev/ttyRC0\ntelemetry_path = /dev/ttyTEL0\n"
    session, outcome, log, err = run_fc(tmp_path, fc, conf, serial=("/dev/ttyRC0", "/dev/ttyTEL0"),
                                        events=events)
    assert outcome.verdict == "ok", (outcome.error, err)
    assert "not SBUS frames; staying disarmed" in err
    assert all(row["armed"] == 0 for row in telemetry(session, "/dev/ttyTEL0"))
    assert {line.split()[-1] for line in log.splitlines() if " duty_cycle " in line} == {"1000000"}


Rows = list[dict[str, float]]
RC_CONF = "rc_path = /dev/ttyRC0\ntelemetry_path = /dev/ttyTEL0\n"
RC_PORTS = ("/dev/ttyRC0", "/dev/ttyTEL0")


def fly_with_sticks(tmp_path: Path, fc: Path, plan: Sequence[tuple[float, dict[str, object]]],
                    duration: float, every: float = 0.1) -> tuple[Rows, Rows, str]:
    """Runs the FC with an SBUS stick emulator following ``plan`` (time, stick or link changes) and
    samples the plant's truth every ``every`` s. Returns (truth rows, FC telemetry rows, stderr)."""
    rc = StickEmulator("/dev/ttyRC0")
    truth: list[dict[str, float]] = []

    def change(what: dict[str, object]) -> Callable[[Session], None]:
        def apply(_: Session) -> None:
            for k, v in what.items():
                setattr(rc if k == "link" else rc.sticks, k, v)
        return apply

    def sample(s: Session) -> None:
        y = s.world.outputs()
        truth.append({"t": s.now_ns / 1e9, "alt": -y["pd"], "vd": y["vd"], "roll": math.degrees(y["roll"]),
                      "pitch": math.degrees(y["pitch"]), "on_ground": y["on_ground"],
                      "pwm1": s.world.pwm[0].pulse_us()})
        s.at(s.now_ns / 1e9 + every, sample)

    events: list[tuple[float, Callable[[Session], None]]] = [(0.0, rc.start), (0.0, sample)]
    events += [(t, change(w)) for t, w in plan]
    session, outcome, _, err = run_fc(tmp_path, fc, RC_CONF, serial=RC_PORTS, events=events,
                                      duration=duration)
    assert outcome.verdict == "ok", (outcome.error, err)
    return truth, telemetry(session, "/dev/ttyTEL0"), err


def at(rows: list[dict[str, float]], t: float) -> dict[str, float]:
    return min(rows, key=lambda r: abs(r["t"] - t))


def test_arm_fly_hold_altitude_then_rc_loss_levels_descends_and_disarms(tmp_path: Path, fc: Path) -> None:
    plan: list[tuple[float, dict[str, object]]] = [(1.5, {"arm": True}), (2.0, {"throttle": 0.56}),
                                                   (4.0, {"mode": "althold"}), (8.0, {"link": "lost"})]
    truth, tel, err = fly_with_sticks(tmp_path, fc, plan, duration=20.0)
    t0 = MONO_BASE_NS / NS                                  # the FC's monotonic clock at sim time 0
    armed_at = min(r["t"] - t0 for r in tel if r["armed"] == 1)
    assert 1.5 <= armed_at < 1.6                           # the first frame with the switch up arms
    assert at(truth, 1.9)["pwm1"] < 1050 and at(truth, 1.9)["on_ground"] == 1   # armed, throttle low
    assert at(truth, 3.5)["on_ground"] == 0 and at(truth, 3.5)["alt"] > 0.5     # throttle up: airborne
    held = [r for r in truth if 6.5 <= r["t"] <= 8.0]      # altitude hold: the climb is stopped and held
    assert max(abs(r["vd"]) for r in held) < 1.5 and all(2.0 < r["alt"] < 6.0 for r in held)
    assert "RC lost at" in err and "failsafe" in err
    after = [r for r in truth if 8.0 <= r["t"] <= 18.0]
    assert max(max(abs(r["roll"]), abs(r["pitch"])) for r in after) < 5.0            # level
    assert at(truth, 13.0)["alt"] < at(truth, 8.0)["alt"] - 1.0                      # descending
    assert max(r["vd"] for r in after) < 2.0                                          # not falling
    disarmed_at = min(r["t"] - t0 for r in tel if r["t"] - t0 > 8 and r["armed"] == 0)
    assert 18.0 <= disarmed_at <= 19.0                     # 0.5 s to declare the loss, 10 s of descent
    assert at(truth, 19.5)["pwm1"] == 1000 and at(truth, 19.5)["on_ground"] == 1


def test_the_arm_switch_with_throttle_up_does_not_arm(tmp_path: Path, fc: Path) -> None:
    plan: list[tuple[float, dict[str, object]]] = [(1.2, {"throttle": 0.6}), (1.5, {"arm": True})]
    truth, tel, _ = fly_with_sticks(tmp_path, fc, plan, duration=3.0)
    assert all(r["armed"] == 0 for r in tel)
    assert all(r["pwm1"] in (0.0, 1000.0) for r in truth)
