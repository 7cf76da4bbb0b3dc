"""The quadrotor plant: an FMI 2.0 co-simulation FMU built from our C sources, run with fmpy.

Open ``plant/variables.py`` for the variable table, ``plant/c/`` for the physics and its FMI wrapper,
``plant/build.py`` for the reproducible build and ``plant/fmu.py`` for the fast Python stepping API.
"""

from rig.plant.fmu import DEFAULT_FMU, Plant, PlantError, PlantState

__all__ = ["DEFAULT_FMU", "Plant", "PlantError", "PlantState"]
