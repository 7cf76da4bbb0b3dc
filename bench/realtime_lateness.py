"""How late the real-time loop runs its scheduled events (docs/bench.md), printed, never asserted.

For ``rig run --realtime`` (the Linux-process DUT, the session answering it) and ``rig run --bridge
virtual`` (the host streaming to build/vbridge, the DUT behind it), each scenario given (default
step_roll and hover_turbulence) is run as the user runs it, in a process of its own, on the machine as
it is and then beside ``--load CMD`` (a CPU hog, or a ``make test``; started once in a session of its
own and ended after the last run). From each run's result.json (``realtime_lateness``): the events run,
the median, 99th percentile and worst lateness, how many were over 1 ms late, and how the loop ran
(SCHED_FIFO, mlockall) where the tree records it, and the host's own figures beside them: how late
the loop's paced waits woke, the hypervisor's steal time, and whose the events over 1 ms late were
(the host's, or the loop's own: result.json's ``late_causes``).

These VMs change speed from one minute to the next: before each run two calibration figures say which
kind of minute it came from: the CPU time of a fixed Python loop (bench/scenario_rates.py's) and how
late a plain 1 ms sleep wakes (median and 99th percentile of 500).

``--wakeups`` measures the wait alone instead (a 1 kHz loop that does nothing but wait, 2000 deadlines
each): Python's selectors with a relative timeout (epoll, select: what the loops used before), and
rig/pace's C wait with and without descriptors (ppoll or clock_nanosleep) and with 0, 50 or 100 µs of
spin, each with the CPU time it costs per wait, under rig.pace.RealtimeHost (SCHED_FIFO, mlockall where
permitted) and without.

The script runs the tree it lives in (its own folder's parent), so a copy of it in another checkout
measures that checkout: that is how the figures before a change are taken.

``python bench/realtime_lateness.py [--mode realtime|virtual]... [--scenario NAME]... [--load CMD]
[--no-idle] [--wakeups]``
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from ab import python_loop_ms  # (bench/ is the script's folder: on sys.path)

REPO = Path(__file__).resolve().parents[1]
MODES = {"realtime": ["--realtime"], "virtual": ["--bridge", "virtual"]}


def sleep_overshoot_us(n: int = 500) -> tuple[float, float]:
    """How late a plain 1 ms sleep wakes (median, p99, µs): the timer noise of the machine right now."""
    late = []
    for _ in range(n):
        t0 = time.perf_counter_ns()
        time.sleep(0.001)
        late.append((time.perf_counter_ns() - t0 - 1_000_000) / 1e3)
    late.sort()
    return late[n // 2], late[int(0.99 * (n - 1))]


def rig_run(mode: str, scenario: str, out: Path) -> dict[str, Any]:
    """One ``rig run`` of the tree this script is in; its result.json's metadata."""
    env = dict(os.environ, PYTHONPATH=str(REPO))
    cmd = [sys.executable, "-m", "rig.cli", "run", *MODES[mode], scenario, "--out", str(out)]
    done = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True)
    result = out / scenario / "result.json"
    if not result.is_file():
        raise SystemExit(f"{' '.join(cmd)} wrote no result.json (exit {done.returncode}):\n{done.stderr}")
    metadata: dict[str, Any] = json.loads(result.read_text())["metadata"]
    metadata["_verdict"] = json.loads(result.read_text()).get("verdict", "?")
    return metadata


def wakeups(n: int = 2000, period_ns: int = 1_000_000) -> None:
    """The wait alone, at 1 kHz: how late it returns after each absolute deadline, and its CPU."""
    import selectors
    import socket

    from rig import pace

    a, b = socket.socketpair()
    wait = pace.native().wait

    def run(kind: str, spin: int) -> str:
        sel: selectors.BaseSelector | None = None
        if kind in ("epoll", "select"):
            sel = selectors.EpollSelector() if kind == "epoll" else selectors.SelectSelector()
            sel.register(a, selectors.EVENT_READ)
        fds = (a.fileno(),) if kind == "ppoll" else ()
        late, t = [], time.monotonic_ns() + period_ns
        c0 = time.process_time()
        for _ in range(n):
            if sel is not None:  # as the loops did: a relative timeout, then look again until due
                while (now := time.monotonic_ns()) < t:
                    sel.select((t - now) / 1e9)
            else:
                wait(t, fds, spin)
            late.append(time.monotonic_ns() - t)
            t += period_ns
        cpu = (time.process_time() - c0) / n * 1e6
        if sel is not None:
            sel.close()
        late.sort()
        return (f"p50 {late[n // 2] / 1e3:7.1f}  p99 {late[int(0.99 * (n - 1))] / 1e3:8.1f}  worst "
                f"{late[-1] / 1e3:8.1f} us  CPU {cpu:5.1f} us/wait")

    variants = [("epoll", 0), ("select", 0)] + [(k, s) for k in ("ppoll", "nanosleep")
                                                for s in (0, 50_000, 100_000)]
    for label, host in (("normal thread", None), ("RealtimeHost", pace.RealtimeHost())):
        if host is not None:
            state = host.__enter__()
            why = "".join(f"; {w}" for w in state.not_taken)
            label += f" (fifo={state.sched_fifo}, mlockall={state.mlockall}{why})"
        try:
            print(f"the wait alone, {n} deadlines at 1 kHz, {label}:")
            for kind, spin in variants:
                print(f"  {kind:9} spin {spin // 1000:3d} us: {run(kind, spin)}", flush=True)
        finally:
            if host is not None:
                host.__exit__(None, None, None)
    a.close()
    b.close()


def line(mode: str, scenario: str, condition: str, calib: tuple[float, float, float],
         meta: dict[str, Any]) -> str:
    lat = meta.get("realtime_lateness", {})
    p50 = f"{lat['p50_s'] * 1e6:7.0f}" if "p50_s" in lat else "      -"
    how = ""
    if "sched_fifo" in lat:
        how = f" fifo={'yes' if lat['sched_fifo'] else 'no'} mlockall={'yes' if lat['mlockall'] else 'no'}"
    if "wait_p99_s" in lat:  # the host's side, where the tree records it (rig/pace/late.py)
        how += f" waits p99 {lat['wait_p99_s'] * 1e6:.0f} us"
    if "steal_s" in lat:
        how += f", steal {lat['steal_s']:.2f} s"
    causes = lat.get("late_causes") or {}
    if any(causes.values()):  # whose the events over 1 ms late were: the host's or the loop's own
        host = causes.get("host_woke_late", 0) + causes.get("host_preempted", 0)
        loop = causes.get("loop_busy", 0) + causes.get("loop_blocked", 0)
        how += f"; >1ms: host {host}, loop {loop}, ? {causes.get('unattributed', 0)}"
    return (f"{mode:8} {scenario:17} {condition:6} {lat.get('events', 0):6d} {p50} "
            f"{lat.get('p99_s', 0) * 1e6:7.0f} {lat.get('max_s', 0) * 1e3:8.2f} "
            f"{lat.get('late_over_1ms', 0):6d}   {calib[0]:5.0f} {calib[1]:5.0f} {calib[2]:6.0f}  "
            f"{meta['_verdict']}{how}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mode", action="append", choices=sorted(MODES), help="default: both")
    ap.add_argument("--scenario", action="append", help="default: step_roll and hover_turbulence")
    ap.add_argument("--load", help="a shell command run beside the second round of runs")
    ap.add_argument("--no-idle", action="store_true", help="only the runs beside --load")
    ap.add_argument("--wakeups", action="store_true", help="the wait alone (rig/pace), no runs")
    args = ap.parse_args()
    modes = args.mode or ["realtime", "virtual"]
    scenarios = args.scenario or ["step_roll", "hover_turbulence"]
    head = subprocess.run(["git", "log", "-1", "--format=%h %s"], cwd=REPO, capture_output=True,
                          text=True).stdout.strip()
    print(f"tree {REPO} at {head}; {os.cpu_count()} CPUs; load average {os.getloadavg()[0]:.2f}")
    print(f"calibration now: Python loop {python_loop_ms():.0f} ms; a 1 ms sleep wakes late by "
          "p50 {:.0f} us, p99 {:.0f} us".format(*sleep_overshoot_us()))
    if args.wakeups:
        wakeups()
        return
    print("mode     scenario          beside events p50 us  p99 us  worst ms  >1ms   loop ms sleep p50/p99 "
          "us  verdict")
    rounds = ([] if args.no_idle else [("idle", None)]) + ([("load", args.load)] if args.load else [])
    for condition, cmd in rounds:
        hog = subprocess.Popen(cmd, shell=True, start_new_session=True, stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL) if cmd else None
        try:
            for mode in modes:
                for scenario in scenarios:
                    calib = (python_loop_ms(), *sleep_overshoot_us())
                    with tempfile.TemporaryDirectory(prefix="rt-lateness-") as tmp:
                        meta = rig_run(mode, scenario, Path(tmp))
                    print(line(mode, scenario, condition, calib, meta), flush=True)
                    if hog is not None and hog.poll() is not None:
                        print(f"  (the load ended, status {hog.returncode}, during this run)")
        finally:
            if hog is not None and hog.poll() is None:
                os.killpg(hog.pid, signal.SIGTERM)
                hog.wait()
    if args.load:
        print(f"load: {args.load}")


if __name__ == "__main__":
    main()
