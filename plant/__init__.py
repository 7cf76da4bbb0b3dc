"""The quadrotor plant: an FMI 2.0 co-simulation FMU built from our C sources, run with fmpy.

Open ``plant/variables.py`` for the variable table, ``plant/c/`` for the physics and its FMI wrapper,
``plant/build.py`` for the reproducible build and ``plant/fmu.py`` for the fast Python stepping API.

The names below are imported from ``fmu.py`` when first asked for, not with the package: the modules
that only build or locate things (``artifacts.py``, ``native_build.py``, ``build.py``) are imported
by the Makefile's helpers and the wheel's build, which have neither fmpy nor numpy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rig.plant.fmu import DEFAULT_FMU, Plant, PlantError, PlantState

__all__ = ["DEFAULT_FMU", "Plant", "PlantError", "PlantState"]


def __getattr__(name: str) -> object:
    if name in __all__:
        from rig.plant import fmu

        return getattr(fmu, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
