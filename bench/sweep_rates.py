"""rig sweep's rate (bench, not a test): runs per minute on the local pool with 1 and 2 workers, and
the overhead per run against a plain `rig run` of the same scenario (the sweep's spec check, pool,
core slot, row and table against flying it). Each sweep starts in a fresh folder; the figures are
wall-clock and vary with the machine.

``--before COMMIT`` sweeps with the rig of COMMIT (built in a temporary worktree, bench/ab.py) and
with this one, interleaved A B with the calibration loop per pair (2 workers), and prints runs per
minute before and after: what a change to the per-cycle path buys a long sweep.

    .venv/bin/python bench/sweep_rates.py [--runs 12] [--jobs 1 2]
    .venv/bin/python bench/sweep_rates.py --runs 200 --before aa79ab7 [--pairs 1]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import ab

SCENARIO = "step_roll"


def sweep(tree: Path, runs: int, jobs: int, folder: Path) -> float:
    """Runs per minute of a ``runs``-seed sweep of SCENARIO with ``jobs`` workers and ``tree``'s rig,
    in a fresh folder under ``folder``."""
    out = Path(tempfile.mkdtemp(prefix="sweep", dir=folder))
    spec = out / "spec.toml"
    spec.write_text(f'[sweep]\nscenario = "{SCENARIO}"\nseeds = {runs}\n')
    argv = ["-m", "rig.cli", "sweep", str(spec), "--out", str(out / "out"), "--jobs", str(jobs)]
    wall = ab.command(tree, argv)
    return runs / wall * 60


def single(runs: int, jobs: list[int]) -> None:
    with tempfile.TemporaryDirectory(prefix="sweep-bench-") as tmp:
        plain = min(ab.command(ab.REPO, ["-m", "rig.cli", "run", SCENARIO, "--seed", str(s), "--out",
                                         f"{tmp}/run{s}"]) for s in range(3))
        print(f"sweep_rates: {SCENARIO} ({runs} seeds); a plain rig run: {plain:.2f} s wall; "
              f"Python loop {ab.python_loop_ms():.0f} ms; {ab.load()}")
        print("  (a plain run includes its process start, checks and index/CSV: a sweep pays them once)")
        rates = {}
        for j in jobs:
            rates[j] = sweep(ab.REPO, runs, j, Path(tmp))
            per_run = 60 / rates[j] * j
            print(f"  {j} worker(s): {rates[j]:6.1f} runs/min, {per_run:.2f} s per run and worker "
                  f"({per_run / plain:.2f}x a plain rig run, overhead {per_run - plain:+.2f} s); "
                  f"Python loop {ab.python_loop_ms():.0f} ms; {ab.load()}")
        if 1 in rates and 2 in rates:
            print(f"  2 workers / 1 worker: {rates[2] / rates[1]:.2f}x")


def before_after(commit: str | None, runs: int, jobs: int, pairs: int) -> None:
    with ab.before_tree(commit) as old, tempfile.TemporaryDirectory(prefix="sweep-bench-") as tmp:
        print(f"sweep_rates: {SCENARIO}, {runs} seeds, {jobs} worker(s); before "
              f"{ab.git('rev-parse', '--short', 'HEAD', cwd=old)}, after this tree "
              f"({ab.git('rev-parse', '--short', 'HEAD')})")
        done = ab.interleave(pairs, lambda tree: sweep(tree, runs, jobs, Path(tmp)), old, label="sweep")
        for p in done:
            print(f"  calibration {p.calibration_ms:4.0f} ms: {p.before:6.1f} -> {p.after:6.1f} runs/min "
                  f"({p.after / p.before:.2f}x)")
        for phase, (n, b, a, ratio) in ab.by_phase(done).items():
            print(f"  {phase} phase ({n} pair(s)): median {b:6.1f} -> {a:6.1f} runs/min; "
                  f"after/before {ratio:.2f}x")


def main() -> int:
    ap = argparse.ArgumentParser(description="rig sweep's runs per minute")
    ap.add_argument("--runs", type=int, default=12, help="seeds per sweep (default 12)")
    ap.add_argument("--jobs", type=int, nargs="+", help="workers (default: 1 and 2; with --before: 2)")
    ap.add_argument("--before", metavar="COMMIT", nargs="?", const="",
                    help="also sweep with COMMIT's rig (default: git merge-base HEAD main), interleaved")
    ap.add_argument("--pairs", type=int, default=1, help="A/B pairs with --before (default 1)")
    args = ap.parse_args()
    if args.runs < 1 or args.pairs < 1 or any(j < 1 for j in args.jobs or []):
        ap.error("--runs, --jobs and --pairs must be at least 1")
    if args.before is None:
        single(args.runs, args.jobs or [1, 2])
    else:
        if args.jobs and len(args.jobs) > 1:
            ap.error("--before takes one --jobs")
        before_after(args.before or None, args.runs, (args.jobs or [2])[0], args.pairs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
