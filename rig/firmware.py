"""What identifies the firmware under test in a DUT command line, and its SHA-256.

For ``--dut ./fc`` the program is the firmware. For ``--dut "python3 mydut.py"`` the program is an
interpreter that every DUT shares, and the firmware is the script: hashing ``python3`` alone made two
different DUTs look the same in every report. So an interpreter's script (or inline code) is hashed,
the interpreter is recorded beside it, and the metadata says which file the hash is of.
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
from pathlib import Path

#: Programs that run a file named by their first operand
INTERPRETERS = re.compile(r"(python|pypy|perl|ruby|node|nodejs|lua|php|bash|sh|dash|zsh|ksh)[\d.]*")
#: Their options that take the next argument as a value (not the script)
OPTIONS_WITH_VALUE = {"-W", "-X", "--require", "-r", "-o"}
#: Options whose value is the program itself (inline code, or a module name)
INLINE = {"-c", "-e", "--eval", "-E"}
MODULE = {"-m"}


def _sha256(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def identify(command: list[str], cwd: Path | None = None) -> dict[str, object]:
    """Metadata naming the firmware: ``dut_firmware`` (what was hashed, in words),
    ``dut_firmware_sha256``, and the program that runs it (``dut_program``, ``dut_program_sha256``)."""
    cwd = cwd or Path.cwd()
    args = list(command)
    exe = shutil.which(args[0]) if args else None
    info: dict[str, object] = {
        "dut_program": str(Path(exe).resolve()) if exe else (args[0] if args else None),
        "dut_program_sha256": _sha256(Path(exe)) if exe else None,
    }
    name = Path(args[0]).name if args else ""
    if name == "env":  # env [-options] [VAR=value …] PROGRAM …
        rest = args[1:]
        while rest and (rest[0].startswith("-") or "=" in rest[0]):
            rest.pop(0)
        if rest:
            return identify(rest, cwd) | {"dut_launcher": "env"}
    if not INTERPRETERS.fullmatch(name):
        info |= {"dut_firmware": f"the program {info['dut_program']}",
                 "dut_firmware_sha256": info["dut_program_sha256"]}
        return info
    i = 1
    while i < len(args):
        a = args[i]
        if a in INLINE and i + 1 < len(args):
            code = args[i + 1]
            info |= {"dut_firmware": f"the inline code {name} {a} runs",
                     "dut_firmware_sha256": hashlib.sha256(code.encode()).hexdigest()}
            return info
        if a in MODULE and i + 1 < len(args):
            info |= {"dut_firmware": f"the module {args[i + 1]!r} that {name} -m runs (not hashed: "
                                     "found only on the DUT's own import path)",
                     "dut_firmware_sha256": None}
            return info
        if a == "--":
            i += 1
            break
        if not a.startswith("-") or a == "-":
            break
        i += 2 if a in OPTIONS_WITH_VALUE else 1
    if i >= len(args) or args[i] == "-":
        info |= {"dut_firmware": f"what {name} reads on its standard input (not hashed)",
                 "dut_firmware_sha256": None}
        return info
    script = Path(args[i])
    path = script if script.is_absolute() else cwd / script
    digest = _sha256(path)
    info |= {"dut_firmware": f"the script {os.path.normpath(path)} that {name} runs",
             "dut_firmware_sha256": digest}
    if digest is None:
        info["dut_firmware"] = f"the script {args[i]} that {name} runs (not found, not hashed)"
    return info
