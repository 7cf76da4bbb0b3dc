"""Nothing outlives `rig exec`: not a child the command detached with setsid, not a command that ignores
SIGTERM, not when rig exec itself is stopped by a signal or killed outright; and time moved by clock
reads counts against the sim-time limits. Bad usage is exit 2 before the command starts."""

from __future__ import annotations

import os
import signal
import subprocess
from pathlib import Path

import pytest

from tests.rig.helpers import DUTS, PY, rig_exec
from tests.waits import pid_fifo, read_pid, wait_gone

BUSY = "import time\nwhile True: time.monotonic()"


def test_a_busy_loop_on_the_clock_ends_at_the_duration(tmp_path: Path) -> None:
    """It read the clock 244 sim-s past --duration 0.5 until the 600 s wall watchdog."""
    run = rig_exec(tmp_path, PY, "-c", BUSY, options=("--duration", "0.5", "--sim-timeout", "1",
                                                     "--wall-timeout", "60"))
    assert run.returncode == 0, run.stderr
    assert 0.5 <= run.summary["sim_time"] < 0.51


def test_a_busy_loop_on_the_clock_meets_the_sim_time_watchdog(tmp_path: Path) -> None:
    run = rig_exec(tmp_path, PY, "-c", BUSY, options=("--sim-timeout", "1", "--wall-timeout", "60"))
    assert run.returncode == 124, run.stderr
    assert "sim-time watchdog" in run.summary["error"]


def test_a_child_detached_with_setsid_ends_with_the_run(tmp_path: Path) -> None:
    pid_file = tmp_path / "pid"
    script = f"setsid sh -c 'exec yes > /dev/null' & echo $! > {pid_file}; sleep 5"
    run = rig_exec(tmp_path, "sh", "-c", script, options=("--duration", "1"))
    assert run.returncode == 0, run.stderr
    assert wait_gone(int(pid_file.read_text()), timeout=0)  # gone when rig exec returned


#: a DUT whose second thread starts a child in a session of its own (a fork from a thread: the kernel
#: lists the child under that thread, not under the process's main thread), waits until the child has
#: its SIGTERM handler, then sleeps past the run's end; the child (without the shim, whose calls would wait
#: for the ended session) writes "term" when SIGTERM comes
THREAD_FORKS = """
import os, subprocess, sys, threading, time
CHILD = ("import signal, sys\\n"
         "def term(*_):\\n    open(sys.argv[1], 'w').write('term'); sys.exit(0)\\n"
         "signal.signal(signal.SIGTERM, term); print(flush=True); signal.pause()")
def spawn():
    env = {k: v for k, v in os.environ.items() if k != "LD_PRELOAD"}  # (a plain process)
    child = subprocess.Popen([sys.executable, "-c", CHILD, sys.argv[1]], start_new_session=True,
                             stdout=subprocess.PIPE, env=env)
    child.stdout.readline()
    open(sys.argv[2], "w").write(str(child.pid))
    ready.set()
    time.sleep(30)
ready = threading.Event()
threading.Thread(target=spawn).start()
ready.wait()
time.sleep(30)
"""


@pytest.mark.parametrize("scan", ["lists", "proc"])
def test_a_child_a_thread_started_gets_sigterm_when_the_run_ends(tmp_path: Path, scan: str,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """The keeper finds the DUT's processes through the kernel's children lists, every thread's (or by
    reading every process in /proc, RIG_KEEPER_FULL_SCAN=1): a child it missed would get only the
    SIGKILL after the grace, and never write "term"."""
    if scan == "proc":
        monkeypatch.setenv("RIG_KEEPER_FULL_SCAN", "1")
    said, pid_file = tmp_path / "said", tmp_path / "pid"
    run = rig_exec(tmp_path, PY, "-c", THREAD_FORKS, str(said), str(pid_file), options=("--duration", "1"))
    assert run.returncode == 0, run.stderr
    assert wait_gone(int(pid_file.read_text()), timeout=0)
    assert said.read_text() == "term"


@pytest.mark.parametrize("how", [signal.SIGTERM, signal.SIGINT, signal.SIGKILL])
def test_a_dut_that_ignores_sigterm_ends_however_rig_exec_is_stopped(tmp_path: Path, how: int) -> None:
    """`timeout rig exec …` (SIGTERM), Ctrl-C, or rig exec killed outright: the DUT, which ignores
    SIGTERM and never talks to the session, is gone all the same (the keeper's SIGKILL after the
    grace; with rig exec killed, the keeper sees its lifeline close)."""
    fifo = pid_fifo(tmp_path / "pid")
    tmp = tmp_path / "tmp"  # (a rig killed outright cannot remove its session folder: keep it here)
    tmp.mkdir()
    proc = subprocess.Popen([PY, "-m", "rig.cli", "exec", "--", PY, str(DUTS / "stubborn_spinner.py"),
                             str(fifo)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "TMPDIR": str(tmp)})
    pid = read_pid(fifo)
    proc.send_signal(how)
    stderr = proc.communicate(timeout=60)[1]
    if how != signal.SIGKILL:
        assert proc.returncode == 128 + how, stderr
        assert "interrupted by" in stderr and "Traceback" not in stderr
        assert wait_gone(pid, timeout=0)  # rig exec returned only after the DUT was gone
    else:
        assert wait_gone(pid)


def test_nothing_is_left_in_the_temporary_folder(tmp_path: Path) -> None:
    """Every run left a /tmp/plant-XXXXXXXX (the unzipped FMU) and, stopped by SIGTERM, its session
    folder (socket, shared page)."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = {**os.environ, "TMPDIR": str(tmp)}
    done = subprocess.run([PY, "-m", "rig.cli", "exec", "--", "i2cget", "-y", "1", "0x68", "0x75"],
                          capture_output=True, text=True, env={**env, "PATH": env["PATH"] + ":/usr/sbin"})
    assert done.returncode == 0, done.stderr
    assert list(tmp.iterdir()) == []


@pytest.mark.parametrize(("options", "says"), [
    (("--param", "bogus=1"), "'bogus' is not a plant parameter"),
    (("--param", "mas=1"), "did you mean 'mass'?"),
    (("--param", "mass=-1"), "the plant refuses it: mass must be > 0"),
    (("--param", "stand=9"), "stand must be 0..4"),
    (("--log", "/proc/no/such.log"), "--log /proc/no/such.log: No such file or directory"),
    (("--summary", "/proc/version"), "--summary /proc/version:"),
])
def test_bad_usage_is_exit_2_before_the_command_starts(tmp_path: Path, options: tuple[str, ...],
                                                       says: str) -> None:
    started = tmp_path / "started"
    done = subprocess.run([PY, "-m", "rig.cli", "exec", *options, "--", "touch", str(started)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2, done.stderr
    assert says in done.stderr and "Traceback" not in done.stderr
    assert not started.exists()
