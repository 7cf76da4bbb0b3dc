"""The plant FMU from Python: fmpy loads it, and a fast path steps it.

fmpy's high-level ``setReal/doStep/getReal`` builds ctypes arrays and Python lists on every call
(about 12 µs a step here). A session steps the plant hundreds of thousands of times per run, so
``Plant.step`` calls the raw FMI function pointers with preallocated ctypes buffers instead, and
exposes numpy views on them: write inputs into ``plant.u``, read outputs from ``plant.y``. Every FMI
status is checked; an error raises ``PlantError`` with the FMU's own message.
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import os
import shutil
import tempfile
from collections.abc import Callable, Mapping, Sequence
from ctypes import (
    POINTER,
    Structure,
    addressof,
    byref,
    c_double,
    c_int,
    c_int32,
    c_int64,
    c_size_t,
    c_uint,
    c_void_p,
)
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2StepFinishedTYPE,
)
from fmpy.fmi2 import calloc as _calloc
from fmpy.fmi2 import free as _free

from rig.plant.artifacts import BUILD

#: Where ``make fmu`` puts the plant (an installed package: its own copy); ``RIG_PLANT_FMU`` overrides it.
DEFAULT_FMU = Path(os.environ.get("RIG_PLANT_FMU", BUILD / "plant" / "quadrotor.fmu"))

_STATUS = {0: "OK", 1: "Warning", 2: "Discard", 3: "Error", 4: "Fatal", 5: "Pending"}


class PlantError(RuntimeError):
    """The FMU refused a call or could not be loaded; the message says why."""


class _Steps(Structure):
    """``struct rig_plant_steps`` (plant/c/plant_steps.c): what several steps in one call need."""

    _fields_ = [("set_real", c_void_p), ("do_step", c_void_p), ("get_real", c_void_p),
                ("component", c_void_p), ("u_vr", c_void_p), ("u", c_void_p), ("n_u", c_size_t),
                ("y_vr", c_void_p), ("y", c_void_p), ("n_y", c_size_t), ("t", c_void_p),
                ("ring", c_void_p), ("ring_rows", c_int64), ("failed_call", c_int32),
                ("failed_status", c_int32)]


_STEP_CALLS = {1: "fmi2SetReal", 2: "fmi2DoStep", 3: "fmi2GetReal"}


@dataclass
class PlantState:
    """A saved FMU state (``fmi2GetFMUstate``) with the Python-side time and inputs that go with it."""

    handle: c_void_p
    time: float
    inputs: np.ndarray


class Plant:
    """One instance of the quadrotor FMU, initialised and ready to step.

    ``params`` and ``inputs`` set start values by variable name before initialisation (names as in
    docs/design.md §4). After construction the time is ``start_time`` and the outputs describe the initial
    state.
    """

    def __init__(self, params: Mapping[str, float] | None = None,
                 inputs: Mapping[str, float] | None = None, fmu_path: str | Path | None = None,
                 start_time: float = 0.0, instance_name: str = "quadrotor") -> None:
        self.fmu_path = Path(fmu_path or DEFAULT_FMU).resolve()
        if not self.fmu_path.is_file():
            raise PlantError(f"plant FMU not found at {self.fmu_path}; build it with `make fmu`")
        self.messages: list[str] = []
        self._states: list[PlantState] = []
        self.fmu_sha256 = hashlib.sha256(self.fmu_path.read_bytes()).hexdigest()
        self._unzip_dir, self._own_unzip_dir = _unzipped(self.fmu_path, self.fmu_sha256)
        try:
            self._load(instance_name)
            self._init(params or {}, inputs or {}, start_time)
        except BaseException:
            self.close()
            raise

    # ---- loading ----------------------------------------------------------------------------

    def _load(self, instance_name: str) -> None:
        md = read_model_description(self._unzip_dir)
        self.model_description = md
        self.variables = {v.name: v for v in md.modelVariables}
        self.input_names = [v.name for v in md.modelVariables
                            if v.causality == "input" and v.type == "Real"]
        self.output_names = [v.name for v in md.modelVariables
                             if v.causality == "output" and v.type == "Real"]
        self._fmu = FMU2Slave(guid=md.guid, unzipDirectory=self._unzip_dir,
                              modelIdentifier=md.coSimulation.modelIdentifier,
                              instanceName=instance_name)
        self._callbacks = fmi2CallbackFunctions()
        self._callbacks.logger = fmi2CallbackLoggerTYPE(self._log)
        self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(_calloc)
        self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(_free)
        self._callbacks.stepFinished = fmi2StepFinishedTYPE()
        self._fmu.instantiate(callbacks=self._callbacks)
        self._component = c_void_p(self._fmu.component)

        # Raw function pointers: dll[name] returns a fresh function object, so fmpy's checked wrappers
        # keep their prototypes. The hot three (set inputs, step, get outputs) have no argtypes and are
        # called only with prebuilt ctypes objects: argument conversion costs more than the physics.
        dll = self._fmu.dll
        self._raw_set_real, self._raw_do_step, self._raw_get_real = (
            self._proto(dll, name) for name in ("fmi2SetReal", "fmi2DoStep", "fmi2GetReal"))
        self._t, self._h, self._no_rollback = c_double(0.0), c_double(0.0), c_int(1)
        vr_p, real_p = POINTER(c_uint), POINTER(c_double)
        self._set_real = self._proto(dll, "fmi2SetReal", c_void_p, vr_p, c_size_t, real_p)
        self._get_real = self._proto(dll, "fmi2GetReal", c_void_p, vr_p, c_size_t, real_p)
        int_p = POINTER(c_int)
        self._get_int = {t: self._proto(dll, f"fmi2Get{t}", c_void_p, vr_p, c_size_t, int_p)
                         for t in ("Integer", "Boolean")}
        self._set_int = {t: self._proto(dll, f"fmi2Set{t}", c_void_p, vr_p, c_size_t, int_p)
                         for t in ("Integer", "Boolean")}
        self._get_state = self._proto(dll, "fmi2GetFMUstate", c_void_p, POINTER(c_void_p))
        self._set_state = self._proto(dll, "fmi2SetFMUstate", c_void_p, c_void_p)
        self._free_state = self._proto(dll, "fmi2FreeFMUstate", c_void_p, POINTER(c_void_p))

        n_u, n_y = len(self.input_names), len(self.output_names)
        self._u_vr = (c_uint * n_u)(*[self.variables[n].valueReference for n in self.input_names])
        self._y_vr = (c_uint * n_y)(*[self.variables[n].valueReference for n in self.output_names])
        self._u_buf = (c_double * n_u)()
        self._y_buf = (c_double * n_y)()
        self._n_u, self._n_y = c_size_t(n_u), c_size_t(n_y)
        #: Inputs (in ``input_names`` order); written to the FMU before every step.
        self.u = np.ctypeslib.as_array(self._u_buf)
        #: The same inputs as doubles to write one at a time: a memoryview's item assignment is a quarter
        #: of a numpy array's 2.1 k instructions (the wind writes three at 100 Hz). Cast through bytes:
        #: the ctypes buffer's "<d" is not a format a memoryview assigns to.
        self.u_cells = memoryview(self._u_buf).cast("B").cast("d")
        #: Outputs (in ``output_names`` order); refreshed after every step.
        self.y = np.ctypeslib.as_array(self._y_buf)
        self.u_index = {n: i for i, n in enumerate(self.input_names)}
        self.y_index = {n: i for i, n in enumerate(self.output_names)}
        self._on_ground_vr = (c_uint * 1)(self.variables["on_ground"].valueReference)
        from rig.plant.steps import (
            get_boolean,  # (here: `python -m rig.plant.steps` must not import itself first)
        )

        #: ``read_on_ground()``: 1 or 0, or minus a failed call's status. A C call bound to this FMU
        #: with no Python frame: the recorder reads on_ground at 100 Hz (through World.on_ground)
        self.read_on_ground: Callable[[], int] = functools.partial(
            get_boolean(), ctypes.cast(self._get_int["Boolean"], c_void_p).value or 0,
            self._component.value or 0, self._on_ground_vr[0])
        self._steps: _Steps | None = None  # for step_many, made on first use
        self._ring: np.ndarray | None = None

    @staticmethod
    def _proto(dll: ctypes.CDLL, name: str, *argtypes: Any) -> Any:  # (a ctypes function pointer)
        fn = dll[name]
        if argtypes:
            fn.argtypes = list(argtypes)
        fn.restype = c_int
        return fn

    def _log(self, env: object, instance: bytes, status: int, category: bytes, message: bytes) -> None:
        text = message.decode("utf-8", "replace") if message else ""
        self.messages.append(f"[{_STATUS.get(status, status)}] {text}")

    def _fail(self, what: str, status: int) -> None:
        detail = self.messages[-1] if self.messages else "no message from the FMU"
        raise PlantError(f"{what} returned {_STATUS.get(status, status)}: {detail}")

    def _check(self, what: str, status: int) -> None:
        if status > 1:  # warnings are kept in self.messages, not raised
            self._fail(what, status)

    def _init(self, params: Mapping[str, float], inputs: Mapping[str, float], start_time: float) -> None:
        for name in params:
            self._require(name, "parameter")
        for name in inputs:
            self._require(name, "input")
        self._check("fmi2SetupExperiment",
                    self._fmu.fmi2SetupExperiment(self._component, 0, 0.0, start_time, 0, 0.0))
        self._check("fmi2EnterInitializationMode",
                    self._fmu.fmi2EnterInitializationMode(self._component))
        for name, value in {**params, **inputs}.items():
            self.set_value(name, value)
        for i, name in enumerate(self.input_names):
            self.u[i] = self.get_value(name)
        self._call_checked("fmi2ExitInitializationMode", self._fmu.fmi2ExitInitializationMode)
        self.time = float(start_time)
        self._read_outputs()

    def _require(self, name: str, causality: str) -> None:
        var = self.variables.get(name)
        if var is None or var.causality != causality:
            known = sorted(v.name for v in self.variables.values() if v.causality == causality)
            raise PlantError(f"unknown {causality} {name!r}; the plant's {causality}s are: "
                             + ", ".join(known))

    def _call_checked(self, what: str, fn: object, *args: object) -> None:
        """Calls one of fmpy's checked wrappers, turning its exception into a PlantError."""
        try:
            fn(self._component, *args)  # type: ignore[operator]
        except Exception as exc:  # fmpy raises FMICallException with the status
            self._fail(what, getattr(exc, "status", 3))

    # ---- by name (slow path: setup, tests, scenario events) ----------------------------------

    def set_value(self, name: str, value: float) -> None:
        """Sets one variable by name through the FMU (any type); inputs also go into ``u``."""
        var = self.variables.get(name)
        if var is None:
            raise PlantError(f"the plant has no variable {name!r}")
        vr = (c_uint * 1)(var.valueReference)
        if var.type == "Real":
            status = self._set_real(self._component, vr, 1, (c_double * 1)(float(value)))
        elif var.type in ("Integer", "Boolean"):
            if float(value) != int(value):
                raise PlantError(f"{name} takes a whole number, not {value!r}")
            status = self._set_int[var.type](self._component, vr, 1, (c_int * 1)(int(value)))
        else:
            raise PlantError(f"{name} has unsupported type {var.type}")
        self._check(f"setting {name}", status)
        if name in self.u_index:
            self.u[self.u_index[name]] = value

    def get_value(self, name: str) -> float:
        """Reads one variable by name from the FMU (any type; booleans as 0.0/1.0)."""
        var = self.variables.get(name)
        if var is None:
            raise PlantError(f"the plant has no variable {name!r}")
        vr = (c_uint * 1)(var.valueReference)
        if var.type == "Real":
            out = (c_double * 1)()
            self._check(f"reading {name}", self._get_real(self._component, vr, 1, out))
            return float(out[0])
        iout = (c_int * 1)()
        self._check(f"reading {name}", self._get_int[var.type](self._component, vr, 1, iout))
        return float(iout[0])

    def set_input(self, name: str, value: float) -> None:
        """Sets an input in ``u``; it reaches the FMU with the next step."""
        if name not in self.u_index:
            self._require(name, "input")
        self.u[self.u_index[name]] = value

    def output(self, name: str) -> float:
        """The latest value of a Real output."""
        if name not in self.y_index:
            self._require(name, "output")
            raise PlantError(f"{name} is not a Real output; read it with get_value")
        return float(self.y[self.y_index[name]])

    def outputs(self) -> dict[str, float]:
        """All Real outputs and ``on_ground``, by name."""
        values = dict(zip(self.output_names, self.y.tolist(), strict=True))
        values["on_ground"] = float(self.on_ground)
        return values

    def reader(self, outputs: Sequence[int], inputs: Sequence[int]
               ) -> Callable[[int, int, tuple[float, ...]], None]:
        """``read(out_address, out_room, extras)``: the outputs and then the inputs at these indices,
        then ``extras``, written as doubles to ``out_address`` (``out_room`` doubles left there): one C
        call bound to this FMU's buffers (plant/steps.py's gather), for a table's row at 100 Hz (the
        recorder's)."""
        from rig.plant.steps import gather

        for what, idx, n in (("output", outputs, len(self.y)), ("input", inputs, len(self.u))):
            if any(not 0 <= i < n for i in idx):
                raise IndexError(f"an {what} index outside the plant's {n}: {list(idx)}")
        return functools.partial(gather(), ctypes.addressof(self._y_buf), len(self.y), tuple(outputs),
                                 ctypes.addressof(self._u_buf), len(self.u), tuple(inputs))

    @property
    def on_ground(self) -> bool:
        got = self.read_on_ground()
        if got < 0:
            self._check("reading on_ground", -got)
        return got == 1

    # ---- fast path ---------------------------------------------------------------------------

    def _read_outputs(self) -> None:
        status = self._get_real(self._component, self._y_vr, self._n_y, self._y_buf)
        if status > 1:
            self._fail("fmi2GetReal", status)

    @property
    def time(self) -> float:
        """The plant's time (s): the communication point of the next step."""
        return self._t.value

    @time.setter
    def time(self, value: float) -> None:
        self._t.value = value

    def step(self, dt: float, write_inputs: bool = True) -> None:
        """Writes ``u`` to the FMU, advances by ``dt`` seconds and refreshes ``y``. A caller that
        steps several times in a row with ``u`` untouched may skip the rewrite (``write_inputs``)."""
        c = self._component
        self._h.value = dt
        if write_inputs:
            status = self._raw_set_real(c, self._u_vr, self._n_u, self._u_buf)
            if status > 1:
                self._fail("fmi2SetReal", status)
        status = self._raw_do_step(c, self._t, self._h, self._no_rollback)
        if status > 1:
            self._fail("fmi2DoStep", status)
        status = self._raw_get_real(c, self._y_vr, self._n_y, self._y_buf)
        if status > 1:
            self._fail("fmi2GetReal", status)
        self._t.value += dt

    def step_many(self, n: int, dt: float, write_inputs: bool = True, ring: np.ndarray | None = None,
                  first_row: int = 0) -> None:
        """``n`` steps of ``dt`` with ``u`` unchanged, in one call into C (plant/c/plant_steps.c):
        the same FMI calls as ``n`` calls of ``step``, so the same result, at about a quarter of the
        cost. With ``ring`` (a C-contiguous float64 array of rows as long as ``y``, kept by the caller
        and passed again every time), ``y`` after step i is also copied into row
        ``(first_row + i) % len(ring)``."""
        steps = self._steps
        if steps is None:
            steps = self._steps = self._make_steps()
        if ring is not self._ring:
            if ring is not None and (ring.dtype != np.float64 or not ring.flags.c_contiguous
                                     or ring.ndim != 2 or ring.shape[1] != len(self.y)):
                raise ValueError(f"a ring holds C-contiguous float64 rows of {len(self.y)} outputs")
            self._ring = ring
            steps.ring = ring.ctypes.data if ring is not None else None
            steps.ring_rows = len(ring) if ring is not None else 0
        done = self._steps_fn(self._steps_at, n, dt, int(write_inputs), first_row)
        if done < n or steps.failed_call:
            self._fail(_STEP_CALLS.get(steps.failed_call, "rig_plant_steps"), steps.failed_status)

    def _make_steps(self) -> _Steps:
        def address(fn: Any) -> int | None:
            return ctypes.cast(fn, c_void_p).value

        steps = _Steps(address(self._raw_set_real), address(self._raw_do_step), address(self._raw_get_real),
                       self._component.value, addressof(self._u_vr), addressof(self._u_buf), len(self.u),
                       addressof(self._y_vr), addressof(self._y_buf), len(self.y), addressof(self._t),
                       None, 0, 0, 0)
        from rig.plant.steps import (
            plant_steps,  # (here: `python -m rig.plant.steps` must not import itself first)
        )

        self._steps_fn = plant_steps()
        self._steps_at = addressof(steps)
        return steps

    def run(self, duration: float, dt: float) -> None:
        """Steps with constant inputs for ``duration`` (a whole number of ``dt``)."""
        for _ in range(int(round(duration / dt))):
            self.step(dt)

    # ---- saved states ------------------------------------------------------------------------

    def save(self) -> PlantState:
        """Saves the complete FMU state, to start runs again from here with ``restore``."""
        handle = c_void_p()
        self._check("fmi2GetFMUstate", self._get_state(self._component, byref(handle)))
        state = PlantState(handle, self.time, self.u.copy())
        self._states.append(state)
        return state

    def restore(self, state: PlantState) -> None:
        """Puts the FMU back to a saved state: time, inputs, physics and outputs."""
        self._check("fmi2SetFMUstate", self._set_state(self._component, state.handle))
        self.time = state.time
        self.u[:] = state.inputs
        self._read_outputs()

    # ---- lifetime ----------------------------------------------------------------------------

    def close(self) -> None:
        """Frees the instance, its saved states and the extracted files; safe to call twice."""
        fmu = getattr(self, "_fmu", None)
        if fmu is not None and fmu.component:
            for state in self._states:
                self._free_state(self._component, byref(state.handle))
            self._states.clear()
            fmu.fmi2FreeInstance(self._component)
            fmu.component = None
            fmu.freeLibrary()
        self._fmu = None
        if getattr(self, "_own_unzip_dir", False):
            shutil.rmtree(self._unzip_dir, ignore_errors=True)
            self._own_unzip_dir = False

    def __enter__(self) -> Plant:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


#: Where an FMU's files are unzipped, beside it: one folder per FMU content, shared by every Plant
UNZIPPED = ".unzipped"


def _unzipped(fmu: Path, digest: str) -> tuple[str, bool]:
    """The FMU's files, unzipped once per content (``<fmu folder>/.unzipped/<sha256>``) and kept for the
    next instance, instead of a fresh temporary folder per instance that a crash or a forgotten close
    leaves behind (there were hundreds in /tmp). Parallel processes race safely: each unzips into a
    folder of its own and renames it into place; the loser removes its copy. Beside a read-only FMU,
    a temporary folder that ``close`` removes (the bool says so)."""
    cache = fmu.parent / UNZIPPED / digest
    if (cache / "modelDescription.xml").is_file():
        return str(cache), False
    try:
        cache.parent.mkdir(exist_ok=True)
        tmp = tempfile.mkdtemp(prefix=".unzipping-", dir=cache.parent)
    except OSError:
        return extract(str(fmu), unzipdir=tempfile.mkdtemp(prefix="plant-")), True
    try:
        extract(str(fmu), unzipdir=tmp)
        os.rename(tmp, cache)
    except OSError:
        shutil.rmtree(tmp, ignore_errors=True)
        if not (cache / "modelDescription.xml").is_file():
            raise
    return str(cache), False
