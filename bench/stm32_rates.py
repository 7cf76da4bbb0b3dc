"""How fast the STM32 tier runs in lockstep (bench, not a test): simulated seconds per second of our
hover firmware (tests/stm32/firmware/hover_rate.c: 168 MHz, the gyro over I2C1 by the HAL's polling,
a 490 Hz rate loop on TIM3's interrupt, four PWM outputs), or with ``--fc`` of the reference FC
(build/stm32/fc.elf, `make stm32`: the whole GY-86 burst at 250 Hz, the estimator, the controllers),
under the rig's QEMU at -icount shift=3.

  link alone     the engine (rig/mcu/stm32_link.py) with a resting chip core, 1 ms steps, the needs
                 served: QEMU's CPU time (its process) and this process's, against the sim time
  scenario       hover_turbulence through the MCU target (the runner, the world, the session), whole run,
                 with its CPU seconds: QEMU and the session take turns, so one over their sum is the rate
                 on a machine with nothing else to do

Wall time follows the neighbours on a shared machine; CPU seconds are the steadier figure. Needs
`make stm32-engine stm32-test-firmware`.

    .venv/bin/python bench/stm32_rates.py [--fc]
"""

from __future__ import annotations

import resource
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rig.emulators.chips.board import build_chip_board  # noqa: E402
from rig.emulators.mpu6050 import ImuTruth  # noqa: E402
from rig.emulators.ms5611 import BaroTruth  # noqa: E402
from rig.mcu import board as boards  # noqa: E402
from rig.mcu import stm32_engine  # noqa: E402
from rig.mcu.stm32_link import Stm32Config, Stm32Engine  # noqa: E402
from rig.runner import run  # noqa: E402
from rig.scenarios.schema import load  # noqa: E402
from rig.targets.mcu import McuTarget  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
HOVER_RATE = REPO / "build" / "stm32" / "test" / "hover_rate.elf"
REFERENCE_FC = REPO / "build" / "stm32" / "fc.elf"
LINK_SIM_S = 5.0
#: the published precedent (ArduPilot's STM32 build on Renode, 2026) and the AVR tier (bench/mcu_rates.py)
ANCHOR = ("ArduPilot on Renode 0.03x stock, 0.2x patched; the AVR tier's reference FC 6.8x "
          "(bench/mcu_rates.py); the goal 5x")


def cpu(who: int) -> float:
    usage = resource.getrusage(who)
    return usage.ru_utime + usage.ru_stime


def link_alone(firmware: Path) -> tuple[float, float, float]:
    """(sim s per wall s, QEMU's CPU s and this process's CPU s per sim s)"""
    chips = build_chip_board(lambda t: ImuTruth((0.0, 0.0, 9.80665), (0.0, 0.0, 0.0)),
                             lambda t: (0.2, 0.0, 0.4), lambda t: BaroTruth(101325.0, 20.0))
    binary = stm32_engine.cached_binary()
    engine = Stm32Engine(Stm32Config(boards.load("stm32f405-gy86"), firmware, binary), chips)
    wall0, own0, children0 = time.perf_counter(), cpu(resource.RUSAGE_SELF), cpu(resource.RUSAGE_CHILDREN)
    t = 0
    while t < LINK_SIM_S * 1e9:
        t += 1_000_000
        while (stop := engine.run_until(t)).kind == "need":
            chips.serve(stop.need)
        assert stop.kind == "reached", stop.describe()
        engine.pulses()
    wall, own = time.perf_counter() - wall0, cpu(resource.RUSAGE_SELF) - own0
    engine.close()  # (QEMU reaped: its CPU time is counted now)
    return LINK_SIM_S / wall, (cpu(resource.RUSAGE_CHILDREN) - children0) / LINK_SIM_S, own / LINK_SIM_S


def scenario(firmware: Path, name: str = "hover_turbulence") -> tuple[float, float, float]:
    """(sim s per wall s, QEMU's CPU s and this process's CPU s per sim s) of the whole run"""
    sc = load(REPO / "scenarios" / "library" / f"{name}.toml")
    wall0, own0, children0 = time.perf_counter(), cpu(resource.RUSAGE_SELF), cpu(resource.RUSAGE_CHILDREN)
    run(sc, McuTarget("stm32f405-gy86", firmware), 0)
    wall, own = time.perf_counter() - wall0, cpu(resource.RUSAGE_SELF) - own0
    return sc.duration / wall, (cpu(resource.RUSAGE_CHILDREN) - children0) / sc.duration, own / sc.duration


def main() -> int:
    firmware = REFERENCE_FC if "--fc" in sys.argv[1:] else HOVER_RATE
    if stm32_engine.cached_binary() is None or not firmware.is_file():
        print("needs `make stm32-engine stm32-test-firmware stm32` first", file=sys.stderr)
        return 1
    print(f"{firmware.relative_to(REPO)}")
    speed, qemu_cpu, own_cpu = link_alone(firmware)
    print(f"link alone: {speed:.2f}x real time; per sim second {qemu_cpu:.2f} s of QEMU's CPU, "
          f"{own_cpu:.2f} s of the session's")
    speed, qemu_cpu, own_cpu = scenario(firmware)
    print(f"scenario hover_turbulence: {speed:.2f}x real time; per sim second {qemu_cpu:.2f} s of QEMU's "
          f"CPU, {own_cpu:.2f} s of the session's: {1 / (qemu_cpu + own_cpu):.2f}x on CPU time (the two "
          "take turns in lockstep: the rate of a machine with nothing else to do)")
    print(f"anchors: {ANCHOR}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
