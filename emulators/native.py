"""The emulators' C library (the sensors' sampling chain): compiled with the system's C compiler on first
use (and again when a source is newer than the library), so a fresh clone needs no separate build step.
``python -m rig.emulators.native`` (``make native``) builds it explicitly.

It is one file, a CPython extension module (emulators/c/fastcalls.c, which includes sampling.c): the
entry points that run every FC cycle are called as the module's functions (``fast()``), at a few
hundred instructions a call where ctypes cost thousands; the set-up entry points (sizes, init) are
called through ctypes on the same file (``sampling()``), which keeps their argument checking in Python.
The Python headers it needs are the ones mypyc needs (python3-dev). The plant's stepping is the
plant's own (plant/steps.py).
"""

from __future__ import annotations

import ctypes
import functools
import sys
from pathlib import Path
from types import ModuleType

from rig.plant.artifacts import BUILD
from rig.plant.native_build import (
    EXTENSION_SUFFIX,
    NativeBuildError,
    compile_extension,
    is_stale,
    load_extension,
)

C_DIR = Path(__file__).resolve().parent / "c"
CHIPS_DIR = Path(__file__).resolve().parent / "chips"
SAMPLING_SOURCE = C_DIR / "sampling.c"
#: the chip core (emulators/chips/chip_core.h), compiled into the same library
CHIP_SOURCES = tuple(CHIPS_DIR / f for f in ("board.c", "mpu6050.c", "hmc5883l.c", "ms5611.c"))
CHIP_HEADERS = (CHIPS_DIR / "chip_core.h", CHIPS_DIR / "chip_internal.h")
#: the module's source first: it includes sampling.c (one translation unit); the chip core's files follow
SOURCES = (C_DIR / "fastcalls.c", SAMPLING_SOURCE, C_DIR / "need_tuple.h", *CHIP_SOURCES, *CHIP_HEADERS)
#: the chip core's entry points are exported (ctypes reaches its set-up calls)
CHIP_FLAGS = ("-DCHIP_API=__attribute__((visibility(\"default\")))", f"-I{CHIPS_DIR}")
MODULE_NAME = "_rignative"
LIB = BUILD / f"{MODULE_NAME}{EXTENSION_SUFFIX}"
BLOCK = 64  #: most samples one call takes: buffers for C are this many rows


_P, _I32, _D = ctypes.c_void_p, ctypes.c_int32, ctypes.c_double
#: the set-up entry points called through ctypes (the per-cycle ones are fast()'s)
_SAMPLING: dict[str, tuple[object, list[object]]] = {
    "rig_channel_size": (ctypes.c_size_t, []),
    "rig_channel_init": (None, [_P, _P, _P, _D, _D, _D]),
    "rig_channel_normals": (None, [_P, _P, _I32]),
    "rig_channel_normals_left": (_I32, [_P]),
    "rig_lowpass_size": (ctypes.c_size_t, []),
    "rig_lowpass_max_depth": (_I32, []),
    "rig_lowpass_catch_up": (None, [_P, _P, _D]),
}


#: the chip core's set-up entry points (emulators/chips/chip_core.h), called through ctypes
_CHIPS: dict[str, tuple[object, list[object]]] = {
    "rig_chip_board_size": (ctypes.c_size_t, []),
    "chip_board_init": (None, [_P, ctypes.c_uint8]),
    "chip_board_demand": (None, [_P, ctypes.c_bool]),
    "chip_ms5611_prom": (None, [_P, _P]),
    "chip_ms5611_max_timing": (None, [_P, ctypes.c_bool]),
    "chip_hmc_status_wraps": (None, [_P, ctypes.c_bool]),
    "chip_bus_fault_add": (ctypes.c_bool, [_P, ctypes.c_uint8, ctypes.c_uint8, *[ctypes.c_uint64] * 4]),
    "chip_bus_fault_seed": (None, [_P, ctypes.c_uint8, ctypes.c_uint64]),
    "chip_bus_fault_clear": (None, [_P, ctypes.c_uint8]),
    "chip_peek": (ctypes.c_uint8, [_P, ctypes.c_uint8, ctypes.c_uint8]),
    "chip_mpu_bypass": (ctypes.c_bool, [_P]),
    "chip_count": (ctypes.c_uint32, [_P, ctypes.c_uint8]),
    "chip_start": (ctypes.c_bool, [_P, ctypes.c_uint64, ctypes.c_uint8, ctypes.c_bool]),
    "chip_write_byte": (None, [_P, ctypes.c_uint8]),
    "chip_read_byte": (ctypes.c_uint8, [_P]),
    "chip_unread_byte": (None, [_P]),
    "chip_read_preview": (ctypes.c_bool, [_P, ctypes.c_uint64, ctypes.c_uint8,
                                          ctypes.POINTER(ctypes.c_uint8)]),
    "chip_prepare": (None, [_P]),
    "chip_stop": (None, [_P]),
}


def build() -> Path:
    from rig.emulators.chips import gen  # the chip core's generated register tables (build/gen/)

    header = gen.write()
    return compile_extension((SOURCES[0], *CHIP_SOURCES), LIB, "the emulators' C library", libs=["-lm"],
                             flags=(*CHIP_FLAGS, f"-I{header.parent}"))


def _sources() -> tuple[Path, ...]:
    from rig.emulators.chips import gen

    return (*SOURCES, *gen.SOURCES)


def _ensure_built() -> Path:
    if is_stale(LIB, _sources()):
        build()
    return LIB


@functools.cache
def sampling() -> ctypes.CDLL:
    """The library through ctypes, its set-up entry points typed (emulators/c/sampling.c)."""
    lib = ctypes.CDLL(str(_ensure_built()))
    for name, (restype, argtypes) in _SAMPLING.items():
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = restype, argtypes
    return lib


@functools.cache
def chips() -> ctypes.CDLL:
    """The chip core's set-up and byte-level entry points through ctypes (the per-transfer ones are
    fast()'s: chip_transfer, chip_advance, chip_push_*)."""
    lib = ctypes.CDLL(str(_ensure_built()))
    for name, (restype, argtypes) in _CHIPS.items():
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = restype, argtypes
    return lib


@functools.cache
def fast() -> ModuleType:
    """The library as a Python module: its per-cycle entry points (emulators/c/fastcalls.c)."""
    return load_extension(MODULE_NAME, _ensure_built())


def state(size_fn: str) -> tuple[ctypes.Array[ctypes.c_char], int]:
    """Zeroed memory for one opaque C state, and its address (keep the buffer alive while in use)."""
    buf = ctypes.create_string_buffer(getattr(sampling(), size_fn)())
    return buf, ctypes.addressof(buf)


if __name__ == "__main__":
    try:
        print(build())
    except NativeBuildError as e:
        sys.exit(str(e))
