"""One variant, flown inside a worker (a local pool's process or a Dask worker's thread): it takes a
core of its own (a lock file per core and host: Dask's workers are not numbered), checks the varied
scenario, flies it, writes the run's artifacts under the sweep's folder, and returns a small row (only
that travels back through the engine). The row is also written next to the artifacts, last and
atomically: a run that finished is never flown again, even when the sweep that asked for it died."""

from __future__ import annotations

import fcntl
import json
import math
import os
import socket
import tempfile
import threading
import time
from collections.abc import Iterator
from contextlib import AbstractContextManager, contextmanager, nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rig import compiled

if TYPE_CHECKING:
    from rig.scenarios.sweep import Variant

#: the runs' folders (runs/<id>/) and a row's file in each
RUNS = "runs"
ROW = "row.json"
SLOTS = ".slots"


@dataclass(frozen=True)
class Task:
    """What a worker needs (picklable, small): the variant (its tables, values and seed) and where to
    write."""

    variant: Variant
    scenario_path: str
    out: str
    dut: list[str] | None = None
    wall_timeout: float = 600.0
    #: the local pool's: a folder of the sweep's own for the runs' temporary files, so a worker killed
    #: mid-run leaves nothing behind once the sweep removes it (None: the system's, as on a cluster)
    tmp: str | None = None
    #: the sweep's DUT (rig/sweep/store.py's dut_identity)
    dut_command: str | None = None
    dut_sha256: str | None = None
    fc_profile_sha256: str | None = None
    #: the FC profile's file (None: the reference FC's)
    fc: str | None = None

    def head(self) -> dict[str, Any]:
        """What begins the variant's row: which run it is, and the DUT that flies it."""
        v = self.variant
        return {
            "id": v.id,
            "index": v.index,
            "values": v.values,
            "seed": v.seed,
            "dut_command": self.dut_command,
            "dut_sha256": self.dut_sha256,
            "fc_profile_sha256": self.fc_profile_sha256,
        }


@contextmanager
def core_slot(folder: Path) -> Iterator[int]:
    """Holds one core of this host for the calling thread (and the DUT it starts): the first free one
    of the thread's allowed cores, else waits for one. The lock is flock on folder/HOST-CPU.lock, so
    it is released when the holder dies, however it dies."""
    folder.mkdir(parents=True, exist_ok=True)
    allowed = sorted(os.sched_getaffinity(0))
    host = socket.gethostname()
    fd = -1
    cpu = allowed[0]
    for blocking in (False, True):
        # (the blocking pass waits on a core picked by pid and thread, so waiters spread out)
        order = allowed if not blocking else [allowed[(os.getpid() + _thread_number()) % len(allowed)]]
        for cpu in order:
            fd = os.open(folder / f"{host}-{cpu}.lock", os.O_RDWR | os.O_CREAT, 0o644)
            try:
                if blocking:
                    with _interruptible():  # (a stopped sweep does not wait for a core)
                        fcntl.flock(fd, fcntl.LOCK_EX)
                else:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                os.close(fd)
                fd = -1
            except BaseException:
                os.close(fd)
                raise
        if fd >= 0:
            break
    try:
        os.sched_setaffinity(0, {cpu})
        yield cpu
    finally:
        os.sched_setaffinity(0, allowed)
        fcntl.flock(fd, fcntl.LOCK_UN)
        os.close(fd)


def _interruptible() -> AbstractContextManager[None]:
    """A local pool's worker (its main thread, where rig/interrupts.py's handlers are) leaves a wait at
    once on a signal; a Dask worker's thread cannot take signals (its worker handles them)."""
    from rig import interrupts

    return interrupts.live() if threading.current_thread() is threading.main_thread() else nullcontext()


def _thread_number() -> int:
    return threading.get_ident() % 9973


def run_dir(out: Path, run_id: str) -> Path:
    return out / RUNS / run_id


def row_files(out: Path) -> list[Path]:
    """The rows the sweep's finished runs left, in run-id order."""
    return sorted((out / RUNS).glob(f"*/{ROW}"))


def read_row(out: Path, run_id: str) -> dict[str, Any] | None:
    """The row a finished run left, or None (not run, or a file that is not one of ours)."""
    try:
        row = json.loads((run_dir(out, run_id) / ROW).read_text())
    except (OSError, ValueError):
        return None
    return row if isinstance(row, dict) and row.get("id") == run_id else None


def _number(v: float) -> float | None:
    return v if math.isfinite(v) else None


def fly(task: Task) -> dict[str, Any]:
    """Runs one variant; never raises for the run's own problems (they are its row's error)."""
    # this is a worker's entry point (a local pool's process, a Dask worker): the session's hot modules
    # from build/mypyc must be found before anything below imports them, as the CLI does at its start
    compiled.install()
    from rig import interrupts
    from rig.reports import html_report, mcap, result_json
    from rig.runner import not_run, run
    from rig.scenarios import profile as profiles
    from rig.scenarios.schema import ScenarioError, check
    from rig.targets.process import ProcessTarget

    out = Path(task.out)
    row: dict[str, Any] = {**task.head(), "host": socket.gethostname(), "pid": os.getpid()}
    if interrupts.stopped() is not None:  # a worker told to stop flies none of the runs queued for it
        return {**row, "verdict": "interrupted", "error": None, "measurements": {}}
    if task.tmp is not None:
        tempfile.tempdir = task.tmp  # (a pool process flies one run at a time)
    v = task.variant
    folder = run_dir(out, v.id)
    folder.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    try:
        scenario = check(v.data, Path(task.scenario_path))
    except ScenarioError as e:  # (the sweep checked every variant: only a changed rig gets here)
        row.update(verdict="error", error=str(e), measurements={}, outcomes={}, wall_s=0.0, cpu=-1)
        _write_row(folder, row)
        return row
    # a local pool's process (rig/sweep/engine.py) has rig/interrupts.py's handlers: a signal stops the
    # run under way cleanly (one that comes while a report is written: the next run); a Dask worker's
    # task thread cannot take signals: its worker handles them
    try:
        with core_slot(out / SLOTS) as cpu:
            try:
                profile = profiles.load(task.fc or profiles.DEFAULT)
                r = run(scenario, ProcessTarget(task.dut), v.seed, folder, task.wall_timeout, profile=profile)
            except Exception as e:  # the rig could not fly it: an error row, the sweep goes on
                r = not_run(scenario, v.seed, f"the rig could not run this variant: {type(e).__name__}: {e}")
    except interrupts.Interrupted:  # while it waited for a core
        return {**row, "verdict": "interrupted", "error": None, "measurements": {}}
    row.update(
        # (what the run itself hashed: a DUT rebuilt since the sweep began shows here)
        dut_sha256=r.metadata.get("dut_firmware_sha256", task.dut_sha256),
        verdict=r.verdict,
        error=r.error,
        cpu=cpu,
        wall_s=round(time.perf_counter() - t0, 3),
        measurements={m.name: _number(m.value) for m in r.measurements},
        outcomes={m.name: m.outcome for m in r.measurements},
        limits={m.name: [m.min, m.max] for m in r.measurements},
        units={m.name: m.units for m in r.measurements},
    )
    if r.verdict == "interrupted" or (r.verdict == "error" and interrupts.stopped() is not None):
        # not kept: a resumed sweep flies it again (an error while a signal stopped the worker is the
        # signal's doing, such as a DUT it killed first)
        return {**row, "verdict": "interrupted"}
    (folder / "result.json").write_text(result_json.render(r))
    (folder / "report.html").write_text(html_report.render(r))
    mcap.write_run(folder, r)
    _write_row(folder, row)
    return row


def _write_row(folder: Path, row: dict[str, Any]) -> None:
    tmp = folder / f".{ROW}.{os.getpid()}"
    tmp.write_text(json.dumps(row, default=str))
    os.replace(tmp, folder / ROW)
