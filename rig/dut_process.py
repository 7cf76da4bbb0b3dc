"""The DUT's process as the rig starts it: the environment the shim reads (``dut_env``) and the keeper,
its parent, that starts it and ends everything it started (``Keeper``). Both sessions use them: the
lockstep and real-time one (rig/session.py) and the bench bridge's (rig/bridge/session.py)."""

from __future__ import annotations

import os
import select
import subprocess
from pathlib import Path
from typing import IO


def dut_env(base: dict[str, str] | None, shim: Path, socket_path: Path | str, shm: Path | str, lockstep: bool,
            i2c_bus: int, serial: dict[str, str], fakes: Path, spin_ns: int = 0) -> dict[str, str]:
    """The DUT's environment: the shim preloaded and told where its session (or a virtual bridge's
    board side) listens, the clock page, the emulated bus, which pty serves each serial path, and how
    long a request polls for its reply (``spin_ns``, rig/cores.py; 0: it sleeps at once)."""
    env = dict(base if base is not None else os.environ)
    preload = env.get("LD_PRELOAD", "")
    env.update({
        "LD_PRELOAD": f"{shim} {preload}".strip(),
        "RIG_SOCKET": str(socket_path),
        "RIG_SHM": str(shm),
        "RIG_LOCKSTEP": "1" if lockstep else "0",
        "RIG_I2C_BUSES": str(i2c_bus),
        "RIG_PWM_CHIP": "0",
        "RIG_SERIAL": ":".join(f"{path}={tty}" for path, tty in serial.items()),
        "RIG_FAKES": str(fakes.resolve()),
    })
    if spin_ns:
        env["RIG_SPIN_NS"] = str(spin_ns)
    return env


def running_threads(pids: list[int]) -> list[str]:
    """The threads of these processes that the kernel has running or ready to run (state R), named as
    the program named them: which one spins when a DUT stops answering (/proc/PID/task/TID/stat)."""
    out = []
    for pid in pids:
        try:
            tids = sorted(os.listdir(f"/proc/{pid}/task"), key=int)
        except OSError:
            continue
        for tid in tids:
            try:
                with open(f"/proc/{pid}/task/{tid}/stat") as f:
                    stat = f.read()
            except OSError:
                continue
            name, state = stat[stat.index("(") + 1:stat.rindex(")")], stat[stat.rindex(")") + 2]
            if state == "R":
                out.append(f"'{name}' (pid {pid}, thread {tid})")
    return out


def ended_within(pid: int, timeout_s: float) -> bool | None:
    """Waits on a pidfd for process ``pid`` to end: True once it has (or it is gone), False when it has
    not within ``timeout_s``, None when the kernel gives no pidfds (Linux before 5.3)."""
    try:
        fd = os.pidfd_open(pid)
    except ProcessLookupError:
        return True
    except OSError:
        return None
    try:
        return bool(select.select([fd], [], [], timeout_s)[0])
    finally:
        os.close(fd)


class Keeper:
    """The DUT's parent, ``build/rig-keeper`` (rig/shim/keeper.c): a subreaper that ends every process
    the DUT started, however it detached, when the lifeline closes or the DUT exits; and ends them
    even when this process dies (the lifeline closes with it). Its status pipe says when the DUT's
    main process has ended, and how."""

    def __init__(self, path: Path, command: list[str], env: dict[str, str], stdout: IO[str] | int | None,
                 stderr: IO[str] | int | None, grace_s: float) -> None:
        status_r, status_w = os.pipe()
        life_r, self._life = os.pipe()
        kenv = dict(env)
        kenv["RIG_KEEPER_PRELOAD"] = kenv.pop("LD_PRELOAD", "")  # the keeper runs without the shim
        try:
            self.proc = subprocess.Popen([str(path), str(status_w), str(life_r), str(round(grace_s * 1000)),
                                          "--", *command], env=kenv, pass_fds=(status_w, life_r),
                                         start_new_session=True, stdout=stdout, stderr=stderr)
        except BaseException:
            for fd in (status_r, self._life):
                os.close(fd)
            raise
        finally:
            os.close(status_w)
            os.close(life_r)
        self.status = status_r
        os.set_blocking(status_r, False)
        self.grace_s = grace_s
        self._buf = b""
        self.done = False                 # the DUT's main process has ended (or never started)
        self.returncode: int | None = None
        self.exec_errno: int | None = None

    def read_status(self) -> None:
        try:
            chunk = os.read(self.status, 256)
        except BlockingIOError:
            return
        if not chunk:  # the keeper is gone: whatever it did not say, the DUT is over
            self.done = True
            return
        self._buf += chunk
        *lines, self._buf = self._buf.split(b"\n")
        for line in lines:
            what, _, value = line.decode("ascii", "replace").partition(" ")
            if what == "exit":
                self.returncode = os.waitstatus_to_exitcode(int(value))
                self.done = True
            elif what == "exec":
                self.exec_errno = int(value)
                self.done = True

    def stop(self) -> None:
        """Closes the lifeline: the keeper sends SIGTERM to the DUT's processes, SIGKILL after grace."""
        if self._life >= 0:
            os.close(self._life)
            self._life = -1

    def _ended_within(self, timeout_s: float) -> bool | None:
        """The keeper's end waited for on a pidfd (ended_within). Popen.wait with a timeout looks with
        sleeps of 0.5 ms, 1 ms, 2 ms...: one or two milliseconds of every run's wall time, a tenth of a
        short lockstep run's. (Not reaped yet, its pid cannot be another's.)"""
        return True if self.proc.poll() is not None else ended_within(self.proc.pid, timeout_s)

    def finish(self) -> None:
        """Stops the DUT if it runs, waits until the keeper has ended everything, reads its last words."""
        self.stop()
        limit = self.grace_s + 5.0
        ended = self._ended_within(limit)
        try:
            self.proc.wait(timeout=limit if ended is None else 0)
        except subprocess.TimeoutExpired:  # (a keeper stuck is a bug of ours; do not hang on it)
            self.proc.kill()
            self.proc.wait()
        while not self.done:
            self.read_status()
        if self.status >= 0:
            os.close(self.status)
            self.status = -1
