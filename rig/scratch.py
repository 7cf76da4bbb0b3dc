"""The rig's temporary folders: each names its owner (its process id, that process's start time and its
pid namespace), so that the next rig to start removes the folders whose owner died without cleaning
up.

Why: a rig ended by SIGKILL (or the OOM killer, or a lost VM) runs no cleanup, and its session's folder
(the shim's socket, the clock page, the fakes), a bench run's or a sweep's stayed in the temporary
directory for good. Every other way a rig ends removes its folders itself; this is for the one that
cannot.

Conservative by design: a folder is removed only when it is this user's, carries an owner file, is
older than GRACE_S (its owner may be writing that file right now), its owner was in this pid namespace
(a pid from another one says nothing here), and no process with that id and that start time exists
(so a reused pid does not keep a dead run's folder, and a live run's folder is never touched).
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Final

PREFIX: Final = "rig-"
OWNER: Final = ".rig-owner"
#: a folder younger than this (s) is never judged: its owner may not have written its owner file yet
GRACE_S: Final = 60.0


def _start_time(pid: int) -> str | None:
    """The process's start time (clock ticks since boot: /proc/PID/stat's 22nd field), or None when
    there is no such process."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = stat[stat.rfind(")") + 2:].split()  # (the command name may hold spaces and parentheses)
    return fields[19] if len(fields) > 19 else None


def _pid_namespace() -> str:
    try:
        return os.readlink("/proc/self/ns/pid")
    except OSError:
        return "?"


def make(kind: str, root: Path | None = None) -> Path:
    """A new folder ``rig-KIND-…`` in the temporary directory (or ``root``), its owner named in it."""
    path = Path(tempfile.mkdtemp(prefix=f"{PREFIX}{kind}-", dir=root))
    pid = os.getpid()
    (path / OWNER).write_text(f"{pid} {_start_time(pid)} {_pid_namespace()}\n")
    return path


@contextmanager
def folder(kind: str, root: Path | None = None) -> Iterator[Path]:
    """``make``'s folder for the length of a ``with``, removed after it."""
    path = make(kind, root)
    try:
        yield path
    finally:
        shutil.rmtree(path, ignore_errors=True)


def _dead(path: str, namespace: str) -> bool:
    try:
        pid, start, owner_namespace = Path(path, OWNER).read_text().split()
        return owner_namespace == namespace and _start_time(int(pid)) != start
    except (OSError, ValueError):  # no owner file, or not one of ours: not ours to judge
        return False


def reap(root: Path | None = None, now: float | None = None) -> list[Path]:
    """Removes the folders (``rig-*`` in the temporary directory, or ``root``) whose owner died without
    removing them; returns them. Errors (a folder going away meanwhile, one not readable) pass."""
    base = Path(root) if root is not None else Path(tempfile.gettempdir())
    now = time.time() if now is None else now
    uid, namespace = os.getuid(), _pid_namespace()
    removed: list[Path] = []
    try:
        entries = list(os.scandir(base))
    except OSError:
        return removed
    for entry in entries:
        if not entry.name.startswith(PREFIX):
            continue
        try:
            if not entry.is_dir(follow_symlinks=False):
                continue
            st = entry.stat(follow_symlinks=False)
        except OSError:
            continue
        if st.st_uid != uid or now - st.st_mtime < GRACE_S or not _dead(entry.path, namespace):
            continue
        shutil.rmtree(entry.path, ignore_errors=True)
        removed.append(Path(entry.path))
    return removed
