"""Sensor error models between plant truth and the devices: mounting rotation, scale and
misalignment, bias and bias random walk (the gyro drift seed 002 eq. 2 models as b' = w), white noise
by spectral density, temperature sensitivity, magnetic disturbance, and the scheduled signal faults.
Deterministic for a given seed. The devices call a model at their own sample instants."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from operator import itemgetter

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

    def matrix(self) -> tuple[tuple[float, float, float], ...]:
        """Scale/misalignment times mounting, as plain floats: a 3x3 product per sample is cheaper in
        Python than a numpy call at these sizes, and a sample is taken a thousand times a second."""
        s, m = self.scale_misalignment, self.mounting
        return tuple(
            tuple(float(sum(s[i][k] * m[k][j] for k in range(3))) for j in range(3)) for i in range(3)
        )  # type: ignore[return-value]


class Normals:
    """Standard normal draws taken from the generator in blocks (one numpy call per thousand values, not
    one per sample). The sequence is the generator's own, value by value, whatever the block size."""

    BLOCK = 3072

    def __init__(self, rng: np.random.Generator) -> None:
        self._rng = rng
        self._buf: list[float] = []
        self._i = 0

    def take(self, n: int) -> list[float]:
        if self._i + n > len(self._buf):
            self._buf = self._buf[self._i:] + self._rng.standard_normal(max(self.BLOCK, n)).tolist()
            self._i = 0
        out = self._buf[self._i:self._i + n]
        self._i += n
        return out


Vec3 = tuple[float, float, float]


@dataclass
class _Channel:
    errors: AxisErrors
    faults: FaultSet
    rng: np.random.Generator
    walk: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    last_t: float | None = None

    def __post_init__(self) -> None:
        self.m = self.errors.matrix()
        self.normals = Normals(self.rng)

    def measure(self, t: float, truth_body: Vec3, temperature_c: float) -> Vec3:
        # unrolled over the three axes: this runs twice per IMU sample, a thousand samples a second
        dt = 0.0 if self.last_t is None else max(0.0, t - self.last_t)
        self.last_t = t
        e = self.errors
        w0, w1, w2 = self.walk
        if e.bias_random_walk and dt > 0:
            s = e.bias_random_walk * math.sqrt(dt)
            z0, z1, z2 = self.normals.take(3)
            w0, w1, w2 = self.walk = [w0 + s * z0, w1 + s * z1, w2 + s * z2]
        x, y, z = truth_body
        b0, b1, b2 = e.bias
        c = e.temp_coefficient * (temperature_c - 25.0)
        r0, r1, r2 = self.m
        v0 = r0[0] * x + r0[1] * y + r0[2] * z + b0 + w0 + c
        v1 = r1[0] * x + r1[1] * y + r1[2] * z + b1 + w1 + c
        v2 = r2[0] * x + r2[1] * y + r2[2] * z + b2 + w2 + c
        if e.noise_density and dt > 0:
            s = e.noise_density / math.sqrt(2.0 * dt)
            n0, n1, n2 = self.normals.take(3)
            v0, v1, v2 = v0 + s * n0, v1 + s * n1, v2 + s * n2
        return self.faults.apply(t, (v0, v1, v2))  # type: ignore[return-value]


TruthFn = Callable[[float], Mapping[str, float]]


class TruthRow(Mapping[str, float]):
    """One plant output row (a list, laid out by ``index``) seen as a mapping, with no dict built per
    sample. The IMU reads its seven values from ``row`` by position instead (``_Picker``): it does so a
    thousand times a second, and a Python-level ``__getitem__`` per value cost more than the lookup."""

    __slots__ = ("index", "row")

    def __init__(self, index: dict[str, int], row: list[float]) -> None:
        self.index, self.row = index, row

    def __getitem__(self, name: str) -> float:
        return self.row[self.index[name]]

    def get(self, name: str, default: float | None = None) -> float | None:  # type: ignore[override]
        i = self.index.get(name)
        return default if i is None else self.row[i]

    def __iter__(self) -> Iterator[str]:
        return iter(self.index)

    def __len__(self) -> int:
        return len(self.index)


class _Picker:
    """Reads ``names`` from a truth mapping as a tuple; from a TruthRow by position (resolved once per
    layout), from any other mapping by name. A missing ``optional`` name reads as its default."""

    def __init__(self, names: tuple[str, ...], optional: tuple[str, float]) -> None:
        self.names, self.optional = names, optional
        self._index: dict[str, int] | None = None
        self._get: Callable[[list[float]], tuple[float, ...]] = itemgetter(0)

    def __call__(self, tr: Mapping[str, float]) -> tuple[float, ...]:
        opt, default = self.optional
        if type(tr) is TruthRow and opt in tr.index:
            if tr.index is not self._index:
                self._index = tr.index
                self._get = itemgetter(*(tr.index[n] for n in (*self.names, opt)))
            return self._get(tr.row)
        return (*(tr[n] for n in self.names), tr.get(opt, default))


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
        self._pick = _Picker(("fx", "fy", "fz", "p", "q", "r"), ("temperature", 15.0))
        rng = np.random.default_rng(self.seed)
        self._a = _Channel(self.accel, self.accel_faults, np.random.default_rng(rng.integers(2**63)))
        self._g = _Channel(self.gyro, self.gyro_faults, np.random.default_rng(rng.integers(2**63)))

    def __call__(self, t: float) -> ImuTruth:
        fx, fy, fz, p, q, r, air_c = self._pick(self.truth(t))
        temp = air_c + self.die_offset_c
        a = self._a.measure(t, (fx, fy, fz), temp)
        g = self._g.measure(t, (p, q, r), temp)
        return ImuTruth(a, g, temp)


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
        dx, dy, dz = self.disturbance(t)
        field_body = (tr["mag_x"] + dx, tr["mag_y"] + dy, tr["mag_z"] + dz)
        return self._c.measure(t, field_body, 25.0)


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
        p = self.faults.apply(t, (p,))[0]
        return BaroTruth(p, tr["temperature"])
