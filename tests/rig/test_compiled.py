"""The hot modules compiled with mypyc (rig/compiled.py): used while they match their sources, never
when they do not, and flying exactly the flight the Python source flies."""

from __future__ import annotations

import hashlib
import importlib
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from rig.compiled import _SUFFIX, MANIFEST, MODULES, OUT, REPO, CompiledFinder, source_of

SCENARIO = REPO / "scenarios" / "library" / "seed000_roll_stand.toml"

# Runs the scenario (its work folder argv[2]) and prints which session ran it and a digest of everything
# it recorded and judged.
FLIGHT = """
import hashlib, sys
import numpy as np
from rig import compiled
compiled.install()
import rig.session
from rig.runner import run
from rig.scenarios.schema import load
r = run(load(sys.argv[1]), work_dir=sys.argv[2])
h = hashlib.sha256(repr(r.measurements).encode())
for name in sorted(r.signals):
    h.update(name.encode())
    h.update(np.asarray(r.signals[name], dtype=float).tobytes())
print(rig.session.__file__, r.verdict, h.hexdigest())
"""


def _flight(pure: bool, work: Path) -> list[str]:
    """The flight's digest; its work folder is the test's, so a child the timeout kills (SIGKILL: no
    clean-up of its own) leaves nothing in the system's temporary folder."""
    env = {k: v for k, v in os.environ.items() if k != "RIG_PURE_PYTHON"}
    if pure:
        env["RIG_PURE_PYTHON"] = "1"
    work.mkdir()
    done = subprocess.run([sys.executable, "-c", FLIGHT, str(SCENARIO), str(work)], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return done.stdout.split()


def test_the_hot_modules_run_compiled() -> None:
    assert MANIFEST.exists(), "build/mypyc is missing: `make compiled` builds it (make test does)"
    for name in MODULES:
        module = importlib.import_module(name)
        assert Path(module.__file__ or "").is_relative_to(OUT), f"{name} runs from {module.__file__}"


def _build_copy(tmp_path: Path, change: dict[str, str] | None = None) -> Path:
    """The real build seen through a manifest in tmp_path (its extensions linked), hashes changed as asked."""
    data = json.loads(MANIFEST.read_text())
    for module, entry in data["modules"].items():
        entry["sha256"] = (change or {}).get(module, entry["sha256"])
    for path in OUT.rglob(f"*{_SUFFIX}"):
        link = tmp_path / path.relative_to(OUT)
        link.parent.mkdir(parents=True, exist_ok=True)
        link.symlink_to(path)
    (tmp_path / "manifest.json").write_text(json.dumps(data))
    return tmp_path / "manifest.json"


def test_one_changed_source_sends_every_hot_module_back_to_source(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """All or none: the compiled world calls the compiled chip board natively, so an edited board.py must
    not run beside a compiled world."""
    fresh = CompiledFinder(_build_copy(tmp_path / "fresh"))
    for name in MODULES:
        spec = fresh.find_spec(name)
        assert spec is not None and Path(spec.origin or "").is_relative_to(tmp_path / "fresh"), name
    assert fresh.find_spec("rig.capture") is None   # not compiled at all: not this finder's to find
    older = hashlib.sha256(b"an older board.py").hexdigest()
    stale = CompiledFinder(_build_copy(tmp_path / "stale", {"rig.emulators.chips.board": older}))
    assert stale.stale == ["rig.emulators.chips.board"]
    assert [stale.find_spec(name) for name in (*MODULES, stale.runtime)] == [None] * (len(MODULES) + 1)
    assert "rig.emulators.chips.board" in capsys.readouterr().err


def test_a_broken_manifest_means_no_compiled_modules(tmp_path: Path) -> None:
    manifest = tmp_path / "manifest.json"
    for text in ("{not json", "[]", json.dumps({"modules": {"rig.session": {"file": "x.so"}}}),
                 json.dumps({"runtime": "rig_hot__mypyc", "modules": {"rig.session": {"file": "x.so"}}}),
                 json.dumps({"runtime": "rig_hot__mypyc", "modules": ["rig.session"]})):
        manifest.write_text(text)
        finder = CompiledFinder(manifest)
        assert finder.find_spec("rig.session") is None and finder.find_spec("rig_hot__mypyc") is None, text


def test_the_makefile_rebuilds_when_any_compiled_source_changes() -> None:
    """The Makefile reads the list from rig/compiled.py (one place): what make sees is MODULES."""
    done = subprocess.run(["make", "-s", "--no-print-directory", "--eval",
                           "print-compiled-sources: ; @echo $(COMPILED_SOURCES)", "print-compiled-sources"],
                          cwd=REPO, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert sorted(done.stdout.split()) == sorted(str(source_of(m).relative_to(REPO)) for m in MODULES)


def test_importing_the_packages_installs_no_import_hook() -> None:
    """The hook is the entry points' to install (CLI, tests, benches), not a side effect of an import."""
    code = ("import sys, rig.plant, rig.emulators, rig.scenarios, rig.reports, rig, rig.session, rig.world\n"
            "from rig.compiled import CompiledFinder\n"
            "print(any(isinstance(f, CompiledFinder) for f in sys.meta_path), rig.session.__file__)")
    done = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    installed, session = done.stdout.split()
    assert installed == "False" and session == str(source_of("rig.session"))


def test_compiled_and_source_fly_the_same_flight_bit_for_bit(tmp_path: Path) -> None:
    """The source is the reference: the compiled modules must not change a single recorded value."""
    compiled = _flight(pure=False, work=tmp_path / "compiled")
    pure = _flight(pure=True, work=tmp_path / "pure")
    assert Path(compiled[0]).is_relative_to(OUT) and pure[0] == str(source_of("rig.session"))
    assert compiled[1] == pure[1] == "pass"
    assert compiled[2] == pure[2]
