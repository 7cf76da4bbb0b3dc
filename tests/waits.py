"""Waiting for other processes by their events, never by sleeping: a FIFO a DUT writes its pid into once
it is up, and a pidfd that becomes readable when a process has ended. Each wait has a generous bound
so that a regression fails the test instead of hanging it."""

from __future__ import annotations

import os
import select
from collections.abc import Callable
from pathlib import Path

from rig.dut_process import ended_within

BOUND_S = 60.0


def pid_fifo(path: Path) -> Path:
    """A FIFO for a DUT to write its pid into (tests/rig/device_clients/*: argv[1])."""
    os.mkfifo(path)
    return path


def read_pid(fifo: Path, timeout: float = BOUND_S) -> int:
    """The pid the DUT writes into ``fifo`` (a line). Opened for reading and writing, so that no writer
    yet is not an end of file (Linux allows it on a FIFO)."""
    fd = os.open(fifo, os.O_RDWR | os.O_NONBLOCK)
    try:
        data = b""
        while not data.endswith(b"\n"):
            ready, _, _ = select.select([fd], [], [], timeout)
            assert ready, f"no pid came through {fifo} in {timeout:g} s"
            data += os.read(fd, 64)
        return host_pid(int(data), str(fifo))
    finally:
        os.close(fd)


def host_pid(pid: int, marker: str) -> int:
    """``pid`` as this process sees it: a DUT in a pid namespace of its own (the service's sandbox,
    rig/sandbox.py) writes the pid it has there. It is the process whose innermost pid is ``pid`` and
    whose command line names ``marker``; ``pid`` itself when there is none."""
    for proc in Path("/proc").iterdir():
        try:
            status = (proc / "status").read_text()
            named = marker.encode() in (proc / "cmdline").read_bytes()
        except OSError:
            continue
        inner = next((line.split()[-1] for line in status.splitlines() if line.startswith("NSpid:")), None)
        if named and inner == str(pid):
            return int(proc.name)
    return pid


def wait_gone(pid: int, timeout: float = BOUND_S) -> bool:
    """True once the process has ended (at once if it already has), False if it is still there after
    ``timeout`` seconds."""
    ended = ended_within(pid, timeout)
    assert ended is not None, "this kernel gives no pidfds (Linux 5.3 or later is needed)"
    return ended


IN_CLOSE_WRITE, IN_CREATE, IN_MOVED_TO = 0x8, 0x100, 0x80


def wait_file(paths: list[Path], timeout: float = BOUND_S,
              ready: Callable[[Path], bool] = Path.exists) -> Path | None:
    """The first of ``paths`` to exist (they may be created, or renamed into place, after the call), by
    inotify on their folders, which must exist; None after ``timeout`` seconds. ``ready`` says when a
    file is there for the caller: one its writer creates empty and fills later (a Dask scheduler file)
    wants its content checked, and each write closed wakes the wait to look again."""
    import ctypes
    import time

    libc = ctypes.CDLL(None, use_errno=True)
    fd = libc.inotify_init1(os.O_NONBLOCK | os.O_CLOEXEC)
    assert fd >= 0, f"inotify_init1: errno {ctypes.get_errno()}"
    try:
        for folder in {p.parent for p in paths}:
            mask = IN_CREATE | IN_MOVED_TO | IN_CLOSE_WRITE
            assert libc.inotify_add_watch(fd, bytes(folder), mask) >= 0, folder
        deadline = time.monotonic() + timeout
        while True:
            for p in paths:  # (after the watches: a file made before them is seen here)
                if ready(p):
                    return p
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([fd], [], [], left)[0]:
                return None
            os.read(fd, 65536)
    finally:
        os.close(fd)
