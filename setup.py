"""The wheel's build: ``pip install .`` and ``pip wheel .`` build everything a run needs with the tree's
own make targets and ship it inside the package, as ``rig/_build/`` (rig/plant/artifacts.py: where the
artifacts are, in a tree and installed).

Why setuptools with a build_py hook (and not meson-python or scikit-build-core): the builds already
exist, once, as make targets over Python build scripts (the FMU's reproducible zip and its generated
header, mypyc's compiled group and its manifest, the chip core's generated tables, the reference FC's own
Makefile). meson-python or scikit-build-core would have us describe every one of them a second time in
meson or CMake, and bring an editable mode of their own; this hook runs the same targets ``make`` runs,
into the same ``build/`` (so a built tree's wheel costs a copy), and copies what a run needs into the
wheel. The editable install (``pip install -e .``, what ``make venv`` does) builds nothing here: its
artifacts stay the tree's ``build/``, built by ``make`` and on first use, exactly as before.

The wheel holds compiled code for this interpreter and machine (cp311, linux_x86_64): built once, it
installs on any machine of the same kind; there it needs no compiler, only the C library (and Debian's
libsimavr for the MCU tier).
"""

from __future__ import annotations

import hashlib
import importlib.machinery
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

from setuptools import Distribution, setup
from setuptools.command.build_py import build_py

TREE = Path(__file__).resolve().parent
sys.path.insert(0, str(TREE))  # the tree's rig, whatever the build environment holds

from rig.plant.artifacts import BUILD, INSTALLED_BUILD, PACKAGE, TREE_COPIES, TREE_FILES  # noqa: E402

#: the make targets that build what a run needs (make all but the docs' and tests' builds)
TARGETS = ("fmu", "shim", "native", "compiled", "dut", "vbridge")
_EXT = importlib.machinery.EXTENSION_SUFFIXES[0]
#: what a run needs, relative to build/: the plant, the shim and the DUT's keeper, the C extensions, the
#: reference FC (and its single-precision twin), the virtual bridge; mypyc's build is copied whole
ARTIFACTS = ("plant/quadrotor.fmu", "librigshim.so", "rig-keeper",
             *(f"{m}{_EXT}" for m in ("_rignative", "_plantsteps", "_rigpace", "_riglockstep",
                                       "_rigtelemetry", "_rigevents")),
             "dut/fc", "dut/fc32", "vbridge")
#: the MCU engine's glue: built when Debian's libsimavr is there (else built on first use, when it is)
OPTIONAL = ("librigmcu.so",)


class BuildWithArtifacts(build_py):
    """build_py, then the artifacts into the package's ``rig/_build`` (not in editable mode)."""

    def run(self) -> None:
        super().run()
        if getattr(self, "editable_mode", False):
            return
        build = BUILD  # (the tree's build/: this is a tree)
        self._make()
        out = Path(self.build_lib) / INSTALLED_BUILD.relative_to(PACKAGE.parent)
        shutil.rmtree(out, ignore_errors=True)
        for rel in ARTIFACTS:
            self._copy(build / rel, out / rel)
        for rel in OPTIONAL:
            if (build / rel).is_file():
                self._copy(build / rel, out / rel)
        shutil.copytree(build / "mypyc", out / "mypyc", ignore=shutil.ignore_patterns("*.tmp"))
        for rel in TREE_FILES:
            self._copy(TREE / rel, out / TREE_COPIES / rel)
        self._unzip_fmu(out / "plant" / "quadrotor.fmu")

    @staticmethod
    def _unzip_fmu(fmu: Path) -> None:
        """The FMU unzipped where the plant looks first (rig/plant/fmu.py's cache beside it): an installed
        rig then writes nothing into site-packages, and a read-only one unzips nothing per run."""
        from rig.plant.fmu import UNZIPPED  # (fmpy: a wheel's build has it, an editable one needs none)

        with zipfile.ZipFile(fmu) as z:
            z.extractall(fmu.parent / UNZIPPED / hashlib.sha256(fmu.read_bytes()).hexdigest())

    @staticmethod
    def _make() -> None:
        """The tree's make targets with this interpreter; the virtualenv make would create is skipped
        (-o: this build environment is the one to use, and installs nothing)."""
        python = sys.executable
        jobs = max(1, len(os.sched_getaffinity(0)))
        subprocess.run(["make", "-s", f"-j{jobs}", "-o", ".venv/.installed", f"PYTHON={python}",
                        f"PY={python}", "INSTALLED=1", *TARGETS], cwd=TREE, check=True)
        mcu = subprocess.run([python, "-c", "from rig.mcu import engine; engine.lib()"], cwd=TREE,
                             capture_output=True, text=True)
        if mcu.returncode != 0:
            print("the MCU engine's glue is not in this wheel (no libsimavr-dev here); an installed rig "
                  "builds it on first use", file=sys.stderr)

    @staticmethod
    def _copy(src: Path, dst: Path) -> None:
        if not src.is_file():
            raise SystemExit(f"the wheel's build: {src} was not built")
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, dst)


class BinaryDistribution(Distribution):
    """A wheel for this interpreter and platform: it holds compiled code."""

    def has_ext_modules(self) -> bool:
        return True


setup(cmdclass={"build_py": BuildWithArtifacts}, distclass=BinaryDistribution)
