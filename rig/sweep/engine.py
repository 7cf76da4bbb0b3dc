"""Where a sweep's runs go: the embedded default, a local process pool (one run per core), or a Dask
distributed cluster (``--engine tcp://HOST:PORT`` or DASK_SCHEDULER_ADDRESS) through
``client.get_executor()``: both are concurrent.futures executors, so the sweep has one code path.
Dask is imported only when asked for (it is a large import).

The local pool's workers are the sweep's own children (spawn), each taking SIGINT, SIGTERM and SIGHUP
as an orderly stop (rig/interrupts.py) from its first moment, and killed by the kernel if the sweep dies
first. They were forkserver's: a SIGTERM or SIGHUP to the group killed the fork server (it ignores only
SIGINT), every worker looked dead to the pool, the sweep printed its tally and removed its temporary
folder, and the workers, never told to end, flew what was queued and waited for more until SIGKILL.
Whatever happens, the pool is not left before every worker has ended (STOP_GRACE_S, then SIGKILL).

A cluster's address is checked before anything (check_address: a malformed one made the half-built
Client hang 20 s on its way out and print a traceback), and a scheduler with no workers is waited for
with a count the user sees, up to a timeout (it was waited for forever, the bar saying ×1)."""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import signal
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import Executor, ProcessPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

ENV = "DASK_SCHEDULER_ADDRESS"
#: how long a sweep waits for the cluster's scheduler to answer
CONNECT_TIMEOUT_S = 10.0
#: how long a sweep waits for a scheduler with no workers to get one (rig sweep --wait-workers)
WORKERS_TIMEOUT_S = 120.0
#: how often the wait says how it stands
WORKERS_SAY_EVERY_S = 10.0
#: the schemes a Dask address can have here (distributed's TCP comm, plain or TLS)
SCHEMES = ("tcp", "tls")
#: how long a local pool's workers get to end (the runs under way stop their DUTs) before SIGKILL
STOP_GRACE_S = 30.0
PR_SET_PDEATHSIG = 1


class EngineError(RuntimeError):
    """The engine cannot be reached or started: the sweep does not start."""


@dataclass
class Engine:
    """The executor and what the sweep says about it."""

    executor: Executor
    name: str  # "local" or the scheduler's address
    workers: int  # runs at once
    stop_running: Any = field(default=None)  # ends the runs under way (a local pool: SIGINT each process)


def check_address(address: str) -> str | None:
    """Why ``address`` cannot be a Dask scheduler's (``tcp://HOST:PORT``; ``HOST:PORT`` is tcp), or None."""
    from urllib.parse import urlsplit

    want = f"expected tcp://HOST:PORT (or tls://), got {address!r}"
    try:
        u = urlsplit(address if "://" in address else f"tcp://{address}")
        port = u.port
    except ValueError:
        return want
    if u.scheme not in SCHEMES or not u.hostname or port is None or not 1 <= port <= 65535:
        return want
    if u.path not in ("", "/") or u.query or u.fragment or u.username:
        return want
    return None


def tls_security(address: str, ca: str | None, cert: str | None, key: str | None) -> tuple[Any, str | None]:
    """Dask's own security object for a ``tls://`` scheduler (mutual TLS: each side shows a certificate
    the CA signed, and the connection is encrypted), or None for ``tcp://``; and why the options do not
    fit the address (a tls:// address needs all three files, a tcp:// one none), or None."""
    given = [x for x in (ca, cert, key) if x]
    if not address.startswith("tls://"):
        return None, ("--tls-ca-file, --tls-cert and --tls-key go with a tls:// address" if given else None)
    if len(given) != 3:
        return None, "a tls:// address needs --tls-ca-file, --tls-cert and --tls-key"
    for path in given:
        if not os.path.isfile(path):
            return None, f"{path}: no such file"
    from distributed.security import Security

    return Security(tls_ca_file=ca, tls_client_cert=cert, tls_client_key=key, tls_worker_cert=cert,
                    tls_worker_key=key, require_encryption=True), None


def add_tls_options(p: Any) -> None:
    """The command line's TLS options for a tls:// Dask scheduler (docs/farm.md)."""
    p.add_argument("--tls-ca-file", metavar="PEM", help="with a tls:// engine: the CA that signed every "
                   "party's certificate")
    p.add_argument("--tls-cert", metavar="PEM", help="with a tls:// engine: this party's certificate")
    p.add_argument("--tls-key", metavar="PEM", help="with a tls:// engine: its private key")


def local_jobs(jobs: int | None) -> int:
    return jobs if jobs is not None else len(os.sched_getaffinity(0))


@contextmanager
def open_engine(jobs: int | None = None, address: str | None = None,
                workers_timeout_s: float = WORKERS_TIMEOUT_S,
                say: Callable[[str], None] = lambda _: None) -> Iterator[Engine]:
    """The local pool (``address`` None and no DASK_SCHEDULER_ADDRESS) or the Dask cluster there: once it
    has a worker, waited for up to ``workers_timeout_s`` (``say`` tells how the wait stands)."""
    address = address or os.environ.get(ENV) or None
    if address is None:
        n = local_jobs(jobs)
        _start_resource_tracker()
        # spawn: workers start from a clean process, not from the sweep's (its progress thread)
        pool = ProcessPoolExecutor(
            max_workers=n,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_worker_start,
            initargs=(os.getpid(),),
        )

        def stop_running() -> None:  # (for a signal sent to the sweep alone, not to its group)
            for pid in [p.pid for p in _processes(pool) if p.pid is not None]:
                try:
                    os.kill(pid, signal.SIGINT)
                except ProcessLookupError:
                    pass

        try:
            yield Engine(pool, "local", n, stop_running)
        finally:
            _shut(pool)
        return
    problem = check_address(address)
    if problem is not None:
        raise EngineError(f"the Dask scheduler's address: {problem}")
    try:
        from distributed import Client
    except ImportError as e:  # pragma: no cover (a dependency of the rig)
        raise EngineError(f"--engine needs dask distributed: {e}") from None
    try:
        client = Client(address, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as e:
        raise EngineError(f"no Dask scheduler at {address}: {e}") from None
    try:
        threads = _wait_for_workers(client, address, workers_timeout_s, say)
        yield Engine(client.get_executor(pure=False), address, threads)
    finally:
        client.close()


def _threads(client: Any) -> int:
    info = client.scheduler_info()
    return sum(int(w.get("nthreads", 1)) for w in info.get("workers", {}).values())


def _wait_for_workers(client: Any, address: str, timeout_s: float, say: Callable[[str], None]) -> int:
    """The cluster's threads, once it has any; EngineError when none came in ``timeout_s``."""
    threads = _threads(client)
    if threads:
        return threads
    say(f"the Dask scheduler at {address} has no workers: waiting up to {timeout_s:g} s for one "
        f"(start one with `dask worker {address}`)")
    waited = 0.0
    while waited < timeout_s:
        step = min(WORKERS_SAY_EVERY_S, timeout_s - waited)
        try:
            client.wait_for_workers(1, timeout=step)
        except TimeoutError:
            waited += step
            if waited < timeout_s:
                say(f"still 0 workers at {address} after {waited:g} s of {timeout_s:g} s")
            continue
        threads = _threads(client)
        if threads:
            say(f"{len(client.scheduler_info().get('workers', {}))} worker(s) at {address}: starting")
            return threads
    raise EngineError(f"no worker joined the Dask scheduler at {address} in {timeout_s:g} s "
                      "(start one with `dask worker ADDRESS`, or give --wait-workers longer)")


def _processes(pool: ProcessPoolExecutor) -> list[multiprocessing.Process]:
    return list((getattr(pool, "_processes", None) or {}).values())  # (the pool's; no public API)


def _shut(pool: ProcessPoolExecutor) -> None:
    """Shuts the pool down and returns once every worker has ended: those still stopping their runs get
    STOP_GRACE_S, then SIGKILL (the DUT's keeper ends the DUT then), so nothing can still write into the
    sweep's folders or its temporary folder afterwards."""
    workers = _processes(pool)

    def kill() -> None:
        for p in workers:
            if p.is_alive():
                p.kill()

    timer = threading.Timer(STOP_GRACE_S, kill)
    timer.daemon = True
    timer.start()
    try:
        pool.shutdown(wait=True, cancel_futures=True)
        for p in workers:
            p.join()
    finally:
        timer.cancel()


def _start_resource_tracker() -> None:
    """multiprocessing's resource tracker (the pool's semaphores) started with SIGHUP blocked, as it
    ignores SIGINT and SIGTERM: a SIGHUP to the sweep's group killed it, and every process that used a
    semaphore afterwards printed a traceback. (It unblocks only the two it ignores, so SIGHUP stays
    blocked there; a SIGHUP meanwhile waits for the sweep's handler.)"""
    from multiprocessing import resource_tracker

    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGHUP})
    try:
        resource_tracker.ensure_running()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _worker_start(parent: int) -> None:
    """A local pool worker's first act: the kernel kills it when the sweep dies (even by SIGKILL), and a
    signal from now on stops its run cleanly and every run after it (rig/interrupts.py)."""
    from rig import interrupts

    ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    if os.getppid() != parent:  # the sweep died before the line above
        os._exit(1)
    interrupts.install()
