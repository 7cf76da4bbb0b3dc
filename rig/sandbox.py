"""The sandbox a DUT runs in when the service starts it (and with ``rig run --sandbox``): the whole
``rig run`` process is wrapped, because the MCU engines parse an uploaded image inside it and the
Linux DUT is its keeper's child (rig/dut_process.py).

Made from existing parts, on purpose: bubblewrap (Debian's ``bwrap``) builds the namespaces and the
mounts, util-linux's ``prlimit`` sets the resource limits inside them, and a pids cgroup bounds the
process count when the rig runs as root (the kernel exempts root's processes from RLIMIT_NPROC).

Inside: the whole file system read-only; the run folder the only writable place (with a private,
empty /run as TMPDIR for the session's socket and clock page); the hidden folders (the service's
data folder: its database, uploads and every run's artifacts) replaced by empty read-only ones,
except the files the command line names under them or the run folder links to (its firmware, its
scenario versions); no network (a loopback of its own: the session's Unix socket, shared memory and
ptys still work); its own pid namespace (the service's processes and their command lines are out of
sight); no capabilities but the two a bench run's real-time loop needs when root starts it; the
token's variable unset. docs/service.md says what is isolated and what is not.
"""

from __future__ import annotations

import contextlib
import itertools
import os
import shutil
import signal
import sys
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Final

#: the environment variables a sandboxed run never sees (the service's token)
SECRET_VARIABLES: Final = ("RIG_TOKEN",)
#: where the sandbox's private temporary files go (a tmpfs over the host's /run)
PRIVATE_TMP: Final = "/run"
PRIVATE_TMP_BYTES: Final = 256 << 20
#: the pids hierarchy of cgroup v1, and cgroup v2's mount
CGROUP_V1_PIDS: Final = Path("/sys/fs/cgroup/pids")
CGROUP_V2: Final = Path("/sys/fs/cgroup")
NO_BWRAP: Final = ("the sandbox needs bubblewrap (bwrap), which is missing: install the Debian package "
                   "bubblewrap (make test-packages does)")


@dataclass(frozen=True)
class Limits:
    """Resource limits of a sandboxed run, each per process except ``processes`` (the whole sandbox):
    CPU seconds, address space, processes and threads, the largest file it may write, and the CPU time
    (µs) a task at a real-time priority may take without blocking."""

    cpu_s: int = 6 * 3600  # (a sweep flies all its runs in one process)
    memory_bytes: int = 4 << 30
    processes: int = 512
    file_bytes: int = 2 << 30
    rt_us: int = 1_000_000

    def prlimit(self) -> list[str]:
        return ["prlimit", f"--cpu={self.cpu_s}", f"--as={self.memory_bytes}", f"--nproc={self.processes}",
                f"--fsize={self.file_bytes}", f"--rttime={self.rt_us}", "--"]


class SandboxError(RuntimeError):
    """The sandbox cannot be made here (no bwrap); the message says what to install."""


def available() -> bool:
    return shutil.which("bwrap") is not None and shutil.which("prlimit") is not None


def _under(path: Path, folders: Sequence[Path]) -> bool:
    return any(path == f or f in path.parents for f in folders)


#: what a sandbox started by root keeps: the real-time loop of a bench run takes SCHED_FIFO and
#: mlockall (rig/pace), as it does outside; RLIMIT_RTTIME (Limits.rt_us) ends a task that holds a
#: real-time priority without ever blocking
REAL_TIME_CAPABILITIES: Final = ("CAP_SYS_NICE", "CAP_IPC_LOCK")


def _privileges() -> list[str]:
    """bwrap's options for who the run is. Started by root: root still (a user namespace would map it
    to root outside anyway, and take away what the real-time loop needs), with every capability but
    REAL_TIME_CAPABILITIES dropped. Started by another user: a user namespace of its own, without
    capabilities."""
    if os.geteuid() != 0:
        return ["--unshare-user", "--cap-drop", "ALL"]
    keep = [a for cap in REAL_TIME_CAPABILITIES for a in ("--cap-add", cap)]
    return ["--cap-drop", "ALL", *keep]


def _devices(command: Sequence[str]) -> list[str]:
    """The device nodes the command names (an operand, or the part after ``MAKE:``), which the sandbox's
    own /dev lacks."""
    found = []
    for a in command:
        path = a.rpartition(":")[2]
        if path.startswith("/dev/") and os.path.exists(path) and not os.path.isdir(path):
            found.append(path)
    return sorted(set(found))


def _linked(folders: Sequence[Path]) -> set[Path]:
    """The files the links in ``folders`` point at (the service's run folder links the scenario
    versions it flies: rig/service/store.py's materialize)."""
    found = set()
    for folder in folders:
        for parent, _, files in os.walk(folder):
            for name in files:
                path = Path(parent, name)
                if path.is_symlink() and path.resolve().is_file():
                    found.add(path.resolve())
    return found


def bwrap_argv(command: Sequence[str], writable: Sequence[Path], hidden: Sequence[Path] = (),
               limits: Limits = Limits()) -> list[str]:
    """``command`` wrapped: bwrap's namespaces and mounts, then prlimit's limits, in the caller's
    working folder. ``writable``: the run folder(s), created if missing; ``hidden``: folders that look
    empty inside, except the files the command names under them or the writable folders link to
    (mounted read-only); a writable folder under a hidden one stays writable. The device nodes the
    command names are passed through."""
    bwrap = shutil.which("bwrap")
    if bwrap is None or shutil.which("prlimit") is None:
        raise SandboxError(NO_BWRAP)
    hidden = [h.resolve() for h in hidden]
    argv = [bwrap, "--die-with-parent", "--unshare-ipc", "--unshare-pid", "--unshare-net", "--unshare-uts",
            "--unshare-cgroup-try", *_privileges(), "--ro-bind", "/", "/", "--dev", "/dev", "--proc", "/proc",
            "--size", str(PRIVATE_TMP_BYTES), "--tmpfs", PRIVATE_TMP,
            "--setenv", "TMPDIR", PRIVATE_TMP]
    for folder in hidden:
        if folder.is_dir():
            argv += ["--tmpfs", str(folder)]
        elif folder.exists():
            argv += ["--ro-bind", os.devnull, str(folder)]
    named = {Path(a).resolve() for a in command if a.startswith("/") and Path(a).is_file()}
    named |= _linked(writable)
    for path in sorted(p for p in named if _under(p, hidden)):
        argv += ["--ro-bind", str(path), str(path)]
    for device in _devices(command):  # (a bench run's bridge and supply: --bridge PORT, --psu MAKE:PORT)
        argv += ["--dev-bind", device, device]
    for folder in writable:
        folder.mkdir(parents=True, exist_ok=True)
        argv += ["--bind", str(folder.resolve()), str(folder.resolve())]
    for folder in hidden:  # (after the mounts made under them: their empty stand-ins read-only too)
        if folder.is_dir():
            argv += ["--remount-ro", str(folder)]
    return [*argv, "--", "env", "--default-signal=INT,TERM", *limits.prlimit(), *command]


def build_first_use_parts() -> None:
    """Compiles now what the rig compiles on its first use (the MCU engine's glue, the real-time wait,
    the telemetry reader, the event queue), each only when missing or older than its sources: inside
    the sandbox the tree is read-only. A part that cannot be built is left to the run inside, which
    says why where it needs it."""
    from rig import event_queue, pace, telemetry
    from rig.mcu import engine

    for part in (engine.build, pace.native, telemetry.native, event_queue.native):
        with contextlib.suppress(Exception):  # (reported by the run that needs it, in its own words)
            part()


def _pids_parent() -> Path | None:
    """The cgroup a child bounding the process count can be made in, or None: cgroup v1's pids
    hierarchy, or cgroup v2 where this process's cgroup delegates the pids controller."""
    try:
        lines = Path("/proc/self/cgroup").read_text().splitlines()
    except OSError:
        return None
    for line in lines:
        _, controllers, path = line.split(":", 2)
        if "pids" in controllers.split(",") and CGROUP_V1_PIDS.is_dir():
            parent = CGROUP_V1_PIDS / path.lstrip("/")
            return parent if os.access(parent, os.W_OK) else None
        if controllers == "":
            parent = CGROUP_V2 / path.lstrip("/")
            try:
                delegated = "pids" in (parent / "cgroup.subtree_control").read_text().split()
            except OSError:
                delegated = False
            if delegated and os.access(parent, os.W_OK):
                return parent
    return None


#: the command's first process: bwrap starts with SIGINT and SIGTERM ignored, so that a Ctrl-C or a
#: SIGTERM to the process group reaches the rig run inside (which stops its DUT and writes its reports)
#: instead of ending bwrap, whose end kills everything inside at once; $0 names the pids cgroup to
#: join first ("-": none). The secrets are unset before bwrap starts: its process inside (pid 1 there)
#: keeps the environment it was started with, readable in /proc/1/environ
LAUNCH: Final = (f'unset {" ".join(SECRET_VARIABLES)}; trap "" INT TERM; '
                 '[ "$0" = - ] || echo $$ > "$0/cgroup.procs" || exit 125; exec "$@"')


@contextmanager
def confined(command: Sequence[str], writable: Sequence[Path], hidden: Sequence[Path] = (),
             limits: Limits = Limits()) -> Iterator[list[str]]:
    """The command line that runs ``command`` sandboxed (bwrap_argv), for as long as the block lasts.
    As root, whose processes RLIMIT_NPROC does not count, the process limit is a pids cgroup made for
    this run (the command joins it as it starts; the cgroup is removed after the block); where none can
    be made, root's sandbox has no process limit beyond its CPU time, and says so on stderr."""
    argv = bwrap_argv(command, writable, hidden, limits)
    build_first_use_parts()
    parent = _pids_parent() if os.geteuid() == 0 else None
    if parent is None:
        if os.geteuid() == 0:
            print("rig: no pids cgroup to join: the sandbox's process limit does not bind root",
                  file=sys.stderr)
        yield ["sh", "-c", LAUNCH, "-", *argv]
        return
    _remove_stale_groups(parent)
    group = parent / f"{GROUP_PREFIX}{os.getpid()}-{next(_serial)}"
    group.mkdir()
    try:
        (group / "pids.max").write_text(str(limits.processes))
        yield ["sh", "-c", LAUNCH, str(group), *argv]
    finally:
        _remove_group(group)


_serial = itertools.count()
GROUP_PREFIX: Final = "rig-sandbox-"
#: a run's cgroup younger than this (s) is never judged stale: its owner may be starting the run
STALE_AFTER_S: Final = 60.0


def _remove_stale_groups(parent: Path) -> None:
    """Removes the empty cgroups of rigs that died without removing theirs (a service ended by
    SIGKILL runs no cleanup): those whose owner (the pid in the name) is gone, and older than
    STALE_AFTER_S. The kernel removes a cgroup only when it is empty, so a live run's never goes."""
    for group in parent.glob(f"{GROUP_PREFIX}*"):
        owner = group.name[len(GROUP_PREFIX):].split("-")[0]
        try:
            stale = time.time() - group.stat().st_mtime > STALE_AFTER_S
        except OSError:
            continue
        if stale and owner.isdigit() and not os.path.exists(f"/proc/{owner}"):
            with contextlib.suppress(OSError):
                group.rmdir()


def _remove_group(group: Path) -> None:
    """Removes the run's pids cgroup once it is empty: bwrap's end ends its pid namespace, but the
    kernel takes a moment to let the last processes go (up to a second here; what is still in it then
    is killed first)."""
    for attempt in range(100):
        try:
            group.rmdir()
            return
        except FileNotFoundError:
            return
        except OSError:
            if attempt == 50:
                with contextlib.suppress(OSError):
                    for pid in (group / "cgroup.procs").read_text().split():
                        with contextlib.suppress(ProcessLookupError):
                            os.kill(int(pid), signal.SIGKILL)
            time.sleep(0.01)
