"""The service's web page, rendered on the server (Jinja2, templates/) with htmx for the parts that
change (the history's filters, the form that starts a run) and uPlot for a run's telemetry, both
vendored and served from here: no build step, no CDN.

Pages: ``/`` the queue, a form that starts a run and the history with filters; ``/runs/ID`` a run: its
status, each scenario's criteria, and its attitude plot (drag to zoom, values under the cursor).
"""

from __future__ import annotations

import datetime
import math
import urllib.parse
from pathlib import Path
from typing import Any

from fastapi import FastAPI, HTTPException, Query, Request, Response
from fastapi.responses import HTMLResponse
from fastapi.staticfiles import StaticFiles
from fastapi.templating import Jinja2Templates
from pydantic import ValidationError

from rig import __version__
from rig.reports.html_report import UPLOT  # the reports' copy: vendored once
from rig.service.db import STATUSES, TERMINAL, Db
from rig.service.store import MAX_SCENARIO, Store
from rig.service.worker import Workers

HERE = Path(__file__).resolve().parent


def _utc(t: float) -> str:
    return datetime.datetime.fromtimestamp(t, datetime.UTC).strftime("%Y-%m-%d %H:%M:%S")


def _num(v: object) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.4g}" if math.isfinite(v) else str(v)
    return str(v)


def register(app: FastAPI, db: Db, workers: Workers, store: Store) -> None:
    from rig.service.app import RunRequest, check_run, problems_of

    templates = Jinja2Templates(directory=str(HERE / "templates"))
    templates.env.filters.update(utc=_utc, num=_num)
    app.mount("/static/htmx", StaticFiles(directory=HERE / "static" / "htmx"), name="htmx")
    app.mount("/static/uplot", StaticFiles(directory=UPLOT), name="uplot")

    def scenario_names() -> list[dict[str, str]]:
        from rig.run_cmd import resolve

        return [{"name": p.stem} for p in resolve([])] + [{"name": n} for n in store.uploaded_scenarios()]

    def page(request: Request, name: str, **context: Any) -> HTMLResponse:
        return templates.TemplateResponse(request, name, {"version": __version__, **context})

    def live() -> dict[str, Any]:
        """What changes on the front page while it is open: the cluster, the benches, the queue (each
        queued bench run with what it waits for)."""
        benches = workers.farm.benches() if workers.farm is not None else []
        queue = [r for status in ("running", "queued") for r in db.list(status=status, limit=100)]
        for r in queue:
            r["waits"] = waits_for(r, benches)
        return {"queue": queue, "benches": benches,
                "engine": workers.farm.state() if workers.farm is not None else None}

    def waits_for(run: dict[str, Any], benches: list[dict[str, Any]]) -> str:
        """What a queued bench run waits for, in words: the benches its selector matches and their
        states (a farm's), or the service's own bench and its holder."""
        if run["status"] != "queued" or run["mode"] != "bridge":
            return ""
        if workers.farm is None:
            holder = db.lease("bench")
            return "the service's bench" + (f" (held by {holder['holder']})" if holder else "")
        from rig.service.farm import matches

        found = [f"{b['name']} ({b['state']}" + (f", run {b['run']})" if b.get("run") else ")")
                 for b in benches if matches(b, run["bench"] or {})]
        return ("a bench: " + ", ".join(found)) if found else "a bench with its labels (none known now)"

    def run_view(run_id: int) -> dict[str, Any]:
        """A run's page's parts: its DUT in words, the artifacts that are there to link (a queued or
        interrupted run has no index.html), what a queued bench run waits for, whether it has ended."""
        run = db.get(run_id)
        if run is None:
            raise HTTPException(404, f"no run {run_id}")
        folder = workers.artifacts / str(run["id"])
        names = (("summary.html", "runs.parquet", "junit.xml") if run["mode"] == "sweep"
                 else ("index.html", "junit.xml"))
        text = dut_text(run["dut"])
        benches = workers.farm.benches() if workers.farm is not None and run["status"] == "queued" else []
        return {"run": run, "dut": text, "present": [n for n in names if (folder / n).is_file()],
                "waits": waits_for(run, benches), "ended": run["status"] in TERMINAL}

    @app.get("/", response_class=HTMLResponse, include_in_schema=False)
    def index(request: Request) -> HTMLResponse:
        return page(request, "index.html", runs=db.list(limit=50), scenarios=scenario_names(),
                    firmware=store.firmware_list(), boards=store.board_list(), statuses=STATUSES, **live())

    @app.get("/ui/live", response_class=HTMLResponse, include_in_schema=False)
    def live_part(request: Request) -> HTMLResponse:
        return page(request, "live.html", **live())

    @app.get("/ui/runs", response_class=HTMLResponse, include_in_schema=False)
    def runs_table(request: Request, status: str = "", scenario: str = "") -> HTMLResponse:
        runs = db.list(status=status if status in STATUSES else None, scenario=scenario or None, limit=50)
        return page(request, "runs_table.html", runs=runs)

    @app.post("/ui/runs", response_class=HTMLResponse, include_in_schema=False)
    async def start(request: Request) -> Response:
        body = await request.body()
        if len(body) > MAX_SCENARIO:
            return refused(["the form is too large"], 413)
        form = urllib.parse.parse_qs(body.decode("utf-8", "replace"))
        try:
            dut = {k: v for k in ("firmware", "board") if (v := (form.get(k) or [""])[0])}
            req = RunRequest(scenarios=form.get("scenarios", []), seed=_whole(form, "seed"),
                             priority=_whole(form, "priority"), dut=dut,
                             mode=form.get("mode", ["lockstep"])[0])  # type: ignore[arg-type]
        except ValidationError as e:
            return refused(problems_of(list(e.errors())))
        except ValueError as e:
            return refused([str(e)])
        problems, versions = check_run(req, store)
        if problems:
            return refused(problems)
        run_id = db.submit(req.scenarios, req.seed, req.dut, req.mode, req.priority, versions=versions)
        workers.wake()
        return HTMLResponse(f'<p>queued <a href="/runs/{run_id}">run {run_id}</a></p>',
                            headers={"HX-Trigger": "refresh"})

    @app.get("/compare", response_class=HTMLResponse, include_in_schema=False)
    def compare(request: Request, a: int, b: int, scenario: str) -> HTMLResponse:
        """Two runs of one scenario overlaid: their criteria side by side, their attitudes on one plot."""
        ra, rb = db.get(a), db.get(b)
        if ra is None or rb is None:
            raise HTTPException(404, "no such run")
        ma, mb = _measured(ra, scenario), _measured(rb, scenario)
        if ma is None or mb is None:
            raise HTTPException(404, f"both runs must have run {scenario!r}")
        rows = [(name, value, mb.get(name)) for name, value in ma.items()]
        return page(request, "compare.html", a=ra, b=rb, scenario=scenario, rows=rows,
                    versions=(_version(ra, scenario), _version(rb, scenario)))

    @app.get("/trend", response_class=HTMLResponse, include_in_schema=False)
    def trend_page(request: Request, scenario: str, measurement: str, version: str = "",
                   seed: int | None = None, mode: str = "", dut: str = "") -> HTMLResponse:
        points = trend(db, scenario, measurement, version, seed=seed, mode=mode, dut=dut)
        everything = trend(db, scenario, measurement)  # (what the filters offer)
        return page(request, "trend.html", scenario=scenario, measurement=measurement, version=version,
                    seed=seed, mode=mode, dut=dut, points=points,
                    series=list(dict.fromkeys(p["series"] for p in points)),
                    choices={k: sorted({p[k] for p in everything}) for k in ("seed", "mode", "firmware")})

    @app.get("/api/trend")
    def trend_api(scenario: str, measurement: str, version: str = "",
                  seed: int | None = Query(default=None, ge=0), mode: str = "",
                  dut: str = Query(default="", description="a DUT as the points' firmware names it")
                  ) -> list[dict[str, Any]]:
        """A measurement of a scenario over the finished runs, oldest first, each point with what makes
        its series: the scenario's version (and its number), the seed, the mode and the DUT
        (``firmware``); ``version`` (a SHA-256's beginning), ``seed``, ``mode`` and ``dut`` keep one."""
        return trend(db, scenario, measurement, version, seed=seed, mode=mode, dut=dut)

    @app.get("/runs/{run_id}", response_class=HTMLResponse, include_in_schema=False)
    def run_page(request: Request, run_id: int) -> HTMLResponse:
        return page(request, "run.html", **run_view(run_id))

    @app.get("/ui/runs/{run_id}", response_class=HTMLResponse, include_in_schema=False)
    def run_part(request: Request, run_id: int) -> HTMLResponse:
        """The run's page's body, which the open page swaps in every second until the run has ended."""
        return page(request, "run_view.html", **run_view(run_id))


def _measured(run: dict[str, Any], scenario: str) -> dict[str, Any] | None:
    for r in run["results"]:
        if r["scenario"] == scenario:
            return {m["name"]: m["value"] for m in r["measurements"]}
    return None


def _version(run: dict[str, Any], scenario: str) -> str:
    """The scenario's version the run flew (its result.json's), or was queued with; "" unknown (a run
    from before versions)."""
    flown = [r.get("sha256") for r in run["results"] if r["scenario"] == scenario]
    return (flown[0] if flown else None) or run.get("versions", {}).get(scenario) or ""


def dut_text(dut: dict[str, str]) -> str:
    """A run's DUT in a few words: the reference FC, its command, or its firmware (on its board)."""
    text = dut.get("firmware") or dut.get("command") or "reference FC"
    return f"{text} on {dut['board']}" if dut.get("board") else text


def trend(db: Db, scenario: str, measurement: str, version: str = "", limit: int = 500,
          seed: int | None = None, mode: str = "", dut: str = "") -> list[dict[str, Any]]:
    """The points of a trend, oldest first: each with what sets a series apart, so no two kinds of
    flight are drawn as one line unawares: the scenario's version the run flew (what its result.json
    says; a run from before versions: "" unknown) and its number (``version_number``, 1 for the first
    version seen, in order), the ``seed``, the ``mode`` and the DUT (``firmware``), and the ``series``
    these make. ``version`` (a SHA-256's beginning), ``seed``, ``mode`` and ``dut`` keep one of each."""
    points = []
    numbers: dict[str, int] = {}
    for run in reversed(db.list(scenario=scenario, limit=limit)):
        for r in run["results"]:
            for m in r["measurements"] if r["scenario"] == scenario else []:
                sha = _version(run, scenario)
                number = numbers.setdefault(sha, len(numbers) + 1)
                numeric = isinstance(m["value"], int | float)
                firmware = dut_text(run["dut"])
                if (m["name"] != measurement or not numeric or not sha.startswith(version)
                        or (seed is not None and run["seed"] != seed) or (mode and run["mode"] != mode)
                        or (dut and firmware != dut)):
                    continue
                series = (f"{scenario}@{sha[:8] or 'unknown'} (v{number}), seed {run['seed']}, "
                          f"{run['mode']}, {firmware}")
                points.append({"run": run["id"], "created": run["created"], "value": m["value"],
                               "outcome": m["outcome"], "version": sha, "version_number": number,
                               "seed": run["seed"], "mode": run["mode"], "firmware": firmware,
                               "series": series})
    return points


def refused(problems: list[str], status: int = 422) -> HTMLResponse:
    """The form's refusal in the service's words, which the page shows beside the form (its htmx
    config swaps a 413 or 422 in as it swaps a success)."""
    return HTMLResponse('<p class="error" id="refused">not started: ' + "; ".join(map(_escape, problems))
                        + "</p>", status_code=status)


def _whole(form: dict[str, list[str]], name: str) -> int:
    text = (form.get(name) or ["0"])[0].strip() or "0"
    try:
        return int(text)
    except ValueError:
        raise ValueError(f"{name}: {text!r} is not a whole number") from None


def _escape(text: str) -> str:
    import html

    return html.escape(text)
