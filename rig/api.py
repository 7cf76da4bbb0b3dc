"""The rig's public Python API (docs/api.md): run a scenario, read its result, check files, sweep.

Firmware teams drive their hardware tests from Python (pytest above all: rig/pytest_plugin.py is
built on this module). Everything here is stable within a major version; the modules behind it
(rig.runner, rig.targets, scenarios.schema, rig.sweep...) stay free to change, so nothing of theirs
leaks out: results are this module's own frozen dataclasses, telemetry and sweep tables are pyarrow
Tables. A run goes through the same checks and writes the same files as ``rig run`` (the option
checks of rig/run_cmd.py's ``plan``, its report folder and its ``write_run``), so a run made here and
one made on the command line are the same run.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from rig.scenarios.schema import Scenario, ScenarioError

if TYPE_CHECKING:
    import pyarrow as pa

__all__ = ["Criterion", "Result", "RigError", "Scenario", "ScenarioError", "load_scenario", "run", "sweep",
           "validate"]

#: The files a run folder may hold, by kind, as ``Result.artifacts`` names them (run.mcap only when the
#: run's writer made it)
ARTIFACTS = {"result": "result.json", "telemetry": "telemetry.csv", "report": "report.html",
             "junit": "junit.xml", "mcap": "run.mcap"}


class RigError(Exception):
    """Bad options, an unreadable scenario, an engine that cannot be reached: nothing was run."""


#: rig run's options that stand for an argument of run(): its problems name the argument, not the flag
#: (``dut=""`` is "dut is empty"; the command line keeps "--dut is empty")
API_NAMES: Final = {"--dut": "dut", "--mcu": "mcu", "--firmware": "mcu's firmware", "--bridge": "bridge",
                    "--spin": "spin", "--seed": "seed", "--wall-timeout": "wall_timeout", "--out": "out",
                    "--jobs": "jobs", "--engine": "engine", "--fresh": "fresh", "--eeprom": "eeprom",
                    "--pwm-channels": "pwm_channels", "--topology": "topology", "--airframe": "airframe",
                    "--fc": "fc"}


def api_words(message: str) -> str:
    """A problem ``rig run`` gave in its flags' words, in run()'s argument names."""
    return re.sub(r"(?<![\w/.-])--[a-z][a-z-]*", lambda m: API_NAMES.get(m.group(0), m.group(0)), message)


@dataclass(frozen=True)
class Criterion:
    """One measured criterion: ``value`` in ``units`` against ``min``/``max`` (None: no limit on that
    side); ``margin`` is how far inside the nearer limit the value is, in % (None: no margin, e.g. a
    one-sided limit at zero); ``outcome`` "pass", "fail", "not judged" (a run that ended early), "not
    measured" (the FC's profile gives no telemetry the rig reads: never a pass) or "skipped"."""

    name: str
    metric: str
    signal: str
    value: float
    units: str
    min: float | None
    max: float | None
    margin: float | None
    outcome: str
    reason: str = ""


@dataclass(frozen=True)
class Result:
    """What one run produced. ``verdict``: "pass", "fail", "skipped" (the FC's profile cannot fly it:
    ``error`` says why), "error" (the DUT crashed, hung or exited;
    ``error`` says why) or "interrupted". ``metadata`` is result.json's "metadata" (seed, scenario
    and firmware SHA-256, the DUT, the rig's figures). ``artifacts`` maps a kind ("result",
    "telemetry", "report", "junit", "mcap") to the file the run wrote."""

    scenario: str  # the file's stem, as rig run names the run's folder
    name: str  # the scenario's [scenario] name
    verdict: str
    error: str | None
    seed: int
    criteria: tuple[Criterion, ...]
    metadata: Mapping[str, Any]
    run_dir: Path
    artifacts: Mapping[str, Path]
    notes: tuple[str, ...] = ()
    _telemetry: pa.Table | None = field(default=None, repr=False, compare=False)

    @property
    def passed(self) -> bool:
        return self.verdict == "pass"

    @property
    def failed_criteria(self) -> tuple[Criterion, ...]:
        return tuple(c for c in self.criteria if c.outcome == "fail")

    @property
    def telemetry(self) -> pa.Table:
        """The recorded signals, one column per signal (telemetry.csv's, units in each field's
        metadata), one row per 10 ms of sim time. ``.to_pandas()`` on it needs pandas installed."""
        if self._telemetry is None:  # a Result made by hand: read the run's CSV
            from rig.reports import telemetry

            return _table(telemetry.read(self.artifacts["telemetry"].read_text()))
        return self._telemetry


def load_scenario(scenario: str | os.PathLike[str]) -> Scenario:
    """A scenario file, or a library scenario by name (``"step_roll"``), read and checked; raises
    ScenarioError (``file: key: message``) for a bad one."""
    from rig.run_cmd import resolve

    return _load(resolve([os.fspath(scenario)])[0])


def _load(path: Path) -> Scenario:
    from rig.scenarios.schema import load

    return load(path)


def _scenario(scenario: str | os.PathLike[str] | Scenario) -> Scenario:
    return scenario if isinstance(scenario, Scenario) else load_scenario(scenario)


def validate(scenario: str | os.PathLike[str]) -> list[str]:
    """Every problem of one scenario file, each as ``file: key: message``; [] for a good file.

    The checker stops at a file's first problem; here each problem's key is taken out of the file's
    tables and the rest checked again, so one call names them all (a missing key, or a problem that
    cannot be taken out, such as bad TOML, ends the list)."""
    import hashlib
    import tomllib

    from rig.run_cmd import resolve
    from rig.scenarios.schema import check

    path = resolve([os.fspath(scenario)])[0]
    try:
        _load(path)
        return []
    except ScenarioError as e:
        problems = [str(e)]
        key = e.key
    if not key:  # the file as a whole (unreadable, not TOML): nothing further can be checked
        return problems
    data = tomllib.loads(path.read_text())  # (it loaded far enough to fail on a key: the TOML is good)
    sha = hashlib.sha256(path.read_bytes()).hexdigest()
    seen = {key}
    while key and _drop(data, key) and len(problems) < 100:
        try:
            check(data, path, sha)
            break
        except ScenarioError as e:
            if e.key in seen:
                break
            problems.append(str(e))
            seen.add(key := e.key)
    return problems


def _drop(data: dict[str, Any], key: str) -> bool:
    """Takes the dotted ``key`` (``criteria[2].max``, ``vehicle.mass``) out of ``data``; False if it is
    not there (a missing key: nothing to take out)."""
    node: Any = data
    parts = key.replace("[", ".[").split(".")
    for k, part in enumerate(parts):
        last = k == len(parts) - 1
        if part.startswith("[") and part.endswith("]") and part[1:-1].isdigit() and isinstance(node, list):
            i = int(part[1:-1])
            if i >= len(node):
                return False
            if last:
                del node[i]
                return True
            node = node[i]
        elif isinstance(node, dict) and part in node:
            if last:
                del node[part]
                return True
            node = node[part]
        else:
            return False
    return False


def run(
    scenario: str | os.PathLike[str] | Scenario,
    *,
    dut: str | Sequence[str] | None = None,
    mcu: tuple[str | os.PathLike[str], str | os.PathLike[str]] | None = None,
    eeprom: str | os.PathLike[str] | None = None,
    bridge: str | None = None,
    seed: int = 0,
    out: str | os.PathLike[str] = "build/reports",
    wall_timeout: float = 600.0,
    spin: bool = False,
    pwm_channels: int | None = None,
    topology: str | None = None,
    airframe: str | os.PathLike[str] | None = None,
    fc: str | os.PathLike[str] | None = None,
) -> Result:
    """Flies one scenario and returns its result; writes ``out/<scenario>/`` as ``rig run`` does.

    The DUT is one of: ``dut``, a command line (a string, split as a shell would, or a list; default:
    the reference FC); ``mcu=(board, firmware)``, a firmware image under emulation (``eeprom``: the
    EEPROM image it starts from instead of the board's, as ``rig run --eeprom``; the run's folder gets
    ``eeprom.bin``, the EEPROM as it ended); ``bridge``, a bench bridge's serial port or "virtual".
    ``fc``: the FC's profile, a shipped name or a file (default the reference FC's; docs/profiles.md).
    ``spin``: as ``rig run --spin`` (two cores, polling).
    ``pwm_channels`` (1..16) and ``topology`` ("gy86", "direct"): a Linux DUT's board, as ``rig run
    --pwm-channels``, ``--topology`` (default: 8 channels on a GY-86).
    ``airframe``: as ``rig run --airframe`` (a shipped airframe's name or a file; default the
    scenario's own).
    Raises RigError for bad options (nothing is run); a DUT that crashes or hangs is a Result with
    verdict "error", as on the command line."""
    import shlex
    import threading

    from rig import compiled, interrupts

    compiled.install()  # (an entry point, as the CLI: the hot modules compiled, before they are imported)
    from rig.run_cmd import ReportFolder, UsageError, flown_on, plan, write_run
    from rig.runner import not_run
    from rig.runner import run as run_one

    sc = _scenario(scenario)
    if mcu is not None and (not isinstance(mcu, tuple) or len(mcu) != 2):
        raise RigError("mcu: expected (board, firmware)")
    words = [str(sc.path), "--out", os.fspath(out), "--seed", str(int(seed)), "--wall-timeout",
             repr(float(wall_timeout))]
    if dut is not None:
        words += ["--dut", shlex.join(dut) if isinstance(dut, Sequence) and not isinstance(dut, str) else dut]
    if bridge is not None:
        words += ["--bridge", bridge]
    if mcu is not None:
        words += ["--mcu", os.fspath(mcu[0]), "--firmware", os.fspath(mcu[1])]
    if eeprom is not None:
        words += ["--eeprom", os.fspath(eeprom)]
    if spin:
        words.append("--spin")
    if pwm_channels is not None:
        words += ["--pwm-channels", str(int(pwm_channels))]
    if topology is not None:
        words += ["--topology", topology]
    if airframe is not None:
        words += ["--airframe", os.fspath(airframe)]
    if fc is not None:
        words += ["--fc", os.fspath(fc)]
    args = _options("run", words)
    # Ctrl-C or a CI job's SIGTERM stops the DUT and finishes the run's files, as in rig run, and then
    # reaches the caller as KeyboardInterrupt; (signal handlers can be set from the main thread only)
    main = threading.current_thread() is threading.main_thread()
    try:
        suite = plan(args)
        sc = flown_on([sc], args.airframe, [])[0]  # (plan has checked it: its problems would have said so)
        with interrupts.handled() if main else contextlib.nullcontext(), ReportFolder(suite.out) as folder:
            run_dir = folder.scenario_dir(sc.stem)
            try:
                r = run_one(sc, suite.target, args.seed, run_dir, args.wall_timeout, profile=suite.profile)
            except Exception as e:  # as rig run: the rig could not fly it, and the result says so
                r = not_run(sc, args.seed, f"the rig could not run this scenario: {type(e).__name__}: {e}",
                            suite.target, suite.profile)
            write_run(run_dir, r)
            if r.verdict == "interrupted":
                raise KeyboardInterrupt(f"{r.error}; the run's files are in {run_dir}")
            interrupts.check()
    except UsageError as e:
        raise RigError(api_words(str(e))) from None
    except interrupts.Interrupted as e:  # (a signal while the files were written: they are whole)
        raise KeyboardInterrupt(f"{e}; the run's files are in {run_dir}") from None
    criteria = tuple(
        Criterion(m.name, m.metric, m.signal, float(m.value), m.units, _float(m.min), _float(m.max),
                  _float(m.margin), m.outcome, m.reason)
        for m in r.measurements
    )
    artifacts = {kind: run_dir / name for kind, name in ARTIFACTS.items() if (run_dir / name).is_file()}
    return Result(sc.stem, sc.name, r.verdict, r.error, args.seed, criteria, dict(r.metadata), run_dir,
                  artifacts, tuple(r.notes), _table(r.signals))


def _float(v: float | None) -> float | None:
    return None if v is None else float(v)


def _table(signals: Mapping[str, Any]) -> pa.Table:
    """Signals as a pyarrow Table in telemetry.csv's column order, units in each field's metadata."""
    import pyarrow as pa

    from rig.scenarios.signals import SIGNALS

    names = ["t"] + [n for n in SIGNALS if n in signals and n != "t"]
    fields = [pa.field(n, pa.float64(), metadata={"units": SIGNALS[n].units if n in SIGNALS else "s"})
              for n in names]
    return pa.table([pa.array(signals[n], type=pa.float64()) for n in names], schema=pa.schema(fields))


def sweep(
    spec: str | os.PathLike[str],
    *,
    out: str | os.PathLike[str],
    engine: str | None = None,
    jobs: int | None = None,
    dut: str | None = None,
    fresh: bool = False,
    wall_timeout: float = 600.0,
    fc: str | os.PathLike[str] | None = None,
) -> pa.Table:
    """Runs a sweep spec (docs/sweeps.md) as ``rig sweep`` does into ``out`` (resumable) and returns
    the runs' table (runs.parquet: one row per run, its variation, verdict and measurements).
    ``engine``: a Dask scheduler's address (default: the local pool, ``jobs`` at once). Raises
    RigError when nothing could be run (a bad spec, bad options, an unreachable engine)."""

    import pyarrow.parquet as pq

    from rig import compiled

    compiled.install()
    from rig import sweep_cmd
    from rig.sweep import store

    words = [os.fspath(spec), "--out", os.fspath(out), "--wall-timeout", repr(float(wall_timeout))]
    words += ["--jobs", str(jobs)] if jobs is not None else []
    words += ["--engine", engine] if engine is not None else []
    words += ["--dut", dut] if dut is not None else []
    words += ["--fc", os.fspath(fc)] if fc is not None else []
    words += ["--fresh"] if fresh else []
    args = _options("sweep", words)
    said = io.StringIO()
    with contextlib.redirect_stderr(said):
        code = sweep_cmd.main(args)
    table = Path(out) / store.TABLE
    if code == sweep_cmd.EXIT_USAGE or not table.is_file():
        raise RigError(api_words(said.getvalue().strip()) or f"rig sweep ended with status {code}")
    return pq.read_table(table)


def _options(command: str, words: list[str]) -> argparse.Namespace:
    """The command line's own options for ``rig COMMAND WORDS`` (rig/cli.py's parser, so the API takes
    exactly what the command takes, defaults and new options included); RigError with argparse's words."""
    from rig.cli import parser

    said = io.StringIO()
    try:
        with contextlib.redirect_stderr(said):
            return parser().parse_args([command, *words])
    except SystemExit:
        raise RigError(api_words(said.getvalue().strip().splitlines()[-1]) if said.getvalue().strip()
                       else f"rig {command}: bad options") from None
