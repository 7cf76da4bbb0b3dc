"""The library's measurements at seeds 0-4, recorded before a change to the per-cycle path and
compared after it.

A change that moves the session's work (to C, say) must not change what the rig measures: every
criterion of every library scenario should come out as it did, or differ only by a floating-point
order that changed, far inside its limit. This flies ``scenarios/library/*.toml`` at seeds 0-4 with
the reference FC in lockstep (``rig.runner.run``, as the tests do) and writes each criterion's value,
limit and verdict, and each run's verdict, to ``bench/reference/library-seeds0-4.json``, with the
commit, the day and the FC's SHA-256. Lockstep runs are deterministic, so two runs write the same
file (on the same day).

    .venv/bin/python bench/library_reference.py              # write the reference
    .venv/bin/python bench/library_reference.py --compare    # fly again, compare with it

``--compare`` prints each value's difference and the difference / |limit| and exits 1 when one is
over ``TOLERANCE`` of its limit or any verdict changed. The comparison is ``compare()``, a pure
function of two such documents (tests/test_bench_reference.py).
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import subprocess
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
LIBRARY = REPO / "scenarios" / "library"
DEFAULT_FILE = REPO / "bench" / "reference" / "library-seeds0-4.json"
SEEDS = range(5)
TOLERANCE = 1e-6  # of the limit: what a changed floating-point order may move a value by
FORMAT = 1


# ---- the document (pure: no rig imports, so the test loads this module cheaply) ----


def encode(x: float | None) -> float | str | None:
    """A value for JSON: non-finite values as strings ("nan", "inf", "-inf"), which strict JSON lacks."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else str(x)


def decode(x: object) -> float | None:
    """``encode``'s inverse; anything else in the file is a clear error."""
    if x is None:
        return None
    if isinstance(x, bool) or not isinstance(x, (int, float, str)):
        raise ValueError(f"not a number: {x!r}")
    if isinstance(x, str) and x not in ("nan", "inf", "-inf"):
        raise ValueError(f"not a number: {x!r}")
    return float(x)


def limit_scale(lo: float | None, hi: float | None) -> float:
    """The |limit| a difference is measured against: the smaller non-zero one of min and max (the
    stricter reading when both are set); 1 when neither is non-zero (then the tolerance is absolute)."""
    sizes = [abs(v) for v in (lo, hi) if v is not None and v != 0 and math.isfinite(v)]
    return min(sizes) if sizes else 1.0


@dataclass(frozen=True)
class Difference:
    """One value of ``after`` against ``before``: ``key`` is "scenario/seed/criterion" (or
    "scenario/seed" for the run's own verdict); ``relative`` is the difference / |limit|."""

    key: str
    before: float | str | None
    after: float | str | None
    difference: float
    relative: float
    problem: str  # "" when within tolerance and the verdicts match

    @property
    def bad(self) -> bool:
        return bool(self.problem)


def _runs(doc: dict[str, Any]) -> dict[str, dict[str, Any]]:
    runs = doc.get("runs")
    if not isinstance(runs, list):
        raise ValueError("the document has no list 'runs'")
    out = {}
    for r in runs:
        if not isinstance(r, dict) or not isinstance(r.get("criteria"), list):
            raise ValueError(f"a run without a list 'criteria': {r!r:.200}")
        out[f"{r['scenario']}/{r['seed']}"] = r
    return out


def compare(before: dict[str, Any], after: dict[str, Any], tolerance: float = TOLERANCE) -> list[Difference]:
    """Every value of ``after`` against ``before``, in ``before``'s order (then what is new). A problem
    is a difference over ``tolerance`` x |limit|, a changed verdict (the run's or a criterion's), a
    limit that changed, or a run or criterion on one side only. NaN equals NaN."""
    a_runs, b_runs = _runs(before), _runs(after)
    out: list[Difference] = []
    for key in [*a_runs, *(k for k in b_runs if k not in a_runs)]:
        a, b = a_runs.get(key), b_runs.get(key)
        if a is None or b is None:
            out.append(Difference(key, None, None, math.nan, math.nan,
                                  "only after" if a is None else "only before"))
            continue
        problem = "" if a["verdict"] == b["verdict"] else f"run verdict {a['verdict']} -> {b['verdict']}"
        out.append(Difference(key, a["verdict"], b["verdict"], 0.0, 0.0, problem))
        a_cr = {c["name"]: c for c in a["criteria"]}
        b_cr = {c["name"]: c for c in b["criteria"]}
        for name in [*a_cr, *(n for n in b_cr if n not in a_cr)]:
            ca, cb = a_cr.get(name), b_cr.get(name)
            ckey = f"{key}/{name}"
            if ca is None or cb is None:
                out.append(Difference(ckey, None, None, math.nan, math.nan,
                                      "only after" if ca is None else "only before"))
                continue
            out.append(_criterion(ckey, ca, cb, tolerance))
    return out


def _criterion(key: str, ca: dict[str, Any], cb: dict[str, Any], tolerance: float) -> Difference:
    va, vb = decode(ca["value"]), decode(cb["value"])
    lo, hi = decode(ca["min"]), decode(ca["max"])
    scale = limit_scale(lo, hi)
    problems = []
    if (lo, hi) != (decode(cb["min"]), decode(cb["max"])):
        problems.append(f"limits [{ca['min']}, {ca['max']}] -> [{cb['min']}, {cb['max']}]")
    if va is None or vb is None:
        diff = 0.0 if va is vb else math.nan
    elif va == vb or (math.isnan(va) and math.isnan(vb)):
        diff = 0.0
    else:
        diff = vb - va  # NaN when one side is NaN
    rel = abs(diff) / scale if math.isfinite(diff) else math.inf
    if rel > tolerance:
        problems.append(f"differs by {rel:.3g} of its limit")
    if ca["outcome"] != cb["outcome"]:
        problems.append(f"verdict {ca['outcome']} -> {cb['outcome']}")
    return Difference(key, ca["value"], cb["value"], diff, rel, "; ".join(problems))


# ---- flying the library ----


def _worker_init() -> None:
    sys.path.insert(0, str(REPO))
    from rig.compiled import install

    install()  # the compiled hot modules, as `rig run` uses them


def fly(task: tuple[str, int]) -> dict[str, Any]:
    """One library scenario at one seed: its verdict and each criterion's value, limits, verdict."""
    path, seed = task
    from rig.runner import run
    from rig.scenarios.schema import load

    res = run(load(Path(path)), seed=seed)
    return {
        "scenario": Path(path).stem,
        "seed": seed,
        "verdict": res.verdict,
        "error": res.error,
        "fc_sha256": res.metadata.get("dut_firmware_sha256"),
        "plant_fmu_sha256": res.metadata.get("plant_fmu_sha256"),
        "criteria": [
            {"name": m.name, "metric": m.metric, "signal": m.signal, "units": m.units,
             "value": encode(m.value), "min": encode(m.min), "max": encode(m.max), "outcome": m.outcome}
            for m in res.measurements
        ],
    }


def fly_library(jobs: int) -> list[dict[str, Any]]:
    """Every library scenario at seeds 0-4, in a pool of ``jobs`` processes; progress on stderr."""
    tasks = [(str(p), s) for p in sorted(LIBRARY.glob("*.toml")) for s in SEEDS]
    runs = []
    with ProcessPoolExecutor(jobs, initializer=_worker_init) as pool:
        for n, r in enumerate(pool.map(fly, tasks), 1):
            print(f"  {n}/{len(tasks)} {r['scenario']} seed {r['seed']}: {r['verdict']}", file=sys.stderr,
                  flush=True)
            runs.append(r)
    return runs


def _git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True, check=True).stdout.strip()


def document(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """The reference file's content: the runs, and what they were flown with (the FC and plant build
    hashes once, taken out of each run)."""
    fc = {r.pop("fc_sha256") for r in runs}
    fmu = {r.pop("plant_fmu_sha256") for r in runs}
    # tracked files changed outside bench/ and tests/: the flown tree is then not the commit's
    dirty = [line[3:] for line in _git("status", "--porcelain", "--untracked-files=no").splitlines()
             if not line[3:].startswith(("bench/", "tests/"))]
    return {
        "format": FORMAT,
        "what": "library measurements, reference FC, Linux program target, lockstep "
                "(bench/library_reference.py)",
        "commit": _git("rev-parse", "HEAD"),
        "tree_changes_outside_bench": dirty,
        "date": datetime.datetime.now(datetime.UTC).date().isoformat(),
        "fc_sha256": sorted(x for x in fc if x) if len(fc) > 1 else next(iter(fc)),
        "plant_fmu_sha256": sorted(x for x in fmu if x) if len(fmu) > 1 else next(iter(fmu)),
        "tolerance_of_limit": TOLERANCE,
        "runs": runs,
    }


def report(diffs: list[Difference], verbose: bool) -> int:
    """Prints the differences (every value with ``verbose``, else the non-zero ones); returns the
    count of bad ones."""
    worst = max((d for d in diffs if math.isfinite(d.relative)), key=lambda d: d.relative, default=None)
    for d in diffs:
        if verbose or d.bad or (d.difference != 0 and not math.isnan(d.difference)):
            flag = "BAD " if d.bad else "    "
            print(f"{flag}{d.key}: {d.before} -> {d.after}: difference {d.difference:.3g}, "
                  f"{d.relative:.3g} of |limit|{'; ' + d.problem if d.problem else ''}")
    bad = sum(d.bad for d in diffs)
    changed = sum(1 for d in diffs if d.difference != 0 and not math.isnan(d.difference))
    print(f"{len(diffs)} values compared: {changed} differ, {bad} over {TOLERANCE:g} of their limit or "
          f"with a changed verdict; largest relative difference "
          f"{worst.relative if worst else 0:.3g}{f' ({worst.key})' if worst and worst.relative else ''}")
    return bad


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    ap.add_argument("--compare", nargs="?", const=DEFAULT_FILE, type=Path, metavar="FILE",
                    help=f"fly again and compare with FILE (default {DEFAULT_FILE.relative_to(REPO)})")
    ap.add_argument("--out", type=Path, default=DEFAULT_FILE, help="where to write the reference")
    ap.add_argument("--jobs", type=int, default=2, help="processes flying at once (default 2)")
    ap.add_argument("--verbose", action="store_true", help="with --compare, print every value")
    args = ap.parse_args(argv)
    if args.jobs < 1:
        ap.error("--jobs must be at least 1")
    before = None
    if args.compare is not None:
        try:
            before = json.loads(args.compare.read_text())
            _runs(before)
        except (OSError, ValueError) as e:
            ap.error(f"{args.compare}: {e}")
    doc = document(fly_library(args.jobs))
    if before is None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(doc, indent=1, allow_nan=False) + "\n")
        print(f"wrote {args.out} ({len(doc['runs'])} runs at {doc['commit'][:12]})")
        return 0
    print(f"before: {args.compare} at {str(before.get('commit'))[:12]}, "
          f"FC {str(before.get('fc_sha256'))[:12]}; after: {doc['commit'][:12]}, "
          f"FC {str(doc['fc_sha256'])[:12]}")
    return 1 if report(compare(before, doc), args.verbose) else 0


if __name__ == "__main__":
    sys.exit(main())
