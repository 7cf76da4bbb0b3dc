"""Why a pytest-xdist worker died, said in the log (a pytest plugin, loaded by tests/conftest.py).

A worker that ends at the process level (a signal, an exit from C, its pipe to the master closed under
it) shows only as "node down: Not properly terminated" and a crashed test, which tells nothing of the
cause. Two things here make the next such crash say it:
  * in the master, the worker's exit status: a signal's name, or the status it exited with;
  * in each worker, a signal that ends it (SIGTERM, SIGHUP, SIGALRM, SIGUSR1/2) first prints every
    thread's Python stack on the suite's stderr, then ends it as before (faulthandler, chained)."""

from __future__ import annotations

import faulthandler
import os
import signal
import subprocess
import sys
from typing import Any

import pytest

_FATAL = (signal.SIGTERM, signal.SIGHUP, signal.SIGALRM, signal.SIGUSR1, signal.SIGUSR2)
_EXIT_WAIT_S = 10.0


def status_words(code: int | None) -> str:
    """A worker's exit status as a person reads it."""
    if code is None:
        return "has not ended"
    if code < 0:
        try:
            return f"was killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"was killed by signal {-code}"
    return f"exited with status {code}"


@pytest.hookimpl(trylast=True)
def pytest_configure(config: pytest.Config) -> None:
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        return
    capture = config.pluginmanager.getplugin("capturemanager")
    if capture is not None:
        with capture.global_and_fixture_disabled():
            fd = os.dup(2)
    else:
        fd = os.dup(2)
    os.set_inheritable(fd, False)
    for sig in _FATAL:
        if signal.getsignal(sig) is signal.SIG_DFL:
            faulthandler.register(sig, file=fd, all_threads=True, chain=True)


def pytest_testnodedown(node: Any, error: object | None) -> None:
    if error is None:  # (a worker that finished its share)
        return
    popen = getattr(getattr(getattr(node, "gateway", None), "_io", None), "popen", None)
    if popen is None:  # (another kind of gateway: nothing to wait for)
        return
    try:
        code = popen.wait(timeout=_EXIT_WAIT_S)
    except subprocess.TimeoutExpired:
        code = None
    print(f"\nworker {node.gateway.id} (pid {popen.pid}) {status_words(code)}: {error}", file=sys.stderr)
