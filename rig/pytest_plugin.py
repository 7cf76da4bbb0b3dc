"""The rig as a pytest plugin (docs/pytest.md), registered by the package's ``pytest11`` entry point.

Firmware teams already run their hardware tests with pytest, its JUnit XML and pytest-xdist; here the
rig meets them there, on top of the public API (rig/api.py) and ``rig run``'s report folder:

* a TOML file with a ``[scenario]`` table is a test item, named by its stem (other TOML files, such as
  pyproject.toml or a sweep spec, are left alone); a file that does not check is a collection error
  naming its key. Nothing is collected that pytest is not already walking (this repository's own
  ``pytest`` walks tests/ only, its testpaths);
* ``--rig-dut CMD``, ``--rig-mcu BOARD --rig-firmware FILE`` (``--rig-eeprom FILE``: its EEPROM),
  ``--rig-bridge PORT`` choose the DUT (default: the reference FC), ``--rig-pwm-channels N`` and
  ``--rig-topology gy86|direct`` a Linux DUT's board, ``--rig-seed N`` the seed, ``--rig-out DIR``
  where runs are written;
* a failing item shows its criteria table (value, limits, margin) and its report's path;
* the ``rig`` fixture hands the API to a test, with the command line's DUT, seed and a folder of the
  test's own; ``@pytest.mark.rig_scenario(*scenarios, seeds=[...])`` parametrises a test's
  ``scenario`` and ``seed`` arguments;
* under pytest-xdist each worker writes under ``DIR/<worker>/`` (a report folder is held by one run at
  a time); JUnit properties carry the seed and the scenario's and firmware's SHA-256;
* the scenario items' folder is a ``rig run`` report folder: ``rig report DIR --pdf`` prints its
  acceptance PDF, and a new session first removes the runs the previous one wrote there (at the root
  and in every worker's folder).

The imports of the rig are deferred to the first run: the plugin is loaded into every pytest session
of an environment the package is installed in, and must cost nothing there.
"""

from __future__ import annotations

import os
import re
import uuid
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from rig.api import Criterion, Result
    from rig.scenarios.schema import Scenario

_SCENARIO_TABLE = re.compile(rb"^[ \t]*\[[ \t]*scenario[ \t]*\]", re.MULTILINE)
DEFAULT_OUT = "build/rig-pytest"


def pytest_addoption(parser: pytest.Parser) -> None:
    g = parser.getgroup("rig", "quadrotor HIL rig (scenario files as tests; docs/pytest.md)")
    g.addoption("--rig-dut", metavar="CMD", help="the DUT's command line (default: the reference FC)")
    g.addoption("--rig-fc", metavar="PROFILE", help="the FC's profile, a shipped name or a file (default: "
                "the reference FC's; docs/profiles.md)")
    g.addoption("--rig-mcu", metavar="BOARD", help="fly a firmware image under emulation on BOARD "
                "(a board file or a shipped board's name); needs --rig-firmware")
    g.addoption("--rig-firmware", metavar="FILE", help="with --rig-mcu: the image (.elf or .hex)")
    g.addoption("--rig-eeprom", metavar="FILE", help="with --rig-mcu: the EEPROM image to start from "
                "instead of the board's (raw bytes, as a run's eeprom.bin, or Intel HEX named .eep/.hex)")
    g.addoption("--rig-bridge", metavar="PORT", help="a bench bridge's serial port, or 'virtual'")
    g.addoption("--rig-pwm-channels", metavar="N", type=int,
                help="a Linux DUT's channels of pwmchip0, 1..16 (default 8)")
    g.addoption("--rig-topology", metavar="gy86|direct",
                help="a Linux DUT's I2C wiring (default gy86: the compass behind the MPU-6050's bypass)")
    g.addoption("--rig-airframe", metavar="NAME|FILE",
                help="the vehicle flown: a shipped airframe or a file (default: each scenario's own)")
    g.addoption("--rig-seed", metavar="N", type=int, default=0, help="the runs' seed (default 0)")
    g.addoption("--rig-out", metavar="DIR", default=DEFAULT_OUT,
                help=f"where runs are written (default {DEFAULT_OUT}; under xdist DIR/<worker>)")


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers", "rig_scenario(*scenarios, seeds=None): run the test once per scenario (its `scenario` "
        "argument: a library name or a file) and seed (its `seed` argument)")
    board, firmware = config.getoption("rig_mcu"), config.getoption("rig_firmware")
    if firmware is not None and board is None:
        raise pytest.UsageError("--rig-firmware goes with --rig-mcu BOARD")
    if board is not None and firmware is None:
        raise pytest.UsageError("--rig-mcu needs --rig-firmware FILE")
    pwm_channels, topology = config.getoption("rig_pwm_channels"), config.getoption("rig_topology")
    if pwm_channels is not None or topology is not None:  # (the rig imported only when they are given)
        from rig.targets.process import hardware_problems

        problems = hardware_problems(pwm_channels, topology)
        if problems:
            raise pytest.UsageError("; ".join(p.replace("--", "--rig-", 1) for p in problems))
    if config.getoption("rig_eeprom") is not None and board is None:
        raise pytest.UsageError("--rig-eeprom goes with --rig-mcu BOARD")


class Options:
    """The command line's choice of DUT, seed and output folder (this worker's own)."""

    def __init__(self, config: pytest.Config) -> None:
        opt = config.getoption
        self.dut: str | None = opt("rig_dut")
        self.fc: str | None = opt("rig_fc")
        self.bridge: str | None = opt("rig_bridge")
        board, firmware = opt("rig_mcu"), opt("rig_firmware")  # (paired: pytest_configure)
        self.mcu: tuple[str, str] | None = (board, firmware) if board is not None else None
        self.eeprom: str | None = opt("rig_eeprom")
        self.seed: int = opt("rig_seed")
        self.pwm_channels: int | None = opt("rig_pwm_channels")
        self.topology: str | None = opt("rig_topology")
        self.airframe: str | None = opt("rig_airframe")
        out = Path(opt("rig_out"))
        if not out.is_absolute():
            out = Path(config.invocation_params.dir) / out
        worker = os.environ.get("PYTEST_XDIST_WORKER")
        self.root = out
        self.out = out / worker if worker else out
        #: this session's identity, shared by its xdist workers (a plain session is one process)
        self.session = os.environ.get("PYTEST_XDIST_TESTRUNUID") or uuid.uuid4().hex
        self.stems: list[str] | None = None  # the scenario items this process has run, in order

    def ran(self, stem: str) -> None:
        """Keeps the folder a report folder as ``rig run`` leaves one (so ``rig report DIR --pdf`` reads
        it): the first scenario item of the session removes the runs the previous session wrote
        (``claim``); each one run is added to the list (.rig-run.json)."""
        import json

        from rig.run_cmd import ReportFolder

        if self.stems is None:
            self.stems = []
            claim(self.root, self.session)
            with ReportFolder(self.out) as folder:
                folder.begin([])
        self.stems.append(stem)
        manifest = self.out / ReportFolder.MANIFEST
        tmp = manifest.with_suffix(".tmp")
        tmp.write_text(json.dumps(self.stems) + "\n")
        tmp.replace(manifest)

    def run(self, scenario: str | os.PathLike[str] | Scenario, out: Path, **kw: Any) -> Result:
        from rig import api

        options: dict[str, Any] = {"dut": self.dut, "mcu": self.mcu, "eeprom": self.eeprom,
                                   "bridge": self.bridge, "seed": self.seed,
                                   "pwm_channels": self.pwm_channels, "topology": self.topology,
                                   "airframe": self.airframe, "fc": self.fc}
        return api.run(scenario, **(options | kw), out=out)


SESSION_FILE = ".rig-pytest-session"
_WORKER_FOLDER = re.compile(r"gw[0-9]+")


def claim(root: Path, session: str) -> None:
    """The first process of a session to run a scenario item removes every run the previous session
    wrote under ``root``: the root's (a plain session's) and every worker folder's (a ``-n`` session's,
    whatever its number of workers), so neither ``rig report DIR`` nor a ``DIR/gwN`` shows an older
    session's run. The workers of one session meet here under a lock; only the first one clears."""
    import fcntl
    import shutil

    from rig.run_cmd import ReportFolder

    root.mkdir(parents=True, exist_ok=True)
    with open(root / f"{SESSION_FILE}.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        marker = root / SESSION_FILE
        if marker.is_file() and marker.read_text().strip() == session:
            return
        workers = sorted(p for p in root.iterdir() if p.is_dir() and _WORKER_FOLDER.fullmatch(p.name))
        for folder in (root, *workers):
            with ReportFolder(folder) as report_folder:
                report_folder.begin([])
        for folder in workers:  # (a worker folder left with nothing but the rig's own files)
            if {p.name for p in folder.iterdir()} <= {ReportFolder.LOCK, ReportFolder.MANIFEST}:
                shutil.rmtree(folder)
        marker.write_text(session + "\n")


def _options(config: pytest.Config) -> Options:
    key = "_rig_options"
    if not hasattr(config, key):
        setattr(config, key, Options(config))
    got: Options = getattr(config, key)
    return got


def pytest_collect_file(file_path: Path, parent: pytest.Collector) -> ScenarioFile | None:
    if file_path.suffix != ".toml":
        return None
    try:
        head = file_path.read_bytes()
    except OSError:
        return None
    if not _SCENARIO_TABLE.search(head):
        return None
    return ScenarioFile.from_parent(parent, path=file_path)


class ScenarioFile(pytest.File):
    """A scenario file: one item, or a collection error naming the file's bad key."""

    def collect(self) -> Iterator[ScenarioItem]:
        from rig import compiled

        # the hot modules compiled (as the CLI runs them) before reading a scenario imports the first of
        # them: a module imported from source stays so, and the compiled ones then reject its objects
        compiled.install()
        from rig.api import ScenarioError, load_scenario

        try:
            sc = load_scenario(self.path)
        except ScenarioError as e:
            raise self.CollectError(f"bad scenario file: {e}") from None
        yield ScenarioItem.from_parent(self, name=sc.stem, scenario=sc)


class ScenarioFailed(Exception):
    """A run whose verdict is not "pass"."""

    def __init__(self, result: Result) -> None:
        super().__init__(result.verdict)
        self.result = result


class ScenarioItem(pytest.Item):
    def __init__(self, *, scenario: Scenario, **kw: Any) -> None:
        super().__init__(**kw)
        self.scenario = scenario

    def runtest(self) -> None:
        opts = _options(self.config)
        self.user_properties += [("seed", opts.seed), ("scenario_sha256", self.scenario.sha256)]
        opts.ran(self.scenario.stem)
        result = opts.run(self.scenario, opts.out)
        record(self.user_properties, result)
        if not result.passed:
            raise ScenarioFailed(result)

    def repr_failure(self, excinfo: pytest.ExceptionInfo[BaseException], style: Any = None) -> str:
        if isinstance(excinfo.value, ScenarioFailed):
            return explain(excinfo.value.result)
        from rig.api import RigError

        if isinstance(excinfo.value, RigError):
            return f"rig: {excinfo.value}"
        return str(super().repr_failure(excinfo))

    def reportinfo(self) -> tuple[Path, int | None, str]:
        return self.path, None, f"scenario {self.name}: {self.scenario.name}"


def record(props: list[tuple[str, object]], result: Result) -> None:
    """The run's identity as JUnit properties: seed, scenario, firmware and FC profile SHA-256 (once each)."""
    have = {k for k, _ in props}
    got = {"seed": result.seed, "scenario_sha256": result.metadata.get("scenario_sha256"),
           "firmware_sha256": result.metadata.get("dut_firmware_sha256"),
           "fc_profile": result.metadata.get("fc_profile"),
           "fc_profile_sha256": result.metadata.get("fc_profile_sha256"), "report": str(result.run_dir)}
    props += [(k, v) for k, v in got.items() if k not in have and v is not None]
    for i, (k, v) in enumerate(props):  # (a value recorded before the run is the run's own value)
        if k in got and got[k] is not None and v != got[k]:
            props[i] = (k, got[k])


def explain(result: Result) -> str:
    """A failed run in words: verdict, the criteria table, the report's path."""
    lines = [f"scenario {result.scenario} ({result.name}): {result.verdict.upper()} with seed {result.seed}"]
    if result.error:
        lines.append(f"error: {result.error}")
    if result.criteria:
        lines += _table(result.criteria)
    report = result.artifacts.get("report", result.run_dir / "report.html")
    lines.append(f"report: {report}")
    return "\n".join(lines)


def _num(v: float | None) -> str:
    return "-" if v is None else f"{v:.4g}"


def _table(criteria: Sequence[Criterion]) -> list[str]:
    rows = [("criterion", "value", "units", "min", "max", "margin %", "outcome")]
    rows += [(c.name, _num(c.value), c.units, _num(c.min), _num(c.max), _num(c.margin), c.outcome.upper())
             for c in criteria]
    widths = [max(len(r[k]) for r in rows) for k in range(len(rows[0]))]
    return ["  " + "  ".join(cell.ljust(w) for cell, w in zip(r, widths, strict=True)).rstrip() for r in rows]


class RigFixture:
    """The API for a hand-written test: ``run`` with the command line's DUT and seed (each overridable)
    into the test's own folder; ``load_scenario``, ``validate`` and ``sweep`` as in rig.api."""

    def __init__(self, request: pytest.FixtureRequest) -> None:
        self._opts = _options(request.config)
        self._node = request.node
        name = re.sub(r"[^A-Za-z0-9_.=-]+", "_", request.node.name)[:120]
        self.out: Path = self._opts.out / "tests" / name
        self.seed: int = self._opts.seed

    def run(self, scenario: str | os.PathLike[str] | Scenario, **kw: Any) -> Result:
        """rig.api.run with the command line's DUT and seed; the run's identity goes into the test's
        JUnit properties."""
        result = self._opts.run(scenario, self.out, **kw)
        record(self._node.user_properties, result)
        return result

    def load_scenario(self, scenario: str | os.PathLike[str]) -> Scenario:
        from rig import api

        return api.load_scenario(scenario)

    def validate(self, scenario: str | os.PathLike[str]) -> list[str]:
        from rig import api

        return api.validate(scenario)

    def sweep(self, spec: str | os.PathLike[str], **kw: Any) -> Any:
        from rig import api

        return api.sweep(spec, **({"out": self.out / "sweep"} | kw))

    explain = staticmethod(explain)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Any:
    """A test that failed on a RigError the rig raised (bad options such as a --rig-firmware that is
    no image: nothing ran) says so in one line, as a scenario item does, not with a traceback into the
    rig's own code."""
    report = yield
    from rig.api import RigError

    error = call.excinfo.value if call.excinfo is not None else None
    if report.failed and isinstance(error, RigError) and not isinstance(item, ScenarioItem):
        report.longrepr = f"rig: {error}"
    return report


@pytest.fixture
def rig(request: pytest.FixtureRequest) -> RigFixture:
    """The rig's API for this test (docs/pytest.md)."""
    return RigFixture(request)


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    for mark in metafunc.definition.iter_markers("rig_scenario"):
        scenarios = list(mark.args)
        seeds = mark.kwargs.get("seeds")
        if scenarios:
            if "scenario" not in metafunc.fixturenames:
                raise pytest.UsageError(f"{metafunc.definition.nodeid}: rig_scenario(...) with scenarios "
                                        "parametrises a `scenario` argument; the test has none")
            metafunc.parametrize("scenario", scenarios, ids=[Path(str(s)).stem for s in scenarios])
        if seeds is not None:
            if "seed" not in metafunc.fixturenames:
                raise pytest.UsageError(f"{metafunc.definition.nodeid}: rig_scenario(seeds=...) "
                                        "parametrises a `seed` argument; the test has none")
            metafunc.parametrize("seed", list(seeds), ids=[f"seed{s}" for s in seeds])
