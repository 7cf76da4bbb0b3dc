"""``rig run``, ``rig validate`` and ``rig list``: the scenario suite, the main job.

``rig run SCENARIO… [--dut CMD] [--out DIR] [--seed N]`` checks every file first (a bad file stops the
suite before anything flies), then runs each scenario in lockstep against the DUT (default: the
reference flight controller) and writes, per run, ``OUT/<scenario>/{junit.xml,result.json,
telemetry.csv,report.html}``, and for the suite ``OUT/junit.xml`` and ``OUT/index.html``. A line per
scenario shows progress on stderr. Exit status: 0 all passed, 1 a criterion failed, 2 bad usage or a bad
scenario file, 3 a run ended in error (crash, hang, early exit of the DUT).
"""

from __future__ import annotations

import argparse
import dataclasses
import shlex
import sys
import time
from pathlib import Path

from scenarios.schema import ScenarioError, load

LIBRARY = Path(__file__).resolve().parents[1] / "scenarios" / "library"
EXIT_FAILED, EXIT_USAGE, EXIT_ERROR = 1, 2, 3


def add_parsers(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "run",
        help="run scenarios against a DUT and write reports",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "scenarios",
        nargs="*",
        metavar="SCENARIO",
        help="scenario files or names from the library (default: the whole library)",
    )
    p.add_argument(
        "--dut",
        help="the DUT command line (default: the reference FC, configured by the "
        "scenario's [fc] table); it reads SBUS on /dev/ttyRC0 and may write "
        "telemetry lines on /dev/ttyTEL0",
    )
    p.add_argument(
        "--out", type=Path, default=Path("build/reports"), help="report folder (default %(default)s)"
    )
    p.add_argument("--seed", type=int, default=0, help="random seed for noise, turbulence and faults")
    p.add_argument(
        "--wall-timeout", type=float, default=600.0, help="wall seconds per run before it is ended"
    )
    p.add_argument(
        "--realtime",
        action="store_true",
        help="pace the runs by the wall clock (a bench) instead of lockstep virtual time; "
        "how late scheduled events ran goes into result.json",
    )
    p.add_argument(
        "--can",
        metavar="INTERFACE:CHANNEL",
        help="python-can interface and channel for scenarios whose PWM capture goes over CAN "
        "(e.g. socketcan:can0 on a bench; default: each scenario's [capture], virtual and private)",
    )
    v = sub.add_parser("validate", help="check scenario files without running them")
    v.add_argument("scenarios", nargs="+", metavar="SCENARIO")
    sub.add_parser("list", help="list the scenario library")


def resolve(names: list[str]) -> list[Path]:
    """Files as given, or library names (with or without .toml); all of the library when empty."""
    if not names:
        return sorted(LIBRARY.glob("*.toml"))
    out = []
    for n in names:
        p = Path(n)
        if not p.exists() and (LIBRARY / f"{p.stem}.toml").exists() and p.parent == Path("."):
            p = LIBRARY / f"{p.stem}.toml"
        out.append(p)
    return out


def cmd_list() -> int:
    for p in resolve([]):  # the whole library
        try:
            sc = load(p)
            print(f"{p.stem:28} {sc.duration:6.1f} s  {sc.name}")
        except ScenarioError as e:
            print(f"{p.stem:28} INVALID  {e}")
    return 0


def cmd_validate(names: list[str]) -> int:
    bad = 0
    for p in resolve(names):
        try:
            sc = load(p)
            print(f"ok   {p}: {len(sc.criteria)} criteria, {sc.duration:g} s")
        except ScenarioError as e:
            print(f"FAIL {e}", file=sys.stderr)
            bad += 1
    return EXIT_USAGE if bad else 0


def cmd_run(args: argparse.Namespace) -> int:
    from reports import html_report, junit, result_json, telemetry
    from scenarios.runner import run

    try:
        scenarios = [load(p) for p in resolve(args.scenarios)]
    except ScenarioError as e:
        print(f"rig run: {e}", file=sys.stderr)
        return EXIT_USAGE
    if not scenarios:
        print("rig run: no scenarios", file=sys.stderr)
        return EXIT_USAGE
    try:
        dut = shlex.split(args.dut) if args.dut else None
    except ValueError as e:
        print(f"rig run: --dut: {e}", file=sys.stderr)
        return EXIT_USAGE
    if dut == []:
        print("rig run: --dut is empty", file=sys.stderr)
        return EXIT_USAGE
    if args.can:
        interface, sep, channel = args.can.partition(":")
        if not (interface and sep and channel):
            print(
                f"rig run: --can: expected INTERFACE:CHANNEL (e.g. socketcan:can0), got {args.can!r}",
                file=sys.stderr,
            )
            return EXIT_USAGE
        scenarios = [
            dataclasses.replace(
                sc, capture=dataclasses.replace(sc.capture, can_interface=interface, can_channel=channel)
            )
            if sc.capture.transport == "can"
            else sc
            for sc in scenarios
        ]
    out: Path = args.out
    results, links = [], []
    t_suite = time.perf_counter()
    for i, sc in enumerate(scenarios, 1):
        run_dir = out / sc.stem
        print(
            f"[{i}/{len(scenarios)}] {sc.stem} ({sc.duration:g} s sim) ...",
            end="",
            file=sys.stderr,
            flush=True,
        )
        try:
            r = run(
                sc,
                dut=dut,
                seed=args.seed,
                work_dir=run_dir,
                wall_timeout=args.wall_timeout,
                realtime=args.realtime,
            )
        except (FileNotFoundError, OSError, ValueError) as e:
            print(f" cannot run: {e}", file=sys.stderr)
            return EXIT_USAGE
        results.append(r)
        links.append(f"{sc.stem}/report.html")
        (run_dir / "junit.xml").write_text(junit.render([r]))
        (run_dir / "result.json").write_text(result_json.render(r))
        (run_dir / "telemetry.csv").write_text(telemetry.render(r.signals))
        (run_dir / "report.html").write_text(html_report.render(r))
        failed = [m.name for m in r.measurements if m.outcome == "fail"]
        rate = r.metadata.get("realtime_factor") or 0.0
        detail = (
            f" error: {r.error}"
            if r.verdict == "error"
            else (f" failed: {'; '.join(failed)}" if failed else "")
        )
        print(
            f" {r.verdict.upper()} ({float(r.metadata['wall_time']):.1f} s wall, {rate:.0f}x){detail}",
            file=sys.stderr,
        )
    (out / "junit.xml").write_text(junit.render(results))
    (out / "index.html").write_text(html_report.render_index(results, links))
    counts = {v: sum(r.verdict == v for r in results) for v in ("pass", "fail", "error")}
    print(
        f"{counts['pass']} passed, {counts['fail']} failed, {counts['error']} errors in "
        f"{time.perf_counter() - t_suite:.1f} s; reports in {out}/index.html",
        file=sys.stderr,
    )
    if counts["error"]:
        return EXIT_ERROR
    return EXIT_FAILED if counts["fail"] else 0
