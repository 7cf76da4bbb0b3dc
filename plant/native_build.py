"""Compiling the rig's C: shared libraries, programs and CPython extension modules, with the system's C
compiler, atomically (a process loading a library at the same moment never sees half a file), and
with a clear message for a missing compiler, missing Python headers or a compile error.

It imports nothing of ours but where the artifacts go (plant/artifacts.py), so every layer uses it:
the plant's stepping (plant/steps.py), the sensors' sampling chain (emulators/native.py), the DUT's
shim and keeper (rig/shim/build.py). It lives with the plant because the plant is the bottom layer
(docs/design.md §2).
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import os
import subprocess
import sysconfig
from collections.abc import Callable, Sequence
from pathlib import Path
from types import ModuleType

from rig.plant.artifacts import INSTALLED

#: -ffp-contract=off: no fused multiply-adds, so C arithmetic rounds as the Python it replaced did.
#: -O3, -fno-semantic-interposition and -fno-math-errno change no result (the plant's build says why, and
#: why -fno-tree-slp-vectorize): the samples' and the chip core's share of an FC cycle 7.4 k -> 6.7 k
#: (bench/cycle_cost.py --breakdown).
CFLAGS = ("-std=c11", "-O3", "-fno-semantic-interposition", "-fno-math-errno", "-Wall", "-Wextra", "-Werror",
          "-ffp-contract=off", "-fno-tree-slp-vectorize")
SHARED = ("-fPIC", "-shared", "-fvisibility=hidden")
EXTENSION_SUFFIX = importlib.machinery.EXTENSION_SUFFIXES[0]


class NativeBuildError(RuntimeError):
    """The compiler failed or is missing; the message carries its output."""


def write_text_if_changed(out: Path, text: str) -> Path:
    """Writes a generated source ``out`` when its text changed (a build then recompiles only what
    needs it), atomically and through a temporary file of this process's own: two builds that make the
    same header at once (``make -j``: the chip library and the virtual bridge) each replace it whole."""
    if not out.is_file() or out.read_text() != text:
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = out.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(text)
        tmp.replace(out)
    return out


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
    """``out`` is missing, or (in a source tree) older than one of ``sources``. An installed package's
    artifacts are never stale: they were built with the wheel from the sources beside them, whose times
    are the unpacking's (rig/plant/artifacts.py)."""
    if INSTALLED or not out.is_file():
        return not out.is_file()
    return out.stat().st_mtime < max(s.stat().st_mtime for s in sources)


def compile_extension(sources: Sequence[Path], out: Path, what: str, libs: Sequence[str] = (),
                      flags: Sequence[str] = ()) -> Path:
    """A CPython extension module (its init function exported, everything else hidden unless marked)."""
    include = sysconfig.get_paths()["include"]
    if not (Path(include) / "Python.h").is_file():
        raise NativeBuildError(f"cannot build {what}: no Python.h in {include} (install python3-dev)")
    return compile_shared(sources, out, what, libs=libs, flags=[f"-I{include}", *flags])


def load_extension(name: str, path: Path) -> ModuleType:
    """The extension module ``name`` from ``path`` (outside sys.path: build/)."""
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def built_extension(name: str, path: Path, sources: Sequence[Path],
                    build: Callable[[], object]) -> ModuleType:
    """The extension module ``name`` from ``path``, made first by ``build`` when it is missing or one of
    ``sources`` is newer: every extension of the rig is built on first use, so a fresh clone needs no
    separate step."""
    if is_stale(path, sources):
        build()
    return load_extension(name, path)
