"""Sensor error models between plant truth and the devices: mounting rotation, scale and
misalignment, bias and bias random walk (the gyro drift seed 002 eq. 2 models as b' = w), white noise
by spectral density, temperature sensitivity, magnetic disturbance, and the scheduled signal faults.
Deterministic for a given seed. The devices call a model at their own sample instants."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from emulators.faults import FaultSet
from emulators.mpu6050 import ImuTruth
from emulators.ms5611 import BaroTruth

#: Body FRD -> sensor frame of a board lying flat, component side up: x forward, y left, z up.
#: A level, resting MPU-6050 then reads +1 g on Z (the plant's specific force is -g on body z).
FLAT_ON_BOARD = ((1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, -1.0))


@dataclass
class AxisErrors:
    """Errors of one triaxial sensor, in the sensor's own units (m/s², rad/s, gauss, Pa)."""

    mounting: tuple[tuple[float, float, float], ...] = FLAT_ON_BOARD
    scale_misalignment: tuple[tuple[float, float, float], ...] = ((1, 0, 0), (0, 1, 0), (0, 0, 1))
    bias: tuple[float, float, float] = (0.0, 0.0, 0.0)
    bias_random_walk: float = 0.0      # units/s/sqrt(Hz): bias' = w, w white
    noise_density: float = 0.0         # units/sqrt(Hz)
    temp_coefficient: float = 0.0      # bias change per degC away from 25 degC

    def matrix(self) -> np.ndarray:
        return np.asarray(self.scale_misalignment, float) @ np.asarray(self.mounting, float)


@dataclass
class _Channel:
    errors: AxisErrors
    faults: FaultSet
    rng: np.random.Generator
    m: np.ndarray = field(init=False)
    walk: np.ndarray = field(default_factory=lambda: np.zeros(3))
    last_t: float | None = None

    def __post_init__(self) -> None:
        self.m = self.errors.matrix()

    def measure(self, t: float, truth_body: np.ndarray, temperature_c: float) -> np.ndarray:
        dt = 0.0 if self.last_t is None else max(0.0, t - self.last_t)
        self.last_t = t
        e = self.errors
        if e.bias_random_walk and dt > 0:
            self.walk = self.walk + self.rng.normal(0.0, e.bias_random_walk * math.sqrt(dt), 3)
        value = self.m @ truth_body + np.asarray(e.bias) + self.walk
        value = value + e.temp_coefficient * (temperature_c - 25.0)
        if e.noise_density and dt > 0:
            value = value + self.rng.normal(0.0, e.noise_density / math.sqrt(2.0 * dt), 3)
        return self.faults.apply(t, value)


TruthFn = Callable[[float], dict[str, float]]


def _vec(truth: dict[str, float], *names: str) -> np.ndarray:
    return np.array([truth[n] for n in names], float)


@dataclass
class ImuModel:
    """Source for the MPU-6050: plant truth (fx fy fz, p q r, temperature) -> sensor-frame ImuTruth."""

    truth: TruthFn
    accel: AxisErrors = field(default_factory=AxisErrors)
    gyro: AxisErrors = field(default_factory=AxisErrors)
    accel_faults: FaultSet = field(default_factory=FaultSet)
    gyro_faults: FaultSet = field(default_factory=FaultSet)
    die_offset_c: float = 10.0        # the die runs warmer than the air
    seed: int = 0

    def __post_init__(self) -> None:
        rng = np.random.default_rng(self.seed)
        self._a = _Channel(self.accel, self.accel_faults, np.random.default_rng(rng.integers(2**63)))
        self._g = _Channel(self.gyro, self.gyro_faults, np.random.default_rng(rng.integers(2**63)))

    def __call__(self, t: float) -> ImuTruth:
        tr = self.truth(t)
        temp = tr.get("temperature", 15.0) + self.die_offset_c
        a = self._a.measure(t, _vec(tr, "fx", "fy", "fz"), temp)
        g = self._g.measure(t, _vec(tr, "p", "q", "r"), temp)
        return ImuTruth(tuple(a), tuple(g), temp)  # type: ignore[arg-type]


@dataclass
class MagModel:
    """Source for the HMC5883L: plant field (mag_x..z, body, gauss) -> sensor frame, plus hard iron
    (bias), soft iron (scale_misalignment) and a scheduled disturbance field (body, gauss)."""

    truth: TruthFn
    errors: AxisErrors = field(default_factory=AxisErrors)
    faults: FaultSet = field(default_factory=FaultSet)
    disturbance: Callable[[float], tuple[float, float, float]] = lambda t: (0.0, 0.0, 0.0)
    seed: int = 1

    def __post_init__(self) -> None:
        self._c = _Channel(self.errors, self.faults, np.random.default_rng(self.seed))

    def __call__(self, t: float) -> tuple[float, float, float]:
        tr = self.truth(t)
        field_body = _vec(tr, "mag_x", "mag_y", "mag_z") + np.asarray(self.disturbance(t), float)
        return tuple(self._c.measure(t, field_body, 25.0))  # type: ignore[return-value]


@dataclass
class BaroModel:
    """Source for the MS5611: plant pressure and temperature plus offset, drift, noise and faults
    (applied to pressure)."""

    truth: TruthFn
    offset_pa: float = 0.0
    drift_pa_per_s: float = 0.0
    noise_pa: float = 0.0
    faults: FaultSet = field(default_factory=FaultSet)
    seed: int = 2

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.seed)

    def __call__(self, t: float) -> BaroTruth:
        tr = self.truth(t)
        p = tr["pressure"] + self.offset_pa + self.drift_pa_per_s * t
        if self.noise_pa:
            p += self._rng.normal(0.0, self.noise_pa)
        p = float(self.faults.apply(t, np.array([p]))[0])
        return BaroTruth(p, tr["temperature"])
