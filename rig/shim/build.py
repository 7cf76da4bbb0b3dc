"""Builds ``build/librigshim.so``, the library ``rig exec`` preloads into the DUT, and
``build/rig-keeper``, the DUT's parent process (``keeper.c``: it ends everything the DUT started).

``rig exec`` calls ``ensure_shim()`` and ``ensure_keeper()`` so a fresh clone needs no separate build
step; ``make shim`` (and ``python -m rig.shim.build``) build both explicitly. ``RIG_SHIM`` points at a
prebuilt library instead.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from rig.plant.artifacts import BUILD
from rig.plant.native_build import NativeBuildError, compile_c, compile_shared, is_stale

SHIM_DIR = Path(__file__).resolve().parent
KEEPER_SOURCE = SHIM_DIR / "keeper.c"
#: The shim's sources, the one file compiled first: rigshim.c includes every other .c here but the
#: keeper's (one translation unit), and protocol.h. All of them decide whether the library is stale.
SOURCES = (SHIM_DIR / "rigshim.c",
           *sorted(p for p in SHIM_DIR.glob("*.[ch]") if p.name not in ("rigshim.c", KEEPER_SOURCE.name)))
DEFAULT_OUT = BUILD / "librigshim.so"
KEEPER = BUILD / "rig-keeper"


def build(out: Path = DEFAULT_OUT, cc: str | None = None) -> Path:
    return compile_shared([SOURCES[0]], out, "the shim", libs=["-ldl", "-lpthread"], cc=cc)


def build_keeper(out: Path = KEEPER, cc: str | None = None) -> Path:
    return compile_c([KEEPER_SOURCE], out, "the DUT keeper", cc=cc)


def ensure_keeper() -> Path:
    """The keeper program, (re)built when stale."""
    if is_stale(KEEPER, [KEEPER_SOURCE]):
        build_keeper()
    return KEEPER


def ensure_shim() -> Path:
    """The shim to preload: ``RIG_SHIM`` if set, else the default build, (re)built when stale."""
    if os.environ.get("RIG_SHIM"):
        path = Path(os.environ["RIG_SHIM"])
        if not path.is_file():
            raise NativeBuildError(f"RIG_SHIM={path} does not exist")
        return path
    if is_stale(DEFAULT_OUT, SOURCES):
        build()
    return DEFAULT_OUT


if __name__ == "__main__":
    try:
        print(build())
        print(build_keeper())
    except NativeBuildError as e:
        sys.exit(str(e))
