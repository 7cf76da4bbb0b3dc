"""Real-time tests on a shared machine: a run paced by the wall clock is only a test of the DUT when the
host kept pace. Every such test hands its runs to ``realtime()``, which checks each run's own
``realtime_lateness`` (result.json's, or a session Outcome's) before the test judges anything: a
starved run is flown again once; starved twice, the test ends inconclusive with ``pytest.skip`` and the
figures (pytest's ``-ra`` summary lists it), never passed silently and never failed as the DUT's fault.
On a loaded VM such runs failed with 18-35 deg of tilt and thousands of events over 1 ms late.
Several runs of one test are judged each on its own (``realtime_each``): only the starved ones are
flown again. Runs a module's tests share are flown by its fixture with ``fly_each``, which skips
nothing: each test calls ``inconclusive_if_starved`` with the runs it judges, so one run starved twice
makes inconclusive only the tests that judge it.
Every such test carries the ``paced`` marker: ``make test`` runs them alone, after the rest of the suite
has run on every core, so the suite's own load does not starve them.

Each run's figures say the host's side too, where it has them: how late the loop's paced waits woke
(``wait_p99_s``), the CPU time the hypervisor took meanwhile (``steal_s``), and each event over 1 ms
late put down to the host or to the loop itself (``late_causes``, rig/pace/late.py). An inconclusive
test quotes them. A starved run most of whose late events the loop made late (``loop_busy``,
``loop_blocked``) is not the host's: the test fails at once, saying so (flying again would not mend
it, and a skip would hide a fault of the rig).

"Starved" is a property of the host, not of the DUT, so the threshold lives here and not in a scenario:
the bench tolerances (tests/bridge/bench_tolerance.json) were derived with the bridge streaming its
samples 3 ms ahead (BenchConfig.lead_s) on a host whose lateness p99 was 0.5-0.6 ms. A run is starved
when its lateness p99 is over STARVED_P99_S, that lead: more than one sample in a hundred then reaches
the bridge after the instant it holds for (underruns), and the flight is the host's, not the DUT's.
(Runs that failed on a loaded VM had 20-30 % of their events over 1 ms late. The share over 1 ms is no
judge by itself: the slcan capture path runs with half its events 1-2.5 ms late and stays within its
tolerances.) One event STARVED_MAX_S late starves a run too: 25 of the FC's 4 ms cycles without
fresh samples, the vehicle flying open-loop meanwhile. Below those, whatever the run measured is the
DUT's."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any, NoReturn, TypeVar

import pytest

from rig.reports.values import host_said

#: lateness p99 (s) above which a run is starved: the bridge's lead
STARVED_P99_S = 0.003
#: one event this late (s) starves the run
STARVED_MAX_S = 0.1
#: how an inconclusive test's skip reason begins: tests/suite_rules.py counts them by it
INCONCLUSIVE = "inconclusive: "

T = TypeVar("T")


def starved(name: str, lateness: Mapping[str, Any]) -> str | None:
    """The figures of a starved run in words, or None when the host kept pace. ``lateness`` is
    result.json's ``realtime_lateness`` (events, late_over_1ms, max_s, p99_s)."""
    events, late = int(lateness.get("events", 0)), int(lateness.get("late_over_1ms", 0))
    worst, p99 = float(lateness.get("max_s", 0.0)), float(lateness.get("p99_s", 0.0))
    if events and (p99 > STARVED_P99_S or worst >= STARVED_MAX_S):
        return (f"{name}: {late} of {events} events over 1 ms late, p99 {p99 * 1e3:.1f} ms, worst "
                f"{worst * 1e3:.1f} ms" + host_said(lateness))
    return None


def of_outcome(outcome: Any) -> dict[str, Any]:
    """A session Outcome's lateness in result.json's shape."""
    return {"events": outcome.events_run, "late_over_1ms": outcome.events_late,
            "max_s": outcome.max_lateness_s, "p99_s": outcome.p99_lateness_s,
            "p50_s": outcome.p50_lateness_s, **outcome.host_state}


def of_results(folder: Path, names: Iterable[str]) -> Callable[[Any], dict[str, dict[str, Any]]]:
    """For ``realtime``: each named run's lateness from ``folder/NAME/result.json`` (a run with no
    result.json is not judged here: the test says what is missing)."""

    def read(_: Any) -> dict[str, dict[str, Any]]:
        out = {}
        for name in names:
            f = folder / name / "result.json"
            if f.is_file():
                out[name] = json.loads(f.read_text())["metadata"].get("realtime_lateness", {})
        return out

    return read


def made_late_by_the_loop(name: str, lateness: Mapping[str, Any]) -> str | None:
    """For a starved run: the figures in words when most of its late events were the loop's own doing
    (``late_causes``: ``loop_busy``, ``loop_blocked``), else None. Such a run is not the host's to
    excuse: flown again it is late again (the slcan capture's reads that slept 1 ms at a time were
    skipped as inconclusive three times), so the test fails and says so."""
    causes = lateness.get("late_causes")
    if not isinstance(causes, Mapping):
        return None
    total = sum(int(v) for v in causes.values())
    own = int(causes.get("loop_busy", 0)) + int(causes.get("loop_blocked", 0))
    if total == 0 or 2 * own <= total:
        return None
    return (f"{name}: {own} of its {total} events over 1 ms late were the loop's own doing (busy "
            f"{causes.get('loop_busy', 0)}, blocked in a call {causes.get('loop_blocked', 0)})")


def _starved_runs(late: Mapping[str, Mapping[str, Any]], names: Iterable[str]) -> dict[str, str]:
    """The named runs the host starved, each with its figures in words; fails the test at once when a
    starved run was made late by the rig's own loop, not by the host."""
    figures = {n: s for n in names if (s := starved(n, late.get(n, {})))}
    said = [s for n in figures if (s := made_late_by_the_loop(n, late[n]))]
    if said:
        pytest.fail("not the host: the rig's real-time loop made the run late (" + "; ".join(said) + ")",
                    pytrace=False)
    return figures


def _inconclusive(tries: list[str]) -> NoReturn:
    """Skips the test as inconclusive, with each try's starved runs in words."""
    pytest.skip(f"{INCONCLUSIVE}the host could not keep real time (starved twice: "
                + " | then ".join(tries) + ")")


def fly_each(names: list[str], fly: Callable[[list[str], int], T],
             lateness: Callable[[T], Mapping[str, Mapping[str, Any]]]
             ) -> tuple[list[tuple[T, list[str]]], dict[str, list[str]]]:
    """Several runs judged each on its own: ``fly(names, attempt)`` flies the named runs (attempt 0, then 1)
    and ``lateness`` reads each one's figures from what it returned. The runs the host starved are flown
    again, alone. Returns each flight with the names it holds the judged runs of (a run kept from the
    first flight is not in the second), and the runs starved twice, each with both tries' figures: a
    test that judges one of them is inconclusive (``inconclusive_if_starved``), the others are not.

    Why not ``realtime`` over all of them: on these VMs one run in six was often starved on each try, a
    different one each time, so flying all again left most tests inconclusive after twice the time."""
    flights: list[tuple[T, list[str]]] = []
    todo: list[str] = list(names)
    said: dict[str, list[str]] = {}
    for attempt in range(2):
        got = fly(todo, attempt)
        figures = _starved_runs(lateness(got), todo)
        flights.append((got, [n for n in todo if n not in figures]))
        for name, words in figures.items():
            said.setdefault(name, []).append(words)
        todo = [n for n in todo if n in figures]
        if not todo:
            break
    return flights, {name: said[name] for name in todo}


def inconclusive_if_starved(starved_twice: Mapping[str, list[str]], *names: str) -> None:
    """Skips the test as inconclusive when a run it judges (``names``) was starved twice (``fly_each``)."""
    mine = [name for name in names if name in starved_twice]
    if mine:
        tries = [starved_twice[name] for name in mine]
        _inconclusive(["; ".join(t[k] for t in tries) for k in range(2)])


def realtime_each(names: list[str], fly: Callable[[list[str], int], T],
                  lateness: Callable[[T], Mapping[str, Mapping[str, Any]]]) -> list[tuple[T, list[str]]]:
    """``fly_each`` for a test that judges every one of the runs: one run starved twice makes the test
    inconclusive (``pytest.skip`` with both tries' figures)."""
    flights, starved_twice = fly_each(names, fly, lateness)
    inconclusive_if_starved(starved_twice, *names)
    return flights


def realtime(fly: Callable[[], T], lateness: Callable[[T], Mapping[str, Mapping[str, Any]]]) -> T:
    """``fly()``'s result once no run in it (``lateness(result)``: run name -> its lateness) was
    starved; flown at most twice, then the test is skipped as inconclusive with both tries' figures."""
    tries: list[str] = []
    for _ in range(2):
        got = fly()
        late = lateness(got)
        figures = _starved_runs(late, late)
        if not figures:
            return got
        tries.append("; ".join(figures.values()))
    _inconclusive(tries)
