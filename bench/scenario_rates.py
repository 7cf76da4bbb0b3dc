"""Real-time factor (sim seconds per wall second) of whole scenario runs with the reference FC in
lockstep: the seed-000 roll recovery and a 30 s hover. Printed, never asserted (target: 20x)."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from scenarios.runner import run  # noqa: E402
from scenarios.schema import load  # noqa: E402


def main() -> None:
    lib = REPO / "scenarios" / "library"
    hover = dataclasses.replace(load(lib / "hover_turbulence.toml"), duration=30.0)
    for label, sc in (
        ("seed-000 roll recovery", load(lib / "seed000_roll_stand.toml")),
        ("30 s hover", hover),
    ):
        r = run(sc)
        m = r.metadata
        print(
            f"{label:24} {m['sim_time']:6.1f} sim-s in {m['wall_time']:6.2f} wall-s: "
            f"{m['realtime_factor']:5.1f}x real time, {m['bus_transactions'] / m['wall_time']:7.0f} I2C tx/s"
        )


if __name__ == "__main__":
    main()
