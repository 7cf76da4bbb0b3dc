"""The rig as a team installs it: a wheel built from the tree (setup.py: the make targets, their artifacts
inside the package), installed into a fresh virtualenv outside the tree, then used from other folders:
``rig --version``, ``rig run step_roll``, and the pytest plugin in a project that has its own
``scenarios`` package and a conftest importing it (the rig installs one import name, ``rig``).

Lean on purpose (the suite's slowest test): the wheel is built once, from a copy of the tree and its
``build/`` (times kept, so make rebuilds nothing that is up to date, and the tree itself is not
written), with this environment's build tools (``--no-build-isolation``); the virtualenv gets no
packages of its own but the wheel (``--no-deps``), and reads the rest from this environment's
site-packages through a ``.pth`` line, which adds the folder and nothing else of it (not the editable
install's hook): nothing is downloaded."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
import tomllib
from pathlib import Path

import pytest

TREE = Path(__file__).resolve().parents[1]
#: build/'s folders that the wheel's make targets write (with the libraries and programs at its top):
#: copied with their times, make finds them up to date; reports and setuptools' own folders are left
MADE_FOLDERS = ("plant", "gen", "mypyc", "dut")


def clean_env() -> dict[str, str]:
    """This environment without what would point the installed rig back at the tree or make its pytest
    a worker of ours: the rig's overrides (RIG_*), pytest-xdist's worker variables, PYTHONPATH."""
    return {k: v for k, v in os.environ.items()
            if not k.startswith(("RIG_", "PYTEST_", "PYTHON")) and k != "VIRTUAL_ENV"}


def run(cmd: list[str], cwd: Path, timeout: float = 600) -> subprocess.CompletedProcess[str]:
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout, env=clean_env())


def copy_tree(dst: Path) -> None:
    """The tree's files as git sees them (tracked and new, not ignored), links kept as links, and what
    its make targets built, all with their times."""
    listed = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=TREE,
                            capture_output=True, check=True).stdout.decode().split("\0")
    for rel in filter(None, listed):
        src = TREE / rel
        if not os.path.lexists(src):
            continue  # (deleted in the work tree, not yet in git)
        (dst / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, dst / rel, follow_symlinks=False)
    build = TREE / "build"
    for made in sorted(build.iterdir()) if build.is_dir() else []:
        if made.is_file() and not made.name.endswith(".tmp"):
            (dst / "build").mkdir(exist_ok=True)
            shutil.copy2(made, dst / "build" / made.name)
        elif made.is_dir() and made.name in MADE_FOLDERS:
            shutil.copytree(made, dst / "build" / made.name, symlinks=True,
                            ignore=shutil.ignore_patterns(".unzipped", "*.tmp"))


@pytest.fixture(scope="session")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fresh virtualenv outside the tree with the wheel installed: its bin folder."""
    tmp = tmp_path_factory.mktemp("install")
    src = tmp / "src"
    copy_tree(src)
    wheels = tmp / "wheels"
    built = run([sys.executable, "-m", "pip", "wheel", "-q", "--no-build-isolation", "--no-deps",
                 "--no-cache-dir", "-w", str(wheels), str(src)], cwd=tmp)
    assert built.returncode == 0, built.stdout + built.stderr
    (wheel,) = wheels.glob("quadrotor_hil_rig-*.whl")
    venv = tmp / "venv"
    made = run([sys.executable, "-m", "venv", "--without-pip", str(venv)], cwd=tmp)
    assert made.returncode == 0, made.stderr
    where = "import sysconfig; print(sysconfig.get_paths()['purelib'])"
    purelib = run([str(venv / "bin" / "python"), "-c", where], cwd=tmp).stdout.strip()
    Path(purelib, "dev-packages.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    done = run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q", "--no-deps", "--no-index",
                str(wheel)], cwd=tmp)
    assert done.returncode == 0, done.stdout + done.stderr
    shutil.rmtree(src)  # (nothing of the tree is left to be found)
    return venv / "bin"


#: the licences the wheel carries: the rig's, and the notices of what it vendors or is built with
NOTICES = ("LICENSE", "plant/fmi2/LICENSE.txt", "reports/vendor/uplot/LICENSE",
           "rig/service/static/htmx/LICENSE")


def test_an_installed_wheel_runs_from_anywhere(installed: Path, tmp_path: Path) -> None:
    """(One test, so that pytest-xdist never builds the wheel twice.)"""
    version = tomllib.loads((TREE / "pyproject.toml").read_text())["project"]["version"]
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()

    probe = "import rig, rig.compiled as c; c.install(); print(rig.__file__); print(c.all_compiled())"
    where = run([str(installed / "python"), "-c", probe], cwd=elsewhere)
    assert where.returncode == 0, where.stderr
    module, compiled = where.stdout.split()
    assert Path(module).is_relative_to(installed.parent) and compiled == "True", where.stdout + where.stderr

    shown = run([str(installed / "rig"), "--version"], cwd=elsewhere)
    assert (shown.returncode, shown.stdout.split()) == (0, ["rig", version]), shown.stdout + shown.stderr

    flown = run([str(installed / "rig"), "run", "step_roll", "--out", "reports"], cwd=elsewhere)
    assert flown.returncode == 0, flown.stdout + flown.stderr
    result = json.loads((elsewhere / "reports" / "step_roll" / "result.json").read_text())
    assert result["verdict"] == "pass"
    # the library's file and the reference FC are the installed package's
    assert Path(result["metadata"]["scenario_file"]).is_relative_to(installed.parent)
    assert result["metadata"]["dut_command"].startswith(str(installed.parent))

    # the STM32 tier needs a clone (QEMU's models are not in the wheel): a clear error, not a traceback
    stm32 = run([str(installed / "rig"), "run", "--mcu", "stm32f405-gy86", "--firmware",
                 str(TREE / "build" / "stm32" / "fc.elf"), "step_roll", "--out", "stm32"], cwd=elsewhere)
    said = stm32.stdout + stm32.stderr
    assert stm32.returncode != 0 and "is built from a clone of the rig" in said, said
    assert "Traceback" not in said and "FileNotFoundError" not in said, said

    (dist,) = Path(module).parents[1].glob("quadrotor_hil_rig-*.dist-info")
    assert all((dist / "licenses" / n).read_bytes() == (TREE / n).read_bytes() for n in NOTICES)
    assert "License-Expression: MIT AND BSD-2-Clause AND 0BSD" in (dist / "METADATA").read_text()

    # the plugin, in a project with its own scenarios package that its conftest imports
    project = tmp_path / "fw"
    (project / "scenarios").mkdir(parents=True)
    (project / "scenarios" / "__init__.py").write_text('NAME = "the team\'s own"\n')
    (project / "conftest.py").write_text("import scenarios\n\nTEAM = scenarios.NAME\n")
    (project / "test_team.py").write_text(
        "import scenarios\n\n\ndef test_own_package():\n    assert scenarios.NAME == \"the team's own\"\n")
    (project / "flights").mkdir()
    shutil.copy(TREE / "scenarios" / "library" / "step_roll.toml", project / "flights")
    done = run([str(installed / "python"), "-m", "pytest", "-p", "no:cacheprovider", "-q", "-n", "0",
                "--rootdir", str(project), "flights", "test_team.py"], cwd=project)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "2 passed" in done.stdout, done.stdout
    ran = json.loads((project / "build" / "rig-pytest" / "step_roll" / "result.json").read_text())
    assert ran["verdict"] == "pass"
