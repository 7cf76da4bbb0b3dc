"""Where a sweep's runs go: the embedded default, a local process pool (one run per core), or a Dask
distributed cluster (``--engine tcp://HOST:PORT`` or DASK_SCHEDULER_ADDRESS) through
``client.get_executor()``: both are concurrent.futures executors, so the sweep has one code path.
Dask is imported only when asked for (it is a large import)."""

from __future__ import annotations

import multiprocessing
import os
import signal
from collections.abc import Iterator
from concurrent.futures import Executor, ProcessPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

ENV = "DASK_SCHEDULER_ADDRESS"
#: how long a sweep waits for the cluster's scheduler to answer
CONNECT_TIMEOUT_S = 10.0


class EngineError(RuntimeError):
    """The engine cannot be reached or started: the sweep does not start."""


@dataclass
class Engine:
    """The executor and what the sweep says about it."""

    executor: Executor
    name: str  # "local" or the scheduler's address
    workers: int  # runs at once
    stop_running: Any = field(default=None)  # ends the runs under way (a local pool: SIGINT each process)


def local_jobs(jobs: int | None) -> int:
    return jobs if jobs is not None else len(os.sched_getaffinity(0))


@contextmanager
def open_engine(jobs: int | None = None, address: str | None = None) -> Iterator[Engine]:
    """The local pool (``address`` None and no DASK_SCHEDULER_ADDRESS) or the Dask cluster there."""
    address = address or os.environ.get(ENV) or None
    if address is None:
        n = local_jobs(jobs)
        # forkserver: workers start from a clean process, not from the sweep's (its progress thread)
        pool = ProcessPoolExecutor(max_workers=n, mp_context=multiprocessing.get_context("forkserver"))

        def stop_running() -> None:
            for p in list(getattr(pool, "_processes", {}).values()):  # (the pool keeps them; no public API)
                try:
                    os.kill(p.pid, signal.SIGINT)
                except (ProcessLookupError, AttributeError):
                    pass

        try:
            yield Engine(pool, "local", n, stop_running)
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
        return
    try:
        from distributed import Client
    except ImportError as e:  # pragma: no cover (a dependency of the rig)
        raise EngineError(f"--engine needs dask distributed: {e}") from None
    try:
        client = Client(address, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as e:
        raise EngineError(f"no Dask scheduler at {address}: {e}") from None
    try:
        info = client.scheduler_info()
        threads = sum(int(w.get("nthreads", 1)) for w in info.get("workers", {}).values())
        yield Engine(client.get_executor(pure=False), address, threads or 1)
    finally:
        client.close()
