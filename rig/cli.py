"""The ``rig`` command line."""

from __future__ import annotations

import argparse
import os
import sys

from rig import __version__, compiled, scratch

EXIT_BROKEN_PIPE = 128 + 13  # as a shell reports a command ended by SIGPIPE


def main(argv: list[str] | None = None) -> int:
    """Runs one command. A reader that goes away early (``rig list | head``) ends it quietly, as it
    ends other Unix commands, instead of with a BrokenPipeError traceback. First, the temporary
    folders of rigs that were killed without cleaning up go (rig/scratch.py)."""
    scratch.reap()
    try:
        code = _dispatch(argv)
        sys.stdout.flush()  # (here, not at exit, where the error could only be printed)
        return code
    except BrokenPipeError:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # the interpreter's own flush at exit finds nowhere to fail
        return EXIT_BROKEN_PIPE


def parser() -> argparse.ArgumentParser:
    """The whole command line (docs/cli.md documents every option it has: tests/test_cli_docs.py)."""
    from rig import exec_cmd, power_cmd, report_cmd, run_cmd, sweep_cmd
    from rig.bridge import probe
    from rig.service import bench_host, client, serve_cmd

    p = argparse.ArgumentParser(prog="rig", description="Quadrotor hardware-in-the-loop test rig")
    p.add_argument("--version", action="version", version=f"rig {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    sub.add_parser("demo", help="fly the plant FMU: seed-000 roll-stand release and open-loop hovers")
    exec_cmd.add_parser(sub)
    run_cmd.add_parsers(sub)
    report_cmd.add_parser(sub)
    probe.add_parser(sub)
    power_cmd.add_parser(sub)
    sweep_cmd.add_parser(sub)
    serve_cmd.add_parser(sub)
    client.add_parsers(sub)
    bench_host.add_parser(sub)
    _plain(p)
    return p


def _plain(p: argparse.ArgumentParser) -> None:
    """The commands' descriptions are their modules' docstrings, which mark code as ``x`` for the
    source's readers: --help shows it as x."""
    for action in p._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child in action.choices.values():
                if child.description:
                    child.description = child.description.replace("``", "")
                _plain(child)


def _dispatch(argv: list[str] | None) -> int:
    compiled.install()  # the hot modules from build/mypyc, before the commands import them
    from rig import exec_cmd, power_cmd, report_cmd, run_cmd, sweep_cmd
    from rig.bridge import probe
    from rig.service import client, serve_cmd

    cli = parser()
    args = cli.parse_args(argv)
    if args.command == "exec":
        return exec_cmd.main(args)
    if args.command == "run":
        return run_cmd.cmd_run(args, sys.argv[1:] if argv is None else argv)
    if args.command == "report":
        return report_cmd.main(args)
    if args.command == "bridge":
        return probe.main(args)
    if args.command == "power":
        return power_cmd.main(args)
    if args.command == "sweep":
        return sweep_cmd.main(args)
    if args.command == "serve":
        return serve_cmd.main(args)
    if args.command == "submit":
        return client.cmd_submit(args)
    if args.command == "status":
        return client.cmd_status(args)
    if args.command == "bench":
        return client.cmd_bench(args)
    if args.command == "bench-host":
        from rig.service import bench_host

        return bench_host.main(args)
    if args.command == "validate":
        return run_cmd.cmd_validate(args.scenarios, args.fc)
    if args.command == "list":
        return run_cmd.cmd_list()
    if args.command == "demo":
        from rig import demo

        return demo.main()
    cli.error(f"unknown command {args.command}")
    return 2


if __name__ == "__main__":
    sys.exit(main())
