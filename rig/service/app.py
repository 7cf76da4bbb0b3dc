"""The service's HTTP API (FastAPI; OpenAPI at /openapi.json), docs/service.md.

Everything a request names is checked before it reaches the queue: scenarios by the validator ``rig
validate`` uses (its words returned as they are), a DUT command by the shell's quoting rules; nothing
from a request becomes a path but through the scenario library's resolver or the run's numeric id.
With a token every request must carry it (``Authorization: Bearer TOKEN``).
"""

from __future__ import annotations

import hmac
import json
import shlex
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Literal

from fastapi import Depends, FastAPI, HTTPException, Query, Request, Response
from fastapi.dependencies.models import Dependant
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, JSONResponse, StreamingResponse
from fastapi.routing import APIRoute
from pydantic import BaseModel, ConfigDict, Field

from rig import __version__
from rig.service.db import SCHEMA_VERSION, SQLITE_INT, STATUSES, TERMINAL, Db
from rig.service.images import BOARD_KINDS, ENGINE_IMAGES, ENGINE_KINDS, describe
from rig.service.store import MAX_SCENARIO, Store, UploadError
from rig.service.worker import Workers

MAX_SCENARIOS = 100
VERDICTS = {"pass": "passed", "fail": "failed", "error": "error"}
WAIT_POLL_S = 0.1
#: artifacts' media types Python's mimetypes does not know (MCAP has no registered type; Foxglove's own
#: servers give it as application/octet-stream)
MEDIA_TYPES = {".mcap": "application/octet-stream"}


class RunRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")  # a mistyped field ("sead") is refused, never defaulted

    scenarios: list[str] = Field(min_length=1, max_length=MAX_SCENARIOS)
    seed: int = Field(default=0, ge=0, lt=2**31)
    dut: dict[str, str] = Field(default_factory=dict)
    #: the FC's profile, a shipped one's name (docs/profiles.md); None: the reference FC's
    fc: str | None = None
    mode: Literal["lockstep", "bridge"] = "lockstep"
    priority: int = Field(default=0, ge=-100, le=100)
    #: a Linux DUT's board (rig run --pwm-channels, --topology; default 8 channels on a GY-86)
    pwm_channels: int | None = Field(default=None, ge=1, le=16)
    topology: Literal["gy86", "direct"] | None = None
    #: a bench run's selector: the labels its bench must have (rig serve --engine: docs/farm.md)
    bench: dict[str, str] | None = None


def problems_of(errors: list[Any]) -> list[str]:
    """Pydantic's errors (a ValidationError's or FastAPI's) as sentences naming the field: what a 422
    carries as ``{"detail": {"problems": [...]}}``, the one shape of every refusal of this API."""
    out = []
    for e in errors:
        where = ".".join(str(x) for x in e.get("loc", ()) if x not in ("body", "query", "path"))
        if e.get("type") == "extra_forbidden":
            out.append(f"{where}: no such field (known: {', '.join(RunRequest.model_fields)})")
        else:
            out.append(f"{where or 'the request'}: {e.get('msg', 'invalid')}")
    return out


def refusal(status: int, message: str) -> HTTPException:
    """An HTTP refusal: a 422 in the shape of every 422 (``{"problems": [...]}``), others a sentence."""
    return HTTPException(status, {"problems": [message]} if status == 422 else message)


def fc_problems(fc: str) -> list[str]:
    """A requested FC profile's problems: the service flies shipped profiles only (a client's file is
    not on the service's disk), named as ``rig run --fc`` names them."""
    import difflib

    from rig.scenarios import profile as profiles

    shipped = profiles.names()
    if fc in shipped:
        return []
    near = difflib.get_close_matches(fc, shipped, n=1)
    hint = f"; did you mean {near[0]!r}?" if near else ""
    return [f"fc: no shipped FC profile {fc!r}{hint} (shipped: {', '.join(shipped)})"]


def check_run(req: RunRequest, store: Store, scenarios: bool = True) -> tuple[list[str], dict[str, str]]:
    """Every problem of a run request, in words (the validator's for the scenarios; ``scenarios``
    False: only the DUT, for a sweep), and the version of each scenario it names: the one checked
    here is the one the run records and flies."""
    from rig.scenarios.schema import ScenarioError, load

    problems = []
    versions: dict[str, str] = {}
    for name in req.scenarios if scenarios else []:
        sha = store.pin(name)
        path = None if sha is None else store.version_file(sha)
        if sha is None or path is None:
            problems.append(f"{name!r}: no library scenario of that name, and none uploaded "
                            "(GET /api/scenarios lists them)")
            continue
        versions[name] = sha
        try:
            load(path)
        except ScenarioError as e:
            problems.append(str(e).replace(str(path), f"{name}.toml"))
    if req.fc is not None:
        problems += fc_problems(req.fc)
    kinds = set(req.dut)
    if (kinds - {"command", "firmware", "board"} or {"command", "firmware"} <= kinds
            or ("board" in kinds and "firmware" not in kinds)):
        problems.append("dut: {\"command\": \"...\"}, {\"firmware\": SHA256} (a Linux program) or "
                        "{\"firmware\": SHA256, \"board\": BOARD} (an AVR or ARM image on a board; GET "
                        "/api/boards); POST /api/firmware first")
    elif "firmware" in kinds:
        problems += firmware_problems(req.dut, req.mode, store)
    elif "command" in kinds:
        try:
            if not shlex.split(req.dut["command"]):
                problems.append("dut.command is empty")
        except ValueError as e:
            problems.append(f"dut.command: {e}")
    if req.mode == "bridge" and (req.pwm_channels is not None or req.topology is not None):
        problems.append("pwm_channels and topology are a Linux DUT's board: not with mode bridge")
    elif "board" in req.dut and (req.pwm_channels is not None or req.topology is not None):
        problems.append("pwm_channels and topology are a Linux DUT's board: an MCU image's board file "
                        "says them (dut.board)")
    return problems, versions


def firmware_problems(dut: dict[str, str], mode: str, store: Store) -> list[str]:
    """An uploaded firmware's problems as a run's DUT: a Linux program runs as it is; an MCU image
    flies on a board (a shipped one's name or an uploaded one's SHA-256) whose MCU's engine takes its
    kind (an AVR image on an AVR, an ARM image on an STM32), whole and within the board's MCU's
    memories, as ``rig run --mcu`` checks it. Each names what was received."""
    from rig.mcu import board as boards
    from rig.mcu.engines import check_firmware
    from rig.mcu.image import FirmwareError

    sha, board = dut["firmware"], dut.get("board")
    path, kind = store.firmware(sha), store.firmware_kind(sha)
    if path is None:
        return [f"dut.firmware: no uploaded firmware {sha!r} (POST /api/firmware)"]
    if kind is None:
        return [f"dut.firmware: {sha[:12]} is neither a Linux program nor an MCU image (upload it again)"]
    if board is None:
        if kind in BOARD_KINDS:
            return [f"dut.firmware: {sha[:12]} is {describe(kind)}: it flies on a board; give dut.board, a "
                    "shipped board's name or an uploaded board's SHA-256 (GET /api/boards)"]
        return []
    where = store.board(board)
    if where is None:
        return [f"dut.board: no shipped board {board!r} and no uploaded board of that SHA-256 "
                f"(shipped: {', '.join(boards.names())}; GET /api/boards)"]
    found = boards.load(where)
    engine = found.mcu.engine
    if kind not in ENGINE_KINDS[engine]:
        return [f"dut.firmware: the board {found.name} ({found.mcu.name}) flies {ENGINE_IMAGES[engine]}; "
                f"{sha[:12]} is {describe(kind)}"]
    if mode != "lockstep":
        return ["dut.board: a board's image flies under emulation in lockstep, not in mode bridge"]
    try:
        check_firmware(found, path)
    except FirmwareError as e:
        return [f"dut.firmware: {str(e).replace(str(path), sha[:12])}"]
    return []


def dut_of(req: RunRequest) -> dict[str, str]:
    """The DUT as the queue stores it: its program (command or firmware) and the board it sees."""
    board = {k: str(v) for k, v in (("pwm_channels", req.pwm_channels), ("topology", req.topology))
             if v is not None}
    return {**req.dut, **board}


def bench_problems(req: RunRequest, workers: Workers) -> list[str]:
    """A bench selector's problems: it goes with mode bridge on a farm, and some bench must have its
    labels (one that matches only busy benches waits in the queue)."""
    if req.bench is None:
        return []
    if req.mode != "bridge":
        return ["bench: a selector goes with mode bridge"]
    if workers.farm is None:
        return ["bench: this service has one bench of its own; selectors need a farm (rig serve --engine)"]
    problem = workers.farm.refuse(req.bench)
    return [] if problem is None else [problem]


async def small_body(request: Request, what: str) -> bytes:
    """A request's body of a text file (a scenario, a board file, a sweep spec), refused (413) as soon as
    it grows over MAX_SCENARIO bytes, before the rest is read."""
    body = b""
    async for chunk in request.stream():
        body += chunk
        if len(body) > MAX_SCENARIO:
            raise HTTPException(413, f"{what} over {MAX_SCENARIO} bytes")
    return body


def _query_names(dependant: Dependant) -> set[str]:
    """The query parameters a route (and its dependencies) take."""
    names = {p.alias for p in dependant.query_params}
    for sub in dependant.dependencies:
        names |= _query_names(sub)
    return names


def create_app(db: Db, workers: Workers, token: str | None, store: Store, artifacts: Path) -> FastAPI:
    """The API over ``db``, its runs executed by ``workers``, uploads in ``store``."""

    def authorised(request: Request) -> None:
        if token is None:
            return
        scheme, _, given = request.headers.get("authorization", "").strip().partition(" ")
        # the scheme is case-insensitive (RFC 9110): "bearer TOKEN" is as good as "Bearer TOKEN"
        if scheme.lower() != "bearer" or not hmac.compare_digest(given.strip().encode(), token.encode()):
            raise HTTPException(401, "this service needs its token: Authorization: Bearer TOKEN",
                                headers={"WWW-Authenticate": "Bearer"})

    def known_query(request: Request) -> None:
        """A query parameter the route does not take is refused by name, as a body's unknown field is."""
        route = request.scope.get("route")
        if not isinstance(route, APIRoute):
            return
        known = _query_names(route.dependant)
        unknown = sorted(set(request.query_params) - known)
        if unknown:
            raise HTTPException(422, {"problems": [
                f"{name}: no such query parameter (known: {', '.join(sorted(known)) or 'none'})"
                for name in unknown]})

    app = FastAPI(title="quadrotor HIL rig", version=__version__,
                  dependencies=[Depends(authorised), Depends(known_query)])

    @app.exception_handler(RequestValidationError)
    async def refused(request: Request, exc: RequestValidationError) -> JSONResponse:
        return JSONResponse({"detail": {"problems": problems_of(list(exc.errors()))}}, status_code=422)

    @app.get("/api/health")
    def health() -> dict[str, Any]:
        """``status`` ok, or ``degraded`` while the Dask cluster (rig serve --engine) cannot be reached:
        nothing is dispatched to it then, and ``engine.problem`` says why."""
        found: dict[str, Any] = {"status": "ok", "version": __version__, "schema": SCHEMA_VERSION,
                                 "bench": db.lease("bench")}
        if workers.farm is not None:
            found["engine"] = workers.farm.state()
            if not found["engine"]["connected"]:
                found["status"] = "degraded"
        return found

    @app.get("/api/scenarios")
    def scenarios() -> list[dict[str, Any]]:
        """The library's scenarios, then the uploaded ones, each with its version (``sha256``)."""
        import hashlib

        from rig.run_cmd import resolve
        from rig.scenarios.schema import ScenarioError, load

        found: list[tuple[str, str, str, Path | None]] = [
            ("library", p.stem, hashlib.sha256(p.read_bytes()).hexdigest(), p) for p in resolve([])]
        found += [("uploaded", name, sha, store.version_file(sha))
                  for name, sha in store.uploaded_scenarios().items()]
        out = []
        for origin, name, sha, path in found:
            entry: dict[str, Any] = {"name": name, "origin": origin, "sha256": sha}
            try:
                if path is None:
                    raise ScenarioError(f"{name}.toml", "", f"its version {sha[:12]} is not in the store")
                sc = load(path)
                entry.update(title=name if sc.name == path.stem else sc.name, duration=sc.duration)
            except ScenarioError as e:
                entry["error"] = str(e)
            out.append(entry)
        return out

    @app.post("/api/scenarios", status_code=201)
    async def upload_scenario(request: Request, response: Response, name: str = Query(),
                              replace: bool = Query(default=False, description="point NAME at this file "
                                                    "even if it points at another version")
                              ) -> dict[str, Any]:
        """A scenario file (TOML, the request's body), checked by the validator ``rig validate`` uses
        (its words returned as they are, 422), stored once under its SHA-256 and NAME pointed at it:
        201 a new version of NAME, 200 the version NAME points at already, 409 NAME points at another
        version (``?replace=true`` points it at this one; runs queued already keep theirs)."""
        body = await small_body(request, "a scenario")
        try:
            stored = store.put_scenario(name, body, replace)
        except UploadError as e:
            raise refusal(e.status, str(e)) from e
        if not stored["new"]:
            response.status_code = 200
        return stored

    @app.get("/api/scenarios/{name}/versions")
    def versions(name: str) -> list[dict[str, Any]]:
        """The versions an uploaded name has pointed at, oldest first; the last is the current one."""
        found = db.history(name)
        if not found:
            raise HTTPException(404, f"no scenario was uploaded as {name!r}")
        return found

    @app.post("/api/firmware", status_code=201)
    async def upload_firmware(request: Request) -> dict[str, Any]:
        """A firmware (the request's body): a Linux program (an ELF for this host, a #! script) or an MCU
        image for a board (AVR: ELF, Intel HEX; ARM: ELF), stored once under its SHA-256 with its
        ``kind``; anything else is a 422 naming what it looks like."""
        try:
            sha, size, kind = await store.put_firmware(request.stream())
        except UploadError as e:
            raise refusal(e.status, str(e)) from e
        return {"sha256": sha, "size": size, "kind": kind}

    @app.get("/api/firmware")
    def firmware() -> list[dict[str, object]]:
        return store.firmware_list()

    @app.post("/api/boards", status_code=201)
    async def upload_board(request: Request) -> dict[str, Any]:
        """A board file (TOML, the request's body; docs/mcu.md), checked as ``rig run --mcu`` checks
        one and stored once under its SHA-256, which a run names as ``dut.board``."""
        body = await small_body(request, "a board file")
        try:
            return store.put_board(body)
        except UploadError as e:
            raise refusal(e.status, str(e)) from e

    @app.get("/api/boards")
    def boards() -> list[dict[str, Any]]:
        """The shipped boards (``board``: the name a run gives) and the uploaded ones (``board``: the
        SHA-256), each with its name and MCU."""
        return store.board_list()

    @app.post("/api/runs", status_code=201)
    def submit(req: RunRequest) -> dict[str, Any]:
        problems, versions = check_run(req, store)
        problems += bench_problems(req, workers)
        if problems:
            raise HTTPException(422, {"problems": problems})
        dut = dut_of(req)
        if req.fc is not None:
            dut = {**dut, "fc": req.fc}  # (the run's DUT: the FC and how it is flown)
        run_id = db.submit(req.scenarios, req.seed, dut, req.mode, req.priority, versions=versions,
                           bench=req.bench)
        workers.wake()
        return {"id": run_id}

    @app.post("/api/sweeps", status_code=201)
    async def submit_sweep(request: Request, priority: int = Query(default=0, ge=-100, le=100),
                           dut: str | None = Query(default=None, description="a DUT command line"),
                           fc: str | None = Query(default=None, description="a shipped FC profile's name"),
                           ) -> dict[str, Any]:
        """A sweep spec (TOML, the request's body; docs/sweeps.md) whose scenario is a library or an
        uploaded one, every variant checked before it is queued (422 with the checker's words). It
        runs as one job of a lockstep slot (``rig sweep --jobs 1``); GET /api/runs/ID follows it and
        its artifacts hold summary.html, runs.parquet and junit.xml."""
        from rig.run_cmd import LIBRARY
        from rig.scenarios.sweep import Sweep, SweepError, load_sweep

        body = await small_body(request, "a sweep spec")
        problems, _ = check_run(RunRequest(scenarios=["-"], dut={"command": dut} if dut is not None else {},
                                           fc=fc), store, scenarios=False)
        if problems:
            raise HTTPException(422, {"problems": problems})
        versions: dict[str, str] = {}

        def pinned(name: str) -> Path | None:  # the version checked here is the one the sweep flies
            sha = store.pin(name)
            if sha is not None:
                versions[name] = sha
            return None if sha is None else store.version_file(sha)

        def check(path: Path) -> Sweep:
            try:
                return load_sweep(path, LIBRARY, pinned)
            except SweepError as e:
                raise HTTPException(422, {"problems": [str(e).replace(str(path), "the spec")]}) from e

        try:
            path, sweep = store.put_sweep(body, check)  # (kept only once checked)
        except UploadError as e:
            raise refusal(e.status, str(e)) from e
        flown_by = {**({"command": dut} if dut is not None else {}), **({"fc": fc} if fc is not None else {})}
        run_id = db.submit([str(path)], 0, flown_by, "sweep", priority, versions=versions)
        workers.wake()
        [(name, sha)] = versions.items()
        return {"id": run_id, "runs": len(sweep.variants), "scenario": name, "sha256": sha}

    @app.get("/api/benches")
    def benches() -> list[dict[str, Any]]:
        """The farm's benches (rig serve --engine): name, labels, host, bridge, and state (free, busy
        with ``run``, offline, maintenance). Without a farm: none."""
        return workers.farm.benches() if workers.farm is not None else []

    @app.post("/api/benches/{name}/{action}")
    def bench_action(name: str, action: Literal["disable", "enable"]) -> dict[str, Any]:
        """Takes a bench out for maintenance (no run is sent to it; the one on it finishes) or puts it
        back."""
        known = {b["name"]: b for b in benches()}
        if name not in known:
            raise HTTPException(404, f"no bench {name!r} (known: {', '.join(known) or 'none'})")
        db.disable_bench(name, action == "disable")
        workers.wake()
        return {b["name"]: b for b in benches()}[name]

    @app.get("/api/sweeps")
    def sweeps(limit: int = Query(default=50, ge=1, le=500)) -> list[dict[str, Any]]:
        """The sweeps, newest first (each a run of mode ``sweep``)."""
        return db.list(limit=limit, mode="sweep")

    @app.get("/api/runs")
    def runs(status: str | None = Query(default=None), verdict: str | None = None,
             scenario: str | None = None, firmware: str | None = None, since: float | None = None,
             limit: int = Query(default=50, ge=1, le=500),
             offset: int = Query(default=0, ge=0, le=SQLITE_INT[1])) -> list[dict[str, Any]]:
        """The runs, newest first. ``verdict`` (pass, fail, error) names a run's outcome as rig run's
        verdicts do; ``firmware`` is an uploaded firmware's SHA-256."""
        if status is not None and status not in STATUSES:
            raise refusal(422, f"status: one of {', '.join(STATUSES)}")
        if verdict is not None:
            if verdict not in VERDICTS or (status is not None and status != VERDICTS[verdict]):
                raise refusal(422, f"verdict: one of {', '.join(VERDICTS)} (and agrees with status)")
            status = VERDICTS[verdict]
        return db.list(status, scenario, since, limit, offset, firmware)

    @app.get("/api/runs/{run_id}")
    def run(run_id: int, wait: float = Query(default=0.0, ge=0.0, le=60.0),
            seen: str | None = Query(default=None, max_length=20)) -> dict[str, Any]:
        """The run; with ``wait``, answered as soon as its status or progress changes, or after that
        many seconds (a client follows a run without polling in a loop of its own). ``seen``, the
        status the client last saw, is what the status is compared with: a change between two calls
        (queued, then running while no call was waiting) is answered at once, never missed."""
        found = db.get(run_id)
        if found is None:
            raise HTTPException(404, f"no run {run_id}")
        deadline = time.monotonic() + wait
        last = (found["status"] if seen is None else seen, found["progress"])
        while (found["status"], found["progress"]) == last and found["status"] not in TERMINAL \
                and time.monotonic() < deadline:
            if workers.stopped.is_set():  # a service stopping answers once its runs have ended (read
                return db.get(run_id) or found  # after the stop: their end): no long poll holds it up
            time.sleep(WAIT_POLL_S)
            found = db.get(run_id) or found
        return found

    def _folder(run_id: int) -> Path:
        if db.get(run_id) is None:
            raise HTTPException(404, f"no run {run_id}")
        return (artifacts / str(run_id)).resolve()

    @app.get("/api/runs/{run_id}/artifacts")
    def artifact_list(run_id: int) -> list[str]:
        """The run's files: the suite's junit.xml and index.html, each scenario's result.json,
        telemetry.csv, run.mcap, report.html, junit.xml and the DUT's output."""
        folder = _folder(run_id)
        if not folder.is_dir():
            return []
        return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file()
                      and not p.is_symlink() and not p.name.startswith("."))

    @app.get("/api/runs/{run_id}/artifacts/{name:path}")
    def artifact(run_id: int, name: str) -> FileResponse:
        folder = _folder(run_id)
        path = (folder / name).resolve()
        # only a file inside the run's own folder, reached by no link and no hidden name
        if (not path.is_relative_to(folder) or not path.is_file() or (folder / name).is_symlink()
                or any(part.startswith(".") for part in Path(name).parts)):
            raise HTTPException(404, f"run {run_id} has no artifact {name!r}")
        # (a name Python's mimetypes does not know would be served as text/plain)
        return FileResponse(path, media_type=MEDIA_TYPES.get(path.suffix))

    @app.get("/api/runs/{run_id}/events")
    def events(run_id: int) -> StreamingResponse:
        """Server-sent events: the run as JSON each time its status or progress changes, until it ends."""
        if db.get(run_id) is None:
            raise HTTPException(404, f"no run {run_id}")

        def stream() -> Iterator[str]:
            seen: tuple[object, object] | None = None
            while True:
                stopping = workers.stopped.is_set()  # (before the read: the runs' end is the last event)
                found = db.get(run_id)
                if found is None:
                    return
                now = (found["status"], found["progress"])
                if now != seen:
                    seen = now
                    yield f"event: run\ndata: {json.dumps(found)}\n\n"
                if found["status"] in TERMINAL or stopping:
                    return
                time.sleep(WAIT_POLL_S)

        return StreamingResponse(stream(), media_type="text/event-stream")

    @app.delete("/api/runs/{run_id}")
    def cancel(run_id: int) -> dict[str, Any]:
        if db.get(run_id) is None:
            raise HTTPException(404, f"no run {run_id}")
        refused = workers.abort(run_id)
        if refused is not None:
            raise HTTPException(409, refused)
        return db.get(run_id) or {}

    from rig.service import page

    page.register(app, db, workers, store)
    return app
