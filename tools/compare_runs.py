"""Two `rig run` report folders side by side, as a Markdown table: each criterion's value in both, its
limits, and both outcomes (docs/avr-fc.md's table of the AVR firmware through the MCU tier beside the
Linux FC in lockstep was made with it).

    python tools/compare_runs.py build/linux-reports build/avr-reports --names "Linux FC" "AVR FC"
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path


def _runs(folder: Path) -> dict[str, dict[str, dict[str, object]]]:
    out: dict[str, dict[str, dict[str, object]]] = {}
    for f in sorted(folder.glob("*/result.json")):
        r = json.loads(f.read_text())
        out[f.parent.name] = {m["name"]: m for m in r["measurements"]}
    return out


def _value(m: dict[str, object] | None) -> str:
    if m is None:
        return "—"
    v = m.get("value")
    if not isinstance(v, int | float) or not math.isfinite(v):
        return str(m.get("value_reason") or v)  # (result.json: null with its reason, nan/inf/-inf)
    return f"{v:.3g}"


def _limits(m: dict[str, object]) -> str:
    lo, hi = m.get("min"), m.get("max")
    if lo is not None and hi is not None:
        return f"{lo:g}..{hi:g}"
    return f"≥ {lo:g}" if lo is not None else f"≤ {hi:g}" if hi is not None else ""


def table(a: Path, b: Path, names: tuple[str, str]) -> str:
    ra, rb = _runs(a), _runs(b)
    lines = [f"| scenario | criterion | {names[0]} | {names[1]} | limits | outcomes |",
             "| --- | --- | ---: | ---: | --- | --- |"]
    for sc in sorted(set(ra) | set(rb)):
        for name in dict.fromkeys([*ra.get(sc, {}), *rb.get(sc, {})]):
            ma, mb = ra.get(sc, {}).get(name), rb.get(sc, {}).get(name)
            ref = ma or mb
            assert ref is not None
            units = f" {ref.get('units')}" if ref.get("units") else ""
            outcomes = " / ".join(str(m.get("outcome")) if m else "—" for m in (ma, mb))
            cells = [sc, name, _value(ma), _value(mb), f"{_limits(ref)}{units}", outcomes]
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("a", type=Path)
    p.add_argument("b", type=Path)
    p.add_argument("--names", nargs=2, default=("A", "B"))
    args = p.parse_args()
    for f in (args.a, args.b):
        if not any(f.glob("*/result.json")):
            print(f"compare_runs: {f}: no run's result.json in it", file=sys.stderr)
            return 2
    sys.stdout.write(table(args.a, args.b, tuple(args.names)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
