"""docs/cli.md is the command line's reference: every option that ``rig COMMAND --help`` lists is
named there, so a new option cannot land undocumented. The help texts are read from the real command
line, subcommands of subcommands included."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

DOC = Path(__file__).resolve().parents[1] / "docs" / "cli.md"
OPTION = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*")
#: argparse's own
GENERIC = {"--help", "--version"}


def help_text(*words: str) -> str:
    done = subprocess.run([sys.executable, "-m", "rig.cli", *words, "--help"], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0, done.stderr
    return done.stdout


def commands(*words: str) -> list[tuple[str, ...]]:
    """``words`` and every subcommand below it, from the help's ``{a,b,c}`` choice list (a choice is a
    subcommand when its own help's usage names it: a positional's choices, as `rig power`'s action, are
    not)."""
    text = help_text(*words)
    out = [words]
    m = re.search(r"^\s*\{([a-z,-]+)\}", text, re.M)
    for name in m.group(1).split(",") if m else []:
        if help_text(*words, name).startswith(f"usage: {' '.join(('rig', *words, name))} "):
            out += commands(*words, name)
    return out


def test_every_option_of_every_command_is_in_the_reference() -> None:
    doc = DOC.read_text()
    listed = set(OPTION.findall(doc))
    missing = []
    found = 0
    for cmd in commands():
        for opt in sorted(set(OPTION.findall(help_text(*cmd))) - GENERIC):
            found += 1
            if opt not in listed:
                missing.append(f"rig {' '.join(cmd)} {opt}")
    assert found > 50  # (the check read the real help texts)
    assert not missing, "options missing from docs/cli.md:\n" + "\n".join(missing)
