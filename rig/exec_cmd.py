"""``rig exec [options] -- CMD ARGS...``: run any program with the emulated devices attached.

``rig exec --mcu BOARD --firmware FILE --duration S``: a firmware image on its board instead of a
command (docs/mcu.md), the world at rest, no scenario; its telemetry USART's bytes go to stdout. It
exits 0 when the duration ends it, 125 when the firmware fails (a crash, a bad opcode, sleep with
interrupts off, a watchdog reset loop, a hang, a bus no chip answers, or never reading a sensor or
driving a motor), 124 on the wall-time watchdog.

The command sees a GY-86 on ``/dev/i2c-1`` (MPU-6050 0x68, MS5611 0x77, HMC5883L 0x1E behind the
MPU's bypass), eight sysfs PWM channels on ``/sys/class/pwm/pwmchip0`` (channels 0..3 drive motors
1..4), the serial paths asked for, and, in lockstep (the default), virtual time. The plant starts at
rest on the ground. The command's exit status passes through; rig's own verdicts use 124 (a
watchdog), 125 (the run could not be judged), 126/127 (not executable / not found) and 128+N (the
command died of signal N).
"""

from __future__ import annotations

import argparse
import difflib
import json
import shutil
import sys
import tempfile
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING

from rig import interrupts
from rig.bridge.esc import ESC_PROTOCOLS
from rig.bridge.session import BenchConfig, BenchSession
from rig.cores import CoresError, allowed_cores, placement
from rig.emulators.topology import TOPOLOGIES
from rig.plant import airframes
from rig.plant.airframes import AirframeError
from rig.plant.variables import PARAMETERS, check_parameters
from rig.run_cmd import add_airframe_option, add_trace_options, seconds_option, trace_options
from rig.scenarios.schema import Event, ScenarioError, _Check, timeline_event
from rig.scheduler import EXIT_RIG_ERROR
from rig.session import Session, SessionConfig
from rig.targets import telemetry_path
from rig.targets.process import hardware_problems
from rig.world import World

if TYPE_CHECKING:
    from rig.scenarios.profile import Profile

CLOCKS = {"0": 0, "100k": 100_000, "400k": 400_000}


def _param(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    try:
        if not sep or not name:
            raise ValueError
        number = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected NAME=NUMBER, got {text!r}") from None
    if name not in PARAMETERS:
        near = difflib.get_close_matches(name, list(PARAMETERS), n=1)
        hint = (f"; did you mean {near[0]!r}?" if near
                else f"; the plant's parameters: {', '.join(PARAMETERS)}")
        raise argparse.ArgumentTypeError(f"{name!r} is not a plant parameter{hint}")
    return name, number


def _plant_params(args: argparse.Namespace, parser: argparse.ArgumentParser) -> dict[str, float]:
    """The plant's parameters: the airframe's (--airframe, default seed 001's), then each --param;
    checked by the FMU's own rules before anything starts (exit 2 naming the problem)."""
    try:
        airframe = airframes.load(args.airframe or airframes.DEFAULT_AIRFRAME)
    except AirframeError as e:
        parser.error(f"--airframe: {e}")
    params = airframe.params | dict(args.param)
    refused = check_parameters(params)
    if refused:
        parser.error(f"--param/--airframe: the plant refuses it: {refused}")
    return params


def _writable(parser: argparse.ArgumentParser, option: str, path: Path | None) -> None:
    """A file the run will write, tried before the run starts (a read-only place is bad usage, not a
    traceback after the command has run)."""
    if path is None:
        return
    try:
        with open(path, "a"):
            pass
    except OSError as e:
        parser.error(f"{option} {path}: {e.strerror}")


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("exec", help="run a command with the emulated devices attached (lockstep by default)",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--realtime", action="store_true", help="follow the wall clock instead of virtual time")
    p.add_argument("--bridge", metavar="PORT|virtual",
                   help="the devices are a bridge's (real time): 'virtual' runs build/vbridge and the "
                        "command against it (behind a real bridge's port is a board, not a command)")
    p.add_argument("--bus", type=int, default=1, metavar="N",
                   help="emulated bus number (/dev/i2c-N; default 1)")
    p.add_argument("--topology", choices=TOPOLOGIES, default="gy86")
    p.add_argument("--esc", choices=tuple(ESC_PROTOCOLS), default="pwm",
                   help="with --bridge: the ESC protocol the bridge captures (default pwm; oneshot125)")
    p.add_argument("--serial", action="append", default=[], metavar="PATH",
                   help="a serial device path the command opens, served by a pty (repeatable)")
    p.add_argument("--pwm-channels", type=int, default=None, metavar="N",
                   help="channels of pwmchip0 (1..16; default 8, or as many as --fc's profile opens)")
    p.add_argument("--fc", metavar="PROFILE",
                   help="the FC's profile (a file or a shipped name; docs/profiles.md): its PWM channels and "
                   "motor order, its frame for the plant, its telemetry port, its arguments or EEPROM image")
    p.add_argument("--i2c-clock", choices=sorted(CLOCKS), default="0",
                   help="each transfer takes its wire time at this SCL clock (default 0: no time)")
    p.add_argument("--quantum-ns", type=int, default=1000, metavar="NS",
                   help="sim time one clock read costs in lockstep (default 1000)")
    p.add_argument("--duration", type=seconds_option, metavar="S",
                   help="run for S sim seconds, then stop the command (a flight controller never exits)")
    p.add_argument("--sim-timeout", type=seconds_option, default=600.0, metavar="S", help="sim-time watchdog")
    p.add_argument("--wall-timeout", type=seconds_option, default=600.0, metavar="S",
                   help="wall-time watchdog")
    p.add_argument("--stall-timeout", type=seconds_option, default=30.0, metavar="S",
                   help="lockstep: wall seconds without a request or clock read before the run is stopped")
    p.add_argument("--pin", action=argparse.BooleanOptionalAction, default=None,
                   help="pin the command and the session to one core (default: in lockstep only)")
    p.add_argument("--spin", action="store_true",
                   help="lockstep on two cores: the command and the session on one each, polling for the "
                   "other's messages instead of sleeping (faster; the results are the same)")
    p.add_argument("--seed", type=int, default=0, help="seed of the sensor noise")
    p.add_argument("--no-noise", action="store_true", help="exact sensors")
    p.add_argument("--param", type=_param, action="append", default=[], metavar="NAME=VALUE",
                   help="plant parameter (repeatable), e.g. --param stand=1")
    add_airframe_option(p)
    p.add_argument("--log", type=Path, metavar="FILE", help="write the transaction log here")
    p.add_argument("--summary", type=Path, metavar="FILE", help="write the outcome as JSON here")
    p.add_argument("--allow-no-devices", action="store_true",
                   help="a command that never touches the devices is not an error")
    p.add_argument("--mcu", metavar="BOARD",
                   help="run a firmware image under emulation instead of a command: BOARD is a board file "
                        "or a shipped board's name (docs/mcu.md); needs --firmware and --duration")
    p.add_argument("--firmware", type=Path, metavar="FILE", help="with --mcu: the image (.elf or .hex)")
    p.add_argument("--trace", type=Path, metavar="DIR",
                   help="with --mcu: write the TWI transactions and motor pin edges as DIR/FIRMWARE.vcd")
    p.add_argument("--eeprom", type=Path, metavar="FILE",
                   help="with --mcu: the EEPROM image to start from instead of the board's (raw bytes, or "
                        "Intel HEX named .eep/.hex)")
    p.add_argument("--eeprom-out", type=Path, metavar="FILE",
                   help="with --mcu: write the EEPROM as the firmware left it here (raw bytes)")
    p.add_argument("--sticks", metavar="SPEC",
                   help="with --mcu: sticks on the board's RC input, constant ('throttle=0.2,arm=on') or a "
                        "timeline ('0:arm=off;1.5:arm=on,throttle=0.1'): roll, pitch, yaw (-1..1), "
                        "throttle (0..1), alt_offset (-1..1), arm, alt_hold (on/off)")
    add_trace_options(p)
    p.add_argument("--hang-limit", type=float, metavar="S",
                   help="with --mcu: a firmware with no TWI transaction, motor pulse, USART byte or output "
                        "pin change for S seconds is hung (default: the board's [limits] hang_s, 1; 0: off)")
    p.add_argument("argv", nargs=argparse.REMAINDER, metavar="-- CMD ARGS", help="the command to run")
    p.set_defaults(exec_parser=p)  # (usage errors found after parsing say "rig exec: error: ...")


def main(args: argparse.Namespace) -> int:
    parser: argparse.ArgumentParser = args.exec_parser
    command = args.argv[1:] if args.argv[:1] == ["--"] else args.argv
    if args.mcu is not None:
        return _exec_mcu(args, parser, command)
    for option, value in (("--firmware", args.firmware), ("--trace", args.trace), ("--eeprom", args.eeprom),
                          ("--eeprom-out", args.eeprom_out), ("--hang-limit", args.hang_limit),
                          ("--sticks", args.sticks), ("--trace-signals", args.trace_signals),
                          ("--trace-window", args.trace_window), ("--trace-gzip", args.trace_gzip or None)):
        if value is not None:
            parser.error(f"{option} goes with --mcu BOARD")
    if not command:
        parser.error("rig exec needs a command after --")
    profile = _profile(args, parser)
    motor_order: tuple[int, ...] = (1, 2, 3, 4)
    if profile is not None:
        motor_order = profile.motors.order
        if args.pwm_channels is None:
            args.pwm_channels = max(profile.motors.pwm_channels, 8)
        port = telemetry_path(profile)
        if profile.telemetry.kind != "none" and port not in args.serial:
            args.serial.append(port)
    if args.pwm_channels is None:
        args.pwm_channels = 8
    for problem in hardware_problems(args.pwm_channels, args.topology):
        parser.error(problem)
    if not 0 <= args.bus < 32:
        parser.error("--bus must be between 0 and 31")
    if args.quantum_ns < 0:
        parser.error("--quantum-ns must not be negative")
    params = _plant_params(args, parser)
    if args.spin:
        if args.bridge is not None:
            parser.error("--spin is for lockstep: not with --bridge")
        try:
            placement(allowed_cores(), not args.realtime, args.pin, True)
        except CoresError as e:
            parser.error(str(e))
    _writable(parser, "--log", args.log)
    _writable(parser, "--summary", args.summary)
    world = World.at_rest(seed=args.seed, topology=args.topology, noise=not args.no_noise,
                          params=params, pwm_channels=args.pwm_channels, motor_order=motor_order,
                          baro_osr_noise=profile is not None and profile.baro_noise)
    if args.bridge is not None and args.bridge != "virtual":
        world.close()
        parser.error("a command runs against the virtual bridge only (--bridge virtual); behind a real "
                     "bridge the board is the DUT: use rig run --bridge PORT")
    # (the FC's own files, {state} in its profile's arguments: a folder of the run's, removed after it)
    state = Path(tempfile.mkdtemp(prefix="rig-fc-state-")) if profile and profile.config.keeps_state else None
    if profile is not None:
        command = [*command, *profile.config.arguments(state)]
    cfg = SessionConfig(command=command, lockstep=not args.realtime, i2c_bus=args.bus, serial=args.serial,
                        i2c_clock_hz=CLOCKS[args.i2c_clock], quantum_ns=args.quantum_ns,
                        duration=args.duration, sim_timeout=args.sim_timeout, wall_timeout=args.wall_timeout,
                        stall_timeout=args.stall_timeout, pin=args.pin, spin=args.spin, log_path=args.log,
                        allow_no_devices=args.allow_no_devices)
    try:
        with interrupts.handled():
            if args.bridge is not None:
                bench = BenchConfig(bridge=args.bridge, command=command, serial=args.serial,
                                    i2c_bus=args.bus, topology=args.topology, duration=args.duration,
                                    sim_timeout=args.sim_timeout, wall_timeout=args.wall_timeout,
                                    esc=args.esc)
                outcome = BenchSession(bench, world).run()
            else:
                outcome = Session(cfg, world).run()
    finally:
        world.close()
        if state is not None:
            shutil.rmtree(state, ignore_errors=True)
    for note in outcome.notes:
        print(f"rig exec: note from the command's shim: {note}", file=sys.stderr)
    for why in outcome.malformed:
        print(f"rig exec: warning: {why}", file=sys.stderr)
    if outcome.error:
        print(f"rig exec: error: {outcome.error}", file=sys.stderr)
    if args.summary:
        summary = asdict(outcome)
        summary["command"] = command
        args.summary.write_text(json.dumps(summary, indent=2, sort_keys=True) + "\n")
    return outcome.exit_code


def _profile(args: argparse.Namespace, parser: argparse.ArgumentParser) -> Profile | None:
    """``--fc``'s profile (None without it); its frame becomes the plant's unless --param sets one."""
    if args.fc is None:
        return None
    from rig.run_cmd import load_profile

    problems: list[str] = []
    profile = load_profile(args.fc, problems)
    if profile is None:
        parser.error("; ".join(problems))
    if not any(name == "frame" for name, _ in args.param):
        args.param.append(("frame", 1.0 if profile.motors.frame == "x" else 0.0))
    return profile


def _exec_mcu(args: argparse.Namespace, parser: argparse.ArgumentParser, command: list[str]) -> int:
    """A firmware image on its board, the world at rest, for --duration sim seconds: the MCU target's
    session (rig/targets/mcu.py) with no scenario events but ``--sticks``."""
    from rig.mcu.board import BoardError
    from rig.mcu.engine import FirmwareError
    from rig.rc import StickEmulator
    from rig.runner import apply_event
    from rig.scenarios import profile as profiles
    from rig.targets import RC_PATH, TELEMETRY_PATH
    from rig.targets.mcu import McuRun, McuTarget, profile_board

    if command:
        parser.error("--mcu runs a firmware image, not a command: nothing goes after --")
    if args.firmware is None:
        parser.error("--mcu needs --firmware FILE (the image: .elf or .hex)")
    if args.duration is None:
        parser.error("--mcu needs --duration S (a firmware never exits)")
    clash = [o for o, v in (("--bridge", args.bridge), ("--realtime", args.realtime), ("--log", args.log),
                            ("--serial", args.serial), ("--pin", args.pin), ("--spin", args.spin)) if v]
    if clash:
        parser.error(f"--mcu runs a firmware image in lockstep: not with {', '.join(clash)}")
    profile = _profile(args, parser)  # (first: its frame joins --param)
    params = _plant_params(args, parser)
    _writable(parser, "--summary", args.summary)
    _writable(parser, "--eeprom-out", args.eeprom_out)
    if args.hang_limit is not None and not 0 <= args.hang_limit <= 600:
        parser.error(f"--hang-limit: expected seconds in 0..600 (0: off), got {args.hang_limit:g}")
    options = trace_options(args)
    if isinstance(options, str):
        parser.error(options)
    try:
        target = McuTarget(args.mcu, args.firmware, eeprom=args.eeprom, hang_limit=args.hang_limit,
                           trace_options=options)
        profile_board(target.board, profile)
    except (BoardError, FirmwareError) as e:
        parser.error(f"--mcu: {e}")
    sticks: list[Event] = []
    if args.sticks is not None:
        if target.board.rc is None:
            parser.error(f"--sticks: the board {target.board.name} has no [rc]: no receiver to give them to")
        try:
            sticks = stick_timeline(args.sticks, args.duration)
        except ScenarioError as e:
            parser.error(str(e))
    trace = None
    if args.trace is not None:
        trace = args.trace / f"{target.firmware.stem}{options.suffix}"
        try:
            args.trace.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            parser.error(f"--trace {args.trace}: {e.strerror}")
        _writable(parser, "--trace", trace)
    world = World.at_rest(seed=args.seed, noise=not args.no_noise, params=params,
                          **target.world_options(profile))
    try:
        with interrupts.handled():
            own = profile.config.eeprom if profile is not None else None  # (the FC profile's EEPROM image)
            run = McuRun(target.session(world, args.duration, {}, args.wall_timeout, trace, args.sim_timeout,
                                        args.eeprom_out, eeprom_image=own, profile=profile))
            if sticks:
                rc = StickEmulator(RC_PATH)
                for ev in sticks:  # (first: the frame at 0 carries the sticks given for 0)
                    run.session.at(ev.t, apply_event(rc, ev, profile or profiles.load(), []))
                rc.start(run.session)
            outcome = run.session.run()
    finally:
        world.close()
    idle = None if outcome.error or args.allow_no_devices else run.idle(outcome)
    if idle is not None:  # (as a command that never touches the devices: nothing was tested)
        outcome.verdict, outcome.exit_code, outcome.error = "error", EXIT_RIG_ERROR, idle
    sys.stdout.buffer.write(run.session.serial_output(TELEMETRY_PATH))
    sys.stdout.flush()
    if outcome.error:
        print(f"rig exec: error: {outcome.error}", file=sys.stderr)
    if args.summary:
        summary = asdict(outcome)
        rate = outcome.sim_time / outcome.wall_time if outcome.wall_time > 0 else None
        summary.update(firmware=str(target.firmware), board=target.board.name, realtime_factor=rate,
                       **run.figures(outcome))
        if trace is not None:
            summary["trace"] = str(trace)
        summary["poll_skip"] = run.session.poll_at_end  # (a figure of the engine's speed: not in result.json)
        args.summary.write_text(json.dumps(summary, indent=2, sort_keys=True) + "\n")
    return outcome.exit_code


def stick_timeline(spec: str, duration: float) -> list[Event]:
    """``--sticks``: "k=v,..." from time 0, or "T:k=v,...;T:..." at sim times T, each checked as a
    scenario's [[timeline]] sticks are (arm and alt_hold take on/off)."""
    check = _Check("--sticks")
    events = []
    for i, part in enumerate(p.strip() for p in spec.split(";")):
        when, _, settings = part.rpartition(":")
        table: dict[str, object] = {}
        try:
            table["t"] = float(when) if when else 0.0
        except ValueError:
            raise check.fail(f"[{i}]", f"expected a time in seconds before ':', got {when!r}") from None
        sticks: dict[str, object] = {}
        for item in filter(None, (s.strip() for s in settings.split(","))):
            key, eq, value = item.partition("=")
            if not eq:
                raise check.fail(f"[{i}]", f"expected stick=value, got {item!r}")
            flag = {"on": True, "off": False, "true": True, "false": False}.get(value.strip().lower())
            try:
                sticks[key.strip()] = flag if flag is not None else float(value)
            except ValueError:
                sticks[key.strip()] = value.strip()  # (the check says what it expected)
        table["sticks"] = sticks
        events.append(timeline_event(check, table, f"[{i}]", duration))
    return events

