"""docs/cli.md is the command line's reference: every option of every ``rig`` command (subcommands of
subcommands included) is named there, so a new option cannot land undocumented. The options are read
from the command line's own parser (rig/cli.py ``parser()``), the one ``--help`` prints."""

from __future__ import annotations

import argparse
import re
from collections.abc import Iterator
from pathlib import Path

from rig.cli import parser

DOC = Path(__file__).resolve().parents[1] / "docs" / "cli.md"
#: argparse's own
GENERIC = {"--help", "--version"}


def options(p: argparse.ArgumentParser, words: tuple[str, ...] = ()) -> Iterator[tuple[str, str]]:
    """(command, option) for every long option of ``p`` and of its subcommands."""
    for action in p._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, child in action.choices.items():
                yield from options(child, (*words, name))
        for opt in action.option_strings:
            if opt.startswith("--") and opt not in GENERIC:
                yield " ".join(("rig", *words)), opt


def test_every_option_of_every_command_is_in_the_reference() -> None:
    doc = DOC.read_text()
    found = list(options(parser()))
    assert len(found) > 50 and ("rig run", "--mcu") in found  # (the walk reached the subcommands)
    missing = [f"{cmd} {opt}" for cmd, opt in found if not named(opt, doc)]
    assert not missing, "options missing from docs/cli.md:\n" + "\n".join(missing)


def named(opt: str, doc: str) -> bool:
    """The option as a word of its own (--modbus-open does not name --modbus)."""
    return re.search(rf"(?<![\w-]){re.escape(opt)}(?![\w-])", doc) is not None


def test_the_walk_sees_a_missing_option() -> None:
    p = argparse.ArgumentParser(prog="rig")
    sub = p.add_subparsers()
    sub.add_parser("x").add_argument("--not-in-the-docs")
    assert list(options(p)) == [("rig x", "--not-in-the-docs")]
    assert not named("--not-in-the-docs", DOC.read_text())
    assert not named("--modbus", "`--modbus-open`") and named("--modbus", "`--modbus PORT`")


def test_help_shows_no_source_markup() -> None:
    """The descriptions come from docstrings that mark code as ``x``: --help shows plain x."""
    marked = []

    def walk(p: argparse.ArgumentParser) -> None:
        if "``" in p.format_help():
            marked.append(p.prog)
        for action in p._actions:
            if isinstance(action, argparse._SubParsersAction):
                for child in action.choices.values():
                    walk(child)

    walk(parser())
    assert marked == []
