"""The scheduler's event queue in C (rig/event_queue): the order heapq's (t_ns, seq, fn) tuples gave,
checked against heapq itself on random schedules; the ends of its time range; what it refuses; and that
a function holding the queue is freed with it (the garbage collector sees into the queue)."""

from __future__ import annotations

import gc
import heapq
import random
import weakref
from typing import Any

import pytest

from rig.event_queue import new_queue

INT64_MAX = 2**63 - 1


@pytest.mark.parametrize("seed", range(5))
def test_pops_in_the_order_heapq_gives_ties_in_the_order_pushed(seed: int) -> None:
    rng = random.Random(seed)
    q: Any = new_queue()  # (names for functions: the queue holds any object)
    ref: list[tuple[int, int, str]] = []
    seq = 0
    popped, expected = [], []
    for _ in range(3000):  # pushes and pops interleaved, many ties (times from a small range)
        if rng.random() < 0.6 or not ref:
            t, name = rng.randrange(-5, 60) * 1_000_000, f"e{seq}"
            q.push(t, name)
            heapq.heappush(ref, (t, seq, name))
            seq += 1
        else:
            assert q.first_ns() == ref[0][0]
            popped.append(q.pop())
            t, _, name = heapq.heappop(ref)
            expected.append((t, name))
        assert len(q) == len(ref)
    while ref:
        popped.append(q.pop())
        t, _, name = heapq.heappop(ref)
        expected.append((t, name))
    assert popped == expected
    assert q.first_ns() is None and len(q) == 0


def test_times_past_64_bits_are_kept_at_the_ends_of_the_range_in_order() -> None:
    q: Any = new_queue()
    pushed = [(2**70, "far"), (INT64_MAX, "last"), (-(2**70), "before"), (0, "zero"), (2**64, "farther")]
    for t, name in pushed:
        q.push(t, name)
    assert [q.pop() for _ in range(5)] == [(-(2**63), "before"), (0, "zero"), (INT64_MAX, "far"),
                                           (INT64_MAX, "last"), (INT64_MAX, "farther")]


def test_refuses_what_is_not_an_int_time_and_an_empty_pop() -> None:
    q = new_queue()
    with pytest.raises(TypeError, match="time"):
        q.push(1.5, print)  # type: ignore[arg-type]
    with pytest.raises(TypeError):
        q.push(1)  # type: ignore[call-arg]
    with pytest.raises(IndexError, match="empty"):
        q.pop()
    assert len(q) == 0


def test_a_function_that_holds_its_queue_is_collected_with_it() -> None:
    class Tick:
        def __call__(self, host: object) -> None: ...

    q = new_queue()
    tick = Tick()
    tick.queue = q  # type: ignore[attr-defined]  # a cycle through the queue
    q.push(5, tick)
    gone = weakref.ref(tick)
    del q, tick
    gc.collect()
    assert gone() is None


def test_the_fast_path_refuses_events_that_are_not_a_queue() -> None:
    from rig.lockstep import module

    with pytest.raises(TypeError, match="EventQueue"):
        module().setup(*[None] * 2, [], [], None, [], *[None] * 10)
