"""What the bridge core costs on the STM32G431's core, in instructions, from QEMU (bench, not a test).

bench/bridge_m4_cost.c runs the core and the real chip core on QEMU's mps2-an386 (a Cortex-M4F, built
with the firmware's flags) under -icount shift=0, where SysTick counts executed instructions (one tick
per 40). It serves a 1 kHz MPU-6050 reader: each millisecond a host sample, a poll and a 14-byte
burst read with a repeated START. Instructions are not cycles: on the G431 at 170 MHz with 4 flash
wait states behind the ART accelerator, expect 1 to 2 cycles an instruction; the microseconds
printed take 1.5. The I2C calls run inside the firmware's interrupt, so their cost is how long SCL
is stretched (docs/bridge-firmware.md, "Not verified on hardware"). The main loop's calls run with
interrupts on except while they hold the HAL's lock: "masked" is the longest such span of a call,
how long an I2C event that arrives then waits.

    .venv/bin/python bench/bridge_m4_cost.py
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.bridge.tools import CHIP_CORE, CORE, REPO, build_tool, run_m4  # noqa: E402

CLOCK_HZ = 170e6
CYCLES_PER_INSN = 1.5


def main() -> int:
    elf = build_tool("bridge_m4_cost", [REPO / "bench" / "bridge_m4_cost.c", *sorted(CORE.glob("*.c")),
                                        *sorted(CHIP_CORE.glob("*.c"))], CHIP_CORE, m4=True)
    done = run_m4(elf, [], qemu_args=("-icount", "shift=0"))
    if done.returncode != 0:
        print(f"bridge_m4_cost failed (status {done.returncode}): {done.stderr}", file=sys.stderr)
        return 1
    print(f"bridge core on a Cortex-M4 (QEMU mps2-an386, -icount): instructions per call, and us at "
          f"{CLOCK_HZ / 1e6:.0f} MHz and {CYCLES_PER_INSN} cycles an instruction")
    for line in done.stdout.splitlines():
        w = line.split()
        name, calls, mean, worst, masked = w[0], int(w[2]), int(w[4]), int(w[6]), int(w[8])
        us = CYCLES_PER_INSN / CLOCK_HZ * 1e6
        where = ("" if name.startswith("i2c_") else
                 f"  masked max {masked:6d} ({masked * us:6.2f} us)")
        print(f"  {name:20} {calls:6d} calls  mean {mean:6d} ({mean * us:6.2f} us)  max {worst:6d} "
              f"({worst * us:6.2f} us){where}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
