"""``rig bench-host --engine tcp://HOST:PORT --bridge PORT [--psu MAKE:PORT] [--label k=v …]``: one
bench's host in the farm (docs/farm.md). It is a Dask worker, in this process, with one unit of the
resource ``bench-NAME``: a bench run asks for that unit, so Dask gives it the bench alone, and the run
flies on this host, where the bridge's real-time link stays local.

At start it checks the bridge (``rig bridge probe``: a bench whose bridge does not answer never joins)
and publishes the bench's identity and labels in the scheduler's metadata (``rig-benches``/NAME): the
service learns benches only through the scheduler, and nothing listens here but Dask's own worker
port. A scheduler that goes away ends this worker; the host joins again when it is back (RETRY_S).
"""

from __future__ import annotations

import argparse
import asyncio
import re
import signal
import socket
import sys
from typing import Any, Final

#: this process's bench, once it is a bench host: what a bench run's task reads (rig/service/farm.py)
BENCH: dict[str, Any] | None = None
#: the scheduler's metadata where benches publish themselves, each under its name
METADATA: Final = "rig-benches"
RESOURCE: Final = "bench-"
NAME: Final = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")
RETRY_S: Final = 1.0


class NameTaken(Exception):
    """Another worker of the scheduler has this bench's name (two bench hosts, one --name)."""


def resource(name: str) -> str:
    return RESOURCE + name


def parse_labels(items: list[str]) -> dict[str, str]:
    """``k=v`` pairs (repeated, or comma-separated) as a dict; ValueError in words."""
    labels: dict[str, str] = {}
    for item in items:
        for pair in item.split(","):
            key, eq, value = pair.strip().partition("=")
            if not eq or not NAME.fullmatch(key) or not value:
                raise ValueError(f"a label is k=v (letters, digits, _ . - in k), got {pair!r}")
            labels[key] = value
    return labels


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bench-host", help="serve one bench to a rig farm: a Dask worker on its host",
                       description=__doc__)
    p.add_argument("--engine", required=True, metavar="tcp://HOST:PORT", help="the Dask scheduler")
    p.add_argument("--bridge", required=True, metavar="PORT|virtual", help="the bench's bridge")
    p.add_argument("--psu", metavar="MAKE:PORT[@BAUD]", help="the bench supply (as rig run --psu)")
    p.add_argument("--label", action="append", default=[], metavar="k=v", help="a label (repeat)")
    p.add_argument("--name", default=socket.gethostname(), help="the bench's name (default: the host's)")
    p.add_argument("--host", default="127.0.0.1",
                   help="the address the worker listens on (default %(default)s); any other needs a tls:// "
                        "engine: Dask's mutual TLS is the credential (docs/farm.md)")
    from rig.sweep.engine import add_tls_options

    add_tls_options(p)


def main(args: argparse.Namespace) -> int:
    global BENCH
    from rig.sweep.engine import check_address

    problem = check_address(args.engine)
    if problem is not None:
        print(f"rig bench-host: --engine: {problem}", file=sys.stderr)
        return 2
    from rig.service.serve_cmd import _loopback
    from rig.sweep.engine import tls_security

    security, problem = tls_security(args.engine, args.tls_ca_file, args.tls_cert, args.tls_key)
    if problem is not None:
        print(f"rig bench-host: {problem}", file=sys.stderr)
        return 2
    if not _loopback(args.host) and security is None:
        print(f"rig bench-host: --host {args.host} listens beyond this machine: give a tls:// --engine with "
              "its certificates (Dask's mutual TLS is the credential)", file=sys.stderr)
        return 2
    if not NAME.fullmatch(args.name):
        print(f"rig bench-host: --name {args.name!r}: letters, digits, _ . - (at most 64)", file=sys.stderr)
        return 2
    try:
        labels = parse_labels(args.label)
    except ValueError as e:
        print(f"rig bench-host: --label: {e}", file=sys.stderr)
        return 2
    from rig.bridge.port import BridgeError
    from rig.bridge.probe import probe

    try:
        found = probe(args.bridge)
    except (BridgeError, OSError) as e:
        print(f"rig bench-host: the bridge on {args.bridge} does not answer: {e}", file=sys.stderr)
        return 3
    BENCH = {"name": args.name, "host": socket.gethostname(), "bridge": args.bridge, "psu": args.psu,
             "labels": labels, "bridge_id": found.bridge_id, "firmware_sha256": found.firmware_sha256}
    try:
        asyncio.run(_serve(args.engine, BENCH, args.host, security))
    except NameTaken:
        print(f"rig bench-host: the scheduler at {args.engine} has a bench named {args.name!r} already "
              "(another rig bench-host): give this one another --name", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("rig bench-host: stopped (Ctrl-C)", file=sys.stderr)
        return 130
    print("rig bench-host: stopped", file=sys.stderr)
    return 0


async def _taken(address: str, worker_name: str, security: Any) -> bool:
    """Whether a worker of the scheduler has this name already (asked before joining: Dask's own refusal
    comes as a traceback after a page of its log)."""
    from distributed import Client

    async with Client(address, asynchronous=True, security=security, timeout=RETRY_S * 10,
                      set_as_default=False) as client:
        workers = (await client.scheduler.identity(n_workers=-1)).get("workers", {})
    return any(w.get("name") == worker_name for w in workers.values())


async def _serve(address: str, bench: dict[str, Any], host: str | None, security: Any) -> None:
    """The worker, joined again whenever its scheduler comes back, until SIGTERM or Ctrl-C."""
    from distributed import Worker

    stopping = asyncio.Event()
    loop = asyncio.get_running_loop()
    loop.add_signal_handler(signal.SIGTERM, stopping.set)
    name = bench["name"]
    while not stopping.is_set():
        try:
            if await _taken(address, f"bench-{name}", security):
                raise NameTaken(name)
            worker = Worker(address, nthreads=1, resources={resource(name): 1}, name=f"bench-{name}",
                            host=host, dashboard=False, security=security)
            await worker
        except (ValueError, RuntimeError) as e:  # (Dask's answer to a name another worker took meanwhile)
            if "name taken" in f"{e} {e.__cause__}":
                raise NameTaken(name) from None
            raise
        except (OSError, TimeoutError) as e:
            print(f"rig bench-host: no scheduler at {address} ({e}): trying again", file=sys.stderr,
                  flush=True)
            try:
                await asyncio.wait_for(stopping.wait(), RETRY_S)
            except TimeoutError:
                pass
            continue
        await worker.scheduler.set_metadata(keys=[METADATA, name], value=bench)
        print(f"rig bench-host: bench {name} ({bench['bridge']}, bridge {bench['bridge_id']}) joined "
              f"{address} as {worker.address}", file=sys.stderr, flush=True)
        finished = asyncio.ensure_future(worker.finished())
        stop = asyncio.ensure_future(stopping.wait())
        await asyncio.wait([finished, stop], return_when=asyncio.FIRST_COMPLETED)
        if stopping.is_set():
            await worker.close(reason="rig bench-host stopped")
            return
        stop.cancel()
        print(f"rig bench-host: the scheduler at {address} went away: joining again", file=sys.stderr,
              flush=True)
