"""A hostile DUT: tries each way out of the sandbox and prints one line per try, ``escape NAME: HOW``
(``blocked`` or what it got), then the limits it runs under, then everything it can see of other
processes' command lines and environments (where a token would show). Arguments: DATA (the service's
data folder), OUTSIDE (a folder outside its run folder), PORT (a TCP listener on the host's loopback),
FORKS (how many processes it tries to start)."""

from __future__ import annotations

import os
import signal
import socket
import sys
from pathlib import Path


def attempt(name: str, action: object) -> None:
    try:
        got = action() if callable(action) else action
    except OSError as e:
        print(f"escape {name}: blocked ({e.strerror})", flush=True)
        return
    print(f"escape {name}: {got!r}", flush=True)


def forks(n: int) -> int:
    """Children that wait, as many as the sandbox allows up to ``n`` (a fork bomb that stops)."""
    started = 0
    for _ in range(n):
        try:
            pid = os.fork()
        except OSError:
            break
        if pid == 0:
            signal.pause()
            os._exit(0)
        started += 1
    return started


def main() -> None:
    data, outside, port, n = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
    attempt("read-database", lambda: (data / "rig.sqlite").read_bytes()[:16])
    attempt("list-data", lambda: sorted(p.name for p in data.iterdir()) or None)
    attempt("list-runs", lambda: sorted(p.name for p in (data / "runs").iterdir()))
    attempt("write-outside", lambda: (outside / "escaped").write_text("out"))
    attempt("write-database", lambda: (data / "rig.sqlite").write_text("gone"))
    attempt("network", lambda: socket.create_connection(("127.0.0.1", port), timeout=5).getsockname())
    print(f"forks {forks(n)}", flush=True)
    for line in Path("/proc/self/limits").read_text().splitlines()[1:]:
        print(f"limit {line}", flush=True)
    for proc in Path("/proc").iterdir():
        for part in ("cmdline", "environ"):
            try:
                print(f"seen {(proc / part).read_bytes()!r}")
            except OSError:
                pass


if __name__ == "__main__":
    main()
