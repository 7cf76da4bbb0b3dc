"""The reference FC's mixers, loaded from the C library, against the plant FMU's rotor geometry: for
each frame the plant can fly, a positive roll, pitch or yaw command must accelerate the real vehicle
about that axis only, in the positive direction (docs/design.md §3). The C test checks the mixers against
its own copy of the geometry; this one checks them against the model the rig flies."""

from __future__ import annotations

import ctypes
import subprocess
from pathlib import Path

import numpy as np
import pytest

from rig.plant.fmu import Plant
from tests.plant.helpers import HOVER_PWM, flying

REPO = Path(__file__).resolve().parents[2]
MIXERS = {0: 0, 1: 1}  # plant frame parameter -> the FC's enum mixer_kind


@pytest.fixture(scope="module")
def fcalgo() -> ctypes.CDLL:
    subprocess.run(["make", "-s", "-C", str(REPO / "dut")], check=True)
    lib = ctypes.CDLL(str(REPO / "build" / "dut" / "libfcalgo.so"))
    lib.mix.argtypes = [ctypes.c_int] + [ctypes.c_double] * 4 + [ctypes.POINTER(ctypes.c_double)]
    return lib


def body_rates_after(plant: Plant, pwm: np.ndarray, seconds: float = 0.05) -> np.ndarray:
    for i in range(4):
        plant.u[plant.u_index[f"pwm{i + 1}_us"]] = pwm[i]
    for _ in range(round(seconds / 0.001)):
        plant.step(0.001)
    return np.array([plant.y[plant.y_index[n]] for n in ("p", "q", "r")])


@pytest.mark.parametrize("frame", [0, 1], ids=["plus", "x"])
@pytest.mark.parametrize("axis", [0, 1, 2], ids=["roll", "pitch", "yaw"])
def test_a_positive_command_turns_the_plant_positively_about_that_axis_only(fcalgo: ctypes.CDLL, frame: int,
                                                                            axis: int) -> None:
    out = (ctypes.c_double * 4)()
    cmd = [0.0, 0.0, 0.0]
    cmd[axis] = 40.0
    fcalgo.mix(MIXERS[frame], HOVER_PWM - 1000, *cmd, out)
    with flying(frame=frame) as plant:
        rates = body_rates_after(plant, 1000 + np.array(out[:]))
    assert rates[axis] > 0.01   # yaw is the slowest: Izz is 22 times Ixx
    others = np.delete(rates, axis)
    assert np.all(np.abs(others) < 1e-3 * abs(rates[axis]) + 1e-9)
