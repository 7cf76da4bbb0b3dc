"""Writes the session promised to acknowledge (rig/shim/protocol.h, struct rig_ack): the shim answers
them itself and sends each as a notice, a round trip fewer per write that only starts something (the
MS5611's conversions). The DUT must see what it would have seen had it waited for the session: the
write's effect at its time, a NACK wherever the chip would give one, and nothing promised that the
session did not say."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rig import lockstep
from rig.emulators.faults import Fault, FaultSet
from rig.scheduler import NS
from rig.session import Session, SessionConfig
from rig.world import World
from tests.rig.helpers import DUTS, PY, rig_exec

CLIENT = str(DUTS / "promised_writes.py")


@pytest.mark.parametrize("path", ["fast path", "handler"])
def test_writes_to_chips_that_always_acknowledge_are_answered_by_the_shim(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, path: str) -> None:
    monkeypatch.setenv(lockstep.PY_PATH_ENV, "1" if path == "handler" else "0")
    printed = tmp_path / "out.json"
    with open(printed, "w") as f:
        session = Session(SessionConfig(command=[PY, CLIENT], stdout=f), World.at_rest())
        outcome = session.run()
    assert outcome.verdict == "ok", outcome.error
    out = json.loads(printed.read_text())
    # the MPU-6050's and the MS5611's writes succeed; the conversion ran from the write's time on: the
    # ADC holds a result 10 ms later (a conversion never started reads 0); the HMC5883L behind the MPU
    # (bypass off) and an empty address NACK as before
    assert {k: out[k] for k in ("mpu_wake", "convert", "adc_command", "hmc_behind_mpu", "nobody")} == {
        "mpu_wake": 2, "convert": 1, "adc_command": 1, "hmc_behind_mpu": "ENXIO", "nobody": "ENXIO"}
    assert int(out["adc"], 16) > 0
    assert outcome.transport["promised_writes"] == 3
    assert outcome.transactions == 6  # every transfer counted, promised or not
    # which side served them: the fast path took the three promised writes' notices (and the other
    # transfers: none went to the handler), or, turned off, the handler took them all
    handler = session.handler
    assert handler is not None
    if path == "fast path":
        assert session.fast is not None
        i2c, _, _, promised = session.fast.counts
        assert (promised, i2c) == (3, 6) and (handler.promised_writes, handler.transactions) == (0, 0)
    else:
        assert session.fast is None
        assert (handler.promised_writes, handler.transactions) == (3, 6)


def test_the_log_marks_the_writes_the_shim_answered(tmp_path: Path) -> None:
    log = tmp_path / "log"
    run = rig_exec(tmp_path, PY, CLIENT, options=("--log", str(log)))
    assert run.returncode == 0, run.stderr
    i2c = [line.split(" ", 3)[3] for line in log.read_text().splitlines() if " i2c-1 " in line]
    assert i2c == ["W68:6b00 ok promised", "W77:48 ok promised", "W77:00 ok promised", "R77[3]="
                   + run.json_out()["adc"] + " ok", "W1e:0070 ENXIO", "W50:00 ENXIO"]


def test_a_promise_ends_where_a_bus_fault_may_silence_the_chip(tmp_path: Path) -> None:
    # the barometer's bus goes off at 50 ms: the writes before it are promised, those after it are
    # requests again, and NACK; the run is an ordinary one (no promise was broken)
    faults = {"baro_bus": FaultSet([Fault("off", 0.05)])}
    out = tmp_path / "out.txt"
    with open(out, "w") as f:
        cfg = SessionConfig(command=[PY, CLIENT, "every", "0.01", "8"], stdout=f)
        outcome = Session(cfg, World.at_rest(faults=faults)).run()
    assert outcome.verdict == "ok", outcome.error
    assert json.loads(out.read_text()) == [1] * 5 + ["ENXIO"] * 3
    assert outcome.transport["promised_writes"] == 5


def test_no_promise_when_a_transfer_takes_bus_time(tmp_path: Path) -> None:
    # at 400 kHz a write's wire time is the session's to say (its reply moves the DUT's clock)
    run = rig_exec(tmp_path, PY, CLIENT, options=("--i2c-clock", "400k"))
    assert run.returncode == 0, run.stderr
    assert run.json_out()["convert"] == 1
    assert run.summary["transport"]["promised_writes"] == 0


@pytest.mark.parametrize("path", ["fast path", "handler"])
def test_a_write_notice_nobody_promised_closes_its_connection_alone(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, path: str) -> None:
    if path == "handler":
        monkeypatch.setenv("RIG_PY_PATH", "1")
    run = rig_exec(tmp_path, PY, str(DUTS / "unpromised_write.py"))
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["True", "0x68"]  # its connection closed, the next one served
    [why] = run.summary["malformed"]
    assert "I2C_WRITE notice to 0x50 on bus 1" in why and "did not promise" in why


def test_the_page_promises_what_the_board_says(tmp_path: Path) -> None:
    from rig.scheduler import SharedPage

    page = SharedPage(tmp_path / "shm", 8, 0, 1000, 10 * NS)
    assert not page.promised(1, 0x77, 0)  # a new page promises nothing
    world = World.at_rest(faults={"baro_bus": FaultSet([Fault("off", 0.05)])})
    page.promise_acks(1, world.board.write_acks())
    assert page.promised(1, 0x68, 9 * NS) and page.promised(1, 0x77, 49_999_999)
    assert not page.promised(1, 0x77, 50_000_000)        # the fault may silence it from then on
    assert not page.promised(2, 0x68, 0)                 # another bus
    assert not page.promised(1, 0x1E, 0)                 # on a GY-86 the HMC5883L hides behind the MPU
    direct = World.at_rest(topology="direct").board.write_acks()
    assert (0x1E, 2**64 - 1) in direct


BROKEN = """
import json, sys
from rig.emulators.chips.board import ChipBoard
from rig.session import Session, SessionConfig
from rig.world import World
ChipBoard.write_acks = lambda self: [(0x50, 2**64 - 1)]  # a rig bug: a promise for an empty address
session = Session(SessionConfig(command=sys.argv[1:]), World.at_rest())
outcome = session.run()
fast = session.fast.counts if session.fast is not None else None
print(json.dumps([outcome.verdict, outcome.exit_code, outcome.error, fast]))
"""


@pytest.mark.parametrize("path", ["fast path", "handler"])
def test_a_broken_promise_voids_the_run(tmp_path: Path, path: str) -> None:
    # the DUT was told a write was acknowledged that the chip did not: nothing it did after that can be
    # judged (RIG_PURE_PYTHON: the board's class as plain Python, so that the bug can be planted)
    import os
    import subprocess

    env = {**os.environ, "RIG_PURE_PYTHON": "1", "RIG_PY_PATH": "1" if path == "handler" else "0"}
    client = "import fcntl, os; fd = os.open('/dev/i2c-1', os.O_RDWR); fcntl.ioctl(fd, 0x0703, 0x50); " \
             "print(os.write(fd, b'\\x00')); import time; time.sleep(1)"
    done = subprocess.run([PY, "-c", BROKEN, PY, "-c", client], capture_output=True, text=True, env=env,
                          timeout=120)
    verdict, code, error, fast = json.loads(done.stdout.strip().splitlines()[-1])
    assert (verdict, code) == ("error", 125), done.stderr
    assert "acknowledged was not (a rig bug)" in error
    # the side under test saw the write: the fast path took its notice (its counts: I2C transfers,
    # waits, PWM writes, promised writes kept), or, turned off, there was none
    assert fast == ([1, 0, 0, 0] if path == "fast path" else None), fast
