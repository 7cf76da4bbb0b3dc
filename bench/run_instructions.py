"""The session's instructions per FC cycle over a whole lockstep flight: the per-cycle path, the
loop's wake-ups and the scheduled events (recorder, wind, sticks) together. Printed, never asserted.

Why: bench/cycle_cost.py counts one FC cycle's messages alone. A flight costs the session several
times that (its loop waking for the DUT, the events at 100 Hz and their trips through Python), and a
change to those parts shows here. Counted by cachegrind in the session's process (the DUT runs
natively beside it, in lockstep, so its speed does not matter): the hover in light turbulence to 4 s
and to 20 s, subtracted, so start-up and take-off cancel and 16 s of hover (4000 FC cycles) remain;
twice, both printed. Instruction counts do not follow these VMs' changes of speed, but the loop's
wake-ups depend a little on whether the DUT's next message is there yet. 16 s, not 4: a full cyclic
garbage collection (a few million instructions, twelve before the session froze the heap it starts
with) lands in one run or the other by where the collector's thresholds fall, and over 4 s that moved
the figure by up to 12 k.

    .venv/bin/python bench/run_instructions.py
"""

from __future__ import annotations

import dataclasses
import shutil
import sys
from pathlib import Path

import cycle_cost

SHORT_S, LONG_S = 4.0, 20.0
#: the loop's wake-ups depend on whether the DUT's next message is already there: counts vary by a few %
REPEATS = 2
FC_HZ = 250


def _child(duration: float) -> None:
    from rig.compiled import install

    install()  # the compiled hot modules, before they are imported
    from rig import scenarios
    from rig.runner import run
    from rig.scenarios.schema import load

    sc = load(Path(scenarios.__file__).parent / "library" / "hover_turbulence.toml")
    run(dataclasses.replace(sc, duration=duration))


def main() -> None:
    if "--child" in sys.argv:
        _child(float(sys.argv[sys.argv.index("--child") + 1]))
        return
    if not shutil.which("valgrind") or not shutil.which("setarch"):
        sys.exit("needs valgrind and setarch (apt-get install valgrind util-linux)")
    from rig.compiled import status

    print(status())
    cycles = (LONG_S - SHORT_S) * FC_HZ
    per = sorted((cycle_cost.instructions([__file__, "--child", str(LONG_S)], {})
                  - cycle_cost.instructions([__file__, "--child", str(SHORT_S)], {})) / cycles / 1000
                 for _ in range(REPEATS))
    print(f"a flight's session cost per FC cycle (hover, {SHORT_S:g} s to {LONG_S:g} s): "
          f"{sum(per) / len(per):.1f} k instructions (mean of {REPEATS}: "
          f"{', '.join(f'{p:.1f}' for p in per)})")


if __name__ == "__main__":
    main()
