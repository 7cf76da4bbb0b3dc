"""The chip core on the rig's bus: a GY-86 (or direct) board whose three chips run in C
(emulators/chips/chip_core.h), fed by the host-side sample producers.

The core runs in demand mode: when a chip reaches a sample instant it has no sample for, the transfer
stops before it and says what it needs; the producer here makes exactly that sample, pushes it, and
the transfer runs again. The producers are the physics side of the split (docs/design.md §8):
``ImuFeed`` (the ImuModel or any IMU source, then the DLPF: the ImuSampler of emulators/dlpf.py,
the Python MPU6050's too), ``MagFeed`` (the MagModel at the measurement instant) and ``BaroFeed``
(clamping, optional OSR noise, then ms5611.encode: the core gets the raw D1/D2). They call the models
at the same float times the Python chips' clocks give (running sums of the period from the same
anchors), so a lockstep flight is bit-identical to one with the Python chips.

``ChipBoard`` keeps the interface the rig used with the Python board: ``bus.transfer`` raising
I2CNack / I2CProtocolError, ``mpu.bypass``, ``baro.prom``, the topology.
"""

from __future__ import annotations

import array
import ctypes
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Final

import numpy as np

from rig.emulators import hmc5883l, mpu6050, ms5611, native
from rig.emulators.dlpf import ImuSampler, sample_rate
from rig.emulators.faults import FaultSet
from rig.emulators.i2c_bus import I2CNack, I2CProtocolError, Msg
from rig.emulators.mpu6050 import CONFIG, SMPLRT_DIV, ImuTruth
from rig.emulators.ms5611 import BaroTruth

BLOCK: Final = native.BLOCK
#: the chip core's topologies (chip_core.h CHIP_TOPOLOGY_*): gy521 is the MPU-6050 alone
TOPOLOGIES: Final = ("gy86", "direct", "gy521")
CHIP_MPU: Final = 1
CHIP_HMC: Final = 2
CHIP_BARO: Final = 3
CHIP_OK: Final = 0
CHIP_NACK: Final = 1
CHIP_PROTOCOL: Final = 2
CHIP_NEED: Final = 3
FAULT_KINDS: Final = {"off": 1, "intermittent": 2, "garbage": 3}
#: chip_count's counters (chip_core.h CHIP_COUNT_*)
COUNTERS: Final = ("mpu_samples", "mpu_underruns", "hmc_measurements", "hmc_underruns", "baro_conversions",
                   "baro_underruns", "nacks", "mpu_resets", "hmc_anchors")
HMC_START_POWER_ON: Final = 0
HMC_START_CONTINUOUS: Final = 1
_NEVER: Final = (1 << 64) - 1

#: a need from the core: (chip, keeps_all, anchor_mpu, osr, t_thirds, hmc_start, count, anchor, epoch,
#: t_ns, period_ns, anchor_ns, target_ns)
Need = tuple[int, int, int, int, int, int, int, int, int, int, int, int, int]


class ImuFeed:
    """The MPU-6050's samples: ``source`` (an ImuModel, or any function of time giving ImuTruth) at the
    chip's sample instants, through the DLPF when ``dlpf`` (an ImuSampler, as the Python MPU6050 takes
    its samples). Only the samples the chip encodes are pushed: the last instant's, or every instant's
    while the FIFO or the aux master keeps them all."""

    def __init__(self, source: Callable[[float], ImuTruth], dlpf: bool = True) -> None:
        self.source, self.dlpf = source, dlpf
        self._sampler = ImuSampler(source, dlpf)
        self._anchor = 0
        self._epoch = 0
        self._push = native.fast().chip_push_imu
        self._cfg, self._div, self._period = -1, -1, 0.0  # the registers the sample period is for
        #: the float times of recent instants every one of which was encoded: (first_ns, period_ns, times)
        self._recent: list[tuple[int, int, list[float]]] = []
        #: serve()'s calls, in a cell the lockstep fast path reads (rig/lockstep/imu_feed.c): what it keeps
        #: of this feed (epoch, anchor, registers, period, the sampler's filters) changes only in serve(),
        #: so while the count stands it need not read them again
        self._serves = array.array("q", [0])
        self.serves_addr: int = self._serves.buffer_info()[0]

    def float_at(self, t_ns: int) -> float:
        """The float time this feed gave the sample instant at ``t_ns`` (the aux master's instants)."""
        for first, period, times in reversed(self._recent):
            k, rest = divmod(t_ns - first, period)
            if rest == 0 and 0 <= k < len(times):
                return times[k]
        return t_ns * 1e-9

    def serve(self, board: ChipBoard, need: Need) -> None:
        self._serves[0] += 1
        keeps_all, count, anchor, epoch = need[1], need[6], need[7], need[8]
        t_ns, period_ns, anchor_ns = need[9], need[10], need[11]
        sampler = self._sampler
        if epoch != self._epoch:  # DEVICE_RESET: the filters start again
            self._epoch = epoch
            sampler.reset_filters()
        if anchor != self._anchor:  # woken: the sample clock restarts there
            self._anchor = anchor
            sampler.next_t = anchor_ns * 1e-9
        cfg, div = board.peek(CHIP_MPU, CONFIG), board.peek(CHIP_MPU, SMPLRT_DIV)
        if cfg != self._cfg or div != self._div:  # the same every block in steady sampling
            self._cfg, self._div = cfg, div
            self._period = 1.0 / sample_rate(cfg, div)
        period = self._period
        _, times = sampler.take(count, period, cfg, bool(keeps_all))
        m = len(times)
        if keeps_all:
            self._push(board.addr, t_ns, period_ns, m, sampler.block_addr, 7)
            self._recent.append((t_ns, period_ns, times))
            del self._recent[:-4]
        else:
            self._push(board.addr, t_ns + (count - 1) * period_ns, 0, 1, sampler.block_addr + 56 * (m - 1), 7)


class MagFeed:
    """The HMC5883L's samples: ``source`` (a MagModel, or any function of time giving the field in gauss)
    at each measurement instant, the float time being the Python chip's clock: the anchor plus two
    periods (continuous), SINGLE_S (single) or POWER_ON_S, then one period apart."""

    def __init__(self, source: Callable[[float], tuple[float, float, float]], imu: ImuFeed) -> None:
        self.source, self.imu = source, imu
        self._anchor = -1
        self._index = 0
        self._next_t = 0.0
        self._push = native.fast().chip_push_mag

    def serve(self, board: ChipBoard, need: Need) -> None:
        anchor_mpu, start, count, anchor = need[2], need[5], need[6], need[7]
        period = 1.0 / hmc5883l.RATES_HZ[(board.peek(CHIP_HMC, hmc5883l.CRA) >> 2) & 0x7]
        if anchor != self._anchor:
            self._anchor, self._index = anchor, 0
            base = self.imu.float_at(need[11]) if anchor_mpu else need[11] * 1e-9
            if start == HMC_START_POWER_ON:
                self._next_t = base + hmc5883l.POWER_ON_S
            elif start == HMC_START_CONTINUOUS:
                self._next_t = base + 2 * period
            else:
                self._next_t = base + hmc5883l.SINGLE_S
        while self._index < count:
            self._next_t += period
            self._index += 1
        x, y, z = self.source(self._next_t)
        self._push(board.addr, need[9], x, y, z)


class BaroFeed:
    """The MS5611's conversion results: ``source`` at the instant the conversion completes, clamped to the
    sensor's range, with the datasheet's OSR noise when asked, encoded to D1/D2 by the exact inverse
    (ms5611.encode)."""

    def __init__(self, source: Callable[[float], BaroTruth], prom: tuple[int, ...] = ms5611.DEFAULT_PROM,
                 timing: str = "typical", encoding: str = "integer", osr_noise: bool = False,
                 seed: int = 0) -> None:
        self.source, self.prom, self.timing = source, prom, timing
        self.encoding, self.osr_noise = encoding, osr_noise
        self._rng = np.random.default_rng(seed)
        self._push = native.fast().chip_push_baro

    def words(self, t: float, osr: int) -> tuple[int, int]:
        """D1 and D2 of a conversion at this OSR index that completes at sim time ``t`` (seconds). A
        bench session (rig/bridge/stream.py) streams these too."""
        truth = self.source(t)
        p = min(max(truth.pressure_pa, 1000.0), 120000.0)
        temp = min(max(truth.temperature_c, -40.0), 85.0)
        if self.osr_noise:
            p = min(max(p + self._rng.normal(0.0, ms5611.NOISE_PA[osr]), 1000.0), 120000.0)
        return ms5611.encode(self.prom, p, temp, self.encoding)

    def serve(self, board: ChipBoard, need: Need) -> None:
        osr = need[3]
        table = ms5611.CONVERSION_MAX if self.timing == "max" else ms5611.CONVERSION_TYPICAL
        d1, d2 = self.words(need[11] * 1e-9 + table[osr], osr)
        self._push(board.addr, need[9], d1, d2)


class ChipBus:
    """The board's bus as the rig drives it: whole transfers at a sim time."""

    def __init__(self, board: ChipBoard) -> None:
        self.board = board
        fast = native.fast()
        self._transfer, self._advance = fast.chip_transfer, fast.chip_advance

    def transfer_ns(self, msgs: Sequence[Msg], t_ns: int) -> list[bytes]:
        """One transfer at ``t_ns``: the bytes of each read message in order. Raises I2CNack when an
        address is not acknowledged and I2CProtocolError when a block read announces an impossible
        count (the messages before it have taken effect)."""
        board = self.board
        self.advance_ns(t_ns)  # the needs served ahead: the transfer then runs once
        while True:
            status, value = self._transfer(board.addr, t_ns, msgs)
            if status == CHIP_OK:
                return value
            if status == CHIP_NEED:
                board.serve(value)
            elif status == CHIP_NACK:
                raise I2CNack(msgs[value].addr)
            else:
                index, count = value
                raise I2CProtocolError(f"block read from 0x{msgs[index].addr:02x} announced {count} bytes")

    def transfer(self, msgs: Sequence[Msg], t: float) -> list[bytes]:
        """One transfer at sim time ``t`` (seconds; to the nearest nanosecond)."""
        return self.transfer_ns(msgs, round(t * 1e9))

    def advance_ns(self, t_ns: int) -> None:
        """Runs every chip up to ``t_ns`` with no transfer."""
        board = self.board
        while (need := self._advance(board.addr, t_ns)) is not None:
            board.serve(need)

    def advance_to(self, t: float) -> None:
        self.advance_ns(round(t * 1e9))


class _MpuView:
    def __init__(self, board: ChipBoard, feed: ImuFeed) -> None:
        self._board, self.feed = board, feed

    @property
    def source(self) -> Callable[[float], ImuTruth]:
        return self.feed.source

    @property
    def bypass(self) -> bool:
        return bool(self._board.lib.chip_mpu_bypass(self._board.addr))

    @property
    def samples(self) -> int:
        return self._board.count("mpu_samples")

    @property
    def regs(self) -> bytes:
        return bytes([self._board.peek(CHIP_MPU, r) for r in range(128)])

    def sample_rate(self) -> float:
        return sample_rate(self._board.peek(CHIP_MPU, CONFIG), self._board.peek(CHIP_MPU, SMPLRT_DIV))


class _HmcView:
    def __init__(self, board: ChipBoard, feed: MagFeed) -> None:
        self._board, self.feed = board, feed
        self._wraps = False

    @property
    def source(self) -> Callable[[float], tuple[float, float, float]]:
        return self.feed.source

    @property
    def status_wraps_to_data(self) -> bool:
        return self._wraps

    @status_wraps_to_data.setter
    def status_wraps_to_data(self, on: bool) -> None:
        self._wraps = on
        self._board.lib.chip_hmc_status_wraps(self._board.addr, on)


class _BaroView:
    def __init__(self, board: ChipBoard, feed: BaroFeed) -> None:
        self._board, self.feed = board, feed

    @property
    def source(self) -> Callable[[float], BaroTruth]:
        return self.feed.source

    @property
    def prom(self) -> tuple[int, ...]:
        return self.feed.prom

    @prom.setter
    def prom(self, words: tuple[int, ...]) -> None:
        self.feed.prom = tuple(words)
        self._board.lib.chip_ms5611_prom(self._board.addr, (ctypes.c_uint16 * 8)(*words))


class ChipBoard:
    """The three chips in C on one bus, with their producers. ``addr`` is the core's chip_board."""

    def __init__(self, imu: ImuFeed, mag: MagFeed, baro: BaroFeed, topology: str = "gy86",
                 mpu_address: int = mpu6050.ADDRESS) -> None:
        if topology not in TOPOLOGIES:
            raise ValueError(f"unknown topology {topology!r}; choose one of {', '.join(TOPOLOGIES)}")
        self.topology = topology
        self.mpu_address = mpu_address
        self.lib = native.chips()
        self._mem = ctypes.create_string_buffer(self.lib.rig_chip_board_size())
        self.addr = ctypes.addressof(self._mem)
        self.lib.chip_board_init(self.addr, TOPOLOGIES.index(topology))
        if not self.lib.chip_mpu_address(self.addr, mpu_address):
            raise ValueError(f"an MPU-6050 answers at 0x68 or 0x69 (AD0 high), not {mpu_address:#04x}")
        self.lib.chip_board_demand(self.addr, True)
        self.feeds: dict[int, ImuFeed | MagFeed | BaroFeed] = {CHIP_MPU: imu, CHIP_HMC: mag, CHIP_BARO: baro}
        self._imu, self._mag, self._baro = imu, mag, baro
        self.mpu, self.hmc, self.baro = _MpuView(self, imu), _HmcView(self, mag), _BaroView(self, baro)
        self.baro.prom = baro.prom
        self.lib.chip_ms5611_max_timing(self.addr, baro.timing == "max")
        self.bus = ChipBus(self)
        self._peek = native.fast().chip_peek  # (every block the IMU producer serves)
        #: per chip, the first instant (ns) a bus fault may keep it from answering (write_acks)
        self._silent_from: dict[int, int] = {}

    def serve(self, need: Any) -> None:
        """Makes and pushes the sample the core needs (demand mode)."""
        chip = need[0]
        if chip == CHIP_MPU:
            self._imu.serve(self, need)
        elif chip == CHIP_HMC:
            self._mag.serve(self, need)
        else:
            self._baro.serve(self, need)

    def peek(self, chip: int, reg: int) -> int:
        return int(self._peek(self.addr, chip, reg))

    def count(self, name: str) -> int:
        return int(self.lib.chip_count(self.addr, COUNTERS.index(name)))

    def write_acks(self) -> list[tuple[int, int]]:
        """(address, until ns): every write to that address that starts before ``until`` is acknowledged,
        whatever the DUT does meanwhile. The chip core acknowledges every byte written to a chip that
        answers its address, so that holds up to the first bus fault that may silence the chip (off,
        intermittent), for the chips found at their address alone: the MPU-6050 and the MS5611, and
        the HMC5883L wired directly (on a GY-86 it answers only while the MPU's bypass is on, which
        the DUT switches)."""
        chips = [(CHIP_MPU, self.mpu_address)]
        if self.topology != "gy521":
            chips.append((CHIP_BARO, ms5611.ADDRESS))
        if self.topology == "direct":
            chips.append((CHIP_HMC, hmc5883l.ADDRESS))
        return [(addr, self._silent_from.get(chip, _NEVER)) for chip, addr in chips]

    def add_bus_faults(self, chip: int, faults: FaultSet) -> None:
        """The bus faults (off, intermittent, garbage) of ``faults`` on ``chip``, scheduled in ns."""
        self.lib.chip_bus_fault_seed(self.addr, chip, faults.seed & _NEVER)
        for f in faults.faults:
            kind = FAULT_KINDS.get(f.kind)
            if kind is None:
                continue
            end = _NEVER if math.isinf(f.end) else round(f.end * 1e9)
            period = round(f.period * 1e9)
            if f.kind != "garbage":  # (garbage changes the bytes read, never the acknowledgement)
                self._silent_from[chip] = min(self._silent_from.get(chip, _NEVER), round(f.start * 1e9))
            if not self.lib.chip_bus_fault_add(self.addr, chip, kind, round(f.start * 1e9), end, period,
                                               round(f.duty * f.period * 1e9)):
                raise ValueError(f"the chip core takes 4 bus faults per chip at most (or a bad {f.kind})")


#: build_chip_board's fault keys: the bus targets of emulators/faults.py
BUS_FAULT_CHIPS: Final = {"mpu": CHIP_MPU, "hmc": CHIP_HMC, "baro_bus": CHIP_BARO, "baro": CHIP_BARO}


def build_chip_board(imu: Callable[[float], ImuTruth], mag: Callable[[float], tuple[float, float, float]],
                     baro: Callable[[float], BaroTruth], topology: str = "gy86", dlpf: bool = True,
                     faults: Mapping[str, FaultSet] | None = None,
                     prom: tuple[int, ...] = ms5611.DEFAULT_PROM, timing: str = "typical",
                     encoding: str = "integer", osr_noise: bool = False,
                     baro_seed: int = 0, status_wraps_to_data: bool = False,
                     mpu_address: int = mpu6050.ADDRESS) -> ChipBoard:
    """A board of the chip core fed by these sources (what topology.build_board is for the Python chips).
    ``faults``: bus faults by target ("mpu", "hmc", "baro_bus"); ``mpu_address``: 0x69 with AD0 high."""
    imu_feed = ImuFeed(imu, dlpf)
    board = ChipBoard(imu_feed, MagFeed(mag, imu_feed),
                      BaroFeed(baro, prom, timing, encoding, osr_noise, baro_seed), topology, mpu_address)
    for name, fs in (faults or {}).items():
        board.add_bus_faults(BUS_FAULT_CHIPS[name], fs)
    if status_wraps_to_data:
        board.hmc.status_wraps_to_data = True
    return board
