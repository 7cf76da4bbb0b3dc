"""What the sandbox (rig/sandbox.py) costs a run, printed, never asserted: ``rig run SCENARIO`` and
``rig run --sandbox SCENARIO`` alternately, each in a process of its own, N times each; the median and
best wall time of each and the CPU time of the whole process tree (its children's rusage). The sandbox
adds a process start (bwrap, then rig run again inside it) and the namespaces and mounts.

The script runs the tree it lives in (its own folder's parent).

``python bench/sandbox_cost.py [--runs N] [--scenario NAME]``
"""

from __future__ import annotations

import argparse
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def one(sandbox: bool, scenario: str, out: Path) -> tuple[float, float]:
    """(wall s, CPU s of the tree) of one run."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "rig.cli", "run", *(["--sandbox"] if sandbox else []), scenario,
                    "--out", str(out)], cwd=ROOT, check=True, capture_output=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=7)
    p.add_argument("--scenario", default="step_roll")
    args = p.parse_args()
    figures: dict[bool, list[tuple[float, float]]] = {False: [], True: []}
    with tempfile.TemporaryDirectory() as tmp:
        one(True, args.scenario, Path(tmp) / "warm")  # (the first run fills the page cache)
        for _ in range(args.runs):
            for sandbox in (False, True):
                figures[sandbox].append(one(sandbox, args.scenario, Path(tmp) / str(sandbox)))
    for sandbox, runs in figures.items():
        walls, cpus = [w for w, _ in runs], [c for _, c in runs]
        print(f"{'--sandbox' if sandbox else 'plain    '}  wall median {statistics.median(walls):.3f} s, "
              f"best {min(walls):.3f} s; CPU median {statistics.median(cpus):.3f} s ({len(runs)} runs)")


if __name__ == "__main__":
    main()
