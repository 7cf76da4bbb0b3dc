"""The hot modules compiled with mypyc (rig/compiled.py): used while they match their sources, never
when they do not, and flying exactly the flight the Python source flies."""

from __future__ import annotations

import hashlib
import importlib
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from rig.compiled import MANIFEST, MODULES, OUT, REPO, CompiledFinder, source_of

SCENARIO = REPO / "scenarios" / "library" / "seed000_roll_stand.toml"

# Runs the scenario and prints which session ran it and a digest of everything it recorded and judged.
FLIGHT = """
import hashlib, sys, tempfile
import numpy as np
import rig.session
from scenarios.runner import run
from scenarios.schema import load
r = run(load(sys.argv[1]), work_dir=tempfile.mkdtemp(prefix="rig-flight-"))
h = hashlib.sha256(repr(r.measurements).encode())
for name in sorted(r.signals):
    h.update(name.encode())
    h.update(np.asarray(r.signals[name], dtype=float).tobytes())
print(rig.session.__file__, r.verdict, h.hexdigest())
"""


def _flight(pure: bool) -> list[str]:
    env = {k: v for k, v in os.environ.items() if k != "RIG_PURE_PYTHON"}
    if pure:
        env["RIG_PURE_PYTHON"] = "1"
    done = subprocess.run([sys.executable, "-c", FLIGHT, str(SCENARIO)], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return done.stdout.split()


def test_the_hot_modules_run_compiled() -> None:
    assert MANIFEST.exists(), "build/mypyc is missing: `make compiled` builds it (make test does)"
    for name in MODULES:
        module = importlib.import_module(name)
        assert Path(module.__file__ or "").is_relative_to(OUT), f"{name} runs from {module.__file__}"


def test_a_module_whose_source_changed_runs_from_the_source(capsys: pytest.CaptureFixture[str]) -> None:
    finder = CompiledFinder()
    spec = finder.find_spec("rig.session")
    assert spec is not None and Path(spec.origin or "").is_relative_to(OUT)
    finder.modules["rig.session"]["sha256"] = hashlib.sha256(b"an older session.py").hexdigest()
    assert finder.find_spec("rig.session") is None  # the path finder then loads rig/session.py
    assert finder.stale == ["rig.session"]
    assert "rig.session" in capsys.readouterr().err
    assert finder.find_spec("rig.capture") is None   # not compiled at all: not ours to find


def test_an_unreadable_manifest_means_no_compiled_modules(tmp_path: Path) -> None:
    (tmp_path / "manifest.json").write_text("{not json")
    assert CompiledFinder(tmp_path / "manifest.json").find_spec("rig.session") is None
    (tmp_path / "manifest.json").write_text(json.dumps({"modules": {"rig.session": {"file": "x.so"}}}))
    assert CompiledFinder(tmp_path / "manifest.json").find_spec("rig.session") is None


def test_the_makefile_rebuilds_when_any_compiled_source_changes() -> None:
    text = (REPO / "Makefile").read_text().replace("\\\n", " ")
    listed = re.search(r"^COMPILED_SOURCES := (.*)$", text, re.M)
    assert listed is not None
    assert sorted(listed[1].split()) == sorted(str(source_of(m).relative_to(REPO)) for m in MODULES)


def test_compiled_and_source_fly_the_same_flight_bit_for_bit() -> None:
    """The source is the reference: the compiled modules must not change a single recorded value."""
    compiled, pure = _flight(pure=False), _flight(pure=True)
    assert Path(compiled[0]).is_relative_to(OUT) and pure[0] == str(source_of("rig.session"))
    assert compiled[1] == pure[1] == "pass"
    assert compiled[2] == pure[2]
