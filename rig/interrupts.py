"""SIGINT, SIGTERM and SIGHUP as an orderly stop of the rig.

A user's Ctrl-C, a CI job's timeout (SIGTERM) or a closed terminal must not leave a DUT running, a
temporary folder behind or a report half written. While ``handled()`` is in force (the CLI's commands),
such a signal raises ``Interrupted`` only where a run can be cut at once, inside ``live()`` (a
session's wait loop, which then stops the DUT and cleans up); anywhere else it waits until the next
``check()`` (between two scenarios), so what is being written is finished first. Outside ``handled()``
(the rig used as a library, tests) Python's own handling is untouched.

A sweep's pool worker (``install()``) differs in one way: the first signal stays. Runs already queued
for it cannot be taken back, so once told to stop it flies none of them (``stopped()``), and the sweep
can end it.
"""

from __future__ import annotations

import signal
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

_pending: int | None = None
_live = False
_worker = False  # install(): a pool worker, which keeps the first signal in _stopped
_stopped: int | None = None


class Interrupted(Exception):
    """The rig was asked to stop by a signal; ``exit_code`` is the shell's convention (128 + N)."""

    def __init__(self, signum: int) -> None:
        self.signum = signum
        self.name = signal.Signals(signum).name
        super().__init__(f"interrupted by {self.name}")

    @property
    def exit_code(self) -> int:
        return 128 + self.signum


def _handler(signum: int, frame: FrameType | None) -> None:
    global _pending, _live, _stopped
    if _worker and _stopped is None:
        _stopped = signum
    if _live:
        _live = False  # once: a second signal must not cut the clean-up the first one started
        raise Interrupted(signum)
    if _pending is None:
        _pending = signum


@contextmanager
def handled() -> Iterator[None]:
    """Installs the handlers for the duration, then restores the previous ones."""
    global _pending
    old = {s: signal.signal(s, _handler) for s in SIGNALS}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        _pending = None


def install() -> None:
    """Installs the handlers for the rest of the process: a sweep's pool worker (rig/sweep/work.py),
    where a signal stops the run under way (or the next one) and never the worker in the middle of
    writing a report; after it, ``stopped()`` says so."""
    global _worker
    _worker = True
    for s in SIGNALS:
        signal.signal(s, _handler)


def stopped() -> int | None:
    """In a process ``install()`` set up: the signal that asked it to stop (for good), else None."""
    return _stopped


@contextmanager
def live() -> Iterator[None]:
    """Inside, a signal raises Interrupted at once (one that came just before, too)."""
    global _live
    check()
    _live = True
    try:
        yield
    finally:
        _live = False


def check() -> None:
    """Raises Interrupted for a signal that came while it had to wait."""
    global _pending
    if _pending is not None:
        signum, _pending = _pending, None
        raise Interrupted(signum)
