"""The emulators' C library (the sensors' sampling chain): compiled with the system's C compiler on first
use (and again when a source is newer than the library), so a fresh clone needs no separate build step.
``python -m emulators.native`` (``make native``) builds it explicitly.

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

from plant.native_build import (
    BUILD,
    EXTENSION_SUFFIX,
    NativeBuildError,
    compile_extension,
    is_stale,
    load_extension,
)

C_DIR = Path(__file__).resolve().parent / "c"
SAMPLING_SOURCE = C_DIR / "sampling.c"
#: the module's source first: it includes the others (one translation unit)
SOURCES = (C_DIR / "fastcalls.c", SAMPLING_SOURCE)
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


def build() -> Path:
    return compile_extension(SOURCES[:1], LIB, "the emulators' C library", libs=["-lm"])


def _ensure_built() -> Path:
    if is_stale(LIB, SOURCES):
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
