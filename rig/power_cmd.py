"""``rig power on|off|cycle|status --psu MAKE:PORT[@BAUD]``: the bench supply by hand (docs/power.md).
Exit status: 0 done, 2 bad usage, 3 the supply did not answer or did not do it (its words printed)."""

from __future__ import annotations

import argparse
import os
import sys

from rig.power.supply import (
    DEFAULT_OFF_S,
    DEFAULT_SETTLE_S,
    DEFAULT_TIMEOUT_S,
    PsuError,
    open_supply,
    power_cycle,
    power_off,
    power_on,
)
from rig.scenarios.bench import parse_psu

EXIT_USAGE, EXIT_PSU = 2, 3


def add_psu_option(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument("--psu", default=os.environ.get("RIG_PSU"), metavar="MAKE:PORT[@BAUD]",
                   help=f"{what}: riden:/dev/ttyUSB0 (Modbus RTU, 115200 baud by default) or "
                        "korad:/dev/ttyACM0 (9600); default $RIG_PSU")


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("power", help="switch, power-cycle or read the bench supply", description=__doc__)
    p.add_argument("action", choices=("on", "off", "cycle", "status"))
    add_psu_option(p, "the supply")
    p.add_argument("--volts", type=float, help="set the output voltage first")
    p.add_argument("--amps", type=float, help="set the supply's current limit first")
    p.add_argument("--off-s", type=float, default=DEFAULT_OFF_S,
                   help="cycle: seconds the output stays off (default %(default)s)")
    p.add_argument("--settle-s", type=float, default=DEFAULT_SETTLE_S,
                   help="on, cycle: seconds the output may take to reach its set voltage "
                        "(default %(default)s)")
    p.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT_S,
                   help="seconds to wait for each answer (default %(default)s)")


def main(args: argparse.Namespace) -> int:
    if not args.psu:
        print("rig power: which supply? --psu MAKE:PORT[@BAUD] (or $RIG_PSU)", file=sys.stderr)
        return EXIT_USAGE
    try:
        spec = parse_psu(args.psu)
    except ValueError as e:
        print(f"rig power: --psu {e}", file=sys.stderr)
        return EXIT_USAGE
    if not (0 < args.timeout <= 10 and 0 <= args.off_s <= 60 and 0 < args.settle_s <= 60):
        print("rig power: --timeout is 0..10 s, --off-s 0..60 s, --settle-s 0..60 s", file=sys.stderr)
        return EXIT_USAGE
    try:
        psu = open_supply(spec, timeout=args.timeout)
        try:
            if args.volts is not None:
                psu.set_voltage(args.volts)
            if args.amps is not None:
                psu.set_current_limit(args.amps)
            if args.action == "off":
                power_off(psu, 0.0)
            elif args.action == "on":
                power_on(psu, args.settle_s)
            elif args.action == "cycle":
                power_cycle(psu, args.off_s, args.settle_s)
            print(f"{psu.identity()} at {spec}: {psu.read().line()}")
        finally:
            psu.close()
    except PsuError as e:
        print(f"rig power: {e}", file=sys.stderr)
        return EXIT_PSU
    return 0
