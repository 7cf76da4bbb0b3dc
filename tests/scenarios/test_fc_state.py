"""``{state}`` in a profile's arguments: a folder for the files an FC keeps between boots (ArduPilot's
parameter storage), empty at the start of every run, so that a run never starts from what an earlier
one saved: under ``rig run`` the run's own ``fc-state`` folder, emptied; under ``rig exec`` a temporary
folder, removed after the run."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from rig.scenarios import profile as profiles
from rig.scenarios import schema
from rig.targets.process import command_for
from tests.api import SHORT

PY = sys.executable


def state_profile(tmp_path: Path) -> Path:
    path = tmp_path / "keeps-state.toml"
    path.write_text('[modes]\nangle_deg = 30\n[config]\nargs = ["--storage-directory", "{state}"]\n')
    return path


def test_state_stands_for_the_folder_given_and_is_required() -> None:
    config = profiles.Config(None, None, ("-s", "{state}/params", "{state}"))
    assert config.keeps_state
    assert config.arguments(Path("/runs/a")) == ["-s", "/runs/a/params", "/runs/a"]
    with pytest.raises(ValueError, match="state"):
        config.arguments()
    assert not profiles.Config(None, None, ("-s", "x")).keeps_state


def test_a_run_into_the_same_folder_starts_from_an_empty_state(tmp_path: Path) -> None:
    profile = profiles.load(state_profile(tmp_path))
    scenario = schema.load(SHORT)
    work = tmp_path / "out" / SHORT.stem
    first = command_for(["fc"], scenario, work, [], profile)
    assert first[:2] == ["fc", "--storage-directory"]
    state = Path(first[2])
    assert state == work / "fc-state" and state.is_dir() and not any(state.iterdir())
    (state / "ArduCopter.stg").write_bytes(b"what the first run saved")
    (state / "logs").mkdir()
    again = command_for(["fc"], scenario, work, [], profile)
    assert again == first and state.is_dir() and not any(state.iterdir())


def test_exec_gives_an_empty_folder_and_removes_it_after(tmp_path: Path) -> None:
    # the command reports what it found in the folder, then leaves a file there
    script = ("import json, os, sys; d = sys.argv[-1]; print(json.dumps([d, os.listdir(d)])); "
              "open(d + '/x', 'w')")
    done = subprocess.run([PY, "-m", "rig.cli", "exec", "--fc", str(state_profile(tmp_path)),
                           "--allow-no-devices", "--wall-timeout", "60", "--", PY, "-c", script],
                          capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    folder, found = json.loads(done.stdout.splitlines()[-1])
    assert found == [] and Path(folder).name.startswith("rig-fc-state-")
    assert not Path(folder).exists()
    assert not list(tmp_path.glob("x")) and not list(tmp_path.glob("*.stg"))
