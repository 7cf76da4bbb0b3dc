"""The test process keeps Python's SIGPIPE disposition (ignored: a write to a closed pipe is an
EPIPE error) once every test module is imported. A module that reset it to SIG_DFL at import (the
vcdvcd package does) made a pytest-xdist worker die of SIGPIPE in a later, unrelated test that wrote
to a child process which had already exited (tests/bridge/tools.py feeds /bin/echo, which reads
nothing)."""

from __future__ import annotations

import signal
import subprocess


def test_sigpipe_is_still_ignored_after_collection() -> None:
    assert signal.getsignal(signal.SIGPIPE) == signal.SIG_IGN


def test_writing_to_a_child_that_reads_nothing_is_survived() -> None:
    done = subprocess.run(["/bin/true"], input=b"x" * (1 << 20), capture_output=True, timeout=60)
    assert done.returncode == 0
