"""The rig's own small C libraries: compiled with the system's C compiler on first use (and again when a
source is newer than the library), so a fresh clone needs no separate build step, and loaded with
ctypes. ``python -m emulators.native`` (``make native``) builds them explicitly.

Why ctypes and not a CPython extension: it needs no Python headers, and the libraries are plain C
with a handful of entry points. The shim (rig/shim/build.py) is compiled by the same function.
"""

from __future__ import annotations

import ctypes
import functools
import os
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
SAMPLING_SOURCE = REPO_ROOT / "emulators" / "c" / "sampling.c"
SAMPLING_LIB = REPO_ROOT / "build" / "libsampling.so"
PLANT_STEPS_SOURCE = REPO_ROOT / "emulators" / "c" / "plant_steps.c"
PLANT_STEPS_LIB = REPO_ROOT / "build" / "libplantsteps.so"
BLOCK = 64  #: most samples one call takes: buffers for C are this many rows
#: -ffp-contract=off: no fused multiply-adds, so the C arithmetic rounds as the Python it replaced did.
CFLAGS = ("-std=c11", "-O2", "-Wall", "-Wextra", "-Werror", "-fPIC", "-shared", "-fvisibility=hidden",
          "-ffp-contract=off")


class NativeBuildError(RuntimeError):
    """The compiler failed or is missing; the message carries its output."""


def compile_shared(sources: Sequence[Path], out: Path, what: str, libs: Sequence[str] = (),
                   cc: str | None = None) -> Path:
    """Compiles ``sources`` into the shared library ``out``, atomically: a process loading it at the
    same moment never sees a half-written file."""
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(f".{os.getpid()}.tmp")
    cmd = [cc or os.environ.get("CC", "gcc"), *CFLAGS, "-o", str(tmp), *map(str, sources), *libs]
    try:
        done = subprocess.run(cmd, capture_output=True, text=True)
    except FileNotFoundError as e:
        raise NativeBuildError(f"cannot build {what}: {e.filename} not found (install gcc)") from e
    if done.returncode != 0:
        tmp.unlink(missing_ok=True)
        raise NativeBuildError(f"building {what} failed:\n{' '.join(cmd)}\n{done.stderr}")
    tmp.replace(out)
    return out


def is_stale(out: Path, sources: Sequence[Path]) -> bool:
    return not out.is_file() or out.stat().st_mtime < max(s.stat().st_mtime for s in sources)


_P, _I32, _D = ctypes.c_void_p, ctypes.c_int32, ctypes.c_double
_Signatures = dict[str, tuple[object, list[object] | None]]
_SAMPLING: _Signatures = {
    "rig_channel_size": (ctypes.c_size_t, []),
    "rig_channel_init": (None, [_P, _P, _P, _D, _D, _D]),
    "rig_channel_normals": (None, [_P, _P, _I32]),
    "rig_channel_normals_left": (_I32, [_P]),
    "rig_channel_measure": (_I32, [_P, _I32, _P, _P, _P, _P]),
    "rig_imu_measure": (_I32, [_P, _P, _I32, _P, _P, _P, _D, _P]),
    "rig_lowpass_size": (ctypes.c_size_t, []),
    "rig_lowpass_max_depth": (_I32, []),
    "rig_lowpass_run": (None, [_P, _I32, _P, _I32, _D, _I32]),
    "rig_lowpass_catch_up": (None, [_P, _P, _D]),
    "rig_mpu_encode": (None, [_P, _P, _P, _P, _I32, _I32, _P, _D]),
}
#: (no argtypes: called once per plant advance with prebuilt ctypes objects, which skips the
#: per-argument conversion that argtypes would cost on every call)
_PLANT_STEPS: _Signatures = {"rig_plant_steps": (ctypes.c_int32, None)}

#: name -> (sources, library, what it is, entry points)
LIBRARIES: dict[str, tuple[list[Path], Path, str, _Signatures]] = {
    "sampling": ([SAMPLING_SOURCE], SAMPLING_LIB, "the sampling library", _SAMPLING),
    "plant_steps": ([PLANT_STEPS_SOURCE], PLANT_STEPS_LIB, "the plant-stepping library", _PLANT_STEPS),
}


def build(name: str) -> Path:
    sources, out, what, _ = LIBRARIES[name]
    return compile_shared(sources, out, what, libs=["-lm"])


@functools.cache
def library(name: str) -> ctypes.CDLL:
    """One of the rig's C libraries, built if missing or stale, its entry points typed."""
    sources, out, _, signatures = LIBRARIES[name]
    if is_stale(out, sources):
        build(name)
    lib = ctypes.CDLL(str(out))
    for fn_name, (restype, argtypes) in signatures.items():
        fn = getattr(lib, fn_name)
        fn.restype = restype
        if argtypes is not None:
            fn.argtypes = argtypes
    return lib


def sampling() -> ctypes.CDLL:
    """The IMU sampling chain (emulators/c/sampling.c)."""
    return library("sampling")


def plant_steps() -> ctypes.CDLL:
    """Several plant steps in one call (emulators/c/plant_steps.c)."""
    return library("plant_steps")


def state(size_fn: str) -> tuple[ctypes.Array[ctypes.c_char], int]:
    """Zeroed memory for one opaque C state, and its address (keep the buffer alive while in use)."""
    buf = ctypes.create_string_buffer(getattr(sampling(), size_fn)())
    return buf, ctypes.addressof(buf)


if __name__ == "__main__":
    try:
        for lib_name in LIBRARIES:
            print(build(lib_name))
    except NativeBuildError as e:
        sys.exit(str(e))
