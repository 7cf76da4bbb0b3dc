"""The session's hot modules compiled to C with mypyc, and the import hook that uses them only while
they match their sources.

Why: in lockstep the session's CPU is the rig's speed limit, and it is spread thin over small Python
functions (message handling, the world's clock, the register files): no single part is worth moving to
C by hand. mypyc compiles these modules, as written and type-annotated, into CPython extensions; the
same source stays the reference and still runs as plain Python.

Why an import hook and not extensions next to the sources: an extension beside ``session.py`` would be
imported instead of it even after the source is edited, and the edit would silently do nothing. The
compiled modules live in ``build/mypyc/`` (installed: the package's copy, plant/artifacts.py) with the
sha256 of each source they came from; they are loaded from there only while every source's hash matches,
else all run from source and one line on stderr says so. ``RIG_PURE_PYTHON=1`` turns the compiled
modules off (a second implementation to compare against, and plain tracebacks).

Built by ``python -m rig.mypyc_build`` (``make compiled``; part of make all, demo, test and bench). The
entry points (rig/cli.py, tests/conftest.py, bench/) call ``install()`` before they import a hot module;
importing a package installs nothing. This module imports only the standard library and where the build
is (plant/artifacts.py), so the Makefile reads the list from it (``python3 -m rig.compiled --sources``).
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import json
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType

from rig.plant.artifacts import BUILD, PACKAGE

#: the folder the modules are named from (the tree's root, or site-packages), and the build's
REPO = PACKAGE.parent
OUT = BUILD / "mypyc"
MANIFEST = OUT / "manifest.json"
GROUP = "rig_hot"  # mypyc's shared runtime library is the extension ``rig_hot__mypyc``

#: What is compiled: the modules that run per DUT message or per scheduled event in lockstep.
#: The chips run in C (emulators/chips/); their Python classes (emulators.mpu6050, hmc5883l,
#: registers) are the plain-Python reference the core is tested against, and the host-side producers
#: that feed the core are compiled instead.
MODULES = ("rig.protocol", "rig.connection", "rig.session", "rig.handler", "rig.scheduler", "rig.world",
           "rig.rc",
           "rig.emulators.chips.board", "rig.emulators.dlpf", "rig.emulators.sensor_models",
           "rig.emulators.faults", "rig.emulators.ms5611", "rig.emulators.i2c_bus", "rig.emulators.sbus",
           "rig.runner")


def source_of(module: str) -> Path:
    return REPO / Path(*module.split(".")).with_suffix(".py")


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


class CompiledFinder(importlib.abc.MetaPathFinder):
    """Finds the compiled extensions of the listed modules while every source is the one they were built
    from. All or none: mypyc compiles the modules as one group whose classes call each other natively,
    so a compiled world.py would go on using the compiled MPU6050 of an edited mpu6050.py."""

    def __init__(self, manifest: Path = MANIFEST) -> None:
        self.dir = manifest.parent
        self.modules: dict[str, str] = {}  # module -> its extension, relative to dir
        self.runtime = ""
        self.stale: list[str] = []
        try:
            data = json.loads(manifest.read_text())
            entries = {str(m): (str(e["file"]), str(e["sha256"])) for m, e in data["modules"].items()}
            runtime = str(data["runtime"])
        except (OSError, ValueError, KeyError, TypeError, AttributeError):
            return  # no build, or not one of ours: everything runs from source
        self.stale = [m for m, (_, digest) in entries.items() if not _built_from(m, digest)]
        if self.stale:
            print(f"rig: {', '.join(self.stale)} changed since {self.dir} was built; the hot modules run "
                  "from their sources (slower) until `make compiled`", file=sys.stderr)
            return
        self.modules, self.runtime = {m: file for m, (file, _) in entries.items()}, runtime

    def find_spec(self, fullname: str, path: Sequence[str] | None = None,
                  target: ModuleType | None = None) -> importlib.machinery.ModuleSpec | None:
        if fullname == self.runtime and self.runtime:
            return self._spec(fullname, self.dir / f"{fullname}{_SUFFIX}")
        file = self.modules.get(fullname)
        return None if file is None else self._spec(fullname, self.dir / file)

    @staticmethod
    def _spec(name: str, path: Path) -> importlib.machinery.ModuleSpec | None:
        if not path.is_file():
            return None
        loader = importlib.machinery.ExtensionFileLoader(name, str(path))
        return importlib.util.spec_from_file_location(name, path, loader=loader)


def _built_from(module: str, digest: str) -> bool:
    try:
        return sha256(source_of(module)) == digest
    except OSError:
        return False


_SUFFIX = importlib.machinery.EXTENSION_SUFFIXES[0]


def _compiled() -> list[str]:
    """The hot modules this process runs compiled (importing them)."""
    loaded = [importlib.import_module(m) for m in MODULES]
    return [m.__name__ for m in loaded if Path(m.__file__ or "").is_relative_to(OUT)]


def all_compiled() -> bool:
    """Every hot module runs compiled in this process (what a benchmark of the compiled session needs)."""
    return len(_compiled()) == len(MODULES)


def status() -> str:
    """Which implementation of the hot modules this process runs, for benchmarks to print."""
    compiled = _compiled()
    if len(compiled) == len(MODULES):
        return "hot modules compiled (build/mypyc)"
    why = "RIG_PURE_PYTHON=1" if os.environ.get("RIG_PURE_PYTHON") == "1" else "build/mypyc missing or stale"
    return f"hot modules: {len(compiled)} of {len(MODULES)} compiled ({why})"


def install() -> None:
    """Puts the finder first on ``sys.meta_path`` (once), unless ``RIG_PURE_PYTHON=1``."""
    if os.environ.get("RIG_PURE_PYTHON") == "1" or any(isinstance(f, CompiledFinder) for f in sys.meta_path):
        return
    if MANIFEST.exists():
        sys.meta_path.insert(0, CompiledFinder())


if __name__ == "__main__":  # the Makefile's list of sources (one place for it)
    if sys.argv[1:] == ["--sources"]:
        print(" ".join(str(source_of(m).relative_to(REPO)) for m in MODULES))
