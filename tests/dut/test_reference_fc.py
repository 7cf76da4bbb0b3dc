"""The reference flight controller (dut/): its C algorithm tests, and the real binary under ``rig exec``
against the emulated board, including the bad inputs it must refuse without driving a motor."""

from __future__ import annotations

import subprocess
from collections.abc import Callable, Sequence
from pathlib import Path

import pytest

from emulators.ms5611 import DEFAULT_PROM
from rig.session import Outcome, Session, SessionConfig
from rig.world import World

REPO = Path(__file__).resolve().parents[2]
BUILD = REPO / "build" / "dut"


@pytest.fixture(scope="module")
def fc() -> Path:
    subprocess.run(["make", "-s", "-C", str(REPO / "dut")], check=True)
    return BUILD / "fc"


def test_algorithms_against_independent_truth(fc: Path) -> None:
    done = subprocess.run([str(BUILD / "test_fc")], capture_output=True, text=True)
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
        session = Session(cfg)
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


@pytest.mark.parametrize("config, message", [
    ("mpu_addr = 0x69\n", "MPU-6050: no answer at 0x69"),
    ("mpu_addr = 0x77\n", "MPU-6050: wrong WHO_AM_I"),
    ("hmc_addr = 0x1f\n", "HMC5883L: no answer at 0x1f"),
    ("estimatr = 1\n", "unknown key 'estimatr'"),
    ("rate_hz = fast\n", "rate_hz expects a number"),
    ("telemetry_every = 0\n", "telemetry_every >= 1"),
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
    events = [(1.5 + 0.1 * k, lambda s: s.serial_write("/dev/ttyRC0", junk)) for k in range(10)]
    conf = "rc_path = /dev/ttyRC0\ntelemetry_path = /dev/ttyTEL0\n"
    session, outcome, log, err = run_fc(tmp_path, fc, conf, serial=("/dev/ttyRC0", "/dev/ttyTEL0"),
                                        events=events)
    assert outcome.verdict == "ok", (outcome.error, err)
    assert "not SBUS frames; staying disarmed" in err
    assert all(row["armed"] == 0 for row in telemetry(session, "/dev/ttyTEL0"))
    assert {line.split()[-1] for line in log.splitlines() if " duty_cycle " in line} == {"1000000"}
