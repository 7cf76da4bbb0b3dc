"""Builds ``build/librigshim.so``, the library ``rig exec`` preloads into the DUT.

``rig exec`` calls ``ensure_shim()`` so a fresh clone needs no separate build step; ``make shim`` (and
``python -m rig.shim.build``) build it explicitly. ``RIG_SHIM`` points at a prebuilt library instead.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

SHIM_DIR = Path(__file__).resolve().parent
REPO_ROOT = SHIM_DIR.parent.parent
SOURCES = (SHIM_DIR / "rigshim.c", SHIM_DIR / "protocol.h")
DEFAULT_OUT = REPO_ROOT / "build" / "librigshim.so"
CFLAGS = ["-std=c11", "-O2", "-Wall", "-Wextra", "-Werror", "-fPIC", "-shared", "-fvisibility=hidden"]


class ShimBuildError(RuntimeError):
    """The compiler failed or is missing; the message carries its output."""


def build(out: Path = DEFAULT_OUT, cc: str | None = None) -> Path:
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(f".{os.getpid()}.tmp")
    cmd = [cc or os.environ.get("CC", "gcc"), *CFLAGS, "-o", str(tmp), str(SOURCES[0]), "-ldl", "-lpthread"]
    try:
        done = subprocess.run(cmd, capture_output=True, text=True)
    except FileNotFoundError as e:
        raise ShimBuildError(f"cannot build the shim: {e.filename} not found (install gcc)") from e
    if done.returncode != 0:
        tmp.unlink(missing_ok=True)
        raise ShimBuildError(f"building the shim failed:\n{' '.join(cmd)}\n{done.stderr}")
    tmp.replace(out)  # atomic: a concurrent `rig exec` never preloads a half-written library
    return out


def ensure_shim() -> Path:
    """The shim to preload: ``RIG_SHIM`` if set, else the default build, (re)built when stale."""
    if os.environ.get("RIG_SHIM"):
        path = Path(os.environ["RIG_SHIM"])
        if not path.is_file():
            raise ShimBuildError(f"RIG_SHIM={path} does not exist")
        return path
    newest = max(s.stat().st_mtime for s in SOURCES)
    if not DEFAULT_OUT.is_file() or DEFAULT_OUT.stat().st_mtime < newest:
        build()
    return DEFAULT_OUT


if __name__ == "__main__":
    try:
        print(build())
    except ShimBuildError as e:
        sys.exit(str(e))
