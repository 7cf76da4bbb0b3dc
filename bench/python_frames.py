"""Which functions a lockstep flight still runs as plain Python, and how often per FC cycle. Printed,
never asserted.

Why: the session's hot modules are compiled (rig/compiled.py) and its per-cycle path is C, so what
runs as Python bytecode in a flight is what slipped through: a dataclass method the ``dataclasses``
module generated (its ``__init__``, ``__eq__``: Python even in a compiled module), a helper in a module
that is not compiled, the standard library. callgrind charges such a function to the interpreter and
to whichever compiled caller it has, where it hides; a profile hook sees only Python frames, so it
names exactly these. Counting them found a fifth of a flight's session instructions in two generated
methods (bench/reference/cycle-after.md).

How: after a short run that imports what a run needs, the hover in light turbulence to 4 s and to
8 s under ``sys.setprofile``, Python frames counted
by function (a generated method also by the class of its ``self``); the difference is 1000 FC cycles.
The counts, not the time: a profile hook slows every Python call alike.

    .venv/bin/python bench/python_frames.py [--top 20]
"""

from __future__ import annotations

import argparse
import collections
import dataclasses
import sys
import types
from pathlib import Path
from typing import Any

SHORT_S, LONG_S = 4.0, 8.0
FC_HZ = 250
REPO = Path(__file__).resolve().parents[1]


def frames(duration: float) -> collections.Counter[str]:
    """Python frames entered during a hover of ``duration`` sim seconds, by function."""
    from rig import scenarios
    from rig.runner import run
    from rig.scenarios.schema import load

    seen: collections.Counter[str] = collections.Counter()

    def hook(frame: types.FrameType, event: str, arg: Any) -> None:
        if event != "call":
            return
        code = frame.f_code
        where = code.co_filename.replace(f"{REPO}/", "")
        name = f"{where}:{code.co_firstlineno} {code.co_name}"
        if code.co_filename == "<string>":  # a method the dataclasses module generated
            name += f" of {type(frame.f_locals.get('self')).__qualname__}"
        seen[name] += 1

    sc = load(Path(scenarios.__file__).parent / "library" / "hover_turbulence.toml")
    sys.setprofile(hook)
    try:
        run(dataclasses.replace(sc, duration=duration))
    finally:
        sys.setprofile(None)
    return seen


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--top", type=int, default=20, help="how many functions to print")
    args = ap.parse_args()
    sys.path.insert(0, str(REPO))
    from rig.compiled import install, status

    install()  # the compiled hot modules, before they are imported
    print(status())
    frames(0.5)  # (a first run imports and caches what every run needs: its frames are not a flight's)
    short, long = frames(SHORT_S), frames(LONG_S)
    cycles = (LONG_S - SHORT_S) * FC_HZ
    per = sorted(((long[k] - short[k]) / cycles, k) for k in long.keys() | short.keys())
    print(f"Python frames per FC cycle (hover, {SHORT_S:g} s to {LONG_S:g} s): {sum(p for p, _ in per):.2f}")
    for p, name in reversed(per[-args.top:]):
        if p > 0:
            print(f"  {p:6.2f}  {name}")


if __name__ == "__main__":
    main()
