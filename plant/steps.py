"""The plant's steps between two requests in one call into C (plant/c/plant_steps.c, as the extension
module ``build/_plantsteps*.so``): built on first use, and again when a source is newer, so a fresh clone
needs no separate step; ``python -m rig.plant.steps`` (part of ``make native``) builds it explicitly."""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

from rig.plant.artifacts import BUILD
from rig.plant.native_build import (
    EXTENSION_SUFFIX,
    NativeBuildError,
    built_extension,
    compile_extension,
)

C_DIR = Path(__file__).resolve().parent / "c"
SOURCES = (C_DIR / "steps_module.c", C_DIR / "plant_steps.c")  # the module first: it includes the other
MODULE_NAME = "_plantsteps"
LIB = BUILD / f"{MODULE_NAME}{EXTENSION_SUFFIX}"


def build() -> Path:
    return compile_extension(SOURCES[:1], LIB, "the plant's stepping")


@functools.cache
def _module() -> ModuleType:
    return built_extension(MODULE_NAME, LIB, SOURCES, build)


def plant_steps() -> Callable[[int, int, float, int, int], int]:
    """``plant_steps(steps_address, n, h, write_inputs, first_row) -> steps completed``."""
    steps: Callable[[int, int, float, int, int], int] = _module().plant_steps
    return steps


def get_boolean() -> Callable[[int, int, int], int]:
    """``get_boolean(fmi2GetBoolean_address, component, vr) -> 0 or 1``, or minus a failed call's status."""
    fn: Callable[[int, int, int], int] = _module().get_boolean
    return fn


#: gather's signature: a's address, length and indices, b's, the row's address, its room, the extras
Gather = Callable[[int, int, tuple[int, ...], int, int, tuple[int, ...], int, int, tuple[float, ...]], None]


def gather() -> Gather:
    """``gather(a_address, a_len, a_indices, b_address, b_len, b_indices, out_address, out_room, extras)``:
    the doubles of two buffers at the given indices (each checked against its buffer's length), then
    the floats of the tuple ``extras``, written to the doubles at ``out_address`` (``out_room`` of them
    left there: a longer row is refused)."""
    fn: Gather = _module().gather
    return fn


if __name__ == "__main__":
    try:
        print(build())
    except NativeBuildError as e:
        sys.exit(str(e))
