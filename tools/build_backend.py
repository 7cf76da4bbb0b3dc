"""The build backend (pyproject.toml's build-backend): setuptools' own, asking for more only to build a
wheel. setup.py's build of a wheel runs the make targets, which need mypy (mypyc, pinned as the project
pins it) and import numpy and fmpy; the editable install (``pip install -e .``, ``make venv``) builds no
artifact, so its build environment stays setuptools alone, as before."""

from __future__ import annotations

from setuptools import build_meta
from setuptools.build_meta import *  # noqa: F403 (every hook as setuptools has it; one is extended)

#: what setup.py's make targets need beyond setuptools
WHEEL_BUILD_REQUIRES = ["mypy==2.4.1", "numpy>=1.26", "fmpy>=0.3.20"]


def get_requires_for_build_wheel(config_settings: dict[str, str | list[str]] | None = None) -> list[str]:
    return [*build_meta.get_requires_for_build_wheel(config_settings), *WHEEL_BUILD_REQUIRES]
