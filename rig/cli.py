"""The ``rig`` command line."""

from __future__ import annotations

import argparse
import sys

from rig import __version__, exec_cmd, run_cmd


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="rig", description="Quadrotor hardware-in-the-loop test rig")
    parser.add_argument("--version", action="version", version=f"rig {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("demo", help="fly the plant FMU: seed-000 roll-stand release and open-loop hovers")
    exec_cmd.add_parser(sub)
    run_cmd.add_parsers(sub)
    args = parser.parse_args(argv)
    if args.command == "exec":
        return exec_cmd.main(args, parser)
    if args.command == "run":
        return run_cmd.cmd_run(args)
    if args.command == "validate":
        return run_cmd.cmd_validate(args.scenarios)
    if args.command == "list":
        return run_cmd.cmd_list()
    if args.command == "demo":
        from rig import demo

        return demo.main()
    parser.error(f"unknown command {args.command}")
    return 2


if __name__ == "__main__":
    sys.exit(main())
