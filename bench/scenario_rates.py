"""Real-time factor (sim seconds per wall second) of whole scenario runs with the reference FC in
lockstep: the seed-000 roll recovery and a 30 s hover. Printed, never asserted (target: 20x).

Each run is repeated; the best and the median are printed, next to the time of a fixed pure-Python
loop measured just before. These VMs change speed by half from one minute to the next, and that
calibration says which kind of minute a number came from. ``RIG_PURE_PYTHON=1`` measures the hot
modules as plain Python instead of compiled (rig/compiled.py)."""

from __future__ import annotations

import dataclasses
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from rig.compiled import install, status  # noqa: E402

install()  # the compiled hot modules, before they are imported
from rig.runner import run  # noqa: E402
from scenarios.schema import load  # noqa: E402

REPEATS = 3


def python_loop_ms() -> float:
    """CPU time of one fixed million-iteration Python loop: the machine's speed right now."""
    t0 = time.process_time()
    x = 0
    for i in range(1_000_000):
        x += i * i
    return (time.process_time() - t0) * 1000


def main() -> None:
    print(status())
    lib = REPO / "scenarios" / "library"
    hover = dataclasses.replace(load(lib / "hover_turbulence.toml"), duration=30.0)
    for label, sc in (
        ("seed-000 roll recovery", load(lib / "seed000_roll_stand.toml")),
        ("30 s hover", hover),
    ):
        rtf, tx, calib, cpu = [], [], [], []
        for _ in range(REPEATS):
            calib.append(python_loop_ms())
            c0 = time.process_time()
            m = run(sc).metadata
            cpu.append((time.process_time() - c0) / m["sim_time"] * 1000)
            rtf.append(m["realtime_factor"])
            tx.append(m["bus_transactions"] / m["wall_time"])
        print(
            f"{label:24} {m['sim_time']:5.1f} sim-s: real-time factor best {max(rtf):5.1f}x, median "
            f"{statistics.median(rtf):5.1f}x; session CPU {statistics.median(cpu):4.0f} ms per sim-s; "
            f"{statistics.median(tx):6.0f} I2C tx/s; Python loop {min(calib):.0f}-{max(calib):.0f} ms"
        )


if __name__ == "__main__":
    main()
