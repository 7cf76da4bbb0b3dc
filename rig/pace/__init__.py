"""The real-time loop's pacing: how a session paced by the wall clock (``rig run --realtime``, and the
bench session of ``--bridge``) waits for its next event, and how the host is set up while it runs.

Why its own module: the loop's lateness was the host's, not the scenario's. Measured before this
module (bench/reference/realtime-before.md): a p99 of about a millisecond and a worst case of tens of
milliseconds, on an idle machine. Three causes, three remedies:

* **The wait.** A selector's timeout is relative, in seconds (epoll's rounded up to whole
  milliseconds). ``PacedSelector`` is a selector whose ``select`` waits in C (pace.c) for the next
  event's *absolute* deadline on CLOCK_MONOTONIC: a sleep in the kernel to ``SPIN_NS`` before it, still
  woken by the loop's descriptors (the DUT's socket and ptys, the bridge's link), then a spin to the
  deadline itself. Python is entered again only when the deadline came or a descriptor is ready.
* **Being preempted.** While the loop runs it is SCHED_FIFO at ``FIFO_PRIORITY`` with its memory
  locked (mlockall), where permitted; result.json's ``realtime_lateness`` says whether, and why not
  (``host_state``). The scheduling class is the loop's thread's only, and is reset in any process it
  starts (SCHED_RESET_ON_FORK): a DUT never inherits FIFO from it (docs/design.md §1, "Real time":
  what priority the DUT gets). FIFO is not taken when the kernel's real-time throttling is off
  (sched_rt_runtime_us -1): an event stuck in a loop could then hold a core forever.
* **Pauses of our own.** No cyclic garbage collection while the loop runs (a full collection of the
  plant's and the models' objects stalled it for tens of milliseconds; reference counting still frees
  what the loop makes) and a timer slack of 1 ns (a normal thread's wake-ups may be deferred 50 µs).

Everything is undone when the loop ends: the rig runs many scenarios in one process.
"""

from __future__ import annotations

import functools
import gc
import os
import selectors
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType, TracebackType
from typing import Any, Final, Protocol

from rig.pace.late import LateCauses
from rig.plant.artifacts import BUILD
from rig.plant.native_build import EXTENSION_SUFFIX, built_extension, compile_extension

SOURCE: Final = Path(__file__).resolve().with_name("pace.c")
LIB: Final = BUILD / f"_rigpace{EXTENSION_SUFFIX}"
NS: Final = 1_000_000_000
#: the loop's SCHED_FIFO priority: above the virtual bridge's and its DUT's SCHED_RR (rig/bridge/session.py)
FIFO_PRIORITY: Final = 20
#: the last part of each wait, spun on the clock instead of slept: about how late this VM's kernel wakes
#: a SCHED_FIFO thread (median 40 µs, p99 60-70 µs on a busy 2-core VM). Spinning 50 µs brought the
#: wait's own lateness to a median of 3 µs and a p99 of 20-40 µs for 40 µs of CPU per wait; 100 µs to a
#: p99 of 6 µs for twice the CPU (bench/realtime_lateness.py --wakeups)
SPIN_NS: Final = 50_000
#: the loop's timer slack (ns)
TIMER_SLACK_NS: Final = 1
RT_RUNTIME: Final = Path("/proc/sys/kernel/sched_rt_runtime_us")


@functools.cache
def native() -> ModuleType:
    """The C side (pace.c), built on first use and again when its source is newer."""
    what = "the real-time loop's wait (rig/pace/pace.c)"
    return built_extension("_rigpace", LIB, [SOURCE], lambda: compile_extension([SOURCE], LIB, what))


def now_ns() -> int:
    """CLOCK_MONOTONIC (ns): the clock the deadlines are on (time.monotonic_ns's)."""
    t: int = native().now()
    return t


class PacedSelector(selectors.SelectSelector):
    """A selector for a paced loop: ``select(timeout)`` returns at the next event's absolute deadline
    (``deadline()``: CLOCK_MONOTONIC ns, or None when no event is due), at ``timeout`` if that is
    sooner (the loop's housekeeping), or as soon as a registered descriptor is readable. Only reads are
    waited for (the loops register nothing else).

    At a deadline it calls ``on_due()`` (the loop's "run what is due") before it returns: the event
    runs straight after the wait, not after a turn of the loop's bookkeeping (35 µs of Python on these
    VMs, most of the lateness that was left)."""

    def __init__(self, deadline: Callable[[], int | None], on_due: Callable[[], object] | None = None,
                 spin_ns: int = SPIN_NS, host: HostState | None = None) -> None:
        super().__init__()
        self._deadline = deadline
        self._on_due = on_due
        self.spin_ns = spin_ns
        self._fds: tuple[int, ...] | None = None
        self._wait = native().wait
        self._now = native().now
        self.wakes = 0  # calls that returned (for the bench)
        #: where it notes how late each wait that ran to its deadline returned, and the loop's thread
        #: at each wait's start and return (rig/pace/late.py)
        self._host = host

    def register(self, fileobj: Any, events: int, data: Any = None) -> selectors.SelectorKey:
        if events != selectors.EVENT_READ:
            raise ValueError("PacedSelector waits for reads only")
        self._fds = None
        return super().register(fileobj, events, data)

    def unregister(self, fileobj: Any) -> selectors.SelectorKey:
        self._fds = None
        return super().unregister(fileobj)

    def select(self, timeout: float | None = None) -> list[tuple[selectors.SelectorKey, int]]:
        keys: Mapping[Any, selectors.SelectorKey] = self.get_map()
        if self._fds is None:
            self._fds = tuple(key.fd for key in keys.values())
        limit = self._now() + round(max(0.0, 3600.0 if timeout is None else timeout) * NS)
        due = self._deadline()
        paced = due is not None and due <= limit
        host = self._host
        if host is not None:
            host.causes.entering(due if paced else None)
        ready = self._wait(due if paced else limit, self._fds, self.spin_ns if paced else 0)
        woke = self._now()
        if host is not None:
            host.causes.returned()
        self.wakes += 1
        if not ready:
            # (a signal ends the wait early, with nothing ready: not a wake at the deadline)
            if paced and host is not None and due is not None and woke >= due:
                host.woke_late_ns.append(woke - due)
            if paced and self._on_due is not None:
                self._on_due()
            return []
        by_fd = {key.fd: key for key in keys.values()}
        return [(by_fd[fd], selectors.EVENT_READ) for fd in ready if fd in by_fd]


class Judged(Protocol):
    """A scheduler that tells a callable of each event it runs over 1 ms late (rig.scheduler.Scheduler)."""

    on_late: Callable[[int], object] | None


@dataclass
class HostState:
    """How the loop ran: under SCHED_FIFO, with its memory locked, and why not where it could not."""

    sched_fifo: bool = False
    mlockall: bool = False
    not_taken: list[str] = field(default_factory=list)
    #: how late the paced waits that ran to their deadline woke (ns; PacedSelector fills it)
    woke_late_ns: list[int] = field(default_factory=list)
    #: the CPU time the hypervisor took from this machine's CPUs while the loop ran (s), or None where
    #: /proc/stat does not say
    steal_s: float | None = None
    #: why the events over 1 ms late were late (the scheduler reports them: Scheduler.on_late)
    causes: LateCauses = field(default_factory=LateCauses)

    def as_dict(self) -> dict[str, object]:
        """For result.json's ``realtime_lateness``: how the loop ran, and the host's own figures beside
        the events' lateness (a late event whose waits woke on time, on a host that took nothing, was
        made late by the loop's own work, not by the host)."""
        out: dict[str, object] = {"sched_fifo": self.sched_fifo, "mlockall": self.mlockall,
                                  "not_taken": list(self.not_taken)}
        if self.woke_late_ns:
            late = sorted(self.woke_late_ns)
            out.update(waits=len(late), wait_p99_s=late[int(0.99 * (len(late) - 1))] / NS,
                       wait_max_s=late[-1] / NS)
        if self.woke_late_ns or any(self.causes.counts.values()):  # (a paced loop ran)
            out["late_causes"] = dict(self.causes.counts)
        if self.steal_s is not None:
            out["steal_s"] = self.steal_s
        return out


def steal_ticks(stat: Path = Path("/proc/stat")) -> int | None:
    """The machine's steal time so far (all CPUs, in clock ticks: /proc/stat's eighth "cpu" column): time
    the hypervisor gave to something else while a CPU of this machine had work. None where it is not
    there (not Linux, an old kernel)."""
    try:
        with stat.open() as f:
            fields = f.readline().split()
        return int(fields[8]) if fields[0] == "cpu" and len(fields) > 8 else None
    except (OSError, ValueError, IndexError):
        return None


class FrozenHeap:
    """The objects alive at ``start()`` left out of the cyclic garbage collector's work until ``stop()``
    (``gc.freeze``), unless something else has frozen objects already (then nothing is done: its
    ``unfreeze`` is its own). Why: a full collection walks every tracked object, the rig's modules,
    functions and dicts included (about 49 000 in a flight's process: some 12 million instructions);
    frozen, it walks what the run itself made (about 4 000), and comes less often. A lockstep flight
    of 4 s and of 8 s made none and one full collection: 12 k instructions per FC cycle over the 4 s
    between, by where the collector's thresholds fell."""

    def __init__(self) -> None:
        self._frozen = False

    def start(self) -> None:
        if not self._frozen and gc.get_freeze_count() == 0:
            self._frozen = True
            gc.freeze()

    def stop(self) -> None:
        if self._frozen:
            self._frozen = False
            gc.unfreeze()


class RealtimeHost:
    """The loop's thread under SCHED_FIFO with its memory locked, no cyclic garbage collection and a fine
    timer slack, as far as permitted (``state`` says how far), from ``start()`` (or entering it as a
    context manager) to ``stop()``, which undoes what was done. Start it before sim time 0: locking the
    memory of a rig process takes 100-200 ms. Processes started meanwhile do not inherit FIFO."""

    def __init__(self, priority: int = FIFO_PRIORITY) -> None:
        self.priority = priority
        self.state = HostState()
        self._policy: tuple[int, os.sched_param] | None = None
        self._slack = 0
        self._started = False
        self._heap = FrozenHeap()
        self._gc_was_enabled = True
        self._steal0: int | None = None

    def start(self, fifo: bool = True) -> HostState:
        """Everything; with ``fifo`` False all but SCHED_FIFO (``take_fifo()`` later: processes started
        in between still inherit the thread's class as it was)."""
        pace = native()
        self._started = True
        self._steal0 = steal_ticks()
        self._heap.start()
        self._gc_was_enabled = gc.isenabled()
        gc.disable()
        self._slack = pace.timerslack(TIMER_SLACK_NS)
        err = pace.mlockall()
        if err:
            self.state.not_taken.append(f"mlockall: {os.strerror(err)}")
        else:
            self.state.mlockall = True
        if fifo:
            self.take_fifo()
        return self.state

    def __enter__(self) -> HostState:
        return self.start()

    def selector(self, deadline: Callable[[], int | None], on_due: Callable[[], object],
                 scheduler: Judged) -> PacedSelector:
        """The paced loop's selector, noting its waits into ``state``, with ``scheduler`` telling
        ``state`` each event that runs over 1 ms late (whose lateness it was: rig/pace/late.py)."""
        scheduler.on_late = self.state.causes.late
        return PacedSelector(deadline, on_due, host=self.state)

    def take_fifo(self) -> None:
        try:
            runtime = int(RT_RUNTIME.read_text())
        except (OSError, ValueError):
            runtime = 0  # (not Linux's /proc: let the kernel decide)
        if runtime < 0:
            self.state.not_taken.append("SCHED_FIFO: not taken, the kernel's real-time throttling is off "
                                        "(sched_rt_runtime_us -1): a stuck event would hold a core")
            return
        old = (os.sched_getscheduler(0), os.sched_getparam(0))
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO | os.SCHED_RESET_ON_FORK, os.sched_param(self.priority))
        except OSError as e:
            self.state.not_taken.append(f"SCHED_FIFO: {e.strerror or e}")
            return
        self._policy = old
        self.state.sched_fifo = True

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.stop()

    def stop(self) -> None:
        """Undoes what ``start()`` did (nothing if it did not run, or ran down already)."""
        if not self._started:
            return
        self._started = False
        steal = steal_ticks()
        if steal is not None and self._steal0 is not None:
            self.state.steal_s = (steal - self._steal0) / os.sysconf("SC_CLK_TCK")
        pace = native()
        if self._policy is not None:
            os.sched_setscheduler(0, *self._policy)
            self._policy = None
        if self.state.mlockall:
            pace.munlockall()
        pace.timerslack(self._slack)
        if self._gc_was_enabled:  # (a caller that had turned the collector off keeps it off)
            gc.enable()
        self._heap.stop()
