"""Steps per second of the plant, four ways, in one run (printed, never asserted).

1. the C physics alone (build/bench/physics_bench, made by `make bench`);
2. the rig's fast path, `plant.Plant.step` (raw FMI pointers, preallocated buffers);
3. `plant.Plant.step_many` four steps a call, as the world steps between two requests of a 250 Hz FC
   (one call into C for the four; inputs written once per call);
4. fmpy's high-level `setReal/doStep/getReal` with the same inputs and outputs.

Each does 1 ms steps with all outputs read (and, but for 3, all inputs written each step).
Usage: python bench/plant_rates.py [--steps N].
"""

from __future__ import annotations

import argparse
import subprocess
import time
from pathlib import Path

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from rig.plant import DEFAULT_FMU, Plant

ROOT = Path(__file__).resolve().parent.parent
HOVER = 1511.0


def c_physics(steps: int) -> float:
    exe = ROOT / "build" / "bench" / "physics_bench"
    out = subprocess.run([str(exe), str(steps * 10)], capture_output=True, text=True, check=True)
    return float(out.stdout.split()[1])


def fast_path(steps: int) -> float:
    with Plant(params={"pd0": -100.0}, inputs={f"pwm{i}_us": HOVER for i in range(1, 5)}) as plant:
        plant.run(0.1, 1e-3)  # warm up
        start = time.perf_counter()
        for _ in range(steps):
            plant.step(1e-3)
        return steps / (time.perf_counter() - start)


def step_many(steps: int) -> float:
    with Plant(params={"pd0": -100.0}, inputs={f"pwm{i}_us": HOVER for i in range(1, 5)}) as plant:
        plant.run(0.1, 1e-3)  # warm up
        start = time.perf_counter()
        for _ in range(steps // 4):
            plant.step_many(4, 1e-3)
        return steps // 4 * 4 / (time.perf_counter() - start)


def fmpy_high_level(steps: int) -> float:
    md = read_model_description(str(DEFAULT_FMU))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(DEFAULT_FMU)), modelIdentifier="quadrotor",
                    instanceName="bench")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu.setReal([vr["pd0"]], [-100.0])
    fmu.exitInitializationMode()
    u_vr = [v.valueReference for v in md.modelVariables if v.causality == "input"]
    y_vr = [v.valueReference for v in md.modelVariables if v.causality == "output" and v.type == "Real"]
    u = [HOVER] * 4 + [0.0] * 9 + [1.0] * 4
    t = 0.0
    start = time.perf_counter()
    for _ in range(steps):
        fmu.setReal(u_vr, u)
        fmu.doStep(t, 1e-3)
        fmu.getReal(y_vr)
        t += 1e-3
    rate = steps / (time.perf_counter() - start)
    fmu.freeInstance()
    return rate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200_000)
    args = parser.parse_args()
    rates = {"C physics alone": c_physics(args.steps), "fast path (plant.Plant.step)": fast_path(args.steps),
             "plant.Plant.step_many, 4 a call": step_many(args.steps),
             "fmpy setReal/doStep/getReal": fmpy_high_level(args.steps // 4)}
    base = rates["fmpy setReal/doStep/getReal"]
    print(f"plant steps per second (1 ms steps, all outputs read), {args.steps} steps:")
    for name, rate in rates.items():
        print(f"  {name:32s} {rate:12,.0f} steps/s  {1e6 / rate:6.2f} us/step  {rate / base:6.1f}x fmpy")
    print(f"  fast path reaches {rates['fast path (plant.Plant.step)'] / rates['C physics alone']:.1%} "
          "of the C physics alone")


if __name__ == "__main__":
    main()
