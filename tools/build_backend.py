"""The build backend (pyproject.toml's build-backend): setuptools' own, asking for more only to build a
wheel. setup.py's build of a wheel runs the make targets, which run the rig's own modules (``python -m
rig.lockstep`` imports the session's world, mypyc analyses the hot modules with their imports): that
build environment gets the project's dependencies (mypy among them, pinned). The editable install
(``pip install -e .``, ``make venv``) builds no artifact, so its build environment stays setuptools
alone, as before."""

from __future__ import annotations

import tomllib
from pathlib import Path

from setuptools import build_meta
from setuptools.build_meta import *  # noqa: F403 (every hook as setuptools has it; one is extended)


def get_requires_for_build_wheel(config_settings: dict[str, str | list[str]] | None = None) -> list[str]:
    project = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())["project"]
    return [*build_meta.get_requires_for_build_wheel(config_settings), *project["dependencies"]]
