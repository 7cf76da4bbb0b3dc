"""rig sweep's rate (bench, not a test): runs per minute on the local pool with 1 and 2 workers, and
the overhead per run against a plain `rig run` of the same scenario (the sweep's spec check, pool,
core slot, row and table against flying it). Each sweep starts in a fresh folder; the figures are
wall-clock and vary with the machine.

    .venv/bin/python bench/sweep_rates.py
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SCENARIO = "step_roll"
RUNS = 12


def cli(*args: str) -> float:
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "rig.cli", *args], capture_output=True, text=True, cwd=REPO)
    if r.returncode not in (0, 1):
        raise SystemExit(f"rig {' '.join(args)} failed ({r.returncode}):\n{r.stderr[-2000:]}")
    return time.perf_counter() - t0


def main() -> int:
    with tempfile.TemporaryDirectory(prefix="sweep-bench-") as tmp:
        spec = Path(tmp) / "spec.toml"
        spec.write_text(f'[sweep]\nscenario = "{SCENARIO}"\nseeds = {RUNS}\n')
        plain = min(cli("run", SCENARIO, "--seed", str(s), "--out", f"{tmp}/run{s}") for s in range(3))
        print(f"sweep_rates: {SCENARIO} ({RUNS} seeds); a plain rig run: {plain:.2f} s wall")
        print("  (a plain run includes its process start, checks and index/CSV: a sweep pays them once)")
        rates = {}
        for jobs in (1, 2):
            wall = cli("sweep", str(spec), "--out", f"{tmp}/sweep{jobs}", "--jobs", str(jobs))
            rates[jobs] = RUNS / wall * 60
            per_run = wall * jobs / RUNS
            print(f"  {jobs} worker(s): {rates[jobs]:6.1f} runs/min, {per_run:.2f} s per run and worker "
                  f"({per_run / plain:.2f}x a plain rig run, overhead {per_run - plain:+.2f} s)")
        print(f"  2 workers / 1 worker: {rates[2] / rates[1]:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
