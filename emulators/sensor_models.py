"""Sensor error models between plant truth and the devices: mounting rotation, scale and
misalignment, bias and bias random walk (the gyro drift seed 002 eq. 2 models as b' = w), white noise
by spectral density, temperature sensitivity, magnetic disturbance, and the scheduled signal faults.
Deterministic for a given seed. The devices call a model at their own sample instants."""

from __future__ import annotations

import ctypes
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from rig.emulators import native
from rig.emulators.faults import FaultSet
from rig.emulators.mpu6050 import ImuTruth
from rig.emulators.ms5611 import BaroTruth

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
        """Scale/misalignment times mounting: the one matrix each sample is multiplied by."""
        s, m = self.scale_misalignment, self.mounting
        def row(i: int) -> tuple[float, float, float]:
            a, b, c = [float(sum([s[i][k] * m[k][j] for k in range(3)])) for j in range(3)]
            return (a, b, c)

        return tuple(row(i) for i in range(3))


Vec3 = tuple[float, float, float]
BLOCK = native.BLOCK


class Normals:
    """Standard normal draws taken from the generator in blocks (one numpy call per thousands of values,
    not one per sample). The sequence is the generator's own, value by value, whatever the block size."""

    BLOCK = 3072

    def __init__(self, rng: np.random.Generator) -> None:
        self._rng = rng
        self.buf = np.empty(0)
        self.pos = 0  # the first unread value in ``buf``
        # ``buf`` as Python floats, made when take() first meets a block: slicing a list of three costs a
        # tenth of slicing the array and converting (2.6 k instructions a call: the wind's, at 100 Hz)
        self._values: list[float] = []
        self._values_of = self.buf

    def reserve(self, n: int) -> None:
        """Makes sure ``buf`` holds at least ``n`` unread values from ``pos`` on."""
        if self.pos + n > len(self.buf):
            self.buf = np.concatenate([self.buf[self.pos:], self._rng.standard_normal(max(self.BLOCK, n))])
            self.pos = 0

    def take(self, n: int) -> list[float]:
        self.reserve(n)
        if self._values_of is not self.buf:
            self._values, self._values_of = self.buf.tolist(), self.buf
        pos = self.pos
        self.pos = pos + n
        return self._values[pos:pos + n]


class _Channel:
    """One triaxial sensor's errors and their state (the random walk, the last sample time), kept in C
    (emulators/c/sampling.c, which has the arithmetic). The normals it draws come from its own
    generator's Normals, whose unread part C reads in place."""

    def __init__(self, errors: AxisErrors, faults: FaultSet, rng: np.random.Generator) -> None:
        self.errors, self.faults = errors, faults
        self.normals = Normals(rng)
        self._lib = native.sampling()
        self._mem, self.addr = native.state("rig_channel_size")
        m = [v for row in errors.matrix() for v in row]
        self._lib.rig_channel_init(self.addr, (ctypes.c_double * 9)(*m), (ctypes.c_double * 3)(*errors.bias),
                                   errors.bias_random_walk, errors.noise_density, errors.temp_coefficient)
        self._t, self._in, self._out = ctypes.c_double(), (ctypes.c_double * 3)(), (ctypes.c_double * 3)()
        self._temp = ctypes.c_double()
        self._addrs = tuple(ctypes.addressof(x) for x in (self._t, self._in, self._temp, self._out))
        self._measure = native.fast().channel_measure

    def refill(self, need: int) -> None:
        """Gives C at least ``need`` unread normals (C has read up to where it says)."""
        nm = self.normals
        nm.pos = len(nm.buf) - self._lib.rig_channel_normals_left(self.addr)
        nm.reserve(need)
        self._lib.rig_channel_normals(self.addr, nm.buf.ctypes.data + 8 * nm.pos, len(nm.buf) - nm.pos)

    def measure(self, t: float, truth: Vec3, temperature_c: float) -> Vec3:
        """One sample, faults applied (the magnetometer's way: tens of samples a second)."""
        self._t.value = t
        self._in[:] = list(truth)
        self._temp.value = temperature_c
        t_at, in_at, temp_at, out_at = self._addrs
        while self._measure(self.addr, 1, t_at, in_at, temp_at, out_at):
            self.refill(6)
        return self.faults.apply(t, tuple(self._out))  # type: ignore[return-value]


TruthFn = Callable[[float], Mapping[str, float]]


class TruthRow(Mapping[str, float]):
    """One plant output row (a list, laid out by ``index``) seen as a mapping, with no dict built per
    sample."""

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


class TruthTable(Protocol):
    """Plant truth as C reads it: a row of float64 per sample instant, the same column for a name in every
    row. The world keeps its plant history this way; ``FunctionTable`` makes one of a truth function."""

    def column(self, name: str) -> int:
        """The column of ``name`` (KeyError when there is none)."""
        ...

    def row_addresses(self, times: Sequence[float]) -> list[int]:
        """The address of the row for each sample instant (valid until the table next changes)."""
        ...


class FunctionTable:
    """A truth function seen as a table: each row asked for is evaluated and written to scratch rows.
    ``defaults`` stand in for names the function's mappings may lack."""

    def __init__(self, fn: TruthFn, names: Sequence[str], defaults: Mapping[str, float]) -> None:
        self.fn, self.names, self.defaults = fn, tuple(names), dict(defaults)
        self._rows = np.zeros((BLOCK, len(self.names)))
        self._addr, self._stride = self._rows.ctypes.data, self._rows.strides[0]

    def column(self, name: str) -> int:
        return self.names.index(name)

    def row_addresses(self, times: Sequence[float]) -> list[int]:
        for i, t in enumerate(times):
            tr = self.fn(t)
            self._rows[i] = [tr.get(n, self.defaults[n]) if n in self.defaults else tr[n] for n in self.names]
        return [self._addr + i * self._stride for i in range(len(times))]


IMU_TRUTH = ("fx", "fy", "fz", "p", "q", "r", "temperature")
AIR_TEMPERATURE_C = 15.0  # when the truth has no temperature (a bare test function)


@dataclass
class ImuModel:
    """Source for the MPU-6050: plant truth (fx fy fz, p q r, temperature) -> sensor-frame samples.
    ``truth`` is a truth function or, faster, a TruthTable (what the world hands it)."""

    truth: TruthFn | TruthTable
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
        # (a table is told by its methods: mypyc cannot compile a runtime-checkable Protocol)
        truth = self.truth
        table: TruthTable = truth if hasattr(truth, "row_addresses") else FunctionTable(  # type: ignore[assignment]
            truth, IMU_TRUTH, {"temperature": AIR_TEMPERATURE_C})
        self._table = table
        self._cols = (ctypes.c_int32 * 7)(*[table.column(n) for n in IMU_TRUTH])
        self._cols_addr = ctypes.addressof(self._cols)
        self._measure = native.fast().imu_measure  # (the times and row addresses as Python sequences)
        self._out: np.ndarray | None = None
        self._out_addr = 0
        self._one = np.zeros((1, 7))

    def sample_block(self, times: Sequence[float], out: np.ndarray) -> None:
        """Takes the samples at ``times`` (at most BLOCK, in order) into ``out``'s first rows: accel xyz
        (m/s²) and gyro xyz (rad/s) in the sensor frame, die temperature (°C). ``out``: float64, C order,
        7 columns."""
        n = len(times)
        if out is not self._out:
            if out.dtype != np.float64 or not out.flags.c_contiguous or out.ndim != 2 or out.shape[1] != 7:
                raise ValueError("ImuModel.sample_block needs a C-ordered float64 array of 7 columns")
            self._out, self._out_addr = out, out.ctypes.data
        if not 0 <= n <= min(BLOCK, len(out)):
            raise ValueError(f"ImuModel.sample_block takes 0..{min(BLOCK, len(out))} samples, not {n}")
        rows = self._table.row_addresses(times)
        while short := self._measure(self._a.addr, self._g.addr, times, rows, self._cols_addr,
                                     self.die_offset_c, self._out_addr):
            (self._a if short == 1 else self._g).refill(6 * n)
        for ch, col in ((self._a, 0), (self._g, 3)):
            if ch.faults.faults:
                for i, t in enumerate(times):
                    out[i, col:col + 3] = ch.faults.apply(t, tuple(out[i, col:col + 3].tolist()))

    def __call__(self, t: float) -> ImuTruth:
        self.sample_block((t,), self._one)
        ax, ay, az, gx, gy, gz, temp = self._one[0].tolist()
        return ImuTruth((ax, ay, az), (gx, gy, gz), temp)


def no_disturbance(t: float) -> tuple[float, float, float]:
    """MagModel's default disturbance: none (a named function, so that the lockstep fast path can tell
    it from a scenario's and make the samples in C, rig/lockstep/mag_feed.c)."""
    return (0.0, 0.0, 0.0)


@dataclass
class MagModel:
    """Source for the HMC5883L: plant field (mag_x..z, body, gauss) -> sensor frame, plus hard iron
    (bias), soft iron (scale_misalignment) and a scheduled disturbance field (body, gauss)."""

    truth: TruthFn
    errors: AxisErrors = field(default_factory=AxisErrors)
    faults: FaultSet = field(default_factory=FaultSet)
    disturbance: Callable[[float], tuple[float, float, float]] = no_disturbance
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
