"""``rig serve``: the service on uvicorn (docs/service.md)."""

from __future__ import annotations

import argparse
import ipaddress
import os
import signal
import sys
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rig.service.worker import Workers

DEFAULT_PORT = 8300
EXIT_INTERRUPTED = 130
#: how long uvicorn waits, once the runs have ended, for its requests under way before it cancels them
SHUTDOWN_GRACE_S = 3


def authority(host: str, port: int) -> str:
    """HOST:PORT as a URL writes it: an IPv6 address in brackets (``[::1]:8300``)."""
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def stopping_server(config: Any, workers: Workers) -> Any:
    """uvicorn's server, whose first Ctrl-C (or SIGTERM) stops the runs at once, then shuts uvicorn down:
    uvicorn alone first waited for its connections, a client's ``?wait=30`` long poll among them, and
    only then were the runs stopped (a DUT was still alive 5 s after the Ctrl-C). The long polls answer
    once the runs have ended (app.py); a request still under way SHUTDOWN_GRACE_S later is cancelled."""
    import asyncio

    import uvicorn

    class Server(uvicorn.Server):
        why = ""

        def handle_exit(self, sig: int, frame: Any) -> None:
            if not self.should_exit:  # (in the signal handler: the runs are stopped in a thread)
                self.why = "Ctrl-C" if sig == signal.SIGINT else signal.Signals(sig).name
                threading.Thread(target=workers.stop, args=(self.why,), name="stop-runs", daemon=True).start()
            super().handle_exit(sig, frame)

        async def shutdown(self, sockets: Any = None) -> None:
            await asyncio.to_thread(workers.stop, self.why)  # (the runs' end first; waits for the above)
            await super().shutdown(sockets)

    return Server(config)


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("serve", help="run the rig as a service: an HTTP API over a queue of runs",
                       description=__doc__)
    p.add_argument("--host", default="127.0.0.1",
                   help="address to listen on (default %(default)s); any other needs --token")
    p.add_argument("--port", type=int, default=DEFAULT_PORT, help="port (default %(default)s)")
    p.add_argument("--data", type=Path, default=Path("build/service"),
                   help="the database and every run's artifacts (default %(default)s)")
    p.add_argument("--token", default=os.environ.get("RIG_TOKEN"),
                   help="every request must carry it (Authorization: Bearer TOKEN); default $RIG_TOKEN")
    p.add_argument("--slots", type=int, default=os.cpu_count() or 1,
                   help="lockstep runs at once (default: one per core, %(default)s)")
    p.add_argument("--engine", metavar="tcp://HOST:PORT",
                   help="run lockstep runs and sweeps on this Dask scheduler's workers instead of local "
                        "slots (docs/farm.md); their folders come back into --data")
    from rig.sweep.engine import add_tls_options

    add_tls_options(p)
    p.add_argument("--modbus", type=int, metavar="PORT",
                   help="also serve the test cell's PLC over Modbus TCP on PORT (docs/plc.md), on --host")
    p.add_argument("--modbus-measure", action="append", default=[], metavar="NAME",
                   help="a measurement the PLC reads as FLOAT32 from register 10 on, two registers each "
                        "(repeat; at most 16)")
    p.add_argument("--modbus-bench", action="store_true",
                   help="the PLC's runs go to the bench (mode bridge) instead of a lockstep slot")
    p.add_argument("--modbus-open", action="store_true",
                   help="allow Modbus TCP beyond loopback: Modbus has no authentication, so anyone who "
                        "reaches the port can start and abort runs (firewall it to the PLC)")


def _loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _data_problem(data: Path) -> str | None:
    """Why --data cannot be the service's folder (a file, under a file, not writable), or None; checked
    before anything is created (it was a traceback from mkdir)."""
    if data.exists():
        if not data.is_dir():
            return f"--data {data} exists and is not a folder"
        return None if os.access(data, os.W_OK | os.X_OK) else f"--data {data}: not writable"
    parent = data.absolute().parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        return f"--data {data}: {parent} is not a folder"
    return None if os.access(parent, os.W_OK | os.X_OK) else f"--data {data}: {parent} is not writable"


def main(args: argparse.Namespace) -> int:
    if not _loopback(args.host) and not args.token:
        print(f"rig serve: --host {args.host} listens beyond this machine: give --token (or $RIG_TOKEN)",
              file=sys.stderr)
        return 2
    if not 1 <= args.slots <= 256 or not 0 <= args.port <= 65535:
        print("rig serve: --slots is 1..256 and --port 0..65535", file=sys.stderr)
        return 2
    problem = _data_problem(args.data)
    if problem is None and args.engine is not None:
        from rig.sweep.engine import check_address

        problem = check_address(args.engine)
        problem = None if problem is None else f"--engine: {problem}"
    security = None
    if problem is None and args.engine is not None:
        from rig.sweep.engine import tls_security

        security, problem = tls_security(args.engine, args.tls_ca_file, args.tls_cert, args.tls_key)
    elif problem is None and (args.tls_ca_file or args.tls_cert or args.tls_key):
        problem = "--tls-ca-file, --tls-cert and --tls-key go with --engine tls://HOST:PORT"
    if problem is not None:
        print(f"rig serve: {problem}", file=sys.stderr)
        return 2
    if args.modbus is not None:
        from rig.service.plc import MAX_MEASUREMENTS

        if not 1 <= args.modbus <= 65535 or args.modbus == args.port:
            print("rig serve: --modbus is a port 1..65535, not the HTTP one", file=sys.stderr)
            return 2
        if len(args.modbus_measure) > MAX_MEASUREMENTS:
            print(f"rig serve: at most {MAX_MEASUREMENTS} --modbus-measure", file=sys.stderr)
            return 2
        if not _loopback(args.host) and not args.modbus_open:
            print(f"rig serve: Modbus TCP has no authentication; on {args.host} anyone could start runs: "
                  "give --modbus-open (and firewall the port to the PLC)", file=sys.stderr)
            return 2
    elif args.modbus_measure or args.modbus_bench:
        print("rig serve: --modbus-measure and --modbus-bench go with --modbus PORT", file=sys.stderr)
        return 2
    import uvicorn

    from rig.service.app import create_app
    from rig.service.db import Db
    from rig.service.store import Store
    from rig.service.worker import Workers

    try:
        args.data.mkdir(parents=True, exist_ok=True)
    except OSError as e:  # (what the checks above cannot foresee: /proc, a read-only mount as root)
        print(f"rig serve: --data {args.data}: {e.strerror or e}", file=sys.stderr)
        return 2
    db = Db(args.data / "rig.sqlite")
    # with a farm, the runs a service that died left running may still fly on the cluster: the farm
    # re-attaches to them (or interrupts them) once it has asked the scheduler
    stale = [r["id"] for r in db.list(status="running", limit=500)] if args.engine is not None else []
    interrupted = 0 if args.engine is not None else db.interrupt_running()
    if stale:
        print(f"rig serve: {len(stale)} run(s) were running when the service last stopped: re-attached if "
              "they are still on the cluster, interrupted otherwise", file=sys.stderr)
    if interrupted:
        print(f"rig serve: {interrupted} run(s) were running when the service last stopped: interrupted",
              file=sys.stderr)
    store = Store(args.data, db)
    farm = None
    if args.engine is not None:
        from rig.service.farm import Farm

        farm = Farm(db, args.data / "runs", store, args.engine, security, stale=stale)
        print(f"rig serve: lockstep runs and sweeps go to the Dask scheduler at {args.engine}",
              file=sys.stderr, flush=True)
    workers = Workers(db, args.data / "runs", store, args.slots, farm)
    plc_server = None
    if args.modbus is not None:
        from rig.service.plc import Plc, PlcServer, library_names

        plc = Plc(db, workers, library_names(), args.modbus_measure,
                  "bridge" if args.modbus_bench else "lockstep")
        plc_server = PlcServer(plc, args.host, args.modbus)
        try:
            plc_server.start()
        except RuntimeError as e:
            print(f"rig serve: {e}", file=sys.stderr)
            db.close()
            return 1
        print(f"rig serve: the PLC's Modbus TCP on {authority(args.host, args.modbus)}, unit 1 (docs/plc.md)",
              file=sys.stderr, flush=True)
    workers.start()
    app = create_app(db, workers, args.token, store, args.data / "runs")
    config = uvicorn.Config(app, host=args.host, port=args.port, log_level="warning",
                            timeout_graceful_shutdown=SHUTDOWN_GRACE_S)
    server = stopping_server(config, workers)

    def announce() -> None:  # the line a test or a supervisor waits for, once the socket listens
        while not server.started and not server.should_exit:
            time.sleep(0.01)
        if server.started:
            print(f"rig serve: listening on http://{authority(args.host, args.port)} (data in {args.data})",
                  file=sys.stderr, flush=True)

    threading.Thread(target=announce, daemon=True).start()
    try:
        server.run()
    except KeyboardInterrupt:  # uvicorn shut down cleanly, then re-raised the Ctrl-C: no traceback
        print("rig serve: stopped (Ctrl-C)", file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        if plc_server is not None:
            plc_server.stop()
        workers.stop()
        db.close()
    return 0
