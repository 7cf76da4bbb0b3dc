"""The virtual bridge (bridge/posix, built to build/vbridge) as the host starts it: `--bridge virtual`.

It is the bridge core as a Linux process. At start it prints one line naming its endpoints:
``vbridge link=PTY board=SOCKET shm=FILE rc=PTY can=PTY``: the pty the host's link opens (as it would a
real bridge's serial port), the board side a Linux-process DUT is started against (the redirection
socket and page its shim connects to, and the pty its RC port reads SBUS from), and the CAN bus its
capture frames go out on, as a USB-CAN adapter speaking slcan presents it (python-can's ``slcan``
interface opens it). It ends when its link
hangs up, so it cannot outlive the rig; ``stop`` ends it sooner.
"""

from __future__ import annotations

import os
import select
import shutil
import signal
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from rig.bridge.port import BridgeError
from rig.plant.artifacts import BUILD

VBRIDGE = BUILD / "vbridge"
KEYS = ("link", "board", "shm", "rc")


@dataclass(frozen=True)
class Endpoints:
    link: str
    board: str
    shm: str
    rc: str
    can: str = ""  # optional: a bridge with no CAN names none


def parse_endpoints(line: str) -> Endpoints:
    """The start line's endpoints; BridgeError naming what is missing or unexpected."""
    words = line.split()
    if not words or words[0] != "vbridge":
        raise BridgeError(f"the virtual bridge's first line is not its endpoints: {line.strip()!r}")
    fields = dict(w.partition("=")[::2] for w in words[1:])
    missing = [k for k in KEYS if not fields.get(k)]
    if missing:
        raise BridgeError(f"the virtual bridge did not name its {', '.join(missing)}: {line.strip()!r}")
    return Endpoints(fields["link"], fields["board"], fields["shm"], fields["rc"], fields.get("can", ""))


class VirtualBridge:
    def __init__(self, exe: Path = VBRIDGE, start_timeout_s: float = 5.0) -> None:
        if not exe.is_file():
            raise BridgeError(f"the virtual bridge is not built at {exe}; run `make vbridge`")
        self._err = tempfile.TemporaryFile()  # (a pipe nobody reads could fill and stall it)
        self.proc = subprocess.Popen([str(exe)], stdout=subprocess.PIPE, stderr=self._err,
                                     start_new_session=True)
        try:
            self.endpoints = parse_endpoints(self._first_line(start_timeout_s))
        except BaseException:
            self.stop()
            raise

    def _first_line(self, timeout_s: float) -> str:
        assert self.proc.stdout is not None
        fd = self.proc.stdout.fileno()
        buf = b""
        deadline = time.monotonic() + timeout_s
        while b"\n" not in buf:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([fd], [], [], left)[0]:
                raise BridgeError(f"the virtual bridge named no endpoints within {timeout_s:g} s")
            chunk = os.read(fd, 4096)
            if not chunk:
                raise BridgeError(f"the virtual bridge exited at start: {self._last_words()}")
            buf += chunk
        return buf.split(b"\n", 1)[0].decode("ascii", "replace")

    def _last_words(self) -> str:
        try:
            self.proc.wait(timeout=2.0)
        except subprocess.TimeoutExpired:
            return "(it said nothing)"
        self._err.seek(0)
        err = self._err.read().decode("utf-8", "replace").strip().splitlines()
        return f"status {self.proc.returncode}" + (f", {err[-1]}" if err else "")

    @property
    def alive(self) -> bool:
        return self.proc.poll() is None

    def stop(self) -> None:
        """SIGTERM, then SIGKILL if it has not ended within two seconds; its pipes closed; and its
        folder removed if it could not remove it itself (killed outright, it runs no clean-up)."""
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGTERM)
            try:
                self.proc.wait(timeout=2.0)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()
        if self.proc.stdout is not None:
            self.proc.stdout.close()
        self._err.close()
        if hasattr(self, "endpoints"):
            folder = Path(self.endpoints.board).parent  # vbridge.XXXXXX, which holds its socket and page
            if folder.name.startswith("vbridge.") and folder.is_dir():
                shutil.rmtree(folder, ignore_errors=True)
