"""What the sandbox (rig/sandbox.py) costs a run, printed, never asserted: ``rig run SCENARIO`` as is,
wrapped as the service wraps it (bwrap, prlimit, a pids cgroup as root), and as ``rig run --sandbox``
(which starts rig run a second time, inside), in turn, each in a process of its own, N times each: the
median and best wall time of each. (Not CPU time: the processes a pid namespace's end reaps are
counted in nobody's rusage.)

The script runs the tree it lives in (its own folder's parent).

``python bench/sandbox_cost.py [--runs N] [--scenario NAME]``
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from rig import sandbox  # noqa: E402  (the tree this script lives in)

MODES = ("plain", "service", "--sandbox")


def one(mode: str, scenario: str, out: Path) -> float:
    """Wall seconds of one run."""
    cmd = [sys.executable, "-m", "rig.cli", "run", *(["--sandbox"] if mode == "--sandbox" else []), scenario,
           "--out", str(out)]
    wrap = sandbox.confined(cmd, [out]) if mode == "service" else contextlib.nullcontext(cmd)
    start = time.perf_counter()
    with wrap as argv:
        subprocess.run(argv, cwd=ROOT, check=True, capture_output=True)
    return time.perf_counter() - start


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=7)
    p.add_argument("--scenario", default="step_roll")
    args = p.parse_args()
    walls: dict[str, list[float]] = {m: [] for m in MODES}
    with tempfile.TemporaryDirectory() as tmp:
        one("service", args.scenario, Path(tmp) / "warm")  # (the first run fills the page cache)
        for _ in range(args.runs):
            for mode in MODES:
                walls[mode].append(one(mode, args.scenario, Path(tmp) / mode.strip("-")))
    for mode, runs in walls.items():
        print(f"{mode:10} wall median {statistics.median(runs):.3f} s, best {min(runs):.3f} s "
              f"({len(runs)} runs)")


if __name__ == "__main__":
    main()
