"""`rig serve` started as a shell's background job (`rig serve &`) inherits SIGINT ignored; uvicorn
catches it all the same, shuts down, and re-raises it into the ignored handler. The service used to
exit 0 then, with no "stopped" line, where the same Ctrl-C in the foreground exits 130. And Dask's
client logs "Failed to reconnect ... closing client" when its own reconnection gives up, though the
farm connects a new client itself."""

from __future__ import annotations

import logging
import signal
import subprocess
import sys
from pathlib import Path

from rig.service.farm import OwnReconnects
from tests.service.test_api import free_port, until_line
from tests.waits import BOUND_S


def _as_background_job() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # what a non-interactive shell does for `cmd &`


def test_a_background_services_sigint_is_a_stop_with_its_line_and_130(tmp_path: Path) -> None:
    args = [sys.executable, "-m", "rig.cli", "serve", "--port", str(free_port()), "--data", str(tmp_path)]
    proc = subprocess.Popen(args, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True,
                            preexec_fn=_as_background_job)
    try:
        until_line(proc, "listening on")
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=BOUND_S)
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode == 130, err
    assert "rig serve: stopped (Ctrl-C)" in err


def _logged(message: str, *args: object) -> bool:
    record = logging.LogRecord("distributed.client", logging.ERROR, __file__, 1, message, args, None)
    return OwnReconnects().filter(record)


def test_only_dasks_give_up_line_is_dropped() -> None:
    # (the message as distributed's Client._reconnect formats it)
    assert not _logged("Failed to reconnect to scheduler after %.2f seconds, closing client", 10.0)
    assert _logged("Unexpected error while collecting tasks %s from %s", "x", "y")
