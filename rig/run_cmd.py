"""``rig run``, ``rig validate`` and ``rig list``: the scenario suite, the main job.

``rig run SCENARIO… [--dut CMD] [--out DIR] [--seed N]`` checks every file first (a bad file stops the
suite before anything flies), then runs each scenario in lockstep against the DUT (default: the
reference flight controller) and writes, per run, ``OUT/<scenario>/{junit.xml,result.json,
telemetry.csv,report.html}``, and for the suite ``OUT/junit.xml`` and ``OUT/index.html``. A line per
scenario shows progress on stderr. Exit status: 0 all passed, 1 a criterion failed, 2 bad usage or a bad
scenario file, 3 a run ended in error (crash, hang, early exit of the DUT). A scenario the FC cannot fly
(its profile lacks a mode or feature it needs) is skipped with the reason: neither a pass nor a failure.
"""

from __future__ import annotations

import argparse
import dataclasses
import fcntl
import json
import math
import os
import shlex
import shutil
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from rig import interrupts
from rig.bridge.esc import ESC_PROTOCOLS
from rig.emulators.topology import TOPOLOGIES
from rig.plant import airframes
from rig.plant.airframes import AirframeError
from rig.scenarios import LIBRARY
from rig.scenarios.schema import Scenario, ScenarioError, load, with_airframe

if TYPE_CHECKING:
    from rig.mcu.vcd import TraceOptions
    from rig.scenarios.profile import Profile
    from rig.scenarios.result import RunResult
    from rig.targets import Target

EXIT_FAILED, EXIT_USAGE, EXIT_ERROR = 1, 2, 3
#: seeds are 0..2^31-1, as the service's API takes them (a run queued there is a run of this command)
SEED_LIMIT = 2**31


def seed_option(text: str) -> int:
    """argparse type of --seed: a bad one is exit 2 before anything runs (-1 reached numpy mid-run)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer 0..{SEED_LIMIT - 1}, got {text!r}") from None
    if not 0 <= value < SEED_LIMIT:
        raise argparse.ArgumentTypeError(f"expected an integer 0..{SEED_LIMIT - 1}, got {text}")
    return value


def seconds_option(text: str) -> float:
    """argparse type of a timeout: a finite number of seconds > 0 (-5 made every run an error)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds, got {text!r}") from None
    if not 0 < value < math.inf:
        raise argparse.ArgumentTypeError(f"expected a finite number of seconds > 0, got {text}")
    return value


def add_parsers(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "run",
        help="run scenarios against a DUT and write reports",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "scenarios",
        nargs="*",
        metavar="SCENARIO",
        help="scenario files or names from the library (default: the whole library)",
    )
    p.add_argument(
        "--dut",
        help="the DUT command line (default: the reference FC, configured by the "
        "scenario's [fc] table); it reads SBUS on /dev/ttyRC0 and may write "
        "telemetry lines on /dev/ttyTEL0",
    )
    add_fc_option(p)
    p.add_argument(
        "--out", type=Path, default=Path("build/reports"), help="report folder (default %(default)s)"
    )
    p.add_argument("--seed", type=seed_option, default=0,
                   help="random seed for noise, turbulence and faults (0..2^31-1)")
    p.add_argument("--sandbox", action="store_true",
                   help="run in a sandbox, as the service runs every DUT: --out the only writable folder, "
                   "no network, resource limits (needs bwrap; docs/service.md)")
    p.add_argument(
        "--wall-timeout", type=seconds_option, default=600.0, help="wall seconds per run before it is ended"
    )
    p.add_argument(
        "--realtime",
        action="store_true",
        help="pace the runs by the wall clock (a bench) instead of lockstep virtual time; "
        "how late scheduled events ran goes into result.json",
    )
    p.add_argument(
        "--spin",
        action="store_true",
        help="lockstep on two CPU cores: the session and the DUT each on its own, polling for the other's "
        "messages instead of sleeping (1.5-1.7x as fast; the results are the same)",
    )
    p.add_argument(
        "--pwm-channels",
        type=int,
        metavar="N",
        help="a Linux DUT's channels of pwmchip0, 1..16 (default 8; channels 0..3 drive motors 1..4)",
    )
    p.add_argument(
        "--topology",
        choices=TOPOLOGIES,
        help="a Linux DUT's I2C wiring: gy86 (default; the HMC5883L behind the MPU-6050's bypass) or "
        "direct (all three chips on the bus)",
    )
    p.add_argument(
        "--bridge",
        metavar="PORT|virtual",
        help="run in real time through a bench bridge: PORT is the serial port of a bridge wired to a "
        "real board (the board is the DUT); 'virtual' runs build/vbridge with the DUT command (default "
        "the reference FC) behind it. The link's figures go into result.json (docs/bench.md)",
    )
    p.add_argument(
        "--can",
        metavar="INTERFACE:CHANNEL",
        help="python-can interface and channel for scenarios whose PWM capture goes over CAN "
        "(e.g. socketcan:can0 on a bench; default: each scenario's [capture], virtual and private); with "
        "--bridge, where the motors' pulse widths come from instead of the bridge's link: a CAN capture "
        "device (socketcan:can0, slcan:/dev/ttyACM1), or slcan:vbridge, the virtual bridge's own frames",
    )
    p.add_argument(
        "--psu",
        metavar="MAKE:PORT[@BAUD]",
        help="with --bridge: the bench supply (riden:/dev/ttyUSB0, korad:/dev/ttyACM0) power-cycles the "
        "board before each run and its volts and amps go into the telemetry; overrides each scenario's "
        "[bench] psu (docs/power.md)",
    )
    p.add_argument(
        "--esc",
        choices=tuple(ESC_PROTOCOLS),
        default="pwm",
        help="with --bridge: the board's ESC protocol, which sets the capture's pulse limits and how a "
        "pulse becomes a motor command (default pwm: 1000..2000 us; oneshot125: 125..250 us)",
    )
    p.add_argument(
        "--mcu",
        metavar="BOARD",
        help="fly a firmware image under emulation in lockstep: BOARD is a board file or a shipped "
        "board's name (mega2560-gy86, promini328-gy86, ...; docs/mcu.md); needs --firmware",
    )
    p.add_argument("--firmware", type=Path, metavar="FILE", help="with --mcu: the image (.elf or .hex)")
    add_airframe_option(p)
    p.add_argument("--trace", type=Path, metavar="DIR",
                   help="with --mcu: write each scenario's TWI transactions and motor pin edges as "
                   "DIR/SCENARIO.vcd (GTKWave, PulseView)")
    p.add_argument("--eeprom", type=Path, metavar="FILE",
                   help="with --mcu: the EEPROM image to start from instead of the board's (raw bytes, as "
                   "a run's eeprom.bin, or Intel HEX named .eep/.hex)")
    add_trace_options(p)
    p.add_argument("--hang-limit", type=float, metavar="S",
                   help="with --mcu: a firmware with no TWI transaction, motor pulse, USART byte or output "
                   "pin change for S seconds is hung (default: the board's [limits] hang_s, 1; 0: off)")
    add_pdf_options(p)
    v = sub.add_parser("validate", help="check scenario files (and an FC profile) without running them")
    v.add_argument("scenarios", nargs="*", metavar="SCENARIO")
    add_fc_option(v)
    sub.add_parser("list", help="list the scenario library")


def add_airframe_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--airframe",
        metavar="NAME|FILE",
        help="the vehicle flown: a shipped airframe (seed-001, f450, racer-250) or an airframe file "
        "(docs/plant.md); default: the scenario's [vehicle] airframe, else seed-001. A scenario's other "
        "[vehicle] keys still apply on top",
    )


def flown_on(scenarios: list[Scenario], airframe: str | None, problems: list[str]) -> list[Scenario]:
    """``--airframe``: the scenarios flying that airframe (each problem appended to ``problems``)."""
    if airframe is None:
        return scenarios
    try:
        chosen = airframes.load(airframe)
    except AirframeError as e:
        problems.append(f"--airframe: {e}")
        return scenarios
    flown = []
    for sc in scenarios:
        try:
            flown.append(with_airframe(sc, chosen))
        except ScenarioError as e:
            problems.append(f"--airframe {airframe}: {e}")
    return flown


def add_fc_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--fc", metavar="PROFILE", default=None,
                   help="the FC's profile: how it is armed, which channel means what, how its telemetry is "
                   "read (a file, or a shipped name: reference, multiwii-2.4, arducopter-4; default "
                   "reference; docs/profiles.md)")


def load_profile(name: str | None, problems: list[str]) -> Profile | None:
    """``--fc``'s profile (the reference FC's without one), or None with the problem said."""
    from rig.scenarios.profile import DEFAULT, ProfileError
    from rig.scenarios.profile import load as load_fc

    try:
        return load_fc(name or DEFAULT)
    except ProfileError as e:
        problems.extend(f"--fc: {p}" for p in e.problems)
        return None


def add_pdf_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--pdf",
        action="store_true",
        help="also write the acceptance report, OUT/acceptance.pdf (and its source, acceptance.html), with "
        "Debian's headless chromium",
    )
    p.add_argument("--operator", default="", help="the operator's name on the acceptance report's cover")


def write_acceptance(out: Path, results: Sequence[RunResult], not_run: Sequence[str], operator: str) -> Path:
    """OUT/acceptance.html and, printed from it, OUT/acceptance.pdf; returns the PDF's path."""
    from rig.reports import acceptance, pdf

    src, dst = out / "acceptance.html", out / "acceptance.pdf"
    src.write_text(acceptance.render(results, not_run, operator))
    pdf.html_to_pdf(src, dst)
    return dst


def resolve(names: list[str]) -> list[Path]:
    """Files as given, or library names (with or without .toml); all of the library when empty."""
    if not names:
        return sorted(LIBRARY.glob("*.toml"))
    out = []
    for n in names:
        p = Path(n)
        if not p.exists() and (LIBRARY / f"{p.stem}.toml").exists() and p.parent == Path("."):
            p = LIBRARY / f"{p.stem}.toml"
        out.append(p)
    return out


def cmd_list() -> int:
    for p in resolve([]):  # the whole library
        try:
            sc = load(p)
            print(f"{p.stem:28} {sc.duration:6.1f} s  {sc.name}")
        except ScenarioError as e:
            print(f"{p.stem:28} INVALID  {e}")
    return 0


def cmd_validate(names: list[str], fc: str | None = None) -> int:
    bad = 0
    if fc is not None:
        problems: list[str] = []
        profile = load_profile(fc, problems)
        for line in problems:
            print(f"FAIL {line}", file=sys.stderr)
        if profile is not None:
            print(f"ok   {profile.path}: profile {profile.name}")
        bad += bool(problems)
        if not names:
            return EXIT_USAGE if bad else 0
    elif not names:
        print("rig validate: expected SCENARIO files, --fc PROFILE or both", file=sys.stderr)
        return EXIT_USAGE
    for p in resolve(names):
        try:
            sc = load(p)
            print(f"ok   {p}: {len(sc.criteria)} criteria, {sc.duration:g} s")
        except ScenarioError as e:
            for problem in e.problems:  # every problem of the file, a line each
                print(f"FAIL {problem}", file=sys.stderr)
            bad += 1
    return EXIT_USAGE if bad else 0


class UsageError(Exception):
    """Bad options or scenario files: said in one message, exit 2, nothing has run."""


@dataclass
class Plan:
    """A suite with every option and scenario checked: what ``rig run`` will do."""

    scenarios: list[Scenario]
    target: Target
    out: Path
    profile: Profile


def plan(args: argparse.Namespace) -> Plan:
    """Checks everything a run depends on before anything runs (raises UsageError naming each
    problem): every scenario file, the DUT command, the reference FC's build, every CAN interface the
    suite would open, the output folder."""
    from rig.capture import check_can
    from rig.targets import REFERENCE_FC

    problems: list[str] = []
    scenarios: list[Scenario] = []
    for p in resolve(args.scenarios):
        if not p.exists() and p.parent == Path(".") and p.suffix != ".toml":
            problems.append(f"{p}: no such file, and no library scenario of that name (see `rig list`)")
            continue
        try:
            scenarios.append(load(p))
        except ScenarioError as e:
            problems.append(str(e))
    if not scenarios and not problems:
        problems.append("no scenarios")
    scenarios = flown_on(scenarios, args.airframe, problems)
    stems: dict[str, Path] = {}
    for sc in scenarios:
        if sc.stem in stems:
            problems.append(f"{stems[sc.stem]} and {sc.path} are both named {sc.stem!r}: their reports would "
                            f"share {args.out / sc.stem}")
        stems[sc.stem] = sc.path
    dut: list[str] | None = None
    if args.dut is not None:
        try:
            dut = shlex.split(args.dut)
        except ValueError as e:
            problems.append(f"--dut: {e}")
        else:
            if not dut or not dut[0]:
                problems.append("--dut is empty")
        if args.bridge not in (None, "virtual"):
            problems.append("--dut with --bridge PORT: behind a bridge's port the DUT is the board wired "
                            "to it; a command runs only behind --bridge virtual")
    elif args.bridge not in (None, "virtual"):
        if not os.path.exists(args.bridge):
            problems.append(f"--bridge {args.bridge}: no such port (a bridge's serial port, e.g. "
                            "/dev/ttyACM0, or 'virtual')")
    elif args.mcu is None and not REFERENCE_FC.is_file():
        problems.append(f"the reference FC is not built ({REFERENCE_FC}); run `make dut`")
    if args.can and args.bridge is not None:  # the motors from a CAN capture device, opened by the run
        if args.can.partition(":")[2] == "vbridge" and args.bridge != "virtual":
            problems.append("--can ...:vbridge is the virtual bridge's CAN: use it with --bridge virtual")
    elif args.can:
        interface, sep, channel = args.can.partition(":")
        if not (interface and sep and channel):
            problems.append(f"--can: expected INTERFACE:CHANNEL (e.g. socketcan:can0), got {args.can!r}")
        else:
            scenarios = [
                dataclasses.replace(
                    sc, capture=dataclasses.replace(sc.capture, can_interface=interface, can_channel=channel)
                )
                if sc.capture.transport == "can"
                else sc
                for sc in scenarios
            ]
            try:
                check_can(interface, channel)  # even when no scenario uses CAN: a typo is still a typo
            except ValueError as e:
                problems.append(f"--can: {e}")
    opened = {(args.can or ""), ""}
    for sc in scenarios:
        key = f"{sc.capture.can_interface}:{sc.capture.can_channel}"
        if sc.capture.transport == "can" and sc.capture.can_interface != "virtual" and key not in opened:
            opened.add(key)
            try:
                check_can(sc.capture.can_interface, sc.capture.can_channel)
            except ValueError as e:
                problems.append(f"{sc.path}: capture: {e}")
    if args.esc != "pwm" and args.bridge is None:
        problems.append(f"--esc {args.esc} is what a bridge captures: it goes with --bridge")
    if args.psu is not None:
        from rig.scenarios.bench import parse_psu

        if args.bridge is None:
            problems.append("--psu powers a board behind a bridge: it goes with --bridge")
        try:
            parse_psu(args.psu)
        except ValueError as e:
            problems.append(f"--psu {e}")
        scenarios = [dataclasses.replace(sc, bench=dataclasses.replace(sc.bench, psu=args.psu))
                     for sc in scenarios]
    if args.out.exists() and not args.out.is_dir():
        problems.append(f"--out {args.out} exists and is not a folder")
    if args.spin:
        from rig.cores import CoresError, allowed_cores, placement

        try:
            placement(allowed_cores(), not args.realtime, None, True)
        except CoresError as e:
            problems.append(str(e))
        if args.bridge is not None or args.mcu is not None:
            problems.append("--spin is for a Linux program in lockstep: not with --bridge or --mcu")
    if args.pdf:
        from rig.reports.pdf import chromium

        if chromium() is None:
            problems.append("--pdf: no chromium on PATH to print the PDF with (Debian: apt-get install "
                            "chromium)")
    from rig.targets.process import hardware_problems

    problems += hardware_problems(args.pwm_channels, args.topology)
    if (args.pwm_channels is not None or args.topology is not None) and (args.bridge or args.mcu):
        problems.append("--pwm-channels and --topology are a Linux DUT's board: not with --bridge or --mcu")
    mcu = _mcu_target(args, problems)
    profile = load_profile(args.fc, problems)
    if problems or profile is None:
        raise UsageError("\n".join(problems))
    return Plan(scenarios, mcu or target_of(args, dut), args.out, profile)


def target_of(args: argparse.Namespace, dut: list[str] | None) -> Target:
    """The target the checked options name (rig/targets)."""
    from rig.targets.bridge import BridgeTarget
    from rig.targets.process import ProcessTarget

    if args.bridge is not None:
        return BridgeTarget(args.bridge, dut, args.can, args.esc)
    return ProcessTarget(dut, args.realtime, spin=args.spin, pwm_channels=args.pwm_channels,
                         topology=args.topology)


def add_trace_options(p: argparse.ArgumentParser) -> None:
    """--trace-signals, --trace-window, --trace-gzip (rig run and rig exec, with --mcu --trace)."""
    p.add_argument("--trace-signals", metavar="LIST",
                   help="with --trace: only these signals, comma-separated: twi, motors, twi.scl, twi.sda, "
                        "twi.byte, twi.ack, twi.busy, m1..m4 (default: all)")
    p.add_argument("--trace-window", metavar="START:END",
                   help="with --trace: only the changes from START to END sim seconds ('2:5'; '2:' to the "
                        "end)")
    p.add_argument("--trace-gzip", action="store_true",
                   help="with --trace: write .vcd.gz (GTKWave opens it; about a tenth of the size)")


def trace_options(args: argparse.Namespace) -> TraceOptions | str:
    """The trace's options from the command line, or what is wrong with them."""
    from rig.mcu.vcd import TraceOptions, signal_problem

    given = [o for o, v in (("--trace-signals", args.trace_signals), ("--trace-window", args.trace_window),
                            ("--trace-gzip", args.trace_gzip)) if v]
    if given and args.trace is None:
        return f"{', '.join(given)} goes with --trace DIR"
    signals = tuple(s.strip() for s in (args.trace_signals or "").split(",") if s.strip())
    problem = signal_problem(signals)
    if problem:
        return f"--trace-signals: {problem}"
    window = None
    if args.trace_window is not None:
        start, colon, end = args.trace_window.partition(":")
        try:
            lo, hi = float(start or 0), float(end) if end else math.inf
        except ValueError:
            lo = hi = math.nan
        if not colon or not 0 <= lo < hi:
            return f"--trace-window: expected START:END in sim seconds, START < END ('2:5', '2:'), got " \
                   f"{args.trace_window!r}"
        window = (round(lo * 1e9), 2**63 - 1 if math.isinf(hi) else round(hi * 1e9))
    return TraceOptions(signals, window, bool(args.trace_gzip))


def _mcu_target(args: argparse.Namespace, problems: list[str]) -> Target | None:
    """``--mcu BOARD --firmware FILE``, both checked (the board file as a scenario is, the image's
    format and size against the board's MCU); None without --mcu."""
    if args.mcu is None:
        for option, value in (("--firmware", args.firmware), ("--trace", args.trace),
                              ("--eeprom", args.eeprom), ("--hang-limit", args.hang_limit),
                              ("--trace-signals", args.trace_signals), ("--trace-window", args.trace_window),
                              ("--trace-gzip", args.trace_gzip or None)):
            if value is not None:
                problems.append(f"{option} goes with --mcu BOARD")
        return None
    if args.firmware is None:
        problems.append("--mcu needs --firmware FILE (the image: .elf or .hex)")
        return None
    clash = [o for o, v in (("--dut", args.dut), ("--bridge", args.bridge), ("--realtime", args.realtime))
             if v]
    if clash:
        problems.append(f"--mcu runs a firmware image in lockstep: not with {', '.join(clash)}")
        return None
    from rig.mcu.board import BoardError
    from rig.mcu.engine import FirmwareError
    from rig.targets.mcu import McuTarget

    if args.hang_limit is not None and not 0 <= args.hang_limit <= 600:
        problems.append(f"--hang-limit: expected seconds in 0..600 (0: off), got {args.hang_limit:g}")
        return None
    if args.trace is not None:
        try:
            args.trace.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            problems.append(f"--trace {args.trace}: {e.strerror}")
            return None
    try:
        options = trace_options(args)
        if isinstance(options, str):
            problems.append(options)
            return None
        return McuTarget(args.mcu, args.firmware, args.trace, args.eeprom, args.hang_limit, options)
    except (BoardError, FirmwareError) as e:
        problems.append(f"--mcu: {e}")
        return None


def write_run(run_dir: Path, r: RunResult) -> None:
    """One run's files, as ``rig run`` and ``rig.api.run`` both write them."""
    from rig.reports import html_report, junit, mcap, result_json, telemetry

    (run_dir / "junit.xml").write_text(junit.render([r]))
    (run_dir / "result.json").write_text(result_json.render(r))
    (run_dir / "telemetry.csv").write_text(telemetry.render(r.signals))
    (run_dir / "report.html").write_text(html_report.render(r))
    mcap.write_run(run_dir, r)


def cmd_run(args: argparse.Namespace, argv: Sequence[str] = ()) -> int:
    """``argv``: the command line's words after ``rig`` (--sandbox runs them again in the sandbox)."""
    try:
        suite = plan(args)
        if args.sandbox and os.environ.get(SANDBOXED) != "1":
            return _sandboxed(suite, argv)
        with interrupts.handled(), ReportFolder(suite.out) as folder:
            return _run_suite(args, suite, folder)
    except UsageError as e:
        for line in str(e).splitlines():
            print(f"rig run: {line}", file=sys.stderr)
        return EXIT_USAGE


#: set in the sandbox's environment: the rig run inside it does not wrap itself again
SANDBOXED = "RIG_SANDBOXED"


def _sandboxed(suite: Plan, argv: Sequence[str]) -> int:
    """The same command line run again inside the sandbox (rig/sandbox.py), its output folder the one
    writable place; its exit status. Ctrl-C and SIGTERM reach that rig run too (same process group)."""
    import subprocess

    from rig import sandbox

    try:
        with sandbox.confined([sys.executable, "-m", "rig.cli", *argv], [suite.out]) as cmd:
            return subprocess.run(cmd, env={**os.environ, SANDBOXED: "1"}).returncode
    except sandbox.SandboxError as e:
        raise UsageError(f"--sandbox: {e}") from None


def _run_suite(args: argparse.Namespace, suite: Plan, folder: ReportFolder) -> int:
    from rig.reports import html_report, junit
    from rig.runner import not_run, run

    results: list[RunResult] = []
    stop: int | None = None  # the exit status a signal asked for
    t_suite = time.perf_counter()
    n = len(suite.scenarios)
    folder.begin([sc.stem for sc in suite.scenarios])
    for i, sc in enumerate(suite.scenarios, 1):
        try:
            interrupts.check()
        except interrupts.Interrupted as e:
            stop = e.exit_code
            break
        run_dir = folder.scenario_dir(sc.stem)
        print(f"[{i}/{n}] {sc.stem} ({sc.duration:g} s sim) ...", end="", file=sys.stderr, flush=True)
        try:
            r = run(sc, suite.target, args.seed, run_dir, args.wall_timeout, profile=suite.profile)
        except Exception as e:  # the rig could not fly it (not the DUT's doing): say so, go on
            r = not_run(sc, args.seed, f"the rig could not run this scenario: {type(e).__name__}: {e}",
                        suite.target, suite.profile)
        results.append(r)
        write_run(run_dir, r)
        failed = [m.name for m in r.measurements if m.outcome == "fail"]
        rate = r.metadata.get("realtime_factor")
        speed = f"{rate:.1f}x" if isinstance(rate, int | float) else "not measured"
        wall = float(r.metadata.get("wall_time") or 0.0)
        if r.verdict in ("error", "interrupted", "skipped"):
            detail = f" {r.verdict}: {r.error}"
        else:
            detail = f" failed: {'; '.join(failed)}" if failed else ""
        timing = "" if r.verdict == "skipped" else f" ({wall:.1f} s wall, {speed})"  # (nothing flew)
        print(f" {r.verdict.upper()}{timing}{detail}", file=sys.stderr)
        if r.verdict == "interrupted" and r.exit_code is not None:
            stop = r.exit_code
            break
    left = [sc.stem for sc in suite.scenarios[len(results):]]
    (suite.out / "junit.xml").write_text(junit.render(results))
    links = [("junit.xml", "JUnit XML for CI")]
    pdf_error = None
    if args.pdf and results:
        from rig.reports.pdf import PdfError

        t_pdf = time.perf_counter()
        try:
            pdf = write_acceptance(suite.out, results, left, args.operator)
            links.insert(0, ("acceptance.pdf", "the acceptance report (PDF)"))
            print(f"acceptance report: {pdf} ({pdf.stat().st_size // 1024} KiB, "
                  f"{time.perf_counter() - t_pdf:.1f} s)", file=sys.stderr)
        except PdfError as e:
            pdf_error = str(e)
            print(f"rig run: error: the acceptance PDF: {e}", file=sys.stderr)
    (suite.out / "index.html").write_text(
        html_report.render_index(results, [f"{r.scenario.stem}/report.html" for r in results], left, links)
    )
    counts = {v: sum(r.verdict == v for r in results)
              for v in ("pass", "fail", "error", "skipped", "interrupted")}
    more = "".join(f", {counts[v]} {v}" for v in ("skipped", "interrupted") if counts[v])
    print(
        f"{counts['pass']} passed, {counts['fail']} failed, {counts['error']} errors{more} in "
        f"{time.perf_counter() - t_suite:.1f} s; reports in {suite.out}/index.html",
        file=sys.stderr,
    )
    if stop is not None:
        print(f"rig run: interrupted; {len(left)} scenario(s) not run", file=sys.stderr)
        return stop
    if counts["error"] or pdf_error:
        return EXIT_ERROR
    return EXIT_FAILED if counts["fail"] else 0


class ReportFolder:
    """The ``--out`` folder, held by one ``rig run`` at a time (an advisory lock on ``.rig-run.lock``;
    a second run into it is refused, naming the first), holding exactly one run's reports: the
    scenario folders the previous run wrote (listed in ``.rig-run.json``) are removed when a new run
    begins, and each scenario's folder is emptied before it flies, so no report of another run can
    sit beside this one's index."""

    LOCK, MANIFEST = ".rig-run.lock", ".rig-run.json"

    def __init__(self, path: Path) -> None:
        self.path = path
        self._fd = -1

    def __enter__(self) -> ReportFolder:
        try:
            self.path.mkdir(parents=True, exist_ok=True)
            self._fd = os.open(self.path / self.LOCK, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        except OSError as e:
            raise UsageError(f"--out {self.path}: {e.strerror}") from None
        try:
            fcntl.flock(self._fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(self._fd, 32, 0).decode("ascii", "replace").strip() or "?"
            os.close(self._fd)
            raise UsageError(f"--out {self.path} is in use by another rig run (pid {holder}); wait for it "
                             "to finish or choose another folder") from None
        os.ftruncate(self._fd, 0)
        os.pwrite(self._fd, f"{os.getpid()}\n".encode(), 0)
        return self

    def __exit__(self, *exc: object) -> None:
        os.ftruncate(self._fd, 0)
        os.close(self._fd)  # (closing releases the lock)

    def begin(self, stems: list[str]) -> None:
        """Removes the previous run's reports, then records this run's scenario folders."""
        manifest = self.path / self.MANIFEST
        try:
            previous = json.loads(manifest.read_text())
        except (OSError, ValueError):
            previous = []
        for name in previous if isinstance(previous, list) else []:
            # only plain names this rig wrote: a manifest edited by hand cannot reach outside the folder
            if isinstance(name, str) and name and "/" not in name and name not in (".", ".."):
                shutil.rmtree(self.path / name, ignore_errors=True)
        for name in ("index.html", "junit.xml", "acceptance.html", "acceptance.pdf"):
            (self.path / name).unlink(missing_ok=True)
        tmp = manifest.with_suffix(".tmp")
        tmp.write_text(json.dumps(stems) + "\n")
        tmp.replace(manifest)

    def scenario_dir(self, stem: str) -> Path:
        d = self.path / stem
        shutil.rmtree(d, ignore_errors=True)
        d.mkdir(parents=True)
        return d
