"""The real-time loop's pacing (rig/pace): its wait never returns before the deadline and still wakes for
a readable descriptor; the host set-up is taken where permitted, said in the outcome, never inherited by
the DUT, and undone; a paced session runs its events in order, none before its due time.

No timing threshold here (timing belongs in bench/realtime_lateness.py): "not before the deadline" is
an ordering, true on any machine; a session run the host starved is flown again, then inconclusive
(tests/realtime.py)."""

from __future__ import annotations

import gc
import json
import os
import select
import selectors
import shutil
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from rig import pace
from rig.scheduler import NS
from rig.session import Outcome, Session, SessionConfig
from rig.world import World
from tests.realtime import of_outcome, realtime

REPO = Path(__file__).resolve().parents[2]


def test_the_wait_returns_at_its_deadline_never_before() -> None:
    a, b = socket.socketpair()
    deadlines: list[int] = []
    sel = pace.PacedSelector(lambda: deadlines[-1])
    try:
        sel.register(a, selectors.EVENT_READ, "a")
        for _ in range(20):
            deadlines.append(pace.now_ns() + 2_000_000)
            assert sel.select(1.0) == []             # nothing to read: the deadline ended the wait
            assert time.monotonic_ns() >= deadlines[-1]  # (the same clock)
    finally:
        sel.close()
        a.close()
        b.close()


def test_a_readable_descriptor_wakes_the_wait_and_is_seen_past_a_deadline() -> None:
    a, b = socket.socketpair()
    far = pace.now_ns() + 3600 * NS
    sel = pace.PacedSelector(lambda: far)
    try:
        sel.register(a, selectors.EVENT_READ, "a")
        sel.register(b, selectors.EVENT_READ, "b")
        b.send(b"x")
        assert [(k.data, ev) for k, ev in sel.select(3600.0)] == [("a", selectors.EVENT_READ)]
        far = pace.now_ns() - NS  # a deadline already past: what is readable is still reported
        assert [k.data for k, _ in sel.select(0.0)] == ["a"]
        sel.unregister(a)
        assert sel.select(0.0) == []                 # the unregistered one is no longer waited on
    finally:
        sel.close()
        a.close()
        b.close()


def test_the_host_set_up_is_said_not_inherited_by_children_and_undone() -> None:
    before = os.sched_getscheduler(0)
    host = pace.RealtimeHost()
    with host as state:
        child = subprocess.run([sys.executable, "-c", "import os; print(os.sched_getscheduler(0))"],
                               capture_output=True, text=True, check=True)
        inside = os.sched_getscheduler(0) & ~os.SCHED_RESET_ON_FORK
    assert state.sched_fifo == (inside == os.SCHED_FIFO)
    assert state.sched_fifo or any(w.startswith("SCHED_FIFO") for w in state.not_taken)
    assert state.mlockall or any(w.startswith("mlockall") for w in state.not_taken)
    assert int(child.stdout) == os.SCHED_OTHER       # a process started by the loop: never FIFO
    assert os.sched_getscheduler(0) == before
    assert state.as_dict()["sched_fifo"] == state.sched_fifo


@pytest.mark.parametrize("enabled", [True, False])
def test_the_host_leaves_the_collector_as_it_found_it(enabled: bool) -> None:
    (gc.enable if enabled else gc.disable)()
    try:
        with pace.RealtimeHost():
            assert not gc.isenabled()                # no cyclic collection while paced
        assert gc.isenabled() == enabled
    finally:
        gc.enable()


def test_a_lockstep_loop_runs_with_the_heap_frozen_and_leaves_it_as_it_was() -> None:
    """The objects alive before a lockstep session's loop are out of the collector's work while it runs
    (frozen), the collector still on; after the run nothing is frozen. A heap frozen by someone else
    is theirs: left frozen, not unfrozen by the session."""
    def fly() -> tuple[list[tuple[bool, int]], str]:
        cfg = SessionConfig(command=["sleep", "0.05"], duration=0.3, allow_no_devices=True)
        session = Session(cfg, World.at_rest(noise=False))
        seen: list[tuple[bool, int]] = []
        session.at(0.01, lambda s: seen.append((gc.isenabled(), gc.get_freeze_count())))
        outcome = session.run()
        return seen, outcome.error or ""

    assert gc.get_freeze_count() == 0
    seen, error = fly()
    assert "exited early" in error  # (sleep ends before the duration: the run ran to then)
    assert len(seen) == 1 and seen[0][0] and seen[0][1] > 1000
    assert gc.get_freeze_count() == 0 and gc.isenabled()
    gc.freeze()
    try:
        frozen = gc.get_freeze_count()
        seen, _ = fly()
        # (the session froze nothing more, and unfroze nothing: a few frozen objects may have been freed)
        assert frozen - 100 < seen[0][1] <= frozen and frozen - 100 < gc.get_freeze_count() <= frozen
    finally:
        gc.unfreeze()


@pytest.mark.paced
def test_a_paced_session_runs_its_events_in_order_none_before_its_time() -> None:
    def fly() -> tuple[Outcome, list[tuple[int, int]]]:
        cfg = SessionConfig(command=["sleep", "5"], lockstep=False, duration=0.3, allow_no_devices=True)
        session = Session(cfg, World.at_rest(noise=False))
        ran: list[tuple[int, int]] = []  # (due ns, wall ns since the start when it ran)
        def note(due: int) -> Callable[[Session], None]:
            return lambda s: ran.append((due, s._wall_ns()))

        for k in range(60):  # scheduled out of order; ties at 0.1 s
            due = (59 - k) * 5_000_000 if k % 3 else 100_000_000
            session.at(due / NS, note(due))
        return session.run(), ran

    outcome, ran = realtime(fly, lambda got: {"paced": of_outcome(got[0])})
    assert outcome.verdict == "ok", outcome.error
    assert [due for due, _ in ran] == sorted(due for due, _ in ran) and len(ran) == 60
    assert all(wall >= due for due, wall in ran)
    state = outcome.host_state
    assert {"sched_fifo", "mlockall", "not_taken"} <= set(state)
    host_figures = {"waits", "wait_p99_s", "wait_max_s", "steal_s", "late_causes"}
    assert set(state) - {"sched_fifo", "mlockall", "not_taken"} <= host_figures
    assert state["sched_fifo"] or state["not_taken"]
    waits = state["waits"]
    assert isinstance(waits, int) and 0 < waits <= 60  # (events due at one instant share a wait)


@pytest.mark.skipif(shutil.which("setpriv") is None, reason="needs setpriv (util-linux) to drop capabilities")
def test_where_not_permitted_the_loop_runs_as_it_is_and_says_why() -> None:
    """A process without CAP_SYS_NICE and CAP_IPC_LOCK (dropped by setpriv, as in a container) and with
    no real-time priority or locked memory allowed: the set-up falls back without an error."""
    code = ("import json, os, resource\n"
            "resource.setrlimit(resource.RLIMIT_MEMLOCK, (65536, 65536))\n"
            "resource.setrlimit(resource.RLIMIT_RTPRIO, (0, 0))\n"
            "from rig import pace\n"
            "with pace.RealtimeHost() as state:\n"
            "    policy = os.sched_getscheduler(0)\n"
            "print(json.dumps([state.as_dict(), policy]))\n")
    done = subprocess.run(["setpriv", "--bounding-set", "-sys_nice,-ipc_lock", sys.executable, "-c", code],
                          capture_output=True, text=True, cwd=REPO)
    if done.returncode and done.stderr.startswith("setpriv:"):  # (not allowed to drop them here)
        pytest.skip(done.stderr.strip())
    assert done.returncode == 0, done.stderr
    state, policy = json.loads(done.stdout)
    assert (state["sched_fifo"], state["mlockall"], policy) == (False, False, os.SCHED_OTHER)
    assert [w.split(":")[0] for w in state["not_taken"]] == ["mlockall", "SCHED_FIFO"]


def test_the_waits_that_reach_their_deadline_say_how_late_they_woke() -> None:
    """Only a wait ended by its deadline is counted (not one a readable descriptor ended), each at least
    0 late (the wait never returns before its deadline), and result.json's figures are their p99 and
    worst."""
    a, b = socket.socketpair()
    state = pace.HostState()
    deadlines: list[int] = []
    sel = pace.PacedSelector(lambda: deadlines[-1], host=state)
    try:
        sel.register(a, selectors.EVENT_READ, "a")
        for _ in range(30):
            deadlines.append(pace.now_ns() + 1_000_000)
            assert sel.select(1.0) == []
        b.send(b"x")
        deadlines.append(pace.now_ns() + 3600 * NS)
        assert [k.data for k, _ in sel.select(3600.0)] == ["a"]  # woken by the socket: not counted
    finally:
        sel.close()
        a.close()
        b.close()
    assert len(state.woke_late_ns) == 30 and min(state.woke_late_ns) >= 0
    figures = state.as_dict()
    late = sorted(state.woke_late_ns)
    assert figures["waits"] == 30 and figures["wait_max_s"] == late[-1] / NS
    assert figures["wait_p99_s"] == late[28] / NS  # the 99th percentile of 30, as the events' (index 28)
    assert "waits" not in pace.HostState().as_dict()  # no paced wait, no figures


def test_steal_time_is_read_from_proc_stat_and_anything_else_is_none(tmp_path: Path) -> None:
    stat = tmp_path / "stat"
    stat.write_text("cpu  3277246 6280 561886 3828482 20254 0 11620 53522 0 0\ncpu0 1 2 3 4 5 6 7 8 9 10\n")
    assert pace.steal_ticks(stat) == 53522  # the eighth value after "cpu" (proc(5): steal)
    for bad in ("cpu  1 2 3 4 5 6 7\n", "cpu0 1 2 3 4 5 6 7 8 9\n", "cpu  1 2 3 4 5 6 7 x\n", ""):
        stat.write_text(bad)
        assert pace.steal_ticks(stat) is None
    assert pace.steal_ticks(tmp_path / "none") is None
    if Path("/proc/stat").is_file():  # this machine's: a count that never goes back
        first = pace.steal_ticks()
        assert first is not None and 0 <= first <= (pace.steal_ticks() or 0)


def test_a_host_run_says_its_steal_time() -> None:
    host = pace.RealtimeHost()
    with host as state:
        pass
    if pace.steal_ticks() is not None:
        assert state.steal_s is not None and state.steal_s >= 0.0
        assert state.as_dict()["steal_s"] == state.steal_s


@pytest.mark.paced
def test_a_late_event_is_put_down_to_the_loop_when_the_loop_made_it_late() -> None:
    """Events that block in a call of their own (a read that waits 2.5 ms) or compute for 2.5 ms of CPU
    make the events due meanwhile late: result.json's late_causes puts those to the loop, not the host.
    (2.5 ms: within the lateness a paced test takes for its host's, tests/realtime.py.)"""
    r, w = os.pipe()

    def block(_: Session) -> None:
        select.select([r], [], [], 0.0025)  # nothing comes: the loop sleeps in a call of its own

    def compute(_: Session) -> None:
        end = time.thread_time_ns() + 2_500_000  # (this thread's CPU time, not the wall clock)
        while time.thread_time_ns() < end:
            pass

    def fly() -> Outcome:
        cfg = SessionConfig(command=["sleep", "5"], lockstep=False, duration=0.5, allow_no_devices=True)
        session = Session(cfg, World.at_rest(noise=False))
        for k in range(1000):  # at 2 kHz, each held up when it comes during one of the eight below
            session.at(k * 0.0005, lambda s: None)
        for k in range(8):
            session.at(0.05 * (k + 1) + 0.0002, block if k % 2 else compute)
        return session.run()

    try:
        # (judged as the host's without its causes: the late events made here on purpose are the loop's)
        outcome = realtime(fly, lambda got: {"paced": {k: v for k, v in of_outcome(got).items()
                                                       if k != "late_causes"}})
    finally:
        os.close(r)
        os.close(w)
    assert outcome.verdict == "ok", outcome.error
    causes = outcome.host_state["late_causes"]
    assert isinstance(causes, dict) and sum(causes.values()) == outcome.events_late >= 8
    assert causes["loop_blocked"] >= 2 and causes["loop_busy"] >= 2, causes
