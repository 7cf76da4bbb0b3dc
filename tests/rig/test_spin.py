"""``--spin``: the session and the DUT on a core each, polling for each other's messages instead of
sleeping (rig/cores.py). It changes only how fast a run goes: the same flight gives the same signals,
measurements and I2C log, bit for bit, and a program sees the same virtual times."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from rig.cores import CoresError, placement
from tests.rig.helpers import PY, assert_same_flight, build_client, rig_exec


@pytest.fixture
def two_cores() -> Iterator[None]:
    """Every core of the machine for this test (an xdist worker holds one: tests/conftest.py), and what
    the rig and the programs it starts inherit; as it was afterwards."""
    was = os.sched_getaffinity(0)
    try:
        os.sched_setaffinity(0, range(os.cpu_count() or 1))
    except OSError:
        pass  # (a cpuset narrower than the machine: what it allows)
    if len(os.sched_getaffinity(0)) < 2:
        os.sched_setaffinity(0, was)
        pytest.skip("--spin takes two cores; this machine gives one")
    yield
    os.sched_setaffinity(0, was)


def test_the_placement_of_each_kind_of_run() -> None:
    cores = {0, 1, 2, 3}
    assert placement(cores, lockstep=True, pin=None, spin=False) == placement(cores, True, True, False)
    assert placement(cores, True, None, False).dut == placement(cores, True, None, False).session == {3}
    assert placement(cores, lockstep=False, pin=None, spin=False).dut is None   # real time: as it is
    assert placement(cores, lockstep=True, pin=False, spin=False).session is None
    spin = placement(cores, lockstep=True, pin=None, spin=True)
    assert spin.dut == {3} and spin.session == {2}                              # a core each
    for allowed, lockstep, pin, said in [({5}, True, None, "this process may use 1"),
                                         (cores, False, None, "lockstep"), (cores, True, True, "--pin")]:
        with pytest.raises(CoresError, match=said):
            placement(allowed, lockstep, pin, spin=True)


def test_a_flight_with_spin_is_the_flight_without(tmp_path: Path, two_cores: None) -> None:
    from rig import scenarios
    from rig.runner import run
    from rig.scenarios.schema import load
    from rig.targets.process import ProcessTarget

    library = Path(scenarios.__file__).parent / "library"
    sc = dataclasses.replace(load(library / "step_roll.toml"), duration=3.0)
    plain, spun = (run(sc, ProcessTarget(spin=s), seed=1, work_dir=tmp_path / str(s)) for s in (False, True))
    assert_same_flight(plain, spun)
    assert (plain.metadata["transport"]["spin"], spun.metadata["transport"]["spin"]) == (False, True)


def test_a_program_sees_the_same_times_and_runs_on_its_own_core(
        tmp_path: Path, tmp_path_factory: pytest.TempPathFactory, two_cores: None) -> None:
    dut = build_client(tmp_path_factory, "clocks_and_pwm")
    plain, spun = (rig_exec(tmp_path, str(dut), options=opts) for opts in ((), ("--spin",)))
    assert plain.returncode == spun.returncode == 0, spun.stderr
    assert spun.stdout == plain.stdout and "nanosleep" in plain.stdout
    # the program's cores and its session's (the parent of its keeper)
    where = ("import json, os; keeper = os.getppid(); "
             "session = int(open(f'/proc/{keeper}/stat').read().rsplit(')', 1)[1].split()[1]); "
             "print(json.dumps([sorted(os.sched_getaffinity(0)), sorted(os.sched_getaffinity(session))]))")
    cores = {opts: json.loads(rig_exec(tmp_path, PY, "-c", where, options=opts).stdout)
             for opts in ((), ("--spin",))}
    assert cores[()][0] == cores[()][1] and len(cores[()][0]) == 1   # without: one core for both
    dut_cores, session_cores = cores[("--spin",)]
    assert len(dut_cores) == len(session_cores) == 1 and dut_cores != session_cores  # a core each


def test_spin_on_one_core_is_refused_before_anything_starts(tmp_path: Path) -> None:
    def one_core() -> None:
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})

    out = tmp_path / "o"
    for argv in (["exec", "--spin", "--", "true"], ["run", "--spin", "--out", str(out), "step_roll"]):
        done = subprocess.run([sys.executable, "-m", "rig.cli", *argv], capture_output=True, text=True,
                              timeout=120, preexec_fn=one_core)
        assert done.returncode == 2, done.stderr
        assert "--spin takes two CPU cores; this process may use 1" in done.stderr
        assert "Traceback" not in done.stderr
    assert not (tmp_path / "o").exists()
