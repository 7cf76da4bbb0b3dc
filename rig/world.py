"""The simulated world a DUT lives in: the plant FMU, the sensor error models and the emulated board,
advanced together in sim time.

The plant steps on a fixed grid (1 ms by default) and keeps a short history of its outputs, so that a
device catching up on samples it owes (the MPU-6050's DLPF after a long sleep) sees the truth of each
sample instant, not only the newest one; sample instants between two plant steps see the step before
(a causal zero-order hold). Motor commands enter as the PWM channels the DUT drives.
"""

from __future__ import annotations

import array
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Final

import numpy as np

from rig.battery import Pack, PackState
from rig.emulators.chips.board import ChipBoard, build_chip_board
from rig.emulators.faults import TARGETS as FAULT_TARGETS
from rig.emulators.faults import FaultSet
from rig.emulators.i2c_bus import Msg
from rig.emulators.sensor_models import (
    FLAT_ON_BOARD,
    AxisErrors,
    BaroModel,
    ImuModel,
    MagModel,
    TruthRow,
    no_disturbance,
)
from rig.plant import Plant
from rig.plant.variables import MOTORS, PWM_INPUTS, SCENARIO_INPUTS, pwm_input

STEP_NS: Final = 1_000_000
HISTORY: Final = 256  # plant steps kept for devices catching up (256 ms at 1 ms)
G0: Final = 9.80665

#: Datasheet noise: MPU-6050 accelerometer 400 µg/√Hz, gyroscope 0.005 °/s/√Hz; HMC5883L about 2 mG
#: RMS at its default 15 Hz. The barometer is left exact so a reading can be checked to the pascal.
DATASHEET_NOISE = {"accel": 400e-6 * G0, "gyro": math.radians(0.005), "mag": 0.002 / math.sqrt(7.5)}


class PwmChannel:
    """One sysfs PWM channel as the DUT left it (the session's mirror of the shim's state). The duty is a
    cell (``duty_addr``) that the lockstep fast path writes in place: four writes an FC cycle, each an
    int object made and an attribute set when it was a field."""

    def __init__(self, exported: bool = False, period_ns: int = 0, duty_ns: int = 0, enabled: bool = False,
                 inversed: bool = False) -> None:
        self.exported, self.period_ns, self.enabled, self.inversed = exported, period_ns, enabled, inversed
        self._duty = array.array("Q", [duty_ns])  # (the shim's unsigned 64-bit value, whatever it is)
        self.duty_addr: int = self._duty.buffer_info()[0]

    @property
    def duty_ns(self) -> int:
        return self._duty[0]

    @duty_ns.setter
    def duty_ns(self, ns: int) -> None:
        self._duty[0] = ns

    def __repr__(self) -> str:
        return (f"PwmChannel(exported={self.exported}, period_ns={self.period_ns}, duty_ns={self.duty_ns}, "
                f"enabled={self.enabled}, inversed={self.inversed})")

    def pulse_us(self) -> float:
        """The high time an ESC measures per period; 0 when no pulses come out."""
        if not (self.exported and self.enabled and self.period_ns > 0):
            return 0.0
        high = self.period_ns - self.duty_ns if self.inversed else self.duty_ns
        return min(max(high, 0), self.period_ns) / 1000.0


class _WorldTruth:
    """The truth the sensor models of a world read, for models made before their world is: a truth
    function and a TruthTable (emulators/sensor_models.py) over the world's plant history."""

    world: World

    def __init__(self, plant: Plant) -> None:
        self.plant = plant

    def __call__(self, t: float) -> Mapping[str, float]:
        return self.world.truth(t)

    def column(self, name: str) -> int:
        return self.plant.y_index[name]

    def row_addresses(self, times: Sequence[float]) -> list[int]:
        return self.world.row_addresses(times)


class Probe:
    """A table of rows, each some plant outputs, the motors' pulse widths and the caller's extras (the
    recorder's 100 Hz row): ``record(extras)`` writes a row by one C call over the plant's buffers
    (Plant.reader) into a float64 table that grows by doubling; ``rows()`` is the table so far. Where
    the values went through Python floats, a tuple per row and numpy's conversion of the tuples after
    the run, a row cost about 15 k instructions more."""

    def __init__(self, plant: Plant, outputs: list[int], motors: list[int], extras: int, rows: int) -> None:
        self._plant = plant  # (its buffers: the reader holds their addresses)
        self._write = plant.reader(outputs, motors)
        self.width = len(outputs) + len(motors) + extras
        self._extras = extras
        self._table = np.zeros((max(rows, 1), self.width))
        self._address = self._table.ctypes.data
        self.count = 0

    def record(self, extras: tuple[float, ...]) -> None:
        """Appends a row: the outputs, the motors, then ``extras`` (as many as the probe was made for)."""
        n = self.count
        table = self._table
        if n == len(table):
            table = self._table = np.concatenate([table, np.zeros_like(table)])
            self._address = table.ctypes.data
        if len(extras) != self._extras:  # (C checks only the table's end: a row must not run into the next)
            raise ValueError(f"a row of this probe has {self._extras} extras, not {len(extras)}")
        width = self.width
        self._write(self._address + n * width * 8, (len(table) - n) * width, extras)
        self.count = n + 1

    def rows(self) -> np.ndarray:
        """The rows recorded so far (a view of the table)."""
        return self._table[:self.count]


@dataclass
class World:
    plant: Plant
    board: ChipBoard
    step_ns: int = STEP_NS
    pwm: list[PwmChannel] = field(default_factory=lambda: [PwmChannel() for _ in range(8)])
    direct_pwm: bool = True
    #: the plant motor (1..4) each of the DUT's first four PWM channels drives (its FC profile's order)
    motor_order: tuple[int, ...] = (1, 2, 3, 4)
    #: the flight pack, when the DUT's board measures one (rig/battery.py): battery_volts
    battery: PackState | None = None

    def __post_init__(self) -> None:
        # the plant steps taken (``_k``), in a cell C reads and moves in place (rig/lockstep: the fast
        # path steps the plant and its samples' producers read the count every FC cycle; as an attribute
        # each read made and dropped an int object, about 0.5 k instructions per cycle)
        self._steps = array.array("q", [0])  # (array, not numpy: a Python read is a fifth of numpy's)
        self.k_addr: int = self._steps.buffer_info()[0]
        self._k = round(self.plant.time * 1e9 / self.step_ns)
        # a ring of output rows that C reads (the IMU's sampling chain): a TruthTable
        self._hist = np.zeros((HISTORY, len(self.plant.y)))
        self._hist_addr, self._row_bytes = self._hist.ctypes.data, self._hist.strides[0]
        self._k0 = self._k
        self._hist[self._k % HISTORY] = self.plant.y
        self._u_pwm = [self.plant.u_index[name] for name in PWM_INPUTS]
        # the input each PWM channel 0..MOTORS-1 drives, in the DUT's output order
        self._u_out = [self.plant.u_index[pwm_input(m)] for m in self.motor_order]
        self._u_named = {name: self.plant.u_index[name] for name in SCENARIO_INPUTS}
        self._u_cells = self.plant.u_cells
        self._read_on_ground = self.plant.read_on_ground

    @classmethod
    def at_rest(
        cls,
        seed: int = 0,
        topology: str = "gy86",
        noise: bool = True,
        params: Mapping[str, float] | None = None,
        pwm_channels: int = 8,
        faults: Mapping[str, FaultSet] | None = None,
        mag_disturbance: Callable[[float], tuple[float, float, float]] | None = None,
        baro_noise_pa: float = 0.0,
        baro_osr_noise: bool = False,
        baro_drift_pa_per_s: float = 0.0,
        mounting: tuple[tuple[float, float, float], ...] = FLAT_ON_BOARD,
        motor_order: tuple[int, ...] = (1, 2, 3, 4),
        mpu_address: int = 0x68,
        battery: Pack | None = None,
    ) -> World:
        """The default world of ``rig exec``: the vehicle resting on the ground, motors off, a GY-86.
        ``faults`` by name: signal faults "accel", "gyro", "mag", "baro" act in the sensor models; bus
        faults "mpu", "hmc", "baro_bus" act on the chip on the bus. The barometer's noise and drift
        are its model's (the barometer is exact by default, so a reading can be checked to the pascal);
        ``baro_osr_noise``: the MS5611 adds its datasheet RMS noise for the OSR asked (1.2 Pa at 4096),
        for an FC that judges a reading unchanged for long a stuck barometer, as ArduPilot does (the
        conversions are then made in Python, not by the chip core's C).
        ``motor_order``: the plant motor each of the DUT's PWM channels 0..3 drives. ``mounting``: body
        FRD to the sensors' frame (the board's; its default lies flat, facing forward). ``topology``
        "gy521" is the MPU-6050 alone, at ``mpu_address`` (0x69: AD0 high). ``battery``: the flight pack
        a board measures, with the faults "battery" on its volts (ValueError: such a fault without one)."""
        faults = dict(faults or {})
        unknown = set(faults) - set(FAULT_TARGETS)
        if unknown:
            raise ValueError(f"unknown fault target(s) {sorted(unknown)}; known: {', '.join(FAULT_TARGETS)}")
        if "battery" in faults and battery is None:
            raise ValueError("a fault on the battery, and no battery: only an MCU board with a [battery] "
                             "has one")
        plant = Plant(params=params or {}, inputs=dict.fromkeys(PWM_INPUTS, 0.0))

        truth = _WorldTruth(plant)  # the models need the world that holds them

        nd = DATASHEET_NOISE if noise else {"accel": 0.0, "gyro": 0.0, "mag": 0.0}
        imu = ImuModel(
            truth,
            accel=AxisErrors(mounting=mounting, noise_density=nd["accel"]),
            gyro=AxisErrors(mounting=mounting, noise_density=nd["gyro"]),
            seed=seed,
            accel_faults=faults.get("accel", FaultSet()),
            gyro_faults=faults.get("gyro", FaultSet()),
        )
        mag = MagModel(
            truth,
            errors=AxisErrors(mounting=mounting, noise_density=nd["mag"]),
            seed=seed + 1,
            faults=faults.get("mag", FaultSet()),
            disturbance=mag_disturbance or no_disturbance,
        )
        baro = BaroModel(truth, seed=seed + 2, faults=faults.get("baro", FaultSet()), noise_pa=baro_noise_pa,
                         drift_pa_per_s=baro_drift_pa_per_s)
        # the chips are the chip core in C (emulators/chips/), fed by these models
        bus_faults: dict[str, FaultSet] = {k: faults[k] for k in ("mpu", "hmc", "baro_bus") if k in faults}
        board = build_chip_board(imu, mag, baro, topology, faults=bus_faults, osr_noise=baro_osr_noise,
                                 baro_seed=seed + 3, mpu_address=mpu_address)
        pack = None if battery is None else PackState(battery, faults.get("battery"))
        world = cls(plant, board, pwm=[PwmChannel() for _ in range(pwm_channels)], motor_order=motor_order,
                    battery=pack)
        truth.world = world
        return world

    # ---- time ------------------------------------------------------------------------------

    @property
    def _k(self) -> int:
        """The plant steps taken since time 0 (the world's time in steps)."""
        return self._steps[0]

    @_k.setter
    def _k(self, k: int) -> None:
        self._steps[0] = k

    @property
    def time_ns(self) -> int:
        return self._k * self.step_ns

    def advance_to(self, t_ns: int) -> None:
        """Steps the plant over every whole step that ends at or before ``t_ns``, in one call into C
        that also fills the history (nothing touches ``u`` between these steps)."""
        n = t_ns // self.step_ns - self._k
        if n > 0:
            self.plant.step_many(n, self.step_ns * 1e-9, ring=self._hist, first_row=self._k + 1)
            self._k += n

    def _slots(self, times: Sequence[float]) -> list[int]:
        """The history slot of the last step at or before each sim time (seconds; clamped to the
        history kept)."""
        oldest, k, step = max(self._k0, self._k - HISTORY + 1), self._k, self.step_ns
        return [min(max(math.floor(t * 1e9 / step + 1e-9), oldest), k) % HISTORY for t in times]

    def truth(self, t: float) -> Mapping[str, float]:
        """Plant outputs at sim time ``t`` (seconds) as of the last step at or before it."""
        return TruthRow(self.plant.y_index, self._hist[self._slots((t,))[0]].tolist())

    def row_addresses(self, times: Sequence[float]) -> list[int]:
        """Where in memory the rows ``truth`` reads are: the same history, for C to read."""
        base, size = self._hist_addr, self._row_bytes
        return [base + slot * size for slot in self._slots(times)]

    # ---- the DUT's side ----------------------------------------------------------------------

    def transfer(self, msgs: Sequence[Msg], t_ns: int) -> list[bytes]:
        """One I2C transfer at ``t_ns`` (raises I2CNack / I2CProtocolError as the bus does)."""
        self.advance_to(t_ns)
        return self.board.bus.transfer_ns(msgs, t_ns)

    def apply_pwm(self, channel: int) -> None:
        """Channels 0..MOTORS-1 drive motors 1..MOTORS at once, unless a capture link (rig/capture.py)
        stands between them and sets ``direct_pwm`` False."""
        if channel < MOTORS and self.direct_pwm:
            self._u_cells[self._u_out[channel]] = self.pwm[channel].pulse_us()

    # ---- the scenario's side: what the world accepts from outside, by name ---------------------

    def set_motor(self, motor: int, pulse_us: float) -> None:
        """The ESC pulse of the DUT's output ``motor`` (0-based, as the PWM channels) from a capture link."""
        self._u_cells[self._u_out[motor]] = pulse_us

    def set_input(self, name: str, value: float) -> None:
        """One of the plant's scenario inputs by name (plant.variables.SCENARIO_INPUTS: wind, external
        force and torque, motor health); it acts from the next plant step."""
        index = self._u_named.get(name)
        if index is None:
            raise KeyError(f"{name!r} is not an input of the world; known: {', '.join(self._u_named)}")
        self._u_cells[index] = value

    def battery_volts(self, t_ns: int) -> float:
        """The flight pack's terminal volts at ``t_ns``, the ESC pulses as they are now setting its current
        from there on (rig/battery.py PackState.update); call it after the step's motor commands."""
        if self.battery is None:
            raise ValueError("this world has no battery")
        cells = self._u_cells
        return self.battery.update(t_ns, [cells[i] for i in self._u_pwm])

    def probe(self, outputs: Sequence[str], extras: int = 0, rows: int = 1024) -> Probe:
        """A table of rows of the named plant outputs, the motors' pulse widths and ``extras`` more values
        (in that order), room for ``rows`` made at once."""
        return Probe(self.plant, [self.plant.y_index[n] for n in outputs], self._u_pwm, extras, rows)

    @property
    def on_ground(self) -> bool:
        # the plant's C reader, not its property (plain Python: 3 k instructions per read at 100 Hz)
        got = self._read_on_ground()
        return got == 1 if got >= 0 else self.plant.on_ground  # (a failed read: the plant raises)

    def outputs(self) -> dict[str, float]:
        return self.plant.outputs()

    def close(self) -> None:
        self.plant.close()
