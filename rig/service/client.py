"""``rig submit`` and ``rig status``: the command line as a client of ``rig serve`` (docs/service.md).

``rig submit --server URL [SCENARIO…] [--seed N] [--dut CMD | --firmware FILE [--board BOARD]]
[--pwm-channels N] [--topology T] [--bridge virtual] [--priority P] [--wait]`` queues a run and prints
its id; with ``--wait`` it follows the run (one line per change of status or progress, on stderr) and
exits as ``rig run`` would: 0 passed, 1 failed, 3 error, 130 interrupted or cancelled. ``rig status
--server URL [ID]`` prints one run, or the latest ones. The token comes from ``--token`` or
``$RIG_TOKEN``. Only the standard library speaks HTTP here.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import urllib.error
import urllib.parse
import urllib.request
from pathlib import Path
from typing import Any

EXIT_BY_STATUS = {"passed": 0, "failed": 1, "error": 3, "interrupted": 130, "cancelled": 130}
EXIT_USAGE, EXIT_UNREACHABLE = 2, 4


class ClientError(Exception):
    """What went wrong, and the HTTP status when the service answered (None: it could not be reached)."""

    def __init__(self, message: str, status: int | None = None) -> None:
        super().__init__(message)
        self.status = status

    @property
    def exit_code(self) -> int:
        """2 for a request the service refused (bad usage), 4 when it could not answer."""
        return EXIT_USAGE if self.status is not None and 400 <= self.status < 500 else EXIT_UNREACHABLE


def call(server: str, method: str, path: str, token: str | None, body: object = None,
         timeout: float = 90.0, raw: bytes | None = None) -> Any:
    """One request: ``body`` as JSON, or ``raw`` bytes as they are (an upload); the answer's JSON."""
    data = raw if raw is not None else None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(server.rstrip("/") + path, method=method, data=data)
    req.add_header("content-type", "application/octet-stream" if raw is not None else "application/json")
    if token:
        req.add_header("authorization", f"Bearer {token}")
    try:
        with urllib.request.urlopen(req, timeout=timeout) as r:
            return json.loads(r.read())
    except urllib.error.HTTPError as e:
        try:
            detail = json.loads(e.read()).get("detail")
        except ValueError:
            detail = e.reason
        raise ClientError("\n".join(_sentences(detail)) or f"HTTP {e.code}: {e.reason}", e.code) from e
    except (urllib.error.URLError, OSError, ValueError) as e:
        raise ClientError(f"cannot reach {server}: {e}") from e


def _sentences(detail: object) -> list[str]:
    """A refusal's detail in words: the service's problems, or (from a service older than this
    client) FastAPI's error dicts as "field: message", never printed as raw dicts."""
    if isinstance(detail, dict) and isinstance(detail.get("problems"), list):
        return [str(p) for p in detail["problems"]]
    if isinstance(detail, list):
        return [".".join(str(x) for x in d.get("loc", ()) if x != "body") + f": {d.get('msg')}"
                if isinstance(d, dict) else str(d) for d in detail]
    return [str(detail)] if detail else []


def server_url(server: str) -> str:
    """``--server`` as a base URL, refused (ClientError, exit 2) unless it is http(s)://HOST[:PORT]."""
    parts = urllib.parse.urlsplit(server)
    if parts.scheme not in ("http", "https") or not parts.hostname:
        raise ClientError(f"--server {server!r} is not a URL: give it as http://HOST:PORT "
                          "(e.g. http://127.0.0.1:8300)", 400)
    return server


def add_parsers(sub: argparse._SubParsersAction) -> None:
    s = sub.add_parser("submit", help="queue a run on a rig service (rig serve) and print its id")
    s.add_argument("--server", required=True, metavar="URL", help="e.g. http://127.0.0.1:8300")
    s.add_argument("scenarios", nargs="+", metavar="SCENARIO", help="library scenario names")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--dut", help="the DUT command line (default: the reference FC)")
    s.add_argument("--firmware", type=Path, metavar="FILE",
                   help="upload FILE and fly it: a Linux program, or with --board an AVR image (.elf, .hex) "
                        "or an ARM image (.elf) for an STM32 board")
    s.add_argument("--board", metavar="BOARD",
                   help="with --firmware: a shipped board's name (mega2560-gy86, ...) or a board file "
                   "(uploaded)")
    s.add_argument("--pwm-channels", type=int, metavar="N", help="a Linux DUT's channels of pwmchip0 (1..16)")
    s.add_argument("--topology", choices=["gy86", "direct"], help="a Linux DUT's I2C wiring (default gy86)")
    s.add_argument("--fc", metavar="PROFILE",
                   help="a shipped FC profile's name (default: the reference FC's; docs/profiles.md)")
    s.add_argument("--bridge", choices=["virtual"], help="run on the service's bench (the virtual bridge)")
    s.add_argument("--bench", metavar="k=v,...",
                   help="run on a farm's bench with these labels (docs/farm.md)")
    s.add_argument("--priority", type=int, default=0, help="higher runs first (-100..100)")
    s.add_argument("--wait", action="store_true", help="follow the run and exit with rig run's codes")
    s.add_argument("--token", default=os.environ.get("RIG_TOKEN"))
    t = sub.add_parser("status", help="a run on a rig service, or the latest runs")
    t.add_argument("--server", required=True, metavar="URL")
    t.add_argument("id", nargs="?", type=int)
    t.add_argument("--token", default=os.environ.get("RIG_TOKEN"))
    b = sub.add_parser("bench", help="take a farm's bench out for maintenance, or put it back")
    b.add_argument("--server", required=True, metavar="URL")
    b.add_argument("action", choices=["disable", "enable", "list"])
    b.add_argument("name", nargs="?")
    b.add_argument("--token", default=os.environ.get("RIG_TOKEN"))


def line(run: dict[str, Any]) -> str:
    """A run in one line: its status, place in the queue and progress, what it flies (the service's
    label: a sweep as "sweep of NAME@VERSION"), its verdicts and its error."""
    where = f" (position {run['position']})" if run.get("position") else ""
    what = run.get("label") or ", ".join(run.get("scenarios") or [])
    if run.get("mode") == "sweep":
        counts = [r["sweep"] for r in run.get("results") or [] if isinstance(r.get("sweep"), dict)]
        verdicts = "; ".join(f"{c.get('pass')} pass, {c.get('fail')} fail, {c.get('error')} error"
                             for c in counts)
        what += f": {verdicts}" if verdicts else ""
    else:  # (the verdicts name the scenarios)
        what = ", ".join(f"{r['scenario']} {r['verdict']}" for r in run.get("results") or []) or what
    return (f"run {run['id']}: {run['status']}{where} {run['progress']:.0f} % — {what}"
            + (f" — {run['error']}" if run.get("error") else ""))


def cmd_submit(args: argparse.Namespace) -> int:
    body: dict[str, Any] = {"scenarios": args.scenarios, "seed": args.seed, "priority": args.priority,
                            "mode": "bridge" if args.bridge or args.bench else "lockstep"}
    if args.bench:
        from rig.service.bench_host import parse_labels

        try:
            body["bench"] = parse_labels([args.bench])
        except ValueError as e:
            print(f"rig submit: --bench: {e}", file=sys.stderr)
            return EXIT_USAGE
    if args.dut:
        body["dut"] = {"command": args.dut}
    problem = _usage_problem(args)
    if problem is not None:
        print(f"rig submit: {problem}", file=sys.stderr)
        return EXIT_USAGE
    for option in ("pwm_channels", "topology"):  # (checked by the service, which says why in a 422)
        if getattr(args, option) is not None:
            body[option] = getattr(args, option)
    if args.fc:
        body["fc"] = args.fc
    run_id = None
    try:
        server_url(args.server)
        if args.firmware is not None:
            body["dut"] = _upload_dut(args)
        run_id = call(args.server, "POST", "/api/runs", args.token, body)["id"]
        print(run_id, flush=True)
        if not args.wait:
            return 0
        seen, ask = "", ""
        while True:
            # the first call does not wait (the run is shown as it is now); the later ones wait for a
            # change from the status last shown (``seen``: one that came between two calls is not missed)
            run = call(args.server, "GET", f"/api/runs/{run_id}{ask}", args.token)
            ask = f"?wait=30&seen={run['status']}"
            if line(run) != seen:
                seen = line(run)
                print(seen, file=sys.stderr, flush=True)
            if run["status"] in EXIT_BY_STATUS:
                return EXIT_BY_STATUS[run["status"]]
    except ClientError as e:
        for problem in str(e).splitlines():
            print(f"rig submit: {problem}", file=sys.stderr)
        return e.exit_code
    except KeyboardInterrupt:  # Ctrl-C stops the waiting, not the run: say so, without a traceback
        where = "" if run_id is None else f": run {run_id} goes on (rig status --server {args.server} " \
            f"{run_id}; cancel it with DELETE /api/runs/{run_id})"
        print(f"rig submit: interrupted{where}", file=sys.stderr)
        return EXIT_BY_STATUS["interrupted"]


def _usage_problem(args: argparse.Namespace) -> str | None:
    """What is wrong with ``--firmware``/``--board`` on this command line (None: nothing), before any
    request: the files must be there to be uploaded."""
    if args.board is not None and args.firmware is None:
        return "--board goes with --firmware FILE (the image it flies)"
    if args.firmware is not None and args.dut:
        return "--firmware and --dut both name the DUT: give one"
    if args.firmware is not None and not args.firmware.is_file():
        return f"--firmware {args.firmware}: no such file"
    return None


def _upload_dut(args: argparse.Namespace) -> dict[str, str]:
    """Uploads ``--firmware`` (and ``--board`` when it is a file, not a shipped board's name): the run's
    ``dut``. The service tells the image's kind and refuses one that does not fit (ClientError)."""
    try:
        image = args.firmware.read_bytes()
    except OSError as e:
        raise ClientError(f"--firmware {args.firmware}: {e.strerror}", 400) from None
    dut = {"firmware": call(args.server, "POST", "/api/firmware", args.token, raw=image)["sha256"]}
    if args.board is not None:
        board = Path(args.board)
        if board.suffix == ".toml" or board.is_file():
            try:
                text = board.read_bytes()
            except OSError as e:
                raise ClientError(f"--board {args.board}: {e.strerror}", 400) from None
            dut["board"] = call(args.server, "POST", "/api/boards", args.token, raw=text)["sha256"]
        else:
            dut["board"] = args.board
    return dut


def cmd_bench(args: argparse.Namespace) -> int:
    """``rig bench --server URL list|disable NAME|enable NAME``: the farm's benches, one a line."""
    try:
        server_url(args.server)
        if args.action == "list":
            found = call(args.server, "GET", "/api/benches", args.token)
        elif not args.name:
            raise ClientError(f"rig bench {args.action} needs a bench's NAME", 400)
        else:
            found = [call(args.server, "POST", f"/api/benches/{urllib.parse.quote(args.name, safe='')}/"
                          f"{args.action}", args.token)]
        for b in found:
            labels = ",".join(f"{k}={v}" for k, v in sorted(b.get("labels", {}).items()))
            run = (f" with run {b['run']}" if b.get("run") else f" ({b['problem']})" if b.get("problem")
                   else "")
            print(f"{b['name']}: {b['state']}{run} — {labels} on {b.get('host')} ({b.get('bridge')})")
    except ClientError as e:
        for problem in str(e).splitlines():
            print(f"rig bench: {problem}", file=sys.stderr)
        return e.exit_code
    return 0


def cmd_status(args: argparse.Namespace) -> int:
    try:
        server_url(args.server)
        if args.id is not None:
            print(line(call(args.server, "GET", f"/api/runs/{args.id}", args.token)))
        else:
            for run in call(args.server, "GET", "/api/runs?limit=20", args.token):
                print(line(run))
    except ClientError as e:
        for problem in str(e).splitlines():
            print(f"rig status: {problem}", file=sys.stderr)
        return e.exit_code
    except KeyboardInterrupt:
        return EXIT_BY_STATUS["interrupted"]
    return 0
