"""``rig exec [options] -- CMD ARGS...``: run any program with the emulated devices attached.

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
import sys
from dataclasses import asdict
from pathlib import Path

from emulators.topology import TOPOLOGIES
from plant.variables import PARAMETERS, check_parameters
from rig import interrupts
from rig.bridge.esc import ESC_PROTOCOLS
from rig.bridge.session import BenchConfig, BenchSession
from rig.session import Session, SessionConfig
from rig.world import World

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


def _positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds, got {text!r}") from None
    if not v > 0:
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, got {text!r}")
    return v


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
    p.add_argument("--pwm-channels", type=int, default=8, metavar="N", help="channels of pwmchip0 (1..16)")
    p.add_argument("--i2c-clock", choices=sorted(CLOCKS), default="0",
                   help="each transfer takes its wire time at this SCL clock (default 0: no time)")
    p.add_argument("--quantum-ns", type=int, default=1000, metavar="NS",
                   help="sim time one clock read costs in lockstep (default 1000)")
    p.add_argument("--duration", type=_positive, metavar="S",
                   help="run for S sim seconds, then stop the command (a flight controller never exits)")
    p.add_argument("--sim-timeout", type=_positive, default=600.0, metavar="S", help="sim-time watchdog")
    p.add_argument("--wall-timeout", type=_positive, default=600.0, metavar="S", help="wall-time watchdog")
    p.add_argument("--stall-timeout", type=_positive, default=30.0, metavar="S",
                   help="lockstep: wall seconds without a request or clock read before the run is stopped")
    p.add_argument("--pin", action=argparse.BooleanOptionalAction, default=None,
                   help="pin the command and the session to one core (default: in lockstep only)")
    p.add_argument("--seed", type=int, default=0, help="seed of the sensor noise")
    p.add_argument("--no-noise", action="store_true", help="exact sensors")
    p.add_argument("--param", type=_param, action="append", default=[], metavar="NAME=VALUE",
                   help="plant parameter (repeatable), e.g. --param stand=1")
    p.add_argument("--log", type=Path, metavar="FILE", help="write the transaction log here")
    p.add_argument("--summary", type=Path, metavar="FILE", help="write the outcome as JSON here")
    p.add_argument("--allow-no-devices", action="store_true",
                   help="a command that never touches the devices is not an error")
    p.add_argument("argv", nargs=argparse.REMAINDER, metavar="-- CMD ARGS", help="the command to run")
    p.set_defaults(exec_parser=p)  # (usage errors found after parsing say "rig exec: error: ...")


def main(args: argparse.Namespace) -> int:
    parser: argparse.ArgumentParser = args.exec_parser
    command = args.argv[1:] if args.argv[:1] == ["--"] else args.argv
    if not command:
        parser.error("rig exec needs a command after --")
    if not 1 <= args.pwm_channels <= 16:
        parser.error("--pwm-channels must be between 1 and 16")
    if not 0 <= args.bus < 32:
        parser.error("--bus must be between 0 and 31")
    if args.quantum_ns < 0:
        parser.error("--quantum-ns must not be negative")
    refused = check_parameters(dict(args.param))  # the FMU's own rules, before anything starts
    if refused:
        parser.error(f"--param: the plant refuses it: {refused}")
    _writable(parser, "--log", args.log)
    _writable(parser, "--summary", args.summary)
    cfg = SessionConfig(command=command, lockstep=not args.realtime, i2c_bus=args.bus, serial=args.serial,
                        i2c_clock_hz=CLOCKS[args.i2c_clock], quantum_ns=args.quantum_ns,
                        duration=args.duration, sim_timeout=args.sim_timeout, wall_timeout=args.wall_timeout,
                        stall_timeout=args.stall_timeout, pin=args.pin, log_path=args.log,
                        allow_no_devices=args.allow_no_devices)
    world = World.at_rest(seed=args.seed, topology=args.topology, noise=not args.no_noise,
                          params=dict(args.param), pwm_channels=args.pwm_channels)
    if args.bridge is not None and args.bridge != "virtual":
        parser.error("a command runs against the virtual bridge only (--bridge virtual); behind a real "
                     "bridge the board is the DUT: use rig run --bridge PORT")
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
