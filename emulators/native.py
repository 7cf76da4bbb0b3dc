"""The rig's own C library: compiled with the system's C compiler on first use (and again when a source
is newer than the library), so a fresh clone needs no separate build step. ``python -m
emulators.native`` (``make native``) builds it explicitly.

It is one file, a CPython extension module (emulators/c/fastcalls.c, which includes sampling.c and
plant_steps.c): the entry points that run every FC cycle are called as the module's functions
(``fast()``), at a few hundred instructions a call where ctypes cost thousands; the set-up entry
points (sizes, init) are called through ctypes on the same file (``sampling()``), which keeps their
argument checking in Python. The Python headers it needs are the ones mypyc needs (python3-dev).
"""

from __future__ import annotations

import ctypes
import functools
import importlib.machinery
import importlib.util
import os
import subprocess
import sys
import sysconfig
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType

REPO_ROOT = Path(__file__).resolve().parent.parent
C_DIR = REPO_ROOT / "emulators" / "c"
SAMPLING_SOURCE = C_DIR / "sampling.c"
#: the module's source first: it includes the others (one translation unit)
SOURCES = (C_DIR / "fastcalls.c", SAMPLING_SOURCE, C_DIR / "plant_steps.c")
MODULE_NAME = "_rignative"
LIB = REPO_ROOT / "build" / f"{MODULE_NAME}{importlib.machinery.EXTENSION_SUFFIXES[0]}"
BLOCK = 64  #: most samples one call takes: buffers for C are this many rows
#: -ffp-contract=off: no fused multiply-adds, so the C arithmetic rounds as the Python it replaced did.
CFLAGS = ("-std=c11", "-O2", "-Wall", "-Wextra", "-Werror", "-ffp-contract=off")
SHARED = ("-fPIC", "-shared", "-fvisibility=hidden")


class NativeBuildError(RuntimeError):
    """The compiler failed or is missing; the message carries its output."""


def compile_shared(sources: Sequence[Path], out: Path, what: str, libs: Sequence[str] = (),
                   cc: str | None = None, flags: Sequence[str] = ()) -> Path:
    """Compiles ``sources`` into the shared library ``out``, atomically: a process loading it at the
    same moment never sees a half-written file."""
    return compile_c(sources, out, what, libs, cc, (*SHARED, *flags))


def compile_c(sources: Sequence[Path], out: Path, what: str, libs: Sequence[str] = (),
              cc: str | None = None, flags: Sequence[str] = ()) -> Path:
    """Compiles and links ``sources`` into ``out`` (a program unless ``flags`` say otherwise),
    atomically."""
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(f".{os.getpid()}.tmp")
    cmd = [cc or os.environ.get("CC", "gcc"), *CFLAGS, *flags, "-o", str(tmp), *map(str, sources), *libs]
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
    include = sysconfig.get_paths()["include"]
    if not (Path(include) / "Python.h").is_file():
        raise NativeBuildError(f"cannot build the rig's C library: no Python.h in {include} "
                               "(install python3-dev)")
    return compile_shared(SOURCES[:1], LIB, "the rig's C library", libs=["-lm"], flags=[f"-I{include}"])


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
    spec = importlib.util.spec_from_file_location(MODULE_NAME, _ensure_built())
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def state(size_fn: str) -> tuple[ctypes.Array[ctypes.c_char], int]:
    """Zeroed memory for one opaque C state, and its address (keep the buffer alive while in use)."""
    buf = ctypes.create_string_buffer(getattr(sampling(), size_fn)())
    return buf, ctypes.addressof(buf)


if __name__ == "__main__":
    try:
        print(build())
    except NativeBuildError as e:
        sys.exit(str(e))
