"""What a bench session streams to the bridge: the three chips' samples, made by the same sensor models
and DLPF as in lockstep (emulators/chips/board.py), each stamped with the bridge time from which it
holds (docs/design.md §8 "Time", docs/bench.md "The lead").

**IMU.** The host follows the emulated MPU-6050's sample clock from the board's register writes
(``MpuClock``: it wakes at the PWR_MGMT_1 write that clears SLEEP, a rate written takes effect after
the next instant of the old rate, DEVICE_RESET puts it back to sleep: the chip core's own rules) and
sends one sample per instant ``c``, ``lead`` samples ahead of it (lead = ⌈Δ / period⌉), valid from
``c − MARGIN_US`` so that the chip at ``c`` reads exactly that sample whatever the jitter of the time
map. The sample for ``c`` must be the DLPF's output at ``c``: a first-order low-pass of the input
``delay`` earlier (``depth`` = delay / period samples). The host takes the input at the event's time,
``c − lead`` samples, and filters it with a delay line ``lead`` samples shorter, so the output for ``c``
is the filtered input of ``c − depth`` samples: the lockstep value, with nothing predicted, whenever
depth ≥ lead (DLPF_CFG ≥ 2 at Δ = 3 ms, 1 kHz). Below that (DLPF_CFG 0, 1 or 7) the input is taken
at its own instant, past the world's newest step: its truth is held there (a zeroth-order
extrapolation: a linear one multiplied the sensor noise by up to five at these lags), its noise and
faults are its instant's; the run's notes say so. The chip faster than
MAX_IMU_HZ (8 kHz without the DLPF) gets every n-th instant: the others hold (counted as underruns).

**Magnetometer and barometer.** Their samples are streamed on the host's grid, MAG_PERIOD_S and
BARO_PERIOD_S apart, valid Δ after the instant their values were taken (their readings lag by Δ; the
field and the pressure change far slower than that). The two grids start MAG_PHASE_S and BARO_PHASE_S
after sim time 0, off the whole milliseconds on which the recorder, the wind and the sticks run and off
each other's: events due at one instant run one after another, the last of a stack late by the others'
work. A chip that measures only now and then (the HMC5883L idle, the MS5611 between commands) finds the
newest: the bridge's queues keep the newest when full.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Final

import numpy as np

from rig.bridge.messages import BY_NAME
from rig.emulators import ms5611
from rig.emulators.chips.board import BaroFeed
from rig.emulators.dlpf import DLPF, LowPass, take_samples
from rig.emulators.mpu6050 import CONFIG, SMPLRT_DIV

if TYPE_CHECKING:
    from rig.bridge.session import BenchSession

PWR_MGMT_1: Final = 0x6B
MPU_ADDR: Final = 0x68
BARO_ADDR: Final = 0x77
MARGIN_US: Final = 100       # a sample is valid this long before the instant it is for
MAX_IMU_HZ: Final = 1000.0   # the most IMU samples a second the host streams
ASLEEP_PERIOD_S: Final = 0.01  # while the MPU sleeps: a fresh sample this often, for the instant it wakes
MAG_PERIOD_S: Final = 0.005
BARO_PERIOD_S: Final = 0.002
MAG_PHASE_S: Final = 0.00125   # (never on the barometer's grid, 0.5 ms + 2 ms k, nor a whole ms)
BARO_PHASE_S: Final = 0.0005
NS: Final = 1_000_000_000
IMU_SAMPLE, MAG_SAMPLE, BARO_SAMPLE = BY_NAME["IMU_SAMPLE"], BY_NAME["MAG_SAMPLE"], BY_NAME["BARO_SAMPLE"]


def mpu_period_us(config: int, smplrt_div: int) -> int:
    """The MPU-6050's sample period in µs: an 8 kHz gyro rate without the DLPF (DLPF_CFG 0 or 7), else
    1 kHz, divided by 1 + SMPLRT_DIV (emulators/chips/mpu6050.c, period_ns)."""
    base = 125 if config & 0x07 in (0, 7) else 1000
    return base * (1 + smplrt_div)


@dataclass
class MpuClock:
    """The emulated MPU-6050's sample instants on the bridge's clock (µs), followed from the board's
    register writes as the chip core sets them."""

    asleep: bool = True
    config: int = 0
    smplrt_div: int = 0
    anchor_us: int = 0  # an instant of the current schedule (the wake, or the first of a new rate)

    @property
    def period_us(self) -> int:
        return mpu_period_us(self.config, self.smplrt_div)

    def write(self, t_us: int, reg: int, value: int) -> None:
        """The board wrote ``value`` to ``reg`` at bridge time ``t_us`` (a REG_WRITE)."""
        if reg == PWR_MGMT_1:
            if value & 0x80:  # DEVICE_RESET: the power-on registers, asleep
                self.asleep, self.config, self.smplrt_div = True, 0, 0
                return
            if self.asleep and not value & 0x40:  # waking: sampling starts at the write
                self.anchor_us = t_us
            self.asleep = bool(value & 0x40)
        elif reg in (CONFIG, SMPLRT_DIV):
            if not self.asleep:  # the instants up to the write keep the old rate; the next one too
                self.anchor_us = self.next_after(t_us)
            if reg == CONFIG:
                self.config = value
            else:
                self.smplrt_div = value

    def next_after(self, t_us: int) -> int:
        """The first instant after ``t_us`` (the sleeping chip has none: asked only while awake)."""
        if t_us < self.anchor_us:
            return self.anchor_us
        p = self.period_us
        return self.anchor_us + ((t_us - self.anchor_us) // p + 1) * p


@dataclass(frozen=True)
class ImuPlan:
    """What every IMU sample of one configuration needs (served step, lead, the DLPF's part not covered
    by the lead), worked out when the board writes the MPU's registers rather than a thousand times a
    second on the real-time loop."""

    cfg: int          # DLPF_CFG
    step_us: int      # the instants the host serves: every one, or every n-th above MAX_IMU_HZ
    lead: int         # Δ in samples of the served step (at least one)
    period_s: float   # step_us in seconds
    a_bw: float
    a_hold_s: float   # the accelerometer's DLPF delay left after the lead (the filter's own delay line)
    g_bw: float
    g_hold_s: float
    short: int        # samples the DLPF's delay does not cover (the input's truth held over them)
    g_delay_s: float

    @classmethod
    def of(cls, clock: MpuClock, lead_s: float) -> ImuPlan:
        p = clock.period_us
        step_us = p * max(1, math.ceil(1e6 / MAX_IMU_HZ / p - 1e-9))
        period = step_us * 1e-6
        lead = max(1, math.ceil(lead_s * 1e6 / step_us - 1e-9))
        cfg = clock.config & 0x07
        a_bw, a_delay, g_bw, g_delay = DLPF[cfg]
        a_depth, g_depth = round(a_delay / period), round(g_delay / period)
        return cls(cfg, step_us, lead, period, a_bw, max(0, a_depth - lead) * period, g_bw,
                   max(0, g_depth - lead) * period, max(lead - a_depth, lead - g_depth, 0), g_delay)


@dataclass
class StreamFigures:
    imu: int = 0
    mag: int = 0
    baro: int = 0
    imu_extrapolated: int = 0  # samples whose truth was held past the world's newest step (delay < Δ)
    notes: list[str] = field(default_factory=list)


class SampleStream:
    """Streams the world's sensor samples to a BenchSession's bridge; ``start`` schedules it, the
    session calls ``on_reg_write`` for every REG_WRITE the bridge reports."""

    def __init__(self, session: BenchSession) -> None:
        self.session = session
        board = session.world.board
        self.imu_source = board.mpu.source
        self.mag_source = board.hmc.source
        self.baro: BaroFeed = board.baro.feed
        self.lead_s = session.cfg.lead_s
        self.clock = MpuClock()
        self.plan = ImuPlan.of(self.clock, self.lead_s)
        self.figures = StreamFigures()
        self._block = np.zeros((1, 7))
        self._block_addr: int = self._block.ctypes.data
        self._accel_f, self._gyro_f = LowPass(), LowPass()
        self._next_c = 0       # the next instant the IMU chain serves (bridge µs); 0: asleep
        self._imu_epoch = 0    # bumped when the clock is re-anchored: events of an old chain stop
        self._osr = len(ms5611.OSR) - 1  # the MS5611's last OSR commanded (its noise, when modelled)
        self._extrapolating: int | None = None

    # ---- the board's writes ---------------------------------------------------------------------

    def on_reg_write(self, t_us: int, addr: int, reg: int, value: int) -> None:
        if addr == BARO_ADDR and 0x40 <= reg <= 0x58:
            self._osr = min((reg & 0x0F) // 2, len(ms5611.OSR) - 1)
            return
        if addr != MPU_ADDR or reg not in (PWR_MGMT_1, CONFIG, SMPLRT_DIV):
            return
        was_asleep, anchor, period = self.clock.asleep, self.clock.anchor_us, self.clock.period_us
        self.clock.write(t_us, reg, value)
        c = self.clock
        self.plan = ImuPlan.of(c, self.lead_s)
        if reg == PWR_MGMT_1 and value & 0x80:  # DEVICE_RESET: the DLPF starts again (as ImuFeed's)
            self._accel_f, self._gyro_f = LowPass(), LowPass()
        if c.asleep:
            if not was_asleep:
                self._restart_imu(None)
        elif was_asleep or (c.anchor_us, c.period_us) != (anchor, period):
            # the chip's schedule changed: serve it from its first instant (past ones are sent at once)
            self._restart_imu(c.anchor_us)

    # ---- scheduling -----------------------------------------------------------------------------

    def start(self) -> None:
        s = self.session
        s.at(MAG_PHASE_S, self._mag_tick)
        s.at(BARO_PHASE_S, self._baro_tick)
        self._restart_imu(None)

    def _restart_imu(self, first_instant_us: int | None) -> None:
        self._imu_epoch += 1
        epoch = self._imu_epoch
        s = self.session
        if first_instant_us is None:  # asleep: keep a fresh sample queued for the instant it wakes
            s.at(max(s.now_ns, 0) / NS, lambda sess: self._asleep_tick(epoch))
            return
        self._next_c = first_instant_us
        s.at(max(self._event_ns(first_instant_us), s.now_ns, 0) / NS, lambda sess: self._imu_tick(epoch))

    def _event_ns(self, instant_us: int) -> int:
        """The sim time at which the sample for this instant is made and sent."""
        plan = self.plan
        return self.session.to_sim_ns(instant_us) - plan.lead * plan.step_us * 1000

    # ---- the IMU ------------------------------------------------------------------------------

    def _asleep_tick(self, epoch: int) -> None:
        if epoch != self._imu_epoch:
            return
        s = self.session
        t_ns = s.now_ns
        take_samples(self.imu_source, (t_ns / NS,), self._block)
        s.send_sample(IMU_SAMPLE, t_ns + round(self.lead_s * NS), self._block[0].tolist())
        self.figures.imu += 1
        s.at(t_ns / NS + ASLEEP_PERIOD_S, lambda sess: self._asleep_tick(epoch))

    def _imu_tick(self, epoch: int) -> None:
        if epoch != self._imu_epoch:
            return
        s = self.session
        c_us = self._next_c
        plan = self.plan
        # the input's instant; past the world's newest step its truth is held (world.truth clamps), while
        # its noise and faults are those of their own instant
        now_ns = s.now_ns
        take_samples(self.imu_source, (now_ns / NS + plan.short * plan.period_s,), self._block)
        addr = self._block_addr
        self._accel_f.run(addr, 1, 7, plan.a_bw, plan.a_hold_s, plan.period_s)
        self._gyro_f.run(addr + 24, 1, 7, plan.g_bw, plan.g_hold_s, plan.period_s)
        if plan.short:
            self._note_extrapolated(plan)
        s.send_sample(IMU_SAMPLE, s.to_sim_ns(c_us - MARGIN_US), self._block[0].tolist())
        self.figures.imu += 1
        self._next_c = c_us + plan.step_us
        s.at(max(self._event_ns(self._next_c), now_ns) / NS, lambda sess: self._imu_tick(epoch))

    def _note_extrapolated(self, plan: ImuPlan) -> None:
        self.figures.imu_extrapolated += 1
        if self._extrapolating != plan.cfg:
            self._extrapolating = plan.cfg
            self.figures.notes.append(
                f"bridge: DLPF_CFG={plan.cfg} delays the gyro {plan.g_delay_s * 1e3:.2f} ms, less than the "
                f"lead Δ {self.lead_s * 1e3:.1f} ms: the IMU's truth was held over up to {plan.short} "
                f"sample(s) of {plan.step_us} µs (a lag lockstep does not have)")

    # ---- magnetometer and barometer -----------------------------------------------------------

    def _mag_tick(self, s: BenchSession) -> None:
        t_ns = s.now_ns
        s.send_sample(MAG_SAMPLE, t_ns + round(self.lead_s * NS), list(self.mag_source(t_ns / NS)))
        self.figures.mag += 1
        s.at(t_ns / NS + MAG_PERIOD_S, self._mag_tick)

    def _baro_tick(self, s: BenchSession) -> None:
        t_ns = s.now_ns
        d1, d2 = self.baro.words(t_ns / NS, self._osr)
        s.send_sample(BARO_SAMPLE, t_ns + round(self.lead_s * NS), [d1, d2])
        self.figures.baro += 1
        s.at(t_ns / NS + BARO_PERIOD_S, self._baro_tick)
