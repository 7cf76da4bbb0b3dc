"""Why a paced loop's event ran late: the host's doing or the loop's own.

Why: an event's lateness alone cannot say whose it is. A paced test skipped runs as "the host could
not keep real time" three times in a row when it was the loop itself (the slcan capture's reads slept
1 ms at a time), and on this kind of VM most late events come from the loop's thread not running at
all for a few milliseconds while it had work. A bench user reading result.json needs the same answer:
a faster host, or a rig fix.

How: the paced wait (rig/pace's PacedSelector) notes the loop thread's state as it enters each wait
and as it returns: the wall clock (CLOCK_MONOTONIC), the thread's CPU time and its count of voluntary
context switches (getrusage(RUSAGE_THREAD) in C: about 1 µs a note on these VMs). The loop's time
thus alternates between waits and work. An event that runs over 1 ms late (the scheduler's LATE_NS)
is judged on its lateness window, from its due time to now, over the last wait and the work on either
side of it:

* within the wait, the time past its deadline (or past its start, if it began late) is the host's:
  the kernel or the hypervisor woke the loop late (``host_woke_late``);
* within work, the thread's CPU time is the loop's own computing (``loop_busy``); the rest is time the
  thread did not run: with a voluntary switch in that stretch it slept in a call of its own
  (``loop_blocked``: a blocking read or write), without one it was preempted, by the hypervisor or a
  higher priority (``host_preempted``);
* what the window reaches before the work before the last wait is ``unattributed``.

Events already due when the loop woke run one after another; the first of them over 1 ms late is
judged as above and the others that follow it are put down to the same cause: their lateness is mostly
the queue behind it (after a host's stall of 10 ms, the last events of the catch-up would otherwise
read as the loop's busy work).

The event counts under the cause with the largest share of its window. Nothing is judged from these:
they stand beside the lateness in result.json, and an inconclusive paced test quotes them.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Final, NamedTuple

CAUSES: Final = ("host_woke_late", "host_preempted", "loop_busy", "loop_blocked", "unattributed")


class Mark(NamedTuple):
    """The loop thread at one instant: wall clock, CPU time (both ns) and voluntary switches so far."""

    wall_ns: int
    cpu_ns: int
    voluntary: int


#: a Mark's fields unnamed, as the wait stores them (made per wait; a Mark only when an event is judged)
Stamp = tuple[int, int, int]


def mark() -> Mark:
    """The calling thread now."""
    return Mark._make(_thread_mark()())


@functools.cache
def _thread_mark() -> Callable[[], Stamp]:
    """pace.c's thread_mark: one getrusage in C (0.8 µs; Python's made a 16-field result: 2.3 µs a mark)."""
    from rig.pace import native  # (imported when first used: the package imports this module)

    fn: Callable[[], Stamp] = native().thread_mark
    return fn


def _work(a: Mark, b: Mark, lo: int, hi: int, share: dict[str, float]) -> None:
    """The work from ``a`` to ``b``, where it overlaps [lo, hi): its CPU part to the loop, the rest to
    blocking (a voluntary switch in it) or preemption, in proportion to the overlap."""
    span = b.wall_ns - a.wall_ns
    overlap = min(hi, b.wall_ns) - max(lo, a.wall_ns)
    if span <= 0 or overlap <= 0:
        return
    busy = min(1.0, max(0.0, (b.cpu_ns - a.cpu_ns) / span))
    share["loop_busy"] += overlap * busy
    idle = "loop_blocked" if b.voluntary > a.voluntary else "host_preempted"
    share[idle] += overlap * (1.0 - busy)


@dataclass
class LateCauses:
    """The loop's last wait and the work around it, and the late events counted by cause."""

    counts: dict[str, int] = field(default_factory=lambda: dict.fromkeys(CAUSES, 0))
    _before: Stamp | None = None      # the return of the wait before the last one
    _entered: Stamp | None = None     # the last wait's start
    _deadline_ns: int | None = None   # ... what it waited for (None: a descriptor or a timeout only)
    _returned: Stamp | None = None    # ... its return
    _backlog: tuple[Stamp, str] | None = None  # the last wait's return and the cause of its first late event

    def entering(self, deadline_ns: int | None, at: Stamp | None = None) -> None:
        """The loop enters a wait for ``deadline_ns`` (CLOCK_MONOTONIC; None: no event due), now or
        ``at``."""
        self._before, self._deadline_ns = self._returned, deadline_ns
        self._entered = at if at is not None else _thread_mark()()

    def returned(self, at: Stamp | None = None) -> None:
        self._returned = at if at is not None else _thread_mark()()

    def late(self, lateness_ns: int, now: Mark | None = None) -> str:
        """An event runs ``lateness_ns`` after its due time (now): counted under its cause, returned."""
        now = now or mark()
        lo, hi = now.wall_ns - lateness_ns, now.wall_ns
        backlog = self._backlog
        if backlog is not None and backlog[0] is self._returned and lo < backlog[0][0]:
            # due before the loop woke, judged after another late event of that wake: queued behind it,
            # its catch-up is the first one's doing (else a host's stall read as the loop's busy work)
            self.counts[backlog[1]] += 1
            return backlog[1]
        share = dict.fromkeys(CAUSES, 0.0)
        if self._entered is not None and self._returned is not None:
            entered, returned = Mark._make(self._entered), Mark._make(self._returned)
            _work(returned, now, lo, hi, share)
            start = max(entered.wall_ns, self._deadline_ns or entered.wall_ns, lo)
            share["host_woke_late"] += max(0, min(hi, returned.wall_ns) - start)
            if self._before is not None:
                _work(Mark._make(self._before), entered, lo, hi, share)
        share["unattributed"] = max(0.0, lateness_ns - sum(share.values()))
        cause = max(CAUSES, key=lambda c: share[c])
        self.counts[cause] += 1
        if self._returned is not None and lo < self._returned[0]:  # the first of the wake's backlog
            self._backlog = (self._returned, cause)
        return cause
