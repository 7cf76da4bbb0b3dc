"""``rig sweep SPEC --out DIR``: every variant of a sweep spec (scenarios/sweep.py) checked, then flown
on the local pool or a Dask cluster (rig/sweep/engine.py), with a progress bar; what finished is kept
in DIR (runs/<id>/, one folder per run), and DIR's runs.parquet, summary.html and junit.xml are
written from it at the end, interrupted or not. The same spec into the same DIR flies only what is
missing (``--retry-errors``: and the runs that ended in error); a DIR whose runs another DUT flew (DIR's
sweep.json, rig/sweep/store.py) is refused unless ``--fresh``, which removes them first.

Exit status: 0 every run passed, 1 a run failed a criterion, 2 bad usage or a bad spec (nothing runs),
3 a run ended in error or the engine could not be reached, 128+N stopped by signal N."""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import os
import shlex
import shutil
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rig import interrupts, scratch
from rig.run_cmd import LIBRARY, ReportFolder, UsageError, add_airframe_option, seconds_option

EXIT_FAIL, EXIT_USAGE, EXIT_ERROR = 1, 2, 3
#: a local pool whose process died (killed, out of memory) is started again this many times
POOL_RESTARTS = 3


def add_parser(sub: Any) -> None:
    p = sub.add_parser(
        "sweep",
        help="run one scenario over many variations (a local pool or a Dask cluster)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("spec", type=Path, help="the sweep spec (TOML; docs/sweeps.md)")
    p.add_argument(
        "--out",
        type=Path,
        required=True,
        help="the sweep's folder (resumable: the same spec again runs only what is missing)",
    )
    p.add_argument("--jobs", type=int, metavar="N", help="local pool: runs at once (default: one per core)")
    p.add_argument(
        "--engine",
        metavar="tcp://HOST:PORT",
        help="a Dask scheduler to run on (default: DASK_SCHEDULER_ADDRESS, else the local pool); "
        "DIR must be on storage the workers share",
    )
    p.add_argument(
        "--wait-workers",
        type=seconds_option,
        default=None,
        metavar="S",
        help="with a Dask cluster: how long to wait for a worker when the scheduler has none "
        "(default 120; the wait is counted on stderr)",
    )
    p.add_argument("--retry-errors", action="store_true", help="fly again the runs that ended in error")
    p.add_argument(
        "--fresh",
        action="store_true",
        help="start afresh: remove the runs DIR holds (needed when they flew another DUT) and fly every run",
    )
    p.add_argument("--dut", help="the DUT command line (default: the reference FC, as rig run)")
    add_airframe_option(p)
    p.add_argument(
        "--wall-timeout",
        type=seconds_option,
        default=600.0,
        metavar="S",
        help="a run that takes longer than this is stopped (an error; default %(default)s)",
    )


def main(args: argparse.Namespace) -> int:
    from rig.scenarios.sweep import SweepError, load_sweep
    from rig.sweep.engine import ENV, check_address

    address = args.engine or os.environ.get(ENV)
    if address:
        problem = check_address(address)
        if problem is not None:
            print(f"rig sweep: {'--engine' if args.engine else ENV}: {problem}", file=sys.stderr)
            return EXIT_USAGE
    elif args.wait_workers is not None:
        print("rig sweep: --wait-workers goes with a Dask cluster (--engine)", file=sys.stderr)
        return EXIT_USAGE
    if args.jobs is not None and not 1 <= args.jobs <= 1024:
        print(f"rig sweep: --jobs: expected 1..1024, got {args.jobs}", file=sys.stderr)
        return EXIT_USAGE
    dut: list[str] | None = None
    if args.dut is not None:
        try:
            dut = shlex.split(args.dut)
        except ValueError as e:
            print(f"rig sweep: --dut: {e}", file=sys.stderr)
            return EXIT_USAGE
        if not dut:
            print("rig sweep: --dut is empty", file=sys.stderr)
            return EXIT_USAGE
    try:
        sweep = load_sweep(args.spec, LIBRARY, airframe=args.airframe)
    except SweepError as e:
        print(f"rig sweep: {args.spec}: {e}", file=sys.stderr)
        return EXIT_USAGE
    try:
        with ReportFolder(args.out), interrupts.handled():
            return _sweep(sweep, args, dut)
    except UsageError as e:
        print(f"rig sweep: {e}", file=sys.stderr)
        return EXIT_USAGE


def _sweep(sweep: Any, args: argparse.Namespace, dut: list[str] | None) -> int:
    from tqdm import tqdm

    from rig.sweep import store
    from rig.sweep.engine import ENV, WORKERS_TIMEOUT_S, EngineError, open_engine
    from rig.sweep.work import Task, fly, read_row

    out: Path = args.out.resolve()
    ident = store.dut_identity(dut)
    if args.fresh:
        _remove_runs(out)
    rows: dict[str, dict[str, Any]] = {}
    for v in sweep.variants:
        row = read_row(out, v.id)
        if row is not None and (row.get("verdict") in ("pass", "fail") or not args.retry_errors):
            rows[v.id] = row
    recorded = store.read_dut(out)
    kept = [*([recorded] if recorded else []), *rows.values()]
    other = next((d for d in kept if not store.same_dut(d, ident)), None)
    if other is not None:
        raise UsageError(
            f"--out {out} holds runs of another DUT: {store.describe(other)}; this sweep's DUT is "
            f"{store.describe(ident)}. Give --fresh to start afresh (it removes those runs), or another --out"
        )
    store.write_dut(out, ident)
    local = not (args.engine or os.environ.get(ENV))
    tmp = str(scratch.make("sweep")) if local else None
    flown_by = {k: ident[k] for k in store.DUT_KEYS}
    todo = [
        Task(v, str(sweep.scenario_path), str(out), dut, args.wall_timeout, tmp, **flown_by)
        for v in sweep.variants
        if v.id not in rows
    ]
    total = len(sweep.variants)
    print(
        f"rig sweep: {sweep.scenario_path.stem}: {total} runs ({len(sweep.vary)} key(s) × {len(sweep.seeds)} "
        f"seed(s), {sweep.mode}); {len(rows)} done already, {len(todo)} to run",
        file=sys.stderr,
    )
    stop: int | None = None
    engine_name = "local"
    t0 = time.perf_counter()
    bar = tqdm(
        total=total,
        initial=len(rows),
        unit="run",
        file=sys.stderr,
        dynamic_ncols=True,
        mininterval=0.5 if sys.stderr.isatty() else 10.0,
    )
    try:
        restarts = 0
        while todo and stop is None:
            try:
                with open_engine(args.jobs, args.engine, args.wait_workers or WORKERS_TIMEOUT_S,
                                 lambda m: bar.write(f"rig sweep: {m}", file=sys.stderr)) as engine:
                    engine_name = engine.name
                    bar.set_description(f"{engine.name} ×{engine.workers}")
                    todo, stop = _run(engine, todo, fly, rows, bar)
            except EngineError as e:
                print(f"\nrig sweep: {e}", file=sys.stderr)
                return EXIT_ERROR
            if todo and stop is None:  # the pool broke (a process killed): the rest on a new one
                restarts += 1
                if restarts > POOL_RESTARTS:
                    print(
                        f"\nrig sweep: the pool broke {restarts} times; {len(todo)} runs left for a resume",
                        file=sys.stderr,
                    )
                    break
                print(f"\nrig sweep: a worker died; {len(todo)} runs go to a new pool", file=sys.stderr)
    finally:
        bar.close()
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    return _finish(sweep, out, rows, engine_name, stop, time.perf_counter() - t0, ident)


def _tally(verdict: str) -> str:
    """The progress bar's column for a row's verdict: pass, fail, or error for anything else."""
    return verdict if verdict in ("pass", "fail") else "error"


def _run(
    engine: Any,
    todo: list[Any],
    fly: Callable[..., dict[str, Any]],
    rows: dict[str, dict[str, Any]],
    bar: Any,
) -> tuple[list[Any], int | None]:
    """Submits ``todo``, collects rows as they come; returns what is left (a broken pool's, or nothing)
    and the signal's exit code when one stopped the sweep."""
    from concurrent.futures.process import BrokenProcessPool

    from rig.sweep.engine import STOP_GRACE_S

    futures = {engine.executor.submit(fly, t): t for t in todo}
    pending = set(futures)
    left: list[Any] = []
    counts = {"pass": 0, "fail": 0, "error": 0}
    for r in rows.values():
        counts[_tally(r["verdict"])] += 1
    stop: int | None = None
    deadline = 0.0
    while pending:
        done, pending = cf.wait(pending, timeout=0.5, return_when=cf.FIRST_COMPLETED)
        for f in done:
            task = futures[f]
            try:
                row = f.result()
            except cf.CancelledError:
                continue
            except BrokenProcessPool:
                left.append(task)
                continue
            except KeyboardInterrupt:  # (defensive: a worker takes SIGINT as the rig's stop)
                continue
            except Exception as e:  # a Dask worker lost too often, or the task itself failed to start
                row = {
                    **task.head(),
                    "verdict": "error",
                    "error": f"{type(e).__name__}: {e}",
                    "measurements": {},
                }
            if row.get("verdict") == "interrupted":
                continue
            rows[task.variant.id] = row
            counts[_tally(row["verdict"])] += 1
            bar.update(1)
            bar.set_postfix(counts, refresh=False)
        if stop is None:
            try:
                interrupts.check()
            except interrupts.Interrupted as e:
                stop = e.exit_code
                for f in pending:
                    f.cancel()
                if engine.stop_running is not None:
                    engine.stop_running()
                deadline = time.monotonic() + STOP_GRACE_S
                print(
                    f"\nrig sweep: {e}: stopping the runs under way, keeping what finished", file=sys.stderr
                )
        elif time.monotonic() > deadline:
            break  # (a Dask run that does not stop: its row is kept by the worker when it ends)
    if stop is None:
        left += [futures[f] for f in pending]
    return left, stop


def _finish(
    sweep: Any,
    out: Path,
    rows: dict[str, dict[str, Any]],
    engine: str,
    stop: int | None,
    wall: float,
    dut: dict[str, Any],
) -> int:
    from rig.reports import sweep as sweep_report
    from rig.sweep import store

    ordered = [rows[v.id] for v in sweep.variants if v.id in rows]
    keys = sweep.columns
    store.write(out / store.TABLE, ordered, keys)
    (out / "junit.xml").write_text(
        sweep_report.junit(ordered, sweep.scenario_path.stem, len(sweep.variants) - len(ordered), dut)
    )
    info = {
        "scenario": sweep.scenario_path.stem,
        "mode": sweep.mode,
        "seeds": len(sweep.seeds),
        "engine": engine,
        "total": len(sweep.variants),
        "not_done": len(sweep.variants) - len(ordered),
        **dut,
    }
    (out / "summary.html").write_text(sweep_report.summary(ordered, info, keys))
    _clean(out)
    verdicts = [r["verdict"] for r in ordered]
    n_pass, n_fail = verdicts.count("pass"), verdicts.count("fail")
    n_err = len(verdicts) - n_pass - n_fail
    print(
        f"rig sweep: {len(ordered)}/{len(sweep.variants)} runs: {n_pass} pass, {n_fail} fail, {n_err} error "
        f"in {wall:.1f} s; {out / 'summary.html'}",
        file=sys.stderr,
    )
    if stop is not None:
        return stop
    if n_err or len(ordered) < len(sweep.variants):
        return EXIT_ERROR
    return EXIT_FAIL if n_fail else 0


def _remove_runs(out: Path) -> None:
    """--fresh: what an earlier sweep wrote in ``out`` goes (only that: other files stay)."""
    from rig.sweep import store

    for name in store.WRITTEN:
        path = out / name
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink(missing_ok=True)


def _clean(out: Path) -> None:
    """The core-slot lock files (rig/sweep/work.py) go with the sweep."""
    from rig.sweep.work import SLOTS

    slots = out / SLOTS
    for f in slots.glob("*.lock"):
        f.unlink(missing_ok=True)
    try:
        slots.rmdir()
    except OSError:
        pass
