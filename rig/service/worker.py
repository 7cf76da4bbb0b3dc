"""The service's workers: one thread per resource slot (the bench, one; lockstep slots, one per core),
each claiming the next queued run of its resource from the database and running it as ``rig run`` in a
process of its own, with its reports in the run's artifact folder.

The child runs in a session of its own (so cancelling ends it and everything it started, as SIGTERM
ends ``rig run``: the DUT stopped, the reports of what finished written) and is tied to the service by
PR_SET_PDEATHSIG: a service that dies, however, takes its runs with it, and the next start marks them
interrupted (Db.interrupt_running).
"""

from __future__ import annotations

import contextlib
import ctypes
import json
import os
import re
import shlex
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from rig import sandbox
from rig.service.db import TERMINAL, Db
from rig.service.store import SWEEP_SPEC, Store
from rig.sweep.work import row_files

if TYPE_CHECKING:
    from rig.service.farm import Farm

PR_SET_PDEATHSIG: Final = 1
BENCH: Final = "bench"
LEASE_TTL_S: Final = 5.0  # the bench's lease lasts this long unless renewed (every HEARTBEAT_S)
HEARTBEAT_S: Final = 1.0
POLL_S: Final = 0.2
#: how often a sweep's progress is counted from its run folders (one listing of them each time)
SWEEP_COUNT_S: Final = 1.0
KILL_GRACE_S: Final = 5.0
#: in a run's folder, the scenario versions it flies as NAME.toml (hidden: not among its artifacts)
PINNED: Final = ".scenarios"
#: rig run's exit status -> the run's status (anything else: error)
STATUS_BY_EXIT: Final = {0: "passed", 1: "failed", 130: "interrupted", 143: "interrupted"}


def stopped_while_running(why: str = "") -> str:
    """A run's error when the service stopped under it; ``why``: what stopped it ("Ctrl-C", "SIGTERM")."""
    return f"the service was stopped ({why}) while this run was running" if why else \
        "the service stopped while this run was running"


def _die_with_parent() -> None:  # (runs in the child between fork and exec)
    ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)


def command(run: dict[str, Any], out: Path, store: Store) -> tuple[list[str], dict[str, str]]:
    """``rig run`` (or ``rig sweep``) for this run, flying the scenario versions it was queued with (the
    API checked every part before it was queued; what an upload that went missing since cannot give is
    refused here, as an error of the run), and those versions by name."""
    pinned = out / PINNED
    if run["mode"] == "sweep":  # one lockstep slot: the sweep's runs one at a time, on its core
        spec, flown = store.sweep_spec(Path(run["scenarios"][0]), pinned, run["versions"])
        cmd = [sys.executable, "-m", "rig.cli", "sweep", str(spec), "--out", str(out), "--jobs", "1"]
        if run["dut"].get("command"):
            cmd += ["--dut", run["dut"]["command"]]
        if run["dut"].get("fc"):
            cmd += ["--fc", run["dut"]["fc"]]
        return cmd, flown
    flown = store.materialize(pinned, run["scenarios"], run["versions"])
    files = [str(pinned / f"{name}.toml") for name in run["scenarios"]]
    cmd = [sys.executable, "-m", "rig.cli", "run", *files, "--seed", str(run["seed"]), "--out", str(out)]
    if run["mode"] == "bridge":
        cmd += ["--bridge", "virtual"]
    for option in ("pwm_channels", "topology"):  # (a Linux DUT's board: app.dut_of)
        if run["dut"].get(option):
            cmd += ["--" + option.replace("_", "-"), run["dut"][option]]
    if run["dut"].get("command"):
        cmd += ["--dut", run["dut"]["command"]]
    elif run["dut"].get("firmware"):
        program = store.firmware(run["dut"]["firmware"])
        if program is None:
            raise LookupError(f"the firmware {run['dut']['firmware']} is no longer there")
        if run["dut"].get("board"):  # an MCU image on its board, under emulation (checked when queued)
            board = store.board(run["dut"]["board"])
            if board is None:
                raise LookupError(f"the board {run['dut']['board']} is no longer there")
            cmd += ["--mcu", str(board), "--firmware", str(program)]
        else:
            cmd += ["--dut", shlex.quote(str(program))]
    if run["dut"].get("fc"):
        cmd += ["--fc", run["dut"]["fc"]]
    return cmd, flown


#: rig run's line as a scenario starts, its verdict added to it when it ends (rig/run_cmd.py)
STARTED: Final = re.compile(r"\[(\d+)/(\d+)\] \S+ \(([0-9.e+]+) s sim\) \.\.\.$")


class RealtimeProgress:
    """A real-time run's progress within a scenario (a bench run, which would otherwise read 0 % for
    its whole flight): in real time sim time runs at the wall clock's pace, so the wall time since
    ``rig run`` wrote that a scenario started, over its duration, is the share of it flown (at most
    99 % until its verdict; rounded to whole percent: one database write a second at most)."""

    def __init__(self, log: Path) -> None:
        self.log = log
        self._line = ""
        self._since = 0.0

    def __call__(self, done: int, total: int) -> float:
        started = STARTED.search(_tail(self.log))
        if started is None or int(started.group(1)) != done + 1:
            return round(100.0 * done / max(total, 1), 1)
        if started.group(0) != self._line:
            self._line, self._since = started.group(0), time.monotonic()
        flown = min((time.monotonic() - self._since) / max(float(started.group(3)), 1e-3), 0.99)
        return float(round(100.0 * (done + flown) / max(total, 1)))


def _tail(log: Path) -> str:
    """The log's last line, as far as it was written (no newline yet: a scenario under way)."""
    try:
        with open(log, "rb") as f:
            f.seek(max(f.seek(0, os.SEEK_END) - 1024, 0))
            return f.read().decode(errors="replace").rsplit("\n", 1)[-1]
    except OSError:
        return ""


def why(what: str, code: int, log: Path, found: list[dict[str, Any]]) -> str:
    """Why a run ended in error, for a person: each scenario's reason as its result.json says it ("the
    DUT never read a sensor"), else how its process ended (``ended``)."""
    reasons = [f"{r['scenario']}: {r['error']}" for r in found if r.get("error")]
    return "; ".join(reasons) if reasons and code > 0 else ended(what, code, log)


def sweep_results(out: Path, scenario: str, sha256: str) -> list[dict[str, Any]]:
    """A sweep's outcome as one result: its scenario and version, the overall verdict and the counts,
    from the rows its runs left (rig/sweep/work.py)."""
    rows = [json.loads(p.read_text()) for p in row_files(out)]
    counts = {v: sum(r.get("verdict") == v for r in rows) for v in ("pass", "fail", "error")}
    verdict = "error" if counts["error"] else "fail" if counts["fail"] else "pass" if rows else "not run"
    return [{"scenario": scenario, "sha256": sha256, "verdict": verdict, "measurements": [],
             "sweep": counts}]


def count_runs(spec: Path) -> int:
    from rig.run_cmd import LIBRARY
    from rig.scenarios.sweep import SweepError, load_sweep

    try:
        return len(load_sweep(spec, LIBRARY).variants)
    except SweepError as e:
        raise LookupError(f"the sweep spec no longer checks: {e}") from None


def sweep_progress(out: Path, total: int) -> float:
    return round(100.0 * len(row_files(out)) / max(total, 1), 1)


def results(out: Path, scenarios: list[str]) -> list[dict[str, Any]]:
    """Each scenario's verdict and measurements, from the result.json rig run wrote (absent: not run)."""
    found: list[dict[str, Any]] = []
    for name in scenarios:
        path = out / Path(name).stem / "result.json"
        try:
            r = json.loads(path.read_text())
        except (OSError, ValueError):
            found.append({"scenario": Path(name).stem, "verdict": "not run", "measurements": []})
            continue
        found.append({"scenario": r["scenario"], "sha256": r.get("metadata", {}).get("scenario_sha256"),
                      "verdict": r["verdict"], "error": r.get("error"),
                      "measurements": [{k: m.get(k) for k in ("name", "value", "units", "min", "max",
                                                                "outcome", "marginal")}
                                       for m in r["measurements"]]})
    return found


class Workers:
    """The local slots; with ``farm`` (rig serve --engine), every run goes to the Dask cluster instead
    (rig/service/farm.py): lockstep runs and sweeps to its workers, bench runs to its bench hosts."""

    def __init__(self, db: Db, artifacts: Path, store: Store, lockstep_slots: int,
                 farm: Farm | None = None, sandbox: bool = True) -> None:
        self.db, self.artifacts, self.store, self.farm = db, artifacts, store, farm
        self.sandbox = sandbox
        benches = 1 if farm is None else 0
        if farm is not None:
            lockstep_slots = 0
        self._wake = threading.Condition()
        self._stop = False
        self._why = ""
        self._stopping = threading.Lock()
        #: set once stop() has ended every run under way (the API's long polls and event streams end then)
        self.stopped = threading.Event()
        self._procs: dict[int, subprocess.Popen[bytes]] = {}
        self._threads = [threading.Thread(target=self._loop, args=(mode,), daemon=True, name=f"{mode}-{k}")
                         for mode, n in (("lockstep", lockstep_slots), ("bridge", benches)) for k in range(n)]

    def start(self) -> None:
        for t in self._threads:
            t.start()
        if self.farm is not None:
            self.farm.start()

    def wake(self) -> None:
        with self._wake:
            self._wake.notify_all()
        if self.farm is not None:
            self.farm.wake()

    def stop(self, why: str = "") -> None:
        """The service is stopping (``why``: what stopped it, in words, for the runs' errors): the runs
        under way end at once, interrupted as at a restart (every rig run asked together, SIGKILLed after
        a grace), then ``stopped`` is set. ``rig serve`` calls it on the signal, before uvicorn waits for
        its connections; a second call waits for the first."""
        with self._stopping:
            if self.stopped.is_set():
                return
            self._why, self._stop = why, True
            _end(*list(self._procs.values()))
            self.wake()
            for t in self._threads:
                t.join(timeout=KILL_GRACE_S + 1)
            if self.farm is not None:
                self.farm.stop(why)
            self.stopped.set()

    def cancel(self, run_id: int) -> None:
        proc = self._procs.get(run_id)
        if proc is not None:
            _end(proc)
        if self.farm is not None:
            self.farm.cancel(run_id)

    def abort(self, run_id: int) -> str | None:
        """Cancels a queued or running run (a running one: its rig run is stopped, its DUT with it).
        None when done; otherwise why not, in words."""
        found = self.db.get(run_id)
        if found is None:
            return f"no run {run_id}"
        if found["status"] in TERMINAL:
            return f"run {run_id} is already {found['status']}"
        if not self.db.update_if(run_id, found["status"], status="cancelled"):
            return f"run {run_id} changed meanwhile; ask again"
        self.cancel(run_id)
        return None

    def _loop(self, mode: str) -> None:
        holder = f"{socket.gethostname()}:{os.getpid()}:{threading.current_thread().name}"
        while not self._stop:
            leased = mode == "bridge"
            if leased and not self.db.acquire(BENCH, holder, LEASE_TTL_S):
                run = None  # another holder has the bench
            else:
                run = self.db.claim(*((mode, "sweep") if mode == "lockstep" else (mode,)))
            if run is None:
                if leased:
                    self.db.release(BENCH, holder)
                with self._wake:
                    self._wake.wait(timeout=1.0)
                continue
            self._run(run, (holder if leased else None))
            if leased:
                self.db.release(BENCH, holder)

    def _confined(self, cmd: list[str], out: Path) -> contextlib.AbstractContextManager[list[str]]:
        """The run's command in the sandbox (rig/sandbox.py): its folder the only writable one, the
        service's data folder (its database, uploads, the other runs) hidden; as given without."""
        if not self.sandbox:
            return contextlib.nullcontext(cmd)
        return sandbox.confined(cmd, [out], [self.artifacts.parent])

    def _run(self, run: dict[str, Any], lease_holder: str | None = None) -> None:
        out = self.artifacts / str(run["id"])
        out.mkdir(parents=True, exist_ok=True)
        sweep = run["mode"] == "sweep"
        try:
            cmd, flown = command(run, out, self.store)
            if sweep:  # (checked when it was queued)
                run["total"] = count_runs(out / PINNED / SWEEP_SPEC)
        except LookupError as e:
            self.db.finish(run["id"], "error", error=str(e))
            return
        if flown != run["versions"]:  # (a run queued before runs recorded versions: pinned now)
            self.db.update(run["id"], versions=flown)
        with open(out / "rig-run.log", "wb") as log, self._confined(cmd, out) as cmd:
            try:
                proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                        start_new_session=True, preexec_fn=_die_with_parent)
            except OSError as e:
                self.db.finish(run["id"], "error", error=f"could not start rig run: {e}")
                return
            self._procs[run["id"]] = proc
            self.db.update(run["id"], pid=proc.pid)
            total = run["total"] if sweep else len(run["scenarios"])
            beat = counted = time.monotonic()
            progress = 0.0
            realtime = RealtimeProgress(out / "rig-run.log") if run["mode"] == "bridge" else None
            while True:
                try:
                    code = proc.wait(timeout=POLL_S)
                    break
                except subprocess.TimeoutExpired:
                    now = time.monotonic()
                    if not sweep:
                        done = sum((out / Path(s).stem / "result.json").is_file() for s in run["scenarios"])
                        now_progress = (realtime(done, total) if realtime is not None
                                        else round(100.0 * done / total, 1))
                    elif now - counted >= SWEEP_COUNT_S:  # (a listing of thousands of run folders)
                        counted = now
                        now_progress = sweep_progress(out, total)
                    else:
                        now_progress = progress
                    if now_progress != progress:  # (the database is written only when it changed)
                        progress = now_progress
                        self.db.update(run["id"], progress=progress)
                    if sweep:
                        continue
                    if lease_holder is not None and time.monotonic() - beat >= HEARTBEAT_S:
                        beat = time.monotonic()  # the bench's heartbeat
                        self.db.acquire(BENCH, lease_holder, LEASE_TTL_S)
            self._procs.pop(run["id"], None)
        status = STATUS_BY_EXIT.get(code, "error")
        what = "rig sweep" if sweep else "rig run"
        found = sweep_results(out, *next(iter(flown.items()))) if sweep else results(out, run["scenarios"])
        error = None if status in ("passed", "failed") else why(what, code, out / "rig-run.log", found)
        if self._stop:
            status, error = "interrupted", stopped_while_running(self._why)
        self.db.finish(run["id"], status, exit_code=code, error=error, progress=100.0, pid=None,
                       results=found)


def _end(*procs: subprocess.Popen[bytes]) -> None:
    """SIGTERM to each run's session (rig run stops its DUT and writes its reports), all at once; SIGKILL
    to those still there after a grace."""
    for proc in procs:
        try:
            os.killpg(proc.pid, signal.SIGTERM)
        except ProcessLookupError:
            pass
    deadline = time.monotonic() + KILL_GRACE_S
    for proc in procs:
        try:
            proc.wait(timeout=max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass


def ended(what: str, code: int, log: Path) -> str:
    """How a run's process ended, for a person: "rig run stopped by SIGKILL", or its exit status with
    the last line it wrote (as written: no shell quoting, control characters shown as escapes)."""
    if code < 0:
        try:
            by = signal.Signals(-code).name
        except ValueError:
            by = f"signal {-code}"
        last = _last_line(log)
        return f"{what} was stopped by {by}" + (f" (its last line: {last})" if last else "")
    return f"{what} exited with status {code}: {_last_line(log) or '(no output)'}"


def _last_line(log: Path) -> str:
    try:
        lines = [x for x in log.read_text(errors="replace").splitlines() if x.strip()]
    except OSError:
        return ""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in lines[-1][:300]) if lines else ""
