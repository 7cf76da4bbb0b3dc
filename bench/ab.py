"""A/B benches: the same measurement on the tree before a change and on this one, interleaved.

These 2-core VMs change speed by half from one minute to the next, so "before" measured at 17:00 and
"after" at 17:30 compare two machines. Here both sides run on the same machine in one sitting: the
commit before the change is checked out in a temporary git worktree and built there (``make all``
with this virtualenv's Python; its compiled C and mypyc modules are its own, in its own ``build/``),
and the measurements alternate A B A B ..., each pair beside the fixed pure-Python loop of
``python_loop_ms`` that says which kind of minute (fast or slow phase) the pair came from.

A measurement is a function of a bench module (``call``) or a command (``command``) run in a fresh
process of this virtualenv whose ``rig`` is the tree's: the bench's own code measures both sides, so
the "before" commit needs none of it. The worktree is removed at exit, on Ctrl-C and on SIGTERM.

    with before_tree("aa79ab7") as old:
        pairs = interleave(3, lambda tree: call(tree, Path(__file__), "measure", "hover"), old)
"""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from typing import Any, Generic, TypeVar

REPO = Path(__file__).resolve().parents[1]
VENV = Path(sys.prefix)  # this interpreter's virtualenv: the packages both trees run with
T = TypeVar("T")

#: a calibration this much slower than the fastest of a bench's pairs marks the slow phase
PHASE_SPLIT = 1.25


def python_loop_ms() -> float:
    """CPU time of one fixed million-iteration Python loop: the machine's speed right now."""
    t0 = time.process_time()
    x = 0
    for i in range(1_000_000):
        x += i * i
    return (time.process_time() - t0) * 1000


def load() -> str:
    """The load average: the calibration loop counts CPU time, so other processes sharing the cores
    slow the wall-clock rates without showing in it."""
    return "load average " + " ".join(f"{x:.1f}" for x in os.getloadavg())


def git(*args: str, cwd: Path = REPO) -> str:
    return subprocess.run(["git", *args], cwd=cwd, capture_output=True, text=True, check=True).stdout.strip()


def default_before() -> str:
    """The commit a branch's change starts from: ``git merge-base HEAD main``."""
    return git("merge-base", "HEAD", "main")


def _build(tree: Path) -> None:
    """``make all`` in ``tree`` with this virtualenv (``-o``: never re-run its bootstrap, whose inputs
    are newer in a fresh checkout: it would reinstall this venv's editable package from the tree)."""
    log = tree / "build" / "ab-make.log"
    log.parent.mkdir(parents=True, exist_ok=True)
    cmd = ["make", "-s", "-C", str(tree), "-o", f"{VENV}/.installed", f"VENV={VENV}",
           f"PYTHON={VENV / 'bin' / 'python'}", "all"]
    t0 = time.perf_counter()
    with open(log, "w") as out:
        done = subprocess.run(cmd, stdout=out, stderr=subprocess.STDOUT)
    if done.returncode:
        tail = log.read_text(errors="replace")[-3000:]
        raise RuntimeError(f"make all in {tree} failed ({done.returncode}):\n{tail}")
    print(f"ab: built {tree} in {time.perf_counter() - t0:.0f} s", file=sys.stderr)


@contextmanager
def before_tree(commit: str | None = None) -> Iterator[Path]:
    """``commit`` (default: ``default_before()``) checked out detached in a temporary worktree and built;
    the worktree and its build are removed on the way out, however it is left (SIGTERM included)."""
    sha = git("rev-parse", "--verify", f"{commit or default_before()}^{{commit}}")
    tmp = Path(tempfile.mkdtemp(prefix="rig-ab-"))
    tree = tmp / sha[:12]

    def term(signum: int, frame: FrameType | None) -> None:
        raise KeyboardInterrupt(f"signal {signum}")

    old = signal.signal(signal.SIGTERM, term)
    try:
        git("worktree", "add", "--detach", str(tree), sha)
        subject = git("log", "-1", "--format=%s", sha)[:60]
        print(f"ab: before = {sha[:12]} ({subject}) in {tree}", file=sys.stderr)
        _build(tree)
        yield tree
    finally:
        signal.signal(signal.SIGTERM, old)
        subprocess.run(["git", "worktree", "remove", "--force", str(tree)], cwd=REPO, capture_output=True)
        shutil.rmtree(tmp, ignore_errors=True)
        subprocess.run(["git", "worktree", "prune"], cwd=REPO, capture_output=True)


_CHILD = """
import importlib.util, json, sys
tree, path, func, args = sys.argv[1:]
sys.path.insert(0, tree)
sys.path.append(str(__import__("pathlib").Path(path).parent))  # the bench's own helpers (this file)
from rig.compiled import install, status
install()
spec = importlib.util.spec_from_file_location("_ab_bench", path)
mod = importlib.util.module_from_spec(spec)
sys.modules["_ab_bench"] = mod
spec.loader.exec_module(mod)
out = getattr(mod, func)(*json.loads(args))
print("\\n" + json.dumps({"status": status(), "result": out}))
"""


def call(tree: Path, module: Path, func: str, *args: Any) -> Any:
    """``func(*args)`` of the bench module file ``module``, in a fresh process of this virtualenv whose
    ``rig`` (and its compiled modules, its FC, its plant) is ``tree``'s; arguments and result as JSON.
    The module must import ``rig`` inside its functions, never at its top."""
    done = subprocess.run([sys.executable, "-c", _CHILD, str(tree), str(module), func, json.dumps(args)],
                          cwd=tree, capture_output=True, text=True)
    lines = done.stdout.strip().splitlines()
    if done.returncode or not lines:
        raise RuntimeError(f"{func}{args} in {tree} failed ({done.returncode}):\n{done.stderr[-3000:]}")
    reply = json.loads(lines[-1])
    if not reply["status"].startswith("hot modules compiled"):
        print(f"ab: warning: in {tree}: {reply['status']}", file=sys.stderr)
    return reply["result"]


def command(tree: Path, argv: list[str]) -> float:
    """Runs ``python argv...`` with this virtualenv in ``tree`` (``-m rig.cli ...`` is its rig); the
    wall seconds it took. Exit status 0 or 1 (a run that failed its criteria) is fine."""
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, *argv], cwd=tree, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(tree)})
    wall = time.perf_counter() - t0
    if done.returncode not in (0, 1):
        raise RuntimeError(f"{' '.join(argv)} in {tree} failed ({done.returncode}):\n{done.stderr[-3000:]}")
    return wall


@dataclass(frozen=True)
class Pair(Generic[T]):
    """One A/B pair: the calibration loop's ms (mean of before and after the pair), then each side."""

    calibration_ms: float
    before: T
    after: T


def interleave(pairs: int, measure: Callable[[Path], T], before: Path, after: Path = REPO,
               label: str = "") -> list[Pair[T]]:
    """``pairs`` times: the calibration loop, ``measure(before)``, ``measure(after)``, the loop again."""
    out = []
    for k in range(pairs):
        c0 = python_loop_ms()
        a = measure(before)
        b = measure(after)
        out.append(Pair((c0 + python_loop_ms()) / 2, a, b))
        print(f"  {label} pair {k + 1}/{pairs}: calibration {out[-1].calibration_ms:.0f} ms, {load()}",
              file=sys.stderr, flush=True)
    return out


def phases(calibrations: list[float]) -> list[str]:
    """Each calibration's phase: "slow" when over ``PHASE_SPLIT`` x the fastest, else "fast"."""
    fastest = min(calibrations)
    return ["slow" if c > PHASE_SPLIT * fastest else "fast" for c in calibrations]


def by_phase(pairs: list[Pair[float]]) -> dict[str, tuple[int, float, float, float]]:
    """Per phase: (pairs, median before, median after, median of the pairs' after/before ratios)."""
    out = {}
    tags = phases([p.calibration_ms for p in pairs])
    for phase in ("fast", "slow"):
        sel = [p for p, tag in zip(pairs, tags, strict=True) if tag == phase]
        if sel:
            out[phase] = (len(sel), statistics.median(p.before for p in sel),
                          statistics.median(p.after for p in sel),
                          statistics.median(p.after / p.before if p.before else math.nan for p in sel))
    return out
