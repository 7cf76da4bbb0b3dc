"""Runs ``rig exec`` as a user would (a subprocess of the real CLI) and reads its JSON summary."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

#: programs that use the emulated devices as a DUT would, run under `rig exec` by the tests
DUTS = Path(__file__).resolve().parent / "device_clients"
PY = sys.executable


@dataclass
class Run:
    returncode: int
    stdout: str
    stderr: str
    summary: dict

    def json_out(self) -> dict:
        return json.loads(self.stdout.strip().splitlines()[-1])


def rig_exec(tmp_path: Path, *command: str, options: tuple[str, ...] = (), stdin: str | None = None) -> Run:
    summary = tmp_path / f"summary-{len(list(tmp_path.glob('summary-*')))}.json"
    done = subprocess.run([PY, "-m", "rig.cli", "exec", "--summary", str(summary), *options, "--", *command],
                          capture_output=True, text=True, input=stdin, timeout=300)
    data = json.loads(summary.read_text()) if summary.exists() else {}
    return Run(done.returncode, done.stdout, done.stderr, data)


def tool(name: str) -> str:
    """A Debian i2c-tools program (in /usr/sbin, which a user's PATH may lack)."""
    found = shutil.which(name, path=os.environ.get("PATH", "") + ":/usr/sbin:/sbin")
    if found is None:
        pytest.fail(f"{name} is missing: the project's setup (tools/bootstrap.sh) installs i2c-tools")
    return found


def build_client(tmp_path_factory: pytest.TempPathFactory, name: str, *flags: str) -> Path:
    """device_clients/NAME.c compiled as a user would build a C program, warnings as errors (flags:
    more of gcc's, -pthread say)."""
    exe = tmp_path_factory.mktemp("dut") / name
    subprocess.run(["gcc", "-std=c11", "-O1", "-Wall", "-Wextra", "-Werror", *flags, "-o", str(exe),
                    str(DUTS / f"{name}.c")], check=True)
    return exe


def assert_same_flight(a: Any, b: Any) -> None:
    """Two runs' results (rig.runner.run) equal to the bit: verdict, measurements, every recorded
    signal, the I2C log and the RC frames (a change of how a run goes, not of what it does)."""
    import dataclasses

    import numpy as np

    assert a.verdict == b.verdict and a.error is None is b.error
    assert [dataclasses.astuple(m) for m in a.measurements] == [
        dataclasses.astuple(m) for m in b.measurements]
    assert a.signals.keys() == b.signals.keys()
    for name, values in a.signals.items():
        assert np.array_equal(values, b.signals[name], equal_nan=True), name
    assert a.i2c is not None and len(a.i2c) > 1000 and a.i2c == b.i2c
    assert a.rc_frames == b.rc_frames
