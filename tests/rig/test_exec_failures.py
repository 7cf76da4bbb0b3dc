"""A DUT that crashes, exits early, never comes, hangs or talks nonsense ends with a clear error, and the
rig itself never hangs (sim-time, wall-time and stall watchdogs bound every run)."""

from __future__ import annotations

from pathlib import Path

import pytest

from rig.scheduler import EXIT_RIG_ERROR, EXIT_WATCHDOG
from rig.session import EXIT_NOT_FOUND
from tests.rig.helpers import DUTS, PY, rig_exec

TOUCH_BUS = "from smbus2 import SMBus; b = SMBus(1); b.read_byte_data(0x68, 0x75); "


def test_a_crash_is_an_error_naming_the_signal(tmp_path: Path) -> None:
    run = rig_exec(tmp_path, PY, "-c", TOUCH_BUS + "import os, time; time.sleep(0.5); os.abort()")
    assert run.returncode == 128 + 6
    assert "killed by SIGABRT at sim t=0.5" in run.stderr
    assert run.summary["verdict"] == "error"


def test_exiting_before_the_runs_duration_is_an_error(tmp_path: Path) -> None:
    run = rig_exec(tmp_path, PY, "-c", TOUCH_BUS + "import time; time.sleep(1.25)",
                   options=("--duration", "5"))
    assert run.returncode == EXIT_RIG_ERROR
    assert "exited early, with status 0, at sim t=1.25" in run.stderr


def test_a_dut_that_runs_to_the_duration_is_stopped_and_passes(tmp_path: Path) -> None:
    forever = TOUCH_BUS + ("import time\nwhile True:\n"
                           "    b.read_i2c_block_data(0x68, 0x3B, 14); time.sleep(0.0025)")
    run = rig_exec(tmp_path, PY, "-c", forever, options=("--duration", "2"))
    assert run.returncode == 0, run.stderr
    assert run.summary["verdict"] == "ok"
    assert 2.0 <= run.summary["sim_time"] <= 2.0026
    assert run.summary["transactions"] >= 2 / 0.0026


def test_a_command_that_never_touches_the_devices_is_an_error(tmp_path: Path) -> None:
    run = rig_exec(tmp_path, "true")
    assert run.returncode == EXIT_RIG_ERROR
    assert "without touching the emulated devices" in run.stderr
    assert rig_exec(tmp_path, "true", options=("--allow-no-devices",)).returncode == 0


def test_a_command_that_is_not_there(tmp_path: Path) -> None:
    run = rig_exec(tmp_path, "/nonexistent/fc")
    assert run.returncode == EXIT_NOT_FOUND and "command not found: /nonexistent/fc" in run.stderr


def test_sleeping_forever_trips_the_sim_time_watchdog(tmp_path: Path) -> None:
    run = rig_exec(tmp_path, PY, "-c", TOUCH_BUS + "import time\nwhile True: time.sleep(1)",
                   options=("--sim-timeout", "30"))
    assert run.returncode == EXIT_WATCHDOG
    assert "sim-time watchdog" in run.stderr and run.summary["sim_time"] == 30.0


def test_spinning_without_a_clock_trips_the_stall_watchdog(tmp_path: Path) -> None:
    run = rig_exec(tmp_path, PY, "-c", TOUCH_BUS + "\nwhile True: pass", options=("--stall-timeout", "0.5"))
    assert run.returncode == EXIT_WATCHDOG
    assert "stopped answering" in run.stderr


def test_blocking_outside_the_devices_trips_the_wall_time_watchdog(tmp_path: Path) -> None:
    # blocked on a pipe nobody writes: no requests, no clock reads; only wall time bounds it
    run = rig_exec(tmp_path, PY, "-c", TOUCH_BUS + "import os; r, w = os.pipe(); os.read(r, 1)",
                   options=("--wall-timeout", "0.5", "--stall-timeout", "60"))
    assert run.returncode == EXIT_WATCHDOG
    assert "wall-time watchdog" in run.stderr


def test_malformed_messages_are_reported_and_the_session_survives(tmp_path: Path) -> None:
    log = tmp_path / "log"
    run = rig_exec(tmp_path, PY, str(DUTS / "malformed_neighbour.py"), options=("--log", str(log)))
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "0x68"                     # the real connection kept working
    reasons = run.summary["malformed"]
    assert len(reasons) == 3
    assert "unknown message type 99" in reasons[0]
    assert "announces 9 messages but carries 4 bytes" in reasons[1]
    assert "exceeds 65536" in reasons[2]
    assert run.stderr.count("malformed message") == 3
    assert log.read_text().count("malformed:") == 3


def test_the_wall_time_watchdog_ends_a_dut_the_fast_path_keeps_busy(tmp_path: Path) -> None:
    # every message is one the fast path takes in C (rig/lockstep/pump.c) and no event is scheduled: the
    # loop's watchdogs still run, because pump hands back to the loop within its budget
    forever = TOUCH_BUS + ("import time\nwhile True:\n"
                           "    b.read_i2c_block_data(0x68, 0x3B, 14); time.sleep(0.0025)")
    run = rig_exec(tmp_path, PY, "-c", forever, options=("--duration", "3600", "--wall-timeout", "1"))
    assert run.returncode == EXIT_WATCHDOG, run.stderr
    assert "wall-time watchdog" in run.stderr
    assert run.summary["sim_time"] < 3600


@pytest.mark.parametrize("path", ["fast path", "handler"])
def test_a_connection_that_never_reads_its_replies_is_closed_alone(tmp_path: Path, path: str) -> None:
    # the replies fill the socket; the session's send waits REPLY_TIMEOUT_S for room (it waited for
    # good, in C where no signal's handler ran: the rig could not even be stopped), then closes that
    # connection. Sent from C (rig/lockstep/reply.c) or, with a log written, from Conn.send.
    options = ("--log", str(tmp_path / "log")) if path == "handler" else ()
    run = rig_exec(tmp_path, PY, str(DUTS / "replies_unread.py"), options=options)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "0x68"  # the process's own bus connection went on working
    [why] = run.summary["malformed"]
    assert why.startswith("replies not taken on connection 1 ")
    assert "replies unread for 2 s" in why
