"""Options are checked before anything runs, as the README promises: a bad value is exit 2 with a
message naming the option, and nothing is written (not a report folder, not a run that errors)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest


def rig(cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rig.cli", *args], capture_output=True, text=True,
                          timeout=120, cwd=cwd)


def tree(root: Path) -> list[Path]:
    return sorted(root.rglob("*"))


@pytest.mark.parametrize(("args", "said"), [
    (("run", "seed000_roll_stand", "--out", "out", "--seed", "-1"),
     "argument --seed: expected an integer 0.."),
    (("run", "seed000_roll_stand", "--out", "out", "--seed", str(2**31)), "argument --seed"),
    (("run", "seed000_roll_stand", "--out", "out", "--wall-timeout", "-5"),
     "argument --wall-timeout: expected a finite number of seconds > 0, got -5"),
    (("run", "seed000_roll_stand", "--out", "out", "--wall-timeout", "nan"), "argument --wall-timeout"),
    (("sweep", "spec.toml", "--out", "out", "--wall-timeout", "-5"),
     "argument --wall-timeout: expected a finite number of seconds > 0, got -5"),
    (("sweep", "spec.toml", "--out", "out", "--wall-timeout", "0"), "argument --wall-timeout"),
    (("serve", "--data", "afile", "--port", "0"), "--data afile exists and is not a folder"),
    (("serve", "--data", "afile/data", "--port", "0"), "afile is not a folder"),
    (("serve", "--data", "d", "--engine", "http://127.0.0.1:8786"), "--engine: expected tcp://HOST:PORT"),
    (("serve", "--data", "d", "--engine", "tls://127.0.0.1:8786"), "a tls:// address needs --tls-ca-file"),
    (("serve", "--data", "d", "--tls-cert", "c.pem"), "go with --engine tls://HOST:PORT"),
    (("bench-host", "--engine", "tcp://127.0.0.1:8786", "--bridge", "virtual", "--host", "10.1.2.3"),
     "--host 10.1.2.3 listens beyond this machine: give a tls:// --engine"),
    (("bench-host", "--engine", "tcp://127.0.0.1:8786", "--bridge", "virtual", "--label", "site"),
     "--label: a label is k=v"),
    (("bench-host", "--engine", "nowhere", "--bridge", "virtual"), "--engine: expected tcp://HOST:PORT"),
    (("submit", "--server", "http://127.0.0.1:1", "step_roll", "--bench", "=x"), "--bench: a label is k=v"),
])
def test_a_bad_option_is_exit_2_with_nothing_written(tmp_path: Path, args: tuple[str, ...],
                                                     said: str) -> None:
    (tmp_path / "spec.toml").write_text('[sweep]\nscenario = "seed000_roll_stand"\nseeds = [0]\n')
    (tmp_path / "afile").write_text("not a folder\n")
    before = tree(tmp_path)
    r = rig(tmp_path, *args)
    assert r.returncode == 2, (r.returncode, r.stderr[-2000:])
    assert said in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert tree(tmp_path) == before  # nothing written
