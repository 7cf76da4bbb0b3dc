"""Which CPU cores a session and its DUT run on.

Lockstep's two processes take turns: one runs while the other waits. By default they share one core
(``pin``): a wake-up there is a pair of context switches, ~14 us on these VMs, where across two idle
cores the host must wake a halted vCPU, ~90 us (bench/reference/roundtrip.md). With ``spin`` each has a
core of its own and polls for the other's message instead of sleeping (up to ``SPIN_NS``; rig/shim's
``recv_spinning``, rig/lockstep's pump): a message is seen within a microsecond or two, and a run
goes 1.5-1.7 times as fast (bench/reference/rates-after.md), for two whole cores. A sweep's pool
gives each run one core, so it never spins; on one core a poller would hold the core its peer needs.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Final

#: how long either side polls for the other's message before it sleeps: longer than a turn usually
#: lasts (the FC's cycle, the session's message and events: tens of microseconds)
SPIN_NS: Final = 500_000


class CoresError(ValueError):
    """A placement the machine or the other options do not allow: said before anything starts."""


@dataclass(frozen=True)
class Placement:
    dut: set[int] | None       # the DUT's (and its keeper's) cores; None: as they are
    session: set[int] | None   # the session's while the DUT runs; None: as they are


def placement(allowed: set[int], lockstep: bool, pin: bool | None, spin: bool) -> Placement:
    """The cores for a run, from those this process may use (``os.sched_getaffinity``)."""
    if not spin:
        one = {max(allowed)}
        return Placement(one, one) if pin or (pin is None and lockstep) else Placement(None, None)
    if not lockstep:
        raise CoresError("--spin is for lockstep runs (real time paces itself)")
    if pin:
        raise CoresError("--spin takes two cores, --pin one: choose one of them")
    if len(allowed) < 2:
        raise CoresError(f"--spin takes two CPU cores; this process may use {len(allowed)}")
    cores = sorted(allowed)
    return Placement({cores[-1]}, {cores[-2]})


def allowed_cores() -> set[int]:
    return set(os.sched_getaffinity(0))
