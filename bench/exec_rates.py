"""``rig exec`` speed: I2C round trips (p50/p99, transactions per second) with the DUT and the session
pinned to one core and not, and sim seconds per wall second for a 400 Hz read-and-sleep loop.
Prints rates and ratios; asserts nothing (speed belongs here, not in tests)."""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

DUTS = Path(__file__).resolve().parent / "exec_programs"  # what the benches run under rig exec
RIG = [sys.executable, "-m", "rig.cli", "exec"]


def run(options: list[str], command: list[str]) -> tuple[str, dict]:
    with tempfile.TemporaryDirectory() as tmp:
        summary = Path(tmp) / "s.json"
        done = subprocess.run([*RIG, "--summary", str(summary), *options, "--", *command],
                              capture_output=True, text=True, check=False)
        if done.returncode != 0:
            sys.exit(f"bench run failed ({done.returncode}): {done.stderr}")
        return done.stdout, json.loads(summary.read_text())


def main() -> None:
    n = 20000
    print(f"rig exec: {n} MPU-6050 14-byte burst reads (I2C_RDWR via smbus2), wall-clock round trips")
    for label, options in (("lockstep, pinned to one core", []), ("lockstep, unpinned", ["--no-pin"]),
                           ("real time, unpinned", ["--realtime"])):
        out, _ = run(options, [sys.executable, str(DUTS / "i2c_rtt.py"), str(n)])
        r = json.loads(out)
        print(f"  {label:30s} p50 {r['p50_us']:6.1f} us  p99 {r['p99_us']:6.1f} us  "
              f"{r['tx_per_s'] / 1e3:6.1f} k transactions/s")
    sim_s = 20.0
    for config, label in ((3, "MPU at 1 kHz (DLPF 3)"), (0, "MPU at 8 kHz (CONFIG 0)")):
        _, s = run(["--duration", str(sim_s)], [sys.executable, str(DUTS / "loop_400hz.py"), str(config)])
        print(f"  400 Hz read-and-sleep loop, {label}, {sim_s:g} s sim: {s['wall_time']:.2f} s wall, "
              f"{s['sim_time'] / s['wall_time']:.1f} sim-s per wall-s ({s['transactions']} transactions)")
    _, s = run([], [sys.executable, "-c", "import time; time.sleep(10)", ])
    print(f"  time.sleep(10): {s['sim_time']:.3f} s sim in {s['wall_time']:.2f} s wall "
          "(interpreter start included)")


if __name__ == "__main__":
    main()
