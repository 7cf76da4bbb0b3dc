"""Real-time factor (sim seconds per wall second) of whole scenario runs with the reference FC in
lockstep: the seed-000 roll recovery and a 30 s hover. Printed, never asserted.

Each run is repeated; the best and the median are printed, next to the time of a fixed pure-Python
loop measured just before. These VMs change speed by half from one minute to the next, and that
calibration says which kind of minute a number came from. ``RIG_PURE_PYTHON=1`` measures the hot
modules as plain Python instead of compiled (rig/compiled.py).

``--before COMMIT`` measures the tree at COMMIT (built in a temporary worktree, bench/ab.py) and this
one in one sitting, interleaved A B A B with the calibration per pair, and prints the medians and
the ratio after/before per phase (fast or slow, by the calibration), so a change's speed-up is not
the VM's.

    .venv/bin/python bench/scenario_rates.py [--spin]
    .venv/bin/python bench/scenario_rates.py --before aa79ab7 [--pairs 5]
"""

from __future__ import annotations

import argparse
import functools
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import ab

REPEATS = 3
LABELS = {"roll": "seed-000 roll recovery", "hover": "30 s hover"}


def measure(which: str, spin: bool = False) -> dict[str, float]:
    """One lockstep run of ``which`` ("roll" or "hover") with the rig importable here (the tree's own
    library scenario): its real-time factor, session CPU ms per sim second, I2C transactions/s. ``spin``:
    on two cores, polling (rig/cores.py; this tree only)."""
    import dataclasses

    from rig import scenarios
    from rig.runner import run
    from rig.scenarios.schema import load

    lib = Path(scenarios.__file__).parent / "library"
    sc = load(lib / "seed000_roll_stand.toml")
    if which == "hover":
        sc = dataclasses.replace(load(lib / "hover_turbulence.toml"), duration=30.0)
    c0 = time.process_time()
    if spin:
        from rig.targets.process import ProcessTarget

        m: Any = run(sc, ProcessTarget(spin=True)).metadata
    else:
        m = run(sc).metadata
    return {"rtf": m["realtime_factor"], "cpu_ms": (time.process_time() - c0) / m["sim_time"] * 1000,
            "tx_s": m["bus_transactions"] / m["wall_time"], "sim_time": m["sim_time"]}


def _measure_in(tree: Path, which: str) -> dict[str, float]:
    result: dict[str, float] = ab.call(tree, Path(__file__), "measure", which)
    return result


def single(spin: bool) -> None:
    """Today's mode: this tree only, REPEATS runs of each, with the calibration loop's range; with
    ``spin`` each run is followed by one with ``--spin`` (rig/cores.py), and both are printed."""
    sys.path.insert(0, str(ab.REPO))
    from rig.compiled import install, status

    install()  # the compiled hot modules, before they are imported
    print(f"{status()}; {ab.load()}")
    for which, label in LABELS.items():
        kinds = (False, True) if spin else (False,)
        runs: dict[bool, list[dict[str, float]]] = {k: [] for k in kinds}
        calib = []
        for _ in range(REPEATS):
            calib.append(ab.python_loop_ms())
            for k in kinds:
                runs[k].append(measure(which, k))
        for k, ms in runs.items():
            rtf = [m["rtf"] for m in ms]
            print(
                f"{label + (' --spin' if k else ''):31} {ms[0]['sim_time']:5.1f} sim-s: real-time factor "
                f"best {max(rtf):5.1f}x, median {statistics.median(rtf):5.1f}x; session CPU "
                f"{statistics.median(m['cpu_ms'] for m in ms):4.0f} ms per sim-s; "
                f"{statistics.median(m['tx_s'] for m in ms):6.0f} I2C tx/s; Python loop "
                f"{min(calib):.0f}-{max(calib):.0f} ms"
            )


def before_after(commit: str | None, pairs: int) -> None:
    with ab.before_tree(commit) as old:
        dirty = " + uncommitted changes" if ab.git("status", "--porcelain", "--untracked-files=no") else ""
        print(f"before: {ab.git('rev-parse', '--short', 'HEAD', cwd=old)}; after: this tree "
              f"({ab.git('rev-parse', '--short', 'HEAD')}{dirty})")
        for which, label in LABELS.items():
            runs = ab.interleave(pairs, functools.partial(_measure_in, which=which), old, label=label)
            print(f"{label}: real-time factor, before -> after (calibration loop ms)")
            for p in runs:
                print(f"  {p.calibration_ms:4.0f} ms: {p.before['rtf']:6.1f}x -> {p.after['rtf']:6.1f}x "
                      f"({p.after['rtf'] / p.before['rtf']:.2f}x); session CPU {p.before['cpu_ms']:4.0f} -> "
                      f"{p.after['cpu_ms']:4.0f} ms per sim-s")
            rtf = [ab.Pair(p.calibration_ms, p.before["rtf"], p.after["rtf"]) for p in runs]
            for phase, (n, b, a, ratio) in ab.by_phase(rtf).items():
                print(f"  {phase} phase ({n} pair(s)): median {b:6.1f}x -> {a:6.1f}x; "
                      f"after/before {ratio:.2f}x")


def main() -> None:
    ap = argparse.ArgumentParser(description="lockstep real-time factor of two scenarios")
    ap.add_argument("--before", metavar="COMMIT", nargs="?", const="",
                    help="also measure COMMIT (default: git merge-base HEAD main), interleaved")
    ap.add_argument("--pairs", type=int, default=5, help="A/B pairs per scenario with --before (default 5)")
    ap.add_argument("--spin", action="store_true", help="also each run with --spin (two cores, polling)")
    args = ap.parse_args()
    if args.before is None:
        single(args.spin)
    else:
        before_after(args.before or None, args.pairs)


if __name__ == "__main__":
    main()
