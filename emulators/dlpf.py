"""The MPU-6050's digital low-pass filter (DLPF_CFG, docs/sensors.md §3.5) as the host runs it: a first-order
low-pass at the configured bandwidth plus a pure delay, stepped at the sample clock. The Python MPU6050
(the reference) and the chip core's host-side producer (emulators/chips/board.py) both use it: the
filter is physics, the register behaviour is the chip's."""

from __future__ import annotations

import math

from emulators import native

#: DLPF_CFG -> (accel bandwidth Hz, accel delay s, gyro bandwidth Hz, gyro delay s), docs/sensors.md §3.5.
DLPF = ((260, 0.0, 256, 0.98e-3), (184, 2.0e-3, 188, 1.9e-3), (94, 3.0e-3, 98, 2.8e-3),
        (44, 4.9e-3, 42, 4.8e-3), (21, 8.5e-3, 20, 8.3e-3), (10, 13.8e-3, 10, 13.4e-3),
        (5, 19.0e-3, 5, 18.6e-3), (260, 0.0, 256, 0.98e-3))


class LowPass:
    """First-order low-pass at the DLPF bandwidth plus a pure delay, stepped at the sample clock over a
    block of samples in place. The arithmetic is in C (emulators/c/sampling.c): it runs for every sample,
    a thousand a second, whether or not anyone reads them."""

    def __init__(self) -> None:
        self._lib = native.sampling()
        self._run = native.fast().lowpass_run
        self._mem, self._addr = native.state("rig_lowpass_size")  # zeroed: no output yet, empty delay
        self._gain: tuple[float, float, float] = (math.nan, math.nan, math.nan)  # (bw, span, a)
        self._depth_for: tuple[float, float] = (math.nan, math.nan)  # (delay, dt) of _depth
        self._depth = 0

    def _a(self, bw_hz: float, span: float) -> float:
        """The gain of the exact first-order response over ``span`` seconds."""
        bw, sp, a = self._gain
        if bw != bw_hz or sp != span:  # the same every block in steady sampling: computed once
            a = 1.0 - math.exp(-2.0 * math.pi * bw_hz * span)
            self._gain = (bw_hz, span, a)
        return a

    def run(self, xs: int, n: int, stride: int, bw_hz: float, delay_s: float, dt: float) -> None:
        """Filters ``n`` samples of three float64 at address ``xs`` (``stride`` values apart) in place."""
        if self._depth_for != (delay_s, dt):
            self._depth_for = (delay_s, dt)
            self._depth = max(0, round(delay_s / dt)) if dt > 0 else 0
            if self._depth > self._lib.rig_lowpass_max_depth():
                raise ValueError(f"DLPF delay {delay_s} s is more samples of {dt} s than the filter keeps")
        self._run(self._addr, n, xs, stride, self._a(bw_hz, dt), self._depth)

    def catch_up(self, x: int, bw_hz: float, span: float) -> None:
        """Advances the filter over ``span`` seconds of the input held at the three float64 at ``x``,
        exactly, in one go (the delay line is refilled by the samples that follow)."""
        self._lib.rig_lowpass_catch_up(self._addr, x, self._a(bw_hz, span))
