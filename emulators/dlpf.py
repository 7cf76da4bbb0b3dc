"""The MPU-6050's samples as the host makes them: the source's samples at the chip's sample instants
through the digital low-pass filter (DLPF_CFG, docs/sensors.md §3.5), a first-order low-pass at the
configured bandwidth plus a pure delay, stepped at the sample clock (``ImuSampler``, over ``LowPass``).
The Python MPU6050 (the reference) and the chip core's host-side producer (emulators/chips/board.py)
both take their samples from an ImuSampler: the error model and the filter are physics, the register
behaviour is the chip's."""

from __future__ import annotations

import array
import math
from collections.abc import Callable, Sequence
from typing import Final, Protocol

import numpy as np

from rig.emulators import native

BLOCK: Final = native.BLOCK

#: DLPF_CFG -> (accel bandwidth Hz, accel delay s, gyro bandwidth Hz, gyro delay s), docs/sensors.md §3.5.
#: (Typed as a tuple of any length: compiled, a fixed-length one is boxed anew at every index.)
DLPF: Final[tuple[tuple[int, float, int, float], ...]] = (
    (260, 0.0, 256, 0.98e-3), (184, 2.0e-3, 188, 1.9e-3), (94, 3.0e-3, 98, 2.8e-3), (44, 4.9e-3, 42, 4.8e-3),
    (21, 8.5e-3, 20, 8.3e-3), (10, 13.8e-3, 10, 13.4e-3), (5, 19.0e-3, 5, 18.6e-3), (260, 0.0, 256, 0.98e-3))


class LowPass:
    """First-order low-pass at the DLPF bandwidth plus a pure delay, stepped at the sample clock over a
    block of samples in place. The arithmetic is in C (emulators/c/sampling.c): it runs for every sample,
    a thousand a second, whether or not anyone reads them."""

    def __init__(self) -> None:
        self._lib = native.sampling()
        self._run = native.fast().lowpass_run
        self._mem, self._addr = native.state("rig_lowpass_size")  # zeroed: no output yet, empty delay
        # the last gain (for bw, span) and delay depth (for delay, dt), as plain floats: the same every
        # block in steady sampling, so computed once (NaN: none yet)
        self._gain_bw, self._gain_span, self._gain = math.nan, math.nan, math.nan
        self._depth_delay, self._depth_dt = math.nan, math.nan
        self._depth = 0

    def _a(self, bw_hz: float, span: float) -> float:
        """The gain of the exact first-order response over ``span`` seconds."""
        if self._gain_bw != bw_hz or self._gain_span != span:
            self._gain_bw, self._gain_span = bw_hz, span
            self._gain = 1.0 - math.exp(-2.0 * math.pi * bw_hz * span)
        return self._gain

    def run(self, xs: int, n: int, stride: int, bw_hz: float, delay_s: float, dt: float) -> None:
        """Filters ``n`` samples of three float64 at address ``xs`` (``stride`` values apart) in place."""
        if self._depth_delay != delay_s or self._depth_dt != dt:
            self._depth_delay, self._depth_dt = delay_s, dt
            self._depth = max(0, round(delay_s / dt)) if dt > 0 else 0
            if self._depth > self._lib.rig_lowpass_max_depth():
                raise ValueError(f"DLPF delay {delay_s} s is more samples of {dt} s than the filter keeps")
        self._run(self._addr, n, xs, stride, self._a(bw_hz, dt), self._depth)

    def catch_up(self, x: int, bw_hz: float, span: float) -> None:
        """Advances the filter over ``span`` seconds of the input held at the three float64 at ``x``,
        exactly, in one go (the delay line is refilled by the samples that follow)."""
        self._lib.rig_lowpass_catch_up(self._addr, x, self._a(bw_hz, span))


def sample_rate(config: int, smplrt_div: int) -> float:
    """The MPU-6050's sample rate (Hz) for CONFIG and SMPLRT_DIV: the gyro rate (8 kHz at DLPF_CFG 0 and
    7, else 1 kHz) over 1 + SMPLRT_DIV."""
    cfg = config & 0x07
    gyro_rate = 8000.0 if cfg in (0, 7) else 1000.0
    return gyro_rate / (1 + smplrt_div)


class ImuSample(Protocol):
    """What an IMU source gives for one instant (emulators.mpu6050.ImuTruth)."""

    @property
    def accel(self) -> tuple[float, float, float]: ...

    @property
    def gyro(self) -> tuple[float, float, float]: ...

    @property
    def temperature_c(self) -> float: ...


class ImuSampler:
    """``source`` (an ImuModel, whose ``sample_block`` takes a block at once, or any function of time
    giving an ImuSample) at the sample instants, through the DLPF when ``dlpf``: a block of up to BLOCK
    samples at a time into the rows of ``block`` (accel xyz, gyro xyz, die °C). The instants are a
    running sum of the period from ``next_t``, the float time of the next one. ``next_t`` lives in a cell
    (``next_t_addr``) that the lockstep fast path (rig/lockstep/imu_feed.c) reads and moves in place."""

    def __init__(self, source: Callable[[float], ImuSample], dlpf: bool = True) -> None:
        self.source, self.dlpf = source, dlpf
        self.block = np.zeros((BLOCK, 7))
        self.block_addr: int = self.block.ctypes.data
        self._next = array.array("d", [0.0])
        self.next_t_addr: int = self._next.buffer_info()[0]
        self._accel_f, self._gyro_f = LowPass(), LowPass()

    @property
    def next_t(self) -> float:
        return self._next[0]

    @next_t.setter
    def next_t(self, t: float) -> None:
        self._next[0] = t

    def reset_filters(self) -> None:
        """DEVICE_RESET / power-on: the filters start again."""
        self._accel_f, self._gyro_f = LowPass(), LowPass()

    def take(self, n: int, period: float, cfg: int, keeps_all: bool) -> tuple[int, list[float]]:
        """Samples the next of ``n`` due instants, ``period`` apart, at DLPF_CFG ``cfg``: at most a block,
        into ``block``'s first rows. Returns how many of the n instants that used up and the block's float
        times. With nothing that keeps every sample (``keeps_all`` false: no FIFO, no aux master) a wait of
        more than BLOCK instants needs only its last BLOCK, enough to refill the DLPF's delay line: the
        filters move over the rest in one exact step with the input held at the first skipped sample
        (LowPass.catch_up)."""
        a_bw, a_delay, g_bw, g_delay = DLPF[cfg & 0x07]
        skip = 0
        if n > BLOCK and not keeps_all:
            skip = n - BLOCK
            self.next_t += skip * period
            n = BLOCK
            if self.dlpf:
                self._take((self.next_t,))
                self._accel_f.catch_up(self.block_addr, a_bw, skip * period)
                self._gyro_f.catch_up(self.block_addr + 24, g_bw, skip * period)
        m = min(n, BLOCK)
        times = []
        t = self.next_t
        for _ in range(m):
            times.append(t)
            t += period
        self.next_t = t
        self._take(times)
        if self.dlpf:
            self._accel_f.run(self.block_addr, m, 7, a_bw, a_delay, period)
            self._gyro_f.run(self.block_addr + 24, m, 7, g_bw, g_delay, period)
        return skip + m, times

    def _take(self, times: Sequence[float]) -> None:
        take_samples(self.source, times, self.block)


def take_samples(source: Callable[[float], ImuSample], times: Sequence[float], out: np.ndarray) -> None:
    """The IMU source's samples at ``times`` into ``out``'s first rows (7 columns: accel, gyro, die
    temperature): in one call for an ImuModel, one by one for a plain function of time (tests, traces)."""
    take = getattr(source, "sample_block", None)
    if take is not None:
        take(times, out)
        return
    for i, t in enumerate(times):
        s = source(t)
        out[i] = (*s.accel, *s.gyro, s.temperature_c)
