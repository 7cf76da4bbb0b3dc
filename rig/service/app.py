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

from fastapi import Depends, FastAPI, HTTPException, Query, Request
from fastapi.responses import FileResponse, StreamingResponse
from pydantic import BaseModel, Field

from rig import __version__
from rig.service.db import SCHEMA_VERSION, STATUSES, TERMINAL, Db
from rig.service.worker import Workers

MAX_SCENARIOS = 100
WAIT_POLL_S = 0.1


class RunRequest(BaseModel):
    scenarios: list[str] = Field(min_length=1, max_length=MAX_SCENARIOS)
    seed: int = Field(default=0, ge=0, lt=2**31)
    dut: dict[str, str] = Field(default_factory=dict)
    mode: Literal["lockstep", "bridge"] = "lockstep"
    priority: int = Field(default=0, ge=-100, le=100)


def check_scenarios(names: list[str]) -> list[str]:
    """Library names (the service runs only what its library holds): each loaded by the validator;
    the problems, in its words."""
    from rig.run_cmd import LIBRARY
    from scenarios.schema import ScenarioError, load

    problems = []
    for name in names:
        path = LIBRARY / f"{Path(name).stem}.toml"
        if not name or "/" in name or name.startswith(".") or not path.is_file():
            problems.append(f"{name!r}: no library scenario of that name (GET /api/scenarios lists them)")
            continue
        try:
            load(path)
        except ScenarioError as e:
            problems.append(str(e))
    return problems


def create_app(db: Db, workers: Workers, token: str | None, artifacts: Path | None = None) -> FastAPI:
    """The API over ``db``, its runs executed by ``workers``."""

    def authorised(request: Request) -> None:
        if token is None:
            return
        given = request.headers.get("authorization", "")
        if not hmac.compare_digest(given.encode(), f"Bearer {token}".encode()):
            raise HTTPException(401, "this service needs its token: Authorization: Bearer TOKEN",
                                headers={"WWW-Authenticate": "Bearer"})

    app = FastAPI(title="quadrotor HIL rig", version=__version__, dependencies=[Depends(authorised)])

    @app.get("/api/health")
    def health() -> dict[str, Any]:
        return {"status": "ok", "version": __version__, "schema": SCHEMA_VERSION}

    @app.get("/api/scenarios")
    def scenarios() -> list[dict[str, Any]]:
        from rig.run_cmd import resolve
        from scenarios.schema import ScenarioError, load

        out = []
        for p in resolve([]):
            try:
                sc = load(p)
                out.append({"name": p.stem, "title": sc.name, "duration": sc.duration})
            except ScenarioError as e:
                out.append({"name": p.stem, "error": str(e)})
        return out

    @app.post("/api/runs", status_code=201)
    def submit(req: RunRequest) -> dict[str, Any]:
        problems = check_scenarios(req.scenarios)
        if set(req.dut) - {"command"}:
            problems.append("dut: {'command': '...'} (firmware uploads come with a later version of the "
                            "service)")
        command = req.dut.get("command")
        if command is not None:
            try:
                if not shlex.split(command):
                    problems.append("dut.command is empty")
            except ValueError as e:
                problems.append(f"dut.command: {e}")
        if problems:
            raise HTTPException(422, {"problems": problems})
        run_id = db.submit([Path(s).stem for s in req.scenarios], req.seed, req.dut, req.mode, req.priority)
        workers.wake()
        return {"id": run_id}

    @app.get("/api/runs")
    def runs(status: str | None = Query(default=None), scenario: str | None = None,
             since: float | None = None, limit: int = Query(default=50, ge=1, le=500),
             offset: int = Query(default=0, ge=0)) -> list[dict[str, Any]]:
        if status is not None and status not in STATUSES:
            raise HTTPException(422, f"status is one of {', '.join(STATUSES)}")
        return db.list(status, scenario, since, limit, offset)

    @app.get("/api/runs/{run_id}")
    def run(run_id: int, wait: float = Query(default=0.0, ge=0.0, le=60.0)) -> dict[str, Any]:
        """The run; with ``wait``, answered as soon as its status or progress changes, or after that
        many seconds (a client follows a run without polling in a loop of its own)."""
        found = db.get(run_id)
        if found is None:
            raise HTTPException(404, f"no run {run_id}")
        deadline = time.monotonic() + wait
        seen = (found["status"], found["progress"])
        while found["status"] not in TERMINAL and time.monotonic() < deadline:
            time.sleep(WAIT_POLL_S)
            found = db.get(run_id) or found
            if (found["status"], found["progress"]) != seen:
                break
        return found

    def _folder(run_id: int) -> Path:
        if db.get(run_id) is None or artifacts is None:
            raise HTTPException(404, f"no run {run_id}")
        return (artifacts / str(run_id)).resolve()

    @app.get("/api/runs/{run_id}/artifacts")
    def artifact_list(run_id: int) -> list[str]:
        """The run's files: the suite's junit.xml and index.html, each scenario's result.json,
        telemetry.csv, report.html, junit.xml and the DUT's output."""
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
        return FileResponse(path)

    @app.get("/api/runs/{run_id}/events")
    def events(run_id: int) -> StreamingResponse:
        """Server-sent events: the run as JSON each time its status or progress changes, until it ends."""
        if db.get(run_id) is None:
            raise HTTPException(404, f"no run {run_id}")

        def stream() -> Iterator[str]:
            seen: tuple[object, object] | None = None
            while True:
                found = db.get(run_id)
                if found is None:
                    return
                now = (found["status"], found["progress"])
                if now != seen:
                    seen = now
                    yield f"event: run\ndata: {json.dumps(found)}\n\n"
                if found["status"] in TERMINAL:
                    return
                time.sleep(WAIT_POLL_S)

        return StreamingResponse(stream(), media_type="text/event-stream")

    @app.delete("/api/runs/{run_id}")
    def cancel(run_id: int) -> dict[str, Any]:
        found = db.get(run_id)
        if found is None:
            raise HTTPException(404, f"no run {run_id}")
        if found["status"] in TERMINAL:
            raise HTTPException(409, f"run {run_id} is already {found['status']}")
        if not db.update_if(run_id, found["status"], status="cancelled"):
            raise HTTPException(409, f"run {run_id} changed meanwhile; ask again")
        workers.cancel(run_id)  # (a running one: its rig run is stopped, its DUT with it)
        return db.get(run_id) or {}

    return app
