"""The lockstep session's per-cycle messages in C (rig/lockstep/fastpath.c, the extension module
``build/_riglockstep*.so``): I2C transfers, PWM duty writes and waits answered without the Python
handler, which stays the reference and acts on everything the fast path declines (see fastpath.c).

Why: a flight controller's cycle (an MPU burst read, four PWM duty notices, a wait) cost the session
about twice the plant and the samples together as Python objects (docs/design.md, the lockstep section).

``RIG_PY_PATH=1`` in the environment turns it off: every message goes to the Python handler, the oracle a
test compares the fast path with. The module is built on first use, and again when a source is newer,
as the other extensions are (plant/native_build.py); ``python -m rig.lockstep`` (part of ``make native``)
builds it explicitly.
"""

from __future__ import annotations

import ctypes
import functools
import math
import os
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any, TypeVar

from rig import event_queue
from rig.cores import SPIN_NS
from rig.emulators import hmc5883l, ms5611, native
from rig.emulators.chips.board import CHIP_BARO, CHIP_HMC, CHIP_MPU, BaroFeed, ImuFeed, MagFeed
from rig.emulators.dlpf import DLPF
from rig.emulators.mpu6050 import CONFIG, SMPLRT_DIV
from rig.emulators.sensor_models import BaroModel, ImuModel, MagModel, no_disturbance
from rig.plant.artifacts import BUILD
from rig.plant.fmu import _STEP_CALLS
from rig.plant.native_build import EXTENSION_SUFFIX, built_extension, compile_extension
from rig.plant.variables import MOTORS
from rig.scenarios.result import I2CRecord
from rig.scenarios.schema import Scenario
from rig.world import HISTORY, World, _WorldTruth

if TYPE_CHECKING:
    from rig.handler import Handler

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent
SHIM_DIR = REPO / "rig" / "shim"
#: the module's source first; the headers it shares with the shim (the wire) and the chip core
PLANT_C = REPO / "plant" / "c"
SOURCES = (HERE / "fastpath.c", HERE / "attrs.c", HERE / "imu_feed.c", HERE / "mag_feed.c",
           HERE / "baro_feed.c", HERE / "pwm_duty.c", HERE / "pump.c", HERE / "mailbox.c", HERE / "events.c",
           HERE / "i2c_log.c", HERE / "reply.c", SHIM_DIR / "protocol.h", SHIM_DIR / "ring.h",
           native.CHIPS_DIR / "chip_core.h", native.C_DIR / "need_tuple.h", PLANT_C / "plant_steps.c",
           event_queue.HERE / "queue.h")
MODULE_NAME = "_riglockstep"
LIB = BUILD / f"{MODULE_NAME}{EXTENSION_SUFFIX}"
Feed = TypeVar("Feed")
Model = TypeVar("Model")
#: the environment variable that sends every message to the Python handler
PY_PATH_ENV = "RIG_PY_PATH"


def build() -> Path:
    return compile_extension(SOURCES[:1], LIB, "the lockstep fast path",
                             flags=(f"-I{SHIM_DIR}", f"-I{native.CHIPS_DIR}", f"-I{native.C_DIR}",
                                    f"-I{PLANT_C}", f"-I{event_queue.HERE}"))


@functools.cache
def module() -> ModuleType:
    return built_extension(MODULE_NAME, LIB, SOURCES, build)


def enabled() -> bool:
    return os.environ.get(PY_PATH_ENV, "") in ("", "0")


def _address(fn: Any) -> int:
    value = ctypes.cast(fn, ctypes.c_void_p).value
    if not value:
        raise RuntimeError("the chip core's entry point has no address")
    return value


class FastPath:
    """The fast path of one lockstep session's handler: ``handle(fd, buf, off)`` acts on the whole
    messages from ``off`` that it takes and returns the offset of the first it leaves to the handler."""

    def __init__(self, handler: Handler) -> None:
        world, sched, cfg = handler.world, handler.sched, handler.cfg
        chips = native.chips()
        self._handle = module().handle
        self._pump = module().pump
        self._spin_ns = SPIN_NS if cfg.spin else 0  # (rig/cores.py)
        self._state = module().setup(
            world.advance_to, world.board.serve, world.pwm, sched.events, sched, handler.i2c_log, handler,
            handler.page.mmap, world.board.addr, _address(chips.chip_transfer), _address(chips.chip_advance),
            world.step_ns, sched.limit_ns, cfg.i2c_clock_hz, cfg.i2c_bus, I2CRecord)
        plant = world.plant
        module().setup_world(self._state, world, plant, world._hist, plant.u.ctypes.data,
                             world._u_pwm[:MOTORS], MOTORS, _STEP_CALLS)
        session = handler.session
        module().setup_events(self._state, sched.run_next, session.in_flight)
        self.imu_in_c = _imu_in_c(self._state, world)
        self.mag_in_c = _mag_in_c(self._state, world)
        self.baro_in_c = _baro_in_c(self._state, world)

    @property
    def handled(self) -> int:
        """The messages acted on here so far (the rest went to the handler)."""
        n: int = module().handled(self._state)
        return n

    @property
    def counts(self) -> tuple[int, int, int, int]:
        """The I2C transfers, waits, PWM writes and promised writes (I2C_WRITE notices, among the
        transfers) acted on here (the handler counts the rest)."""
        i2c, waits, pwm, promised = module().counts(self._state)
        return int(i2c), int(waits), int(pwm), int(promised)

    @property
    def made_here(self) -> tuple[int, int, int]:
        """The magnetometer's measurements, the barometer's conversions and the IMU's blocks of samples
        made in C so far."""
        mag, baro, imu = module().made_here(self._state)
        return int(mag), int(baro), int(imu)

    def handle(self, fd: int, buf: bytearray, off: int) -> int:
        off_after: int = self._handle(self._state, fd, buf, off)
        return off_after

    def pump(self, fd: int, epoll_fd: int, buf: bytearray, ptys: tuple[tuple[int, bytearray], ...] = ()
             ) -> int:
        """Reads connection ``fd`` and acts on its messages in C until something needs the session's loop
        (pump.c: a message for the handler, another of ``epoll_fd``'s descriptors ready, its time budget
        spent); what it did not act on is left in ``buf``. A pty of ``ptys`` (master fd, the bytearray its
        bytes go to) that is ready is read into its bytearray meanwhile, as the loop would. Returns the
        bytes it received, or -1 with nothing done: the loop's own read takes over (the connection ended,
        or ``buf`` is too full)."""
        got: int = self._pump(self._state, fd, epoll_fd, buf, ptys, self._spin_ns)
        return got

    # a connection's mailbox (rig/shim/ring.h, mailbox.c; rig/connection.py uses them)
    def mailbox_open(self, fd: int) -> int:
        """A memfd holding connection ``fd``'s new mailbox (the caller closes it); -1: none left."""
        memfd: int = module().mailbox_open(self._state, fd)
        return memfd

    def mailbox_close(self, fd: int) -> None:
        module().mailbox_close(self._state, fd)

    def mailbox_take(self, fd: int, buf: bytearray) -> int:
        """The mailbox's bytes appended to ``buf``: their count; -1 for a broken ring."""
        got: int = module().mailbox_take(self._state, fd, buf)
        return got

    def mailbox_put(self, fd: int, data: bytes) -> bool:
        """A reply into the mailbox, whole; False (nothing written) when it has no room."""
        return bool(module().mailbox_put(self._state, fd, data))

    def mailbox_ready(self) -> list[int]:
        """The connections whose mailbox has bytes; from here on a new one rings the socket."""
        fds: list[int] = module().mailbox_ready(self._state)
        return fds


def _imu_in_c(state: object, world: World) -> bool:
    """The IMU's samples made in C (imu_feed.c) when the producer is the world's own: an ImuModel over
    the world's history, through the DLPF. Another source (a test's function of time) stays Python."""
    feed = world.board.feeds[CHIP_MPU]
    model = getattr(feed, "source", None)
    if not isinstance(feed, ImuFeed) or not isinstance(model, ImuModel) or not feed.dlpf:
        return False
    table = model._table
    if not isinstance(table, _WorldTruth) or table.world is not world:
        return False
    lib = native.sampling()
    sampler = feed._sampler
    module().setup_imu(
        state, feed, sampler, model._a, model._g, model.accel_faults.faults, model.gyro_faults.faults, world,
        model._cols_addr, model.die_offset_c, sampler.block_addr, world._k0, HISTORY, world._hist_addr,
        world._row_bytes, lib.rig_lowpass_max_depth(), world.step_ns, CONFIG, SMPLRT_DIV, DLPF,
        _address(lib.rig_imu_measure), _address(lib.rig_lowpass_run), _address(lib.chip_push_imu),
        _address(lib.chip_peek))
    return True


def _own_model(world: World, chip: int, feed_kind: type[Feed], model_kind: type[Model]
               ) -> tuple[Feed, Model] | None:
    """The chip's producer and its model when the model reads the world's own history (what C can make
    in their place), else None."""
    feed = world.board.feeds[chip]
    model = getattr(feed, "source", None)
    if not isinstance(feed, feed_kind) or not isinstance(model, model_kind):
        return None
    truth = getattr(model, "truth", None)
    return (feed, model) if isinstance(truth, _WorldTruth) and truth.world is world else None


def _mag_in_c(state: object, world: World) -> bool:
    """The magnetometer's samples made in C (mag_feed.c) when the producer is the world's own: a MagModel
    over the world's history, with no disturbance or a scenario's window. Another source or disturbance
    stays Python."""
    own = _own_model(world, CHIP_HMC, MagFeed, MagModel)
    if own is None:
        return False
    feed, model = own
    dist = model.disturbance
    scenario = getattr(dist, "__self__", None)
    if dist is no_disturbance:
        vec, start, end = (0.0, 0.0, 0.0), math.inf, -math.inf
    elif isinstance(scenario, Scenario) and getattr(dist, "__func__", None) is Scenario.mag_disturbance_at:
        vec, start, end = scenario.mag_disturbance_window
    else:
        return False
    lib = native.sampling()
    cols = [world.plant.y_index[n] for n in ("mag_x", "mag_y", "mag_z")]
    module().setup_mag(
        state, feed, model._c, model._c.faults.faults, world, world._k0, HISTORY, world._hist_addr,
        world._row_bytes, world.step_ns, hmc5883l.CRA, hmc5883l.RATES_HZ, cols, vec, start, end,
        _address(lib.rig_channel_measure), _address(lib.chip_push_mag), _address(lib.chip_peek))
    return True


def _baro_in_c(state: object, world: World) -> bool:
    """The barometer's conversions made in C (baro_feed.c) when the producer is the world's own: a
    BaroModel over the world's history (baro_feed.c declines, conversion by conversion, what it does not
    make: noise, faults, the float encoding)."""
    own = _own_model(world, CHIP_BARO, BaroFeed, BaroModel)
    if own is None:
        return False
    feed, model = own
    lib = native.sampling()
    cols = [world.plant.y_index[n] for n in ("pressure", "temperature")]
    module().setup_baro(
        state, feed, model, model.faults.faults, world, world._k0, HISTORY, world._hist_addr,
        world._row_bytes, world.step_ns, cols, ms5611.CONVERSION_TYPICAL + ms5611.CONVERSION_MAX,
        _address(lib.chip_push_baro))
    return True


def handled_total() -> int:
    """The messages the fast path has acted on in this process, all sessions together (a test's
    evidence that a flight went through it)."""
    n: int = module().handled(None)
    return n


def pending_input() -> Callable[[int], int]:
    """``pending_input(fd)`` -> the bytes readable on ``fd`` (FIONREAD), one C call (events.c's own
    count): what the session's serial writes ask ~70 times a second in lockstep."""
    fn: Callable[[int], int] = module().pending_input
    return fn


def attach(handler: Handler) -> FastPath | None:
    """The fast path for ``handler``'s session, or None: in real time, or turned off (RIG_PY_PATH=1)."""
    if not handler.lockstep or not enabled():
        return None
    return FastPath(handler)
