"""tests/realtime.py, the judge of every real-time test's host: a starved run is flown once more, then
the test is inconclusive with the figures; a run the host kept pace with is judged at once."""

from __future__ import annotations

from typing import Any

import pytest

from tests.realtime import (
    INCONCLUSIVE,
    STARVED_MAX_S,
    STARVED_P99_S,
    fly_each,
    inconclusive_if_starved,
    made_late_by_the_loop,
    realtime,
    realtime_each,
    starved,
)

KEPT = {"events": 10_000, "late_over_1ms": 3, "max_s": 0.004, "p99_s": 0.0006}
STARVED = {"events": 10_000, "late_over_1ms": 2_400, "max_s": 0.031, "p99_s": 0.012}


def test_starved_is_a_p99_beyond_the_lead_or_one_long_stall() -> None:
    assert starved("a", KEPT) is None
    assert starved("a", {**KEPT, "late_over_1ms": 5000, "p99_s": 0.0025}) is None  # late, within the lead
    assert starved("a", {**KEPT, "p99_s": STARVED_P99_S + 1e-4}) is not None
    assert starved("a", {**KEPT, "max_s": STARVED_MAX_S}) is not None
    assert starved("a", {}) is None  # (no figures: not a real-time run)
    assert starved("step_roll", STARVED) == ("step_roll: 2400 of 10000 events over 1 ms late, p99 12.0 ms, "
                                             "worst 31.0 ms")


def test_a_starved_run_quotes_the_hosts_own_figures_where_it_has_them() -> None:
    causes = {"host_woke_late": 0, "host_preempted": 2, "loop_busy": 0, "loop_blocked": 2398,
              "unattributed": 0}
    host = {"waits": 9000, "wait_p99_s": 0.00004, "wait_max_s": 0.0021, "steal_s": 0.0, "late_causes": causes}
    assert starved("step_roll", {**STARVED, **host}) == (
        "step_roll: 2400 of 10000 events over 1 ms late, p99 12.0 ms, worst 31.0 ms; the loop's waits woke "
        "p99 0.04 ms late, worst 2.1 ms; the hypervisor took 0.00 s of the host's CPUs; late by cause: host "
        "preempted 2, loop blocked 2398")
    assert starved("a", {**KEPT, **host}) is None  # the figures judge nothing by themselves


def flights(*lateness: dict[str, Any]) -> tuple[list[int], Any, Any]:
    flown: list[int] = []

    def fly() -> int:
        flown.append(len(flown))
        return flown[-1]

    return flown, fly, lambda k: {"run": lateness[k]}


def test_a_run_that_kept_pace_is_judged_at_once() -> None:
    flown, fly, late = flights(KEPT, KEPT)
    assert realtime(fly, late) == 0 and flown == [0]


def test_a_starved_run_is_flown_again_and_the_second_is_judged() -> None:
    flown, fly, late = flights(STARVED, KEPT)
    assert realtime(fly, late) == 1 and flown == [0, 1]


def test_starved_twice_is_inconclusive_with_the_figures_never_a_pass_or_a_failure() -> None:
    flown, fly, late = flights(STARVED, {**STARVED, "late_over_1ms": 900, "p99_s": 0.004})
    with pytest.raises(pytest.skip.Exception) as e:
        realtime(fly, late)
    assert flown == [0, 1]
    said = str(e.value)
    assert said.startswith("inconclusive: the host could not keep real time")
    assert "run: 2400 of 10000 events over 1 ms late" in said
    assert "then run: 900 of 10000 events over 1 ms late, p99 4.0 ms" in said


def each(*tries: dict[str, dict[str, Any]]) -> tuple[list[tuple[list[str], int]], Any, Any]:
    """Flights of several runs: the k-th flight's figures per run are tries[k]'s."""
    flown: list[tuple[list[str], int]] = []

    def fly(names: list[str], attempt: int) -> int:
        flown.append((list(names), attempt))
        return attempt

    return flown, fly, lambda k: {n: v for n, v in tries[k].items() if n in flown[k][0]}


def test_only_the_starved_runs_are_flown_again_and_each_is_judged_where_it_kept_pace() -> None:
    flown, fly, late = each({"a": KEPT, "b": STARVED, "c": KEPT}, {"b": KEPT})
    assert realtime_each(["a", "b", "c"], fly, late) == [(0, ["a", "c"]), (1, ["b"])]
    assert flown == [(["a", "b", "c"], 0), (["b"], 1)]


def test_runs_that_kept_pace_at_once_are_flown_once() -> None:
    flown, fly, late = each({"a": KEPT, "b": KEPT})
    assert realtime_each(["a", "b"], fly, late) == [(0, ["a", "b"])] and len(flown) == 1


def test_a_run_starved_twice_is_inconclusive_whatever_the_others_did() -> None:
    flown, fly, late = each({"a": STARVED, "b": KEPT, "c": STARVED}, {"a": KEPT, "c": STARVED})
    with pytest.raises(pytest.skip.Exception) as e:
        realtime_each(["a", "b", "c"], fly, late)
    assert flown == [(["a", "b", "c"], 0), (["a", "c"], 1)]
    said = str(e.value)
    assert said.startswith("inconclusive: the host could not keep real time")
    # the figures of the run starved twice, both tries; not a's, kept on its second
    assert "(starved twice: c: 2400 of 10000" in said and "then c: 2400 of 10000" in said and "a:" not in said


def test_each_test_is_inconclusive_only_for_its_own_run_starved_twice() -> None:
    flown, fly, late = each({"a": STARVED, "b": KEPT, "c": STARVED}, {"a": KEPT, "c": STARVED})
    flights, starved_twice = fly_each(["a", "b", "c"], fly, late)
    assert flights == [(0, ["b"]), (1, ["a"])] and list(starved_twice) == ["c"]
    inconclusive_if_starved(starved_twice, "a", "b")  # (judges a and b: judged)
    with pytest.raises(pytest.skip.Exception) as e:
        inconclusive_if_starved(starved_twice, "b", "c")
    assert str(e.value).startswith(INCONCLUSIVE) and "c: 2400 of 10000" in str(e.value)


def causes(busy: int, blocked: int, host: int) -> dict[str, int]:
    return {"host_woke_late": host, "host_preempted": 0, "loop_busy": busy, "loop_blocked": blocked,
            "unattributed": 0}


def test_a_starved_run_the_loop_made_late_fails_at_once_and_is_not_flown_again() -> None:
    mine = {**STARVED, "late_causes": causes(busy=100, blocked=2200, host=100)}
    flown, fly, late = flights(mine, KEPT)
    with pytest.raises(pytest.fail.Exception) as e:
        realtime(fly, late)
    assert flown == [0]  # (flying again would not mend it)
    assert str(e.value) == (
        "not the host: the rig's real-time loop made the run late (run: 2300 of its 2400 events over 1 ms "
        "late were the loop's own doing (busy 100, blocked in a call 2200))")
    flights_of_each, fly_each, late_each = each({"a": KEPT, "b": mine})
    with pytest.raises(pytest.fail.Exception):
        realtime_each(["a", "b"], fly_each, late_each)
    assert len(flights_of_each) == 1


def test_the_host_is_excused_only_when_it_made_most_of_the_lateness() -> None:
    assert made_late_by_the_loop("r", {"late_causes": causes(busy=600, blocked=0, host=600)}) is None  # half
    assert made_late_by_the_loop("r", {"late_causes": causes(busy=0, blocked=601, host=600)}) is not None
    assert made_late_by_the_loop("r", {"late_causes": causes(0, 0, 0)}) is None
    assert made_late_by_the_loop("r", {}) is None  # (a run with no causes: as before)
    # a run that kept pace is judged whatever its few late events were
    flown, fly, late = flights({**KEPT, "late_causes": causes(busy=3, blocked=0, host=0)})
    assert realtime(fly, late) == 0
    # starved by the host: flown again, then inconclusive, as before
    host_made = {**STARVED, "late_causes": causes(busy=100, blocked=0, host=2300)}
    flown, fly, late = flights(host_made, host_made)
    with pytest.raises(pytest.skip.Exception):
        realtime(fly, late)
    assert flown == [0, 1]
