"""Lockstep runs and sweeps on a Dask cluster (``rig serve --engine tcp://HOST:PORT``, docs/farm.md),
instead of the service's local slots. Dask is the scheduler; nothing here schedules but the queue's
order, which stays the database's.

* **No shared file system.** A run's inputs (the scenario versions it flies, its firmware) travel to the
  worker as bytes inside the task; the worker flies it with ``rig run`` (or ``rig sweep``) in a
  temporary folder of its own and returns the run's whole folder as one tar archive, which the service
  unpacks into DATA/runs/ID with tarfile's ``data`` filter (a worker's bytes are not trusted: no
  absolute path, no way out of the folder, no device or link outside).
* **Only what the cluster can run now is dispatched** (its threads minus the runs in flight): the rest
  stays queued in the database, with its position, and survives a restart of the service or of the
  scheduler.
* **A scheduler that goes away stops dispatch.** Dask cancels the futures in flight (their results
  would never come back), so those runs are ``interrupted``; what is queued stays queued; the service
  connects again every RECONNECT_S and says how it stands (``state``: /api/health, the page).
* **Cancelling** is a Dask Event per run (``rig-cancel-ID``) that the task checks while its run flies,
  then SIGTERM as the local worker gives (the DUT stopped, the reports of what finished written): Dask
  cannot stop a running task's thread itself.
"""

from __future__ import annotations

import io
import logging
import secrets
import socket
import subprocess
import sys
import tarfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

from rig import sandbox, scratch
from rig.service.db import Db
from rig.service.store import SWEEP_SPEC, Store
from rig.service.worker import (
    PINNED,
    POLL_S,
    STATUS_BY_EXIT,
    RealtimeProgress,
    _die_with_parent,
    _end,
    command,
    count_runs,
    results,
    stopped_while_running,
    sweep_progress,
    sweep_results,
    why,
)

#: stands for the run's folder on the worker in a task's command line (a NUL is in no real argument)
OUT: Final = "\0out\0"
#: stands for the worker's Python (each host has its own)
PYTHON: Final = "\0python\0"
#: stands for the bench host's bridge in a bench run's command line (rig bench-host --bridge)
BRIDGE: Final = "\0bridge\0"
#: in the run's folder on the worker: the firmware it flies and an uploaded board file (hidden, not
#: sent back)
FIRMWARE: Final = ".firmware"
BOARD: Final = ".board"
#: how long a connection to the scheduler is tried before the service says it is unreachable
CONNECT_S: Final = 5.0
#: how often an unreachable scheduler is tried again
RECONNECT_S: Final = 1.0
#: how often a task looks whether its run was cancelled
CANCEL_POLL_S: Final = 1.0
#: the Dask event topic a task reports its run's progress on ({"run": ID, "progress": PERCENT})
PROGRESS: Final = "rig-progress"
#: the largest run folder a worker may send back (a lockstep run's MCAP and CSVs are a few MiB)
MAX_ARCHIVE: Final = 1 << 30


@dataclass(frozen=True)
class Job:
    """What a worker needs to fly one run (picklable; the inputs as bytes, no path of the service's)."""

    run_id: int
    argv: list[str]
    files: dict[str, bytes]  # relative to the run's folder
    label: str = ""
    #: how its progress is counted on the worker: each scenario's result.json (relative to the run's
    #: folder), or a sweep's rows out of sweep_total
    results: tuple[str, ...] = ()
    sweep_total: int = 0


def cancel_event(run_id: int) -> str:
    return f"rig-cancel-{run_id}"


def dataset(run_id: int) -> str:
    """The name its future is published under while it flies: a service that restarts finds it again."""
    return f"rig-run-{run_id}"


def fly(job: Job) -> dict[str, Any]:
    """On a worker: the run in a temporary folder of this host, its folder back as a tar archive (its
    inputs left out). Its exit status as rig run's."""
    with scratch.folder("farm") as tmp:
        out = Path(tmp) / "run"
        out.mkdir()
        for rel, data in job.files.items():
            path = out / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
            if rel.startswith(FIRMWARE + "/"):
                path.chmod(0o755)
        argv = [sys.executable if a == PYTHON else a.replace(OUT, str(out)) for a in job.argv]
        if BRIDGE in argv:
            argv = _on_the_bench(argv, job.run_id)
        # the sandbox (rig/sandbox.py): the run's folder writable, this host's other runs out of sight
        with open(out / "rig-run.log", "wb") as log, \
                sandbox.confined(argv, [out], [Path(tmp).parent]) as argv:
            proc = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                    cwd=tmp, start_new_session=True, preexec_fn=_die_with_parent)
            code = _watch(proc, job, out)
        inputs = {Path(rel).parts[0] for rel in job.files}
        return {"exit_code": code, "archive": _pack(out, inputs), "host": socket.gethostname(),
                "folder": str(out)}


def _on_the_bench(argv: list[str], run_id: int) -> list[str]:
    """A bench run's command line on its bench host: its bridge (and supply). Refused if this run has
    started once already (its bench host died meanwhile and came back): a bench run is never flown
    again behind its user's back."""
    from rig.service import bench_host

    bench = bench_host.BENCH
    if bench is None:
        raise RuntimeError("a bench run reached a worker that is no bench host")
    try:
        from distributed import Variable, get_client

        started = Variable(f"rig-started-{run_id}", client=get_client())
        try:
            started.get(timeout=0.1)
        except TimeoutError:
            started.set(bench["name"])
        else:
            raise RuntimeError(f"bench run {run_id} started once already: it is not flown again")
    except ValueError:  # (not on a Dask worker)
        pass
    argv = [bench["bridge"] if a == BRIDGE else a for a in argv]
    return argv + (["--psu", bench["psu"]] if bench.get("psu") else [])


def _watch(proc: subprocess.Popen[bytes], job: Job, out: Path) -> int:
    """The run's exit status; its progress reported as it changes (the PROGRESS topic); a cancelled
    run (its Event set by the service) is stopped first."""
    event = worker = None
    try:
        from distributed import Event, get_client, get_worker

        event = Event(cancel_event(job.run_id), client=get_client())
        worker = get_worker()
    except (ImportError, ValueError):  # (not on a Dask worker: a test calling fly directly)
        pass
    looked = time.monotonic()
    progress = 0.0
    realtime = RealtimeProgress(out / "rig-run.log") if "--bridge" in job.argv else None
    while True:
        try:
            return proc.wait(timeout=POLL_S)
        except subprocess.TimeoutExpired:
            pass
        if event is None or worker is None or time.monotonic() - looked < CANCEL_POLL_S:
            continue
        looked = time.monotonic()
        done = sum((out / r).is_file() for r in job.results)
        now = (sweep_progress(out, job.sweep_total) if job.sweep_total
               else realtime(done, len(job.results)) if realtime is not None
               else round(100.0 * done / max(len(job.results), 1), 1))
        try:
            if now != progress:
                progress = now
                worker.log_event(PROGRESS, {"run": job.run_id, "progress": progress})
            cancelled = event.is_set()
        except Exception:  # (the scheduler is unreachable: this worker goes too, and the run with it)
            cancelled = False
        if cancelled:
            _end(proc)


def _pack(folder: Path, leave_out: set[str]) -> bytes:
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w:gz") as tar:
        for path in sorted(folder.iterdir()):
            if path.name not in leave_out:
                tar.add(path, arcname=path.name)
    return buf.getvalue()


def unpack(archive: bytes, folder: Path) -> None:
    """A worker's run folder into ``folder``: only regular files and folders inside it (no absolute
    path, no ``..``, no link, device or FIFO); ValueError when it is not that. Written member by member
    rather than by ``extractall``: its ``filter`` argument, which would do this, is not in Debian 12's
    Python 3.11.2, and a worker's bytes are not trusted."""
    if len(archive) > MAX_ARCHIVE:
        raise ValueError(f"the run's folder is over {MAX_ARCHIVE} bytes")
    try:
        with tarfile.open(fileobj=io.BytesIO(archive), mode="r:gz") as tar:
            members = tar.getmembers()
            for member in members:
                parts = Path(member.name).parts
                if member.name.startswith("/") or ".." in parts or not parts:
                    raise tarfile.TarError(f"{member.name!r} is not inside the run's folder")
                if not (member.isfile() or member.isdir()):
                    raise tarfile.TarError(f"{member.name!r} is not a regular file or a folder")
            folder.mkdir(parents=True, exist_ok=True)
            for member in members:
                target = folder.joinpath(*Path(member.name).parts)
                if member.isdir():
                    target.mkdir(parents=True, exist_ok=True)
                    continue
                source = tar.extractfile(member)
                assert source is not None  # (a regular file, checked above)
                target.parent.mkdir(parents=True, exist_ok=True)
                target.write_bytes(source.read())
    except (tarfile.TarError, OSError, EOFError) as e:
        raise ValueError(f"the run's folder came back unreadable: {e}") from None


def job_for(run: dict[str, Any], out: Path, store: Store) -> tuple[Job, dict[str, str]]:
    """The run's Job: the command ``command`` gives for a local slot, its paths into the run's folder
    made the worker's, its inputs as bytes. (The versions flown, by name.) LookupError as command's."""
    cmd, flown = command(run, out, store)
    files = {f"{PINNED}/{p.name}": p.read_bytes() for p in sorted((out / PINNED).iterdir()) if p.is_file()}
    program = store.firmware(run["dut"]["firmware"]) if run["dut"].get("firmware") else None
    board = store.board(run["dut"]["board"]) if run["dut"].get("board") else None
    # the service's files the command names, as the worker's copies in the run's folder (a shipped
    # board's name stays a name: the worker has the same rig)
    inputs = {str(p): f"{where}/{p.name}" for p, where in ((program, FIRMWARE), (board, BOARD))
              if isinstance(p, Path)}
    argv = []
    for k, arg in enumerate(cmd):
        if k == 0 and arg == sys.executable:
            argv.append(PYTHON)
            continue
        for path, rel in inputs.items():
            if path in arg:
                files[rel] = Path(path).read_bytes()
                arg = arg.replace(path, f"{OUT}/{rel}")
        argv.append(arg.replace(str(out), OUT))
    if run["mode"] == "bridge":  # (command gives the service's own bench: the virtual bridge)
        argv[argv.index("--bridge") + 1] = BRIDGE
    watched = tuple(f"{Path(n).stem}/result.json" for n in run["scenarios"]) if run["mode"] != "sweep" else ()
    total = count_runs(out / PINNED / SWEEP_SPEC) if run["mode"] == "sweep" else 0
    return Job(run["id"], argv, files, run.get("label", ""), watched, total), flown


@dataclass
class Flight:
    run: dict[str, Any]
    future: Any
    flown: dict[str, str]
    bench: str | None = None  # a bench run's bench, and the worker that holds it
    worker: str | None = None
    started: float = field(default_factory=time.monotonic)


def published_bench(name: object, bench: object) -> bool:
    """Whether a bench's entry in the scheduler's metadata has the shape rig bench-host gives it (anyone
    who reaches the scheduler can write there: an entry of another shape is ignored)."""
    from rig.service.bench_host import NAME

    if not isinstance(name, str) or not NAME.fullmatch(name) or not isinstance(bench, dict):
        return False
    labels = bench.get("labels")
    return (isinstance(labels, dict)
            and all(isinstance(k, str) and isinstance(v, str) for k, v in labels.items())
            and all(isinstance(bench.get(k), str) for k in ("host", "bridge"))
            and bench.get("name") == name)


def matches(bench: dict[str, Any], selector: dict[str, str]) -> bool:
    labels = bench.get("labels") or {}
    return all(labels.get(k) == v for k, v in selector.items())


def labels_text(labels: dict[str, str]) -> str:
    return ",".join(f"{k}={v}" for k, v in sorted(labels.items())) or "no labels"


class OwnReconnects(logging.Filter):
    """Drops Dask's "Failed to reconnect to scheduler ..., closing client": the farm then connects a new
    client itself and says so (health, the page, its own lines), so the line told an operator the
    service had given up while it was reconnecting."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not record.getMessage().startswith("Failed to reconnect to scheduler")


class Farm:
    """Dispatches lockstep runs and sweeps to the Dask scheduler at ``address``'s workers, and bench runs
    to its bench hosts (one thread of its own), and brings their folders back into ``artifacts``."""

    def __init__(self, db: Db, artifacts: Path, store: Store, address: str, security: Any = None,
                 stale: list[int] | None = None) -> None:
        """``stale``: runs a service that died left running: re-attached to once the scheduler answers if
        their tasks are still there (each is published as a Dask dataset while it flies), interrupted
        otherwise (or if the first connection fails: a scheduler restarted has none of them)."""
        self.db, self.artifacts, self.store, self.address = db, artifacts, store, address
        self.security = security
        self._stale = list(stale or [])
        self._client: Any = None
        self._flights: dict[int, Flight] = {}
        #: the benches the scheduler knows (published by rig bench-host), each with its worker or None
        self._benches: dict[str, dict[str, Any]] = {}
        self._wake = threading.Condition()
        self._stop = False
        self._state: dict[str, Any] = {"address": address, "connected": False, "workers": 0, "threads": 0,
                                       "running": 0, "problem": "not connected yet"}
        self._thread = threading.Thread(target=self._loop, daemon=True, name="farm")
        self._tried = threading.Event()  # set once the first connection has been tried

    def start(self) -> None:
        client_log = logging.getLogger("distributed.client")
        if not any(isinstance(f, OwnReconnects) for f in client_log.filters):
            client_log.addFilter(OwnReconnects())
        self._thread.start()

    def wake(self) -> None:
        with self._wake:
            self._wake.notify_all()

    def state(self) -> dict[str, Any]:
        """How the cluster stands, for /api/health and the page: connected, its workers and threads, the
        runs in flight, and the problem in words when it is not reachable."""
        return dict(self._state)

    def benches(self) -> list[dict[str, Any]]:
        """Every bench the scheduler knows: its labels, host, bridge and state (free, busy with a run,
        offline: its host is not connected, maintenance: disabled here; unknown while the scheduler
        cannot be reached, with the ``problem``: what was last seen of it is no news of it now)."""
        disabled = self.db.disabled_benches()
        running = {f.bench: f.run["id"] for f in list(self._flights.values()) if f.bench}
        state_now = dict(self._state)
        out = []
        for name, b in sorted(self._benches.items()):
            state = ("maintenance" if name in disabled else "unknown" if not state_now["connected"]
                     else "offline" if not b.get("worker") else "busy" if name in running else "free")
            out.append({"name": name, "state": state, "run": running.get(name), "labels": b.get("labels", {}),
                        **{k: b.get(k) for k in ("host", "bridge", "psu", "bridge_id", "firmware_sha256")},
                        **({"problem": state_now["problem"]} if state == "unknown" else {})})
        return out

    def refuse(self, selector: dict[str, str]) -> str | None:
        """Why no bench could ever take a run with this selector (it names labels no bench has), or None:
        a run that matches only busy, offline or disabled benches waits, and so does every run while
        the scheduler cannot be reached (its benches are not known then)."""
        self._tried.wait(timeout=CONNECT_S + 1)  # (a request right after the start: the first look)
        if not self._state["connected"]:
            return None  # (the benches cannot be known: the run waits in the queue with the rest)
        benches = dict(self._benches)
        if not any(matches(b, selector) for b in benches.values()):
            try:  # (a bench that joined since the last look, every RECONNECT_S)
                self._survey()
                benches = dict(self._benches)
            except Exception:
                pass
        if any(matches(b, selector) for b in benches.values()):
            return None
        known = "; ".join(f"{n}: {labels_text(b.get('labels') or {})}" for n, b in sorted(benches.items()))
        return (f"bench: no bench has the labels {labels_text(selector)} "
                f"(known: {known or 'none: no bench host has joined the scheduler'})")

    def cancel(self, run_id: int) -> None:
        """The run's task stops its rig run (the status is the caller's: cancelled)."""
        if run_id in self._flights:
            self._set(run_id)

    def _set(self, run_id: int) -> None:
        client = self._client
        if client is None:
            return
        try:
            from distributed import Event

            Event(cancel_event(run_id), client=client).set()
        except Exception:  # (the scheduler went away: the run is interrupted with it)
            pass

    def stop(self, why: str = "") -> None:
        """The service is stopping (``why``: what stopped it, in words): the runs in flight are stopped on
        their workers and interrupted."""
        self._stop = True
        for run_id in list(self._flights):
            self.cancel(run_id)
        self.wake()
        self._thread.join(timeout=CONNECT_S + 5)
        for run_id in list(self._flights):
            self._flights.pop(run_id)
            self._forget(run_id)
            self.db.finish(run_id, "interrupted", pid=None, error=stopped_while_running(why))
        if self._client is not None:
            try:
                self._client.close(timeout=CONNECT_S)
            except Exception:
                pass

    # ---- the dispatch thread ------------------------------------------------------------------------

    def _loop(self) -> None:
        while not self._stop:
            connected = self._connected()
            if connected and not self._tried.is_set():
                try:
                    self._survey()
                except Exception:
                    pass
            self._tried.set()
            if not connected:
                with self._wake:
                    self._wake.wait(timeout=RECONNECT_S)
                continue
            for run_id, flight in list(self._flights.items()):
                if flight.future.done():
                    self._flights.pop(run_id)
                    self._land(flight)
            try:
                plain, threads = self._survey()
            except Exception as e:  # (the scheduler went away between two looks)
                self._lost(f"the Dask scheduler at {self.address} stopped answering: {e}")
                continue
            self._check_benches()
            while not self._stop and sum(f.bench is None for f in self._flights.values()) < threads:
                run = self.db.claim("lockstep", "sweep")
                if run is None:
                    break
                self._dispatch(run, workers=plain)
            self._dispatch_benches()
            self._state["running"] = len(self._flights)
            with self._wake:
                self._wake.wait(timeout=RECONNECT_S)

    def _connected(self) -> bool:
        """A client with the scheduler running (made anew when the last one closed); False when not."""
        client = self._client
        if client is not None and client.status == "running":
            return True
        if client is not None and client.status in ("connecting", "newly-created"):
            self._lost(f"the Dask scheduler at {self.address} went away: reconnecting")
            return False
        if client is not None:
            try:
                client.close(timeout=CONNECT_S)
            except Exception:
                pass
            self._client = None
        try:
            from distributed import Client

            self._client = Client(self.address, timeout=CONNECT_S, set_as_default=False,
                                  security=self.security)
        except (OSError, TimeoutError, ValueError) as e:
            self._lost(f"no Dask scheduler at {self.address}: {e}")
            self._reattach(False)
            return False
        try:
            self._client.subscribe_topic(PROGRESS, self._progressed)
            self._survey()
        except Exception as e:
            self._lost(f"the Dask scheduler at {self.address}: {e}")
            self._reattach(False)
            return False
        self._state.update(connected=True, problem=None)
        self._reattach(True)
        return True

    def _reattach(self, connected: bool) -> None:
        """The runs a service that died left running, once: each still on the cluster is followed
        again, as if dispatched here; the others are interrupted (and told to stop, if they fly)."""
        stale, self._stale = self._stale, []
        for run_id in stale:
            run = self.db.get(run_id)
            if run is None or run["status"] != "running":
                continue
            future = None
            if connected:
                try:
                    future = self._client.get_dataset(dataset(run_id))
                except Exception:  # (KeyError: not published, i.e. not on the cluster any more)
                    self._set(run_id)
            if future is None:
                self.db.finish(run_id, "interrupted", pid=None, error=stopped_while_running())
                continue
            bench = run.get("bench_name")
            future.add_done_callback(lambda _: self.wake())
            self._flights[run_id] = Flight(run, future, run["versions"], bench,
                                           (self._benches.get(bench) or {}).get("worker") if bench else None)

    def _progressed(self, event: tuple[float, Any]) -> None:
        """A task's report of its run's progress (from the worker: checked before it is believed)."""
        msg = event[1] if isinstance(event, tuple) and len(event) == 2 else None
        if not isinstance(msg, dict):
            return
        run_id, progress = msg.get("run"), msg.get("progress")
        if (type(run_id) is int and run_id in self._flights and isinstance(progress, int | float)
                and 0.0 <= progress < 100.0):
            self.db.update_if(run_id, "running", progress=float(progress))

    def _survey(self) -> tuple[list[str], int]:
        """The workers for lockstep runs (not bench hosts) and their threads; the benches published in
        the scheduler's metadata, each with the worker that holds its resource now (None: offline)."""
        from rig.service.bench_host import METADATA, RESOURCE

        workers = self._client.scheduler_info().get("workers", {})
        published = self._client.get_metadata([METADATA], default={}) or {}
        where: dict[str, str] = {}
        plain: list[str] = []
        threads = 0
        for address, w in workers.items():
            names = [r[len(RESOURCE):] for r in (w.get("resources") or {}) if r.startswith(RESOURCE)]
            for name in names:
                where[name] = address
            if not names:
                plain.append(address)
                threads += int(w.get("nthreads", 1))
        self._benches = {n: {**b, "worker": where.get(n)} for n, b in published.items()
                         if published_bench(n, b)}
        self._state.update(workers=len(plain), threads=threads, benches=len(where))
        return plain, threads

    def _check_benches(self) -> None:
        """A bench run whose bench host went away (or came back as another worker) is interrupted, its
        task cancelled: never flown again, here or on another bench."""
        for run_id, flight in list(self._flights.items()):
            if flight.bench is None or flight.future.done():
                continue
            if (self._benches.get(flight.bench) or {}).get("worker") != flight.worker:
                self._flights.pop(run_id)
                self._forget(run_id)
                flight.future.cancel()
                self.db.finish(run_id, "interrupted", pid=None, error=f"the bench host of {flight.bench} "
                               "went away while this run was running; it is not run again")

    def _dispatch_benches(self) -> None:
        """Each queued bench run, in the queue's order, onto a free bench its selector matches."""
        disabled = self.db.disabled_benches()
        busy = {f.bench for f in self._flights.values() if f.bench}
        for run in self.db.queued("bridge"):
            free = [n for n, b in sorted(self._benches.items())
                    if b.get("worker") and n not in busy and n not in disabled and matches(b, run["bench"])]
            if not free:
                continue
            claimed = self.db.claim_run(run["id"], bench_name=free[0])
            if claimed is not None:
                busy.add(free[0])
                self._dispatch(claimed, bench=free[0])

    def _lost(self, problem: str) -> None:
        """No scheduler: nothing is dispatched; the runs in flight are interrupted (Dask cancelled them)."""
        self._state.update(connected=False, problem=problem, workers=0, threads=0)
        for run_id, flight in list(self._flights.items()):
            if flight.future.done() and flight.future.status == "finished":
                continue  # (its result came back before: landed on the next look)
            self._flights.pop(run_id)
            self.db.finish(run_id, "interrupted", pid=None, error=f"{problem} while this run was running")
        self._state["running"] = len(self._flights)

    def _dispatch(self, run: dict[str, Any], workers: list[str] | None = None,
                  bench: str | None = None) -> None:
        out = self.artifacts / str(run["id"])
        out.mkdir(parents=True, exist_ok=True)
        try:
            job, flown = job_for(run, out, self.store)
        except (LookupError, OSError) as e:
            self.db.finish(run["id"], "error", error=str(e))
            return
        if flown != run["versions"]:
            self.db.update(run["id"], versions=flown)
        try:
            from distributed import Event

            Event(cancel_event(run["id"]), client=self._client).clear()  # (a restart's leftover)
            from rig.service.bench_host import resource

            where: dict[str, Any] = ({"resources": {resource(bench): 1}} if bench is not None
                                     else {"workers": workers} if workers else {})
            future = self._client.submit(fly, job, key=f"rig-run-{run['id']}-{secrets.token_hex(4)}",
                                         pure=False, retries=0, **where)
        except Exception as e:
            self.db.update_if(run["id"], "running", status="queued", started=None,
                              bench_name=None)  # (tried again)
            self._lost(f"the Dask scheduler at {self.address} refused the run: {e}")
            return
        try:
            self._client.publish_dataset(future, name=dataset(run["id"]), override=True)
        except Exception:  # (then a restart of the service interrupts it, as before)
            pass
        future.add_done_callback(lambda _: self.wake())
        self._flights[run["id"]] = Flight(run, future, flown, bench,
                                          (self._benches.get(bench) or {}).get("worker") if bench else None)

    def _forget(self, run_id: int) -> None:
        try:
            self._client.unpublish_dataset(dataset(run_id))
        except Exception:  # (not published, or the scheduler is gone: nothing to forget)
            pass

    def _here(self, text: str, folder: str, run: dict[str, Any], out: Path) -> str:
        """Words from a worker with its temporary run folder (gone now) named as the service's: its
        copies of the inputs as the store's files, the rest as the run's folder here."""
        dut = run["dut"]
        program = self.store.firmware(dut["firmware"]) if dut.get("firmware") else None
        board = self.store.board(dut["board"]) if dut.get("board") else None
        for path, where in ((program, FIRMWARE), (board, BOARD)):
            if isinstance(path, Path):
                text = text.replace(f"{folder}/{where}/{path.name}", str(path))
        return text.replace(folder, str(out))

    def _land(self, flight: Flight) -> None:
        """A run's task has ended: its folder into the data folder, its status as rig run's exit says."""
        run, out = flight.run, self.artifacts / str(flight.run["id"])
        self._forget(run["id"])
        sweep = run["mode"] == "sweep"
        what = "rig sweep" if sweep else "rig run"
        try:
            answer = flight.future.result(timeout=CONNECT_S)
            code = int(answer["exit_code"])
            unpack(answer["archive"], out)
        except Exception as e:  # (cancelled with the scheduler, the worker killed more than Dask allows)
            name = type(e).__name__
            status = "interrupted" if name in ("CancelledError", "KilledWorker") else "error"
            self.db.finish(run["id"], status, pid=None, error=f"{what} on the Dask cluster: {name}: {e}")
            return
        status = STATUS_BY_EXIT.get(code, "error")
        found = (sweep_results(out, *next(iter(flight.flown.items()))) if sweep
                 else results(out, run["scenarios"]))
        folder = answer.get("folder")
        for r in found if isinstance(folder, str) and folder else []:
            if r.get("error"):
                r["error"] = self._here(r["error"], folder, run, out)
        error = None if status in ("passed", "failed") else why(what, code, out / "rig-run.log", found)
        if error is not None and isinstance(folder, str) and folder:
            error = self._here(error, folder, run, out)
        self.db.finish(run["id"], status, exit_code=code, error=error, progress=100.0, pid=None,
                       results=found)
