"""``rig serve``: the service on uvicorn (docs/service.md)."""

from __future__ import annotations

import argparse
import ipaddress
import os
import sys
import threading
import time
from pathlib import Path

DEFAULT_PORT = 8300


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


def _loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def main(args: argparse.Namespace) -> int:
    if not _loopback(args.host) and not args.token:
        print(f"rig serve: --host {args.host} listens beyond this machine: give --token (or $RIG_TOKEN)",
              file=sys.stderr)
        return 2
    if not 1 <= args.slots <= 256 or not 0 <= args.port <= 65535:
        print("rig serve: --slots is 1..256 and --port 0..65535", file=sys.stderr)
        return 2
    import uvicorn

    from rig.service.app import create_app
    from rig.service.db import Db
    from rig.service.store import Store
    from rig.service.worker import Workers

    args.data.mkdir(parents=True, exist_ok=True)
    db = Db(args.data / "rig.sqlite")
    interrupted = db.interrupt_running()
    if interrupted:
        print(f"rig serve: {interrupted} run(s) were running when the service last stopped: interrupted",
              file=sys.stderr)
    store = Store(args.data)
    workers = Workers(db, args.data / "runs", store, args.slots)
    workers.start()
    app = create_app(db, workers, args.token, store, args.data / "runs")
    config = uvicorn.Config(app, host=args.host, port=args.port, log_level="warning")
    server = uvicorn.Server(config)

    def announce() -> None:  # the line a test or a supervisor waits for, once the socket listens
        while not server.started and not server.should_exit:
            time.sleep(0.01)
        if server.started:
            print(f"rig serve: listening on http://{args.host}:{args.port} (data in {args.data})",
                  file=sys.stderr, flush=True)

    threading.Thread(target=announce, daemon=True).start()
    try:
        server.run()
    finally:
        workers.stop()
        db.close()
    return 0
