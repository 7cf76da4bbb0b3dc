"""Virtual time under ``rig exec``: every clock and wait of libc follows the session's clock, exactly."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rig.scheduler import EPOCH_NS, MONO_BASE_NS, NS
from rig.session import Session, SessionConfig
from rig.world import World
from tests.rig.helpers import DUTS, PY, build_client, rig_exec

QUANTUM = 1000  # ns per clock read (the default)


@pytest.fixture(scope="module")
def c_dut(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_client(tmp_path_factory, "clocks_and_pwm")


def parse_lines(text: str) -> dict[str, list[int]]:
    return {k: [int(x) for x in rest] for k, *rest in (line.split() for line in text.splitlines())}


def test_every_libc_wait_lasts_exactly_its_sim_time(tmp_path: Path, c_dut: Path) -> None:
    run = rig_exec(tmp_path, str(c_dut))
    assert run.returncode == 0, run.stderr
    out = parse_lines(run.stdout)
    # each interval is the wait plus the one clock read that ends it
    for name, wait_ns in [("nanosleep", 100_000_000), ("usleep", 50_000_000), ("sleep", NS),
                          ("clock_nanosleep_rel", 20_000_000), ("select", 250_000_000),
                          ("poll", 300_000_000), ("epoll_wait", 150_000_000)]:
        assert out[name][0] == wait_ns + QUANTUM, name
    # absolute deadline: two clock reads (setting the deadline, then measuring) since the last mark
    assert out["clock_nanosleep_abs"][0] == 2 * NS + 2 * QUANTUM
    assert out["select"][1] == out["poll"][1] == out["epoll_wait"][1] == 0   # timeouts, nothing ready
    # calendar clocks start at the session's epoch and agree with each other
    elapsed_s = 3.9
    assert out["realtime_s"][0] == EPOCH_NS // NS + int(elapsed_s)
    assert out["time_s"][0] == out["realtime_s"][0]
    assert out["gettimeofday_minus_realtime_us"][0] in (0, 1)                # one quantum later
    assert out["boottime_minus_monotonic"][0] == -2 * QUANTUM  # time() and mono() read after boottime


def test_sysfs_pwm_through_stdio_drives_the_motors(tmp_path: Path, c_dut: Path) -> None:
    run = rig_exec(tmp_path, str(c_dut))
    out = parse_lines(run.stdout)
    assert out["pwm1_before_export"] == [-1]       # no pwm1 directory before export
    assert out["pwm2_duty_read"] == [1_300_000]
    # ESC: omega = (pulse - 1000 us) / 1000 us * omega_max (600 rad/s), settled after 1 s (tau 20 ms)
    for motor, pulse_us in enumerate((1100, 1200, 1300, 1400), start=1):
        expected = (pulse_us - 1000) / 1000 * 600
        assert run.summary["plant"][f"omega{motor}"] == pytest.approx(expected, rel=1e-9)


def test_python_sleep_10s_is_10s_of_sim_time_and_the_plant_moves_with_it(tmp_path: Path) -> None:
    run = rig_exec(tmp_path, PY, str(DUTS / "sleep_ten.py"))
    assert run.returncode == 0, run.stderr
    out = run.json_out()
    assert 10 * NS <= out["monotonic_ns"] <= 10 * NS + 10 * QUANTUM
    assert 10 * NS <= out["time_ns"] <= 10 * NS + 10 * QUANTUM
    assert run.summary["plant_time"] >= 10.0
    assert run.summary["sim_time"] == pytest.approx(run.summary["plant_time"], abs=1e-3)


def test_a_transfer_takes_its_wire_time_at_400khz(tmp_path: Path) -> None:
    # write 0x3B then read 14 bytes: START + (addr+ACK) + 1 byte, rSTART + (addr+ACK) + 14 bytes, STOP
    bits = 1 + (10 + 9) + (10 + 9 * 14)
    run = rig_exec(tmp_path, PY, str(DUTS / "burst_timed.py"), options=("--i2c-clock", "400k"))
    assert int(run.stdout) == bits * NS // 400_000 + QUANTUM
    run = rig_exec(tmp_path, PY, str(DUTS / "burst_timed.py"))
    assert int(run.stdout) == QUANTUM                           # without bus time a transfer is instant


def test_two_lockstep_runs_give_byte_identical_transaction_logs(tmp_path: Path) -> None:
    logs = []
    for i in range(2):
        log = tmp_path / f"run{i}.log"
        run = rig_exec(tmp_path, PY, str(DUTS / "smbus_probe.py"), options=("--log", str(log)))
        assert run.returncode == 0, run.stderr
        logs.append(log.read_bytes())
    assert logs[0] == logs[1]
    assert logs[0].count(b" i2c-1 ") > 10 and b" wait " in logs[0]


def test_a_polling_dut_wakes_when_the_session_writes_its_serial_port(tmp_path: Path) -> None:
    out = tmp_path / "out.txt"
    with open(out, "w") as f:
        cfg = SessionConfig(command=[PY, str(DUTS / "serial_echo.py")], serial=["/dev/ttyRC0"], stdout=f)
        session = Session(cfg, World.at_rest())
        session.at(0.5, lambda s: s.serial_write("/dev/ttyRC0", b"hello"))
        outcome = session.run()
    assert outcome.verdict == "ok", outcome.error
    got = json.loads(out.read_text())
    assert got["data"] == "hello"
    # woken at the event's instant (plus the clock read), not at the 2 s timeout
    assert 0.5 * NS + QUANTUM <= got["woke_ns"] - MONO_BASE_NS <= 0.5 * NS + 10 * QUANTUM
    assert got["waited_ns"] < 0.5 * NS
    assert session.serial_output("/dev/ttyRC0") == b"pong"


def test_bytes_written_during_a_sleep_are_there_when_it_ends(tmp_path: Path) -> None:
    # The shim answers a sleep itself (WAIT AHEAD, no round trip) and the session runs the world to its
    # end only when it reads that notice; the DUT's first look outside (select, read) syncs first.
    out, log = tmp_path / "out.txt", tmp_path / "session.log"
    with open(out, "w") as f:
        cfg = SessionConfig(command=[PY, str(DUTS / "sleep_then_read.py")], serial=["/dev/ttyRC0"], stdout=f,
                            log_path=log)
        session = Session(cfg, World.at_rest())
        session.at(0.5, lambda s: s.serial_write("/dev/ttyRC0", b"sbus"))
        outcome = session.run()
    assert outcome.verdict == "ok", outcome.error
    got = json.loads(out.read_text())
    assert got == {"ready": True, "data": "sbus", "slept_ns": got["slept_ns"]}
    assert 1.0 * NS <= got["slept_ns"] <= 1.0 * NS + 100 * QUANTUM  # the sleep lasted 1 s
    waits = [line for line in log.read_text().splitlines() if " wait " in line]
    assert any(line.endswith(" ahead") for line in waits)                      # it went ahead
