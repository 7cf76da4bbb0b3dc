"""A callgrind profile's instructions split by part of the rig (bench/cycle_cost.py --breakdown).

Why: the count of instructions per FC cycle says how much the session costs, not where. The parts are
what a change to the per-cycle path moves (message handling, plant, samples, chip core, scheduler), and
they live in mypyc-compiled Python, in C extension modules and in plain Python run by the interpreter.
So a part is named by patterns on callgrind's object file, source file and function name (``PARTS``,
data: a new C path adds its files there), and every instruction is charged to a part:

* a function a pattern names is charged to its part, with everything it calls that no pattern names
  (the interpreter running plain Python, CPython's dict and call machinery, libc, libm);
* a function no pattern names is charged to the part of its caller, shared among callers by the
  cost of their calls to it (callgrind's inclusive cost per call edge; gprof's assumption that a
  function costs the same whoever calls it);
* what no part reaches (start-up, the bench's own harness) is "other".

The split conserves the profile's total. ``python bench/callgrind.py FILE`` prints one profile's split.
"""

from __future__ import annotations

import re
import sys
from collections import defaultdict
from dataclasses import dataclass, field

#: (part, pattern): the first whose pattern matches "OBJECT FILE:FUNCTION" names the function's part.
#: mypyc names a compiled function CPyDef_/CPyPy_ MODULE___CLASS___METHOD (attribute accessors without
#: the prefix); C functions are named by their source file.
MYPYC = r"(?:^|:)(?:CPy(?:Def|Py)_)?"
#: The lockstep fast path (rig/lockstep, one object file) is split by its functions.
LOCKSTEP = r"_riglockstep[^:]*:"
PARTS: list[tuple[str, str]] = [
    ("scheduler", MYPYC + r"scheduler___|" + LOCKSTEP + r"clear_until\b"),
    ("plant", r"/plant/c/|_plantsteps|" + MYPYC + r"world___World___advance_to|"
              + LOCKSTEP + r"(world_to|plant_steps_of|rig_plant_steps)\b"),
    ("samples", r"emulators/c/sampling\.c:|:fc_(imu_measure|lowpass_run|mpu_encode|channel_measure)\b|"
                + LOCKSTEP + r"(serve|imu_serve|attr_ll|attr_double|filter_addr|need_tuple)\b|"
                + MYPYC + r"(sensor_models|dlpf|faults)___|"
                + MYPYC + r"world___(World___(row_addresses|_slots|truth)|TruthTable)"),
    ("chip core", r"/emulators/chips/|:fc_chip_|" + r"_rignative[^:]*:(chip|mpu|hmc|baro|fifo)_|"
                  + MYPYC + r"(board|ms5611|i2c_bus)___|"
                  + MYPYC + r"world___World___transfer"),
    ("message handling", MYPYC + r"(session|handler|protocol|world|rc|sbus|host)___|_riglockstep"),
]
OTHER = "other"


@dataclass
class Profile:
    """A callgrind.out's functions: self cost and calls (caller -> callee: inclusive cost), one event."""

    total: int = 0
    self_cost: dict[str, int] = field(default_factory=lambda: defaultdict(int))
    calls: dict[str, dict[str, int]] = field(default_factory=lambda: defaultdict(lambda: defaultdict(int)))
    where: dict[str, str] = field(default_factory=dict)  # function -> "OBJECT FILE" it was first seen in


_NAMED = re.compile(r"\((\d+)\)(?: (.*))?")


def parse(text: str) -> Profile:
    """Reads callgrind's format (name compression, relative positions, inlined-file switches); the first
    event only. Functions are keyed "OBJECT:FUNCTION" (static functions share names across objects)."""
    prof = Profile()
    names: dict[tuple[str, str], str] = {}

    def name(kind: str, value: str) -> str:
        m = _NAMED.fullmatch(value)
        if not m:
            return value
        if m.group(2) is not None:
            names[(kind, m.group(1))] = m.group(2)
        return names.get((kind, m.group(1)), value)

    ob = fl = fn = ""
    cob = cfl = cfn = ""
    in_call = False
    for line in text.splitlines():
        if not line or line[0] in "#":
            continue
        c = line[0]
        if c.isdigit() or c in "+-*":
            parts = line.split()
            cost = int(parts[1]) if len(parts) > 1 else 0
            if in_call:
                prof.calls[fn][cfn] += cost
                prof.where.setdefault(cfn, f"{cob} {cfl}")
                in_call = False
                cob, cfl = ob, fl  # (a callee's object and file hold for one call only)
            else:
                prof.self_cost[fn] += cost
            continue
        key, _, value = line.partition("=")
        if key == "ob":
            ob = name("ob", value)
        elif key == "fl":
            fl = name("fl", value)
        elif key in ("fi", "fe"):
            name("fl", value)  # an inlined file: the cost stays the function's
        elif key == "fn":
            fn = f"{ob}:{name('fn', value)}"
            prof.self_cost[fn] += 0
            prof.where.setdefault(fn, f"{ob} {fl}")
            cob, cfl = ob, fl
        elif key == "cob":
            cob = name("ob", value)
        elif key in ("cfi", "cfl"):
            cfl = name("fl", value)
        elif key == "cfn":
            cfn = f"{cob}:{name('fn', value)}"
        elif key == "calls":
            in_call = True
        elif key in ("summary", "totals") or line.startswith(("summary:", "totals:")):
            prof.total = int(line.split(":", 1)[1].split()[0])
    return prof


def part_of(function: str, where: str, parts: list[tuple[str, str]]) -> str | None:
    obj_file = where
    func = function.split(":", 1)[1] if ":" in function else function
    text = f"{obj_file}:{func}"
    for part, pattern in parts:
        if re.search(pattern, text):
            return part
    return None


def inclusive(prof: Profile, function: str) -> int:
    """The instructions in calls to the functions named ``function`` (any object), from their callers
    other than themselves: callgrind's inclusive cost of them."""
    return sum(cost for caller, out in prof.calls.items() for callee, cost in out.items()
               if callee.split(":", 1)[-1] == function and caller != callee)


def split(prof: Profile, parts: list[tuple[str, str]] | None = None) -> dict[str, float]:
    """The profile's instructions by part (see the module's docstring); they sum to its total.

    The charge is a linear system over states (function, part it inherits): mass enters at the uncalled
    functions and flows down each call edge by the edge's share of the caller's inclusive cost; each
    state keeps its self-cost share. A function's calls to itself (callgrind's recursion, counted twice
    in its inclusive cost) are left out, which spreads the same mass over its other costs."""
    import numpy as np
    from scipy.sparse import coo_matrix, identity
    from scipy.sparse.linalg import spsolve

    parts = PARTS if parts is None else parts
    names = [OTHER, *dict.fromkeys(p for p, _ in parts)]
    fns = sorted(set(prof.self_cost) | {g for out in prof.calls.values() for g in out})
    index = {f: k for k, f in enumerate(fns)}
    own = [part_of(f, prof.where.get(f, ""), parts) for f in fns]
    own_k = [names.index(p) if p else -1 for p in own]
    selfc = np.array([prof.self_cost.get(f, 0) for f in fns], dtype=float)
    edges = [[(index[g], c) for g, c in prof.calls.get(f, {}).items() if c > 0 and g != f] for f in fns]
    incl = selfc + np.array([sum(c for _, c in e) for e in edges], dtype=float)
    n, k = len(fns), len(names)
    rows, cols, vals = [], [], []
    for fi, calls in enumerate(edges):
        for p in range(k):
            part = own_k[fi] if own_k[fi] >= 0 else p
            for gi, c in calls:
                rows.append(gi * k + (own_k[gi] if own_k[gi] >= 0 else part))
                cols.append(fi * k + p)
                vals.append(c / incl[fi])
    flow = coo_matrix((vals, (rows, cols)), shape=(n * k, n * k)).tocsc()
    entry = np.zeros(n * k)
    called = {g for calls in edges for g, _ in calls}
    for fi in set(range(n)) - called:
        entry[fi * k + (own_k[fi] if own_k[fi] >= 0 else 0)] = incl[fi]
    mass = spsolve((identity(n * k, format="csc") - flow), entry)  # mass = entry + flow @ mass
    kept = (mass.reshape(n, k) * np.divide(selfc, incl, out=np.zeros(n), where=incl > 0)[:, None])
    by_part: dict[str, float] = defaultdict(float)
    for fi in range(n):
        for p in range(k):
            by_part[names[own_k[fi] if own_k[fi] >= 0 else p]] += float(kept[fi, p])
    return dict(by_part)


def main(argv: list[str]) -> int:
    prof = parse(open(argv[0]).read())
    by_part = split(prof)
    for part, cost in sorted(by_part.items(), key=lambda kv: -kv[1]):
        print(f"{part:18} {cost:15,.0f} ({cost / max(prof.total, 1) * 100:5.1f} %)")
    print(f"{'total':18} {sum(by_part.values()):15,.0f} (callgrind's summary {prof.total:,})")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
