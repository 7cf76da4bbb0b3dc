"""Sim time in a session: the clock page the DUT's shim reads, the scheduled events, the world run up to
an instant, the run's limits, and the verdict.

This is the session's third job, kept apart from the process and transport loop (rig/session.py) and
from the DUT's messages (rig/handler.py) so that it can be tested, and read, without a DUT: events run
in order of time (ties in order of scheduling) before the world moves past them, an event that raises
ends the run as an error instead of taking the rig down, and time past ``--duration`` (the run is
over, well) or ``--sim-timeout`` (the watchdog) stops everything.
"""

from __future__ import annotations

import mmap
import os
import signal
from collections.abc import Callable
from pathlib import Path
from typing import Any, Final

from rig import interrupts
from rig import protocol as P
from rig.event_queue import EventQueue, new_queue
from rig.world import World

NS: Final = 1_000_000_000
EPOCH_NS: Final = 1_767_225_600 * NS  # CLOCK_REALTIME at sim time 0: 2026-01-01T00:00:00Z
MONO_BASE_NS: Final = 1_000 * NS  # CLOCK_MONOTONIC at sim time 0, as if the board had been up 1000 s

EXIT_WATCHDOG: Final = 124  # as timeout(1)
EXIT_RIG_ERROR: Final = 125  # the run could not be judged: the DUT never came, left early, ...
LATE_NS: Final = 1_000_000  # real time: an event run more than 1 ms after its due time counts as late

#: An event: called with the session (rig/session.py) at its sim time
Event = Callable[[Any], None]


class Stop(Exception):
    """The run is over (limit reached or a failure); no further replies."""


class SharedPage:
    """The page the session shares with the DUT's shim (rig/shim/protocol.h, struct rig_shm): in
    lockstep the one clock, which the shim moves by a quantum per clock read and the session moves
    when it answers a wait; the PWM states; the run's end, where a clock read asks the session."""

    def __init__(self, path: Path, npwm: int, start_ns: int, quantum_ns: int, limit_ns: int) -> None:
        with open(path, "wb") as f:
            f.write(bytes(P.SHM_SIZE))
        fd = os.open(path, os.O_RDWR)
        try:
            self._mm = mmap.mmap(fd, P.SHM_SIZE)
        finally:
            os.close(fd)
        P.SHM_HEAD.pack_into(self._mm, 0, P.SHM_MAGIC, P.PROTOCOL_VERSION, npwm, start_ns, quantum_ns,
                             EPOCH_NS, MONO_BASE_NS)
        self._words = memoryview(self._mm).cast("Q")
        self._words[P.SHM_LIMIT_OFFSET // 8] = limit_ns

    def now(self) -> int:
        return self._words[P.SIM_NS_OFFSET // 8]

    @property
    def mmap(self) -> mmap.mmap:
        """The page itself (the lockstep fast path, rig/lockstep, writes the clock through it)."""
        return self._mm

    def set(self, t_ns: int) -> None:
        """Moves the clock forward to ``t_ns`` (never back: the DUT may have read it on already)."""
        if t_ns > self._words[P.SIM_NS_OFFSET // 8]:
            self._words[P.SIM_NS_OFFSET // 8] = t_ns

    def promise_acks(self, bus: int, acks: list[tuple[int, int]]) -> None:
        """The session's promises (protocol.h struct rig_ack): a write of one message to each address on
        ``bus`` that starts before its time (ns) is acknowledged; the shim sends those as notices."""
        if len(acks) > P.ACK_MAX:
            raise ValueError(f"{len(acks)} promises; the page holds {P.ACK_MAX}")
        for i, (addr, until_ns) in enumerate(acks):
            P.SHM_ACK.pack_into(self._mm, P.SHM_ACKS_OFFSET + i * P.SHM_ACK.size, bus, addr, 0, until_ns)

    def promised(self, bus: int, addr: int, t_ns: int) -> bool:
        """A write to ``addr`` on ``bus`` starting at ``t_ns`` is one the page promises to acknowledge."""
        for i in range(P.ACK_MAX):
            b, a, _, until = P.SHM_ACK.unpack_from(self._mm, P.SHM_ACKS_OFFSET + i * P.SHM_ACK.size)
            if b == bus and a == addr and t_ns < until:
                return True
        return False


class Scheduler:
    """Runs the scheduled events and the world forward in sim time, and knows when the run is over.

    ``host`` is what events are called with (the session). ``wall_now`` is given in real time only: it
    says how late each event ran (measured and reported, never hidden)."""

    def __init__(self, world: World, host: object, duration: float | None, sim_timeout: float,
                 wall_now: Callable[[], int] | None = None) -> None:
        self.world, self.host = world, host
        self.duration, self.sim_timeout = duration, sim_timeout
        self.limit_ns = round((duration if duration is not None else sim_timeout) * NS)
        self._wall_now = wall_now
        #: by time, ties in the order scheduled (a heap in C: the fast path reads its first event's time)
        self.events: EventQueue = new_queue()
        # (push and pop bound once: a method called by name from compiled code is looked up at every call)
        self._push: Callable[[int, Event], None] = self.events.push
        self._pop: Callable[[], tuple[int, Event]] = self.events.pop
        self.event_ns: int | None = None   # inside an event: its time
        self.event_output = False          # the running event sent the DUT data
        self.error: tuple[int, str] | None = None
        self.ended_by_duration = False
        self.over = False  # an error or the end of the duration: no more answers to the DUT
        # ``over`` again as a byte (0 or 1), which the lockstep fast path reads before each answer
        # without a getattr (fastpath.c's clear_until: 7 reads per FC cycle, ~150 instructions each)
        self.over_byte = bytearray(1)
        self.lateness_ns: list[int] = []   # real time: wall clock minus due time, per event
        #: real time: told the lateness of each event that runs over LATE_NS late, as it starts (the
        #: paced loop's judge of whose lateness it was: rig/pace/late.py)
        self.on_late: Callable[[int], object] | None = None

    def at(self, t: float, fn: Event) -> None:
        """Runs ``fn(host)`` at sim time ``t`` seconds (before any DUT request at or after it)."""
        self._push(round_half_even(t * NS), fn)

    def fail(self, code: int, message: str) -> None:
        """Ends the run with this error (the first one stands)."""
        if self.error is None:
            self.error = (code, message)
        self._end()

    def _end(self) -> None:
        """The run is over: ``over`` and its byte."""
        self.over = True
        self.over_byte[0] = 1

    def advance(self, t_ns: int, stop_on_output: bool = False) -> int:
        """Runs scheduled events and the world up to ``t_ns``. Returns the time reached: earlier than
        ``t_ns`` when ``stop_on_output`` and an event sent the DUT data. Raises Stop at a limit."""
        if t_ns > self.limit_ns:
            self.advance(self.limit_ns)
            if self.duration is not None:
                self.ended_by_duration = True
                self._end()
            else:
                self.fail(EXIT_WATCHDOG, f"sim-time watchdog: the command was still running after "
                                         f"{self.sim_timeout:g} s of sim time")
            raise Stop
        events = self.events
        while (first := events.first_ns()) is not None and first <= t_ns:
            te = self.run_next()
            if stop_on_output and self.event_output:
                return te
        self.world.advance_to(t_ns)
        return t_ns

    def run_next(self) -> int:
        """Runs the first event, the world stepped to its time first; returns that time. One step of
        advance(), and what the lockstep fast path calls for each event a wait crosses
        (rig/lockstep/events.c), so an event runs alike whichever path reached it."""
        te, fn = self._pop()
        if self._wall_now is not None:
            late = max(0, self._wall_now() - te)
            self.lateness_ns.append(late)
            if late > LATE_NS and self.on_late is not None:
                self.on_late(late)
        world = self.world
        te = max(te, world.time_ns)
        world.advance_to(te)
        self.event_output = False
        self.event_ns = te
        try:
            fn(self.host)
        except interrupts.Interrupted:  # a signal that stops the rig, not the event's fault: the
            raise                       # session ends the run as interrupted (rig/interrupts.py)
        except Exception as e:  # a scenario's event must not take the rig down; the run is void
            self.fail(EXIT_RIG_ERROR, f"event at {fmt(te)} failed: {type(e).__name__}: {e}")
            raise Stop from e
        finally:
            self.event_ns = None
        return te

    def next_event_ns(self) -> int | None:
        """The next event's due time, or None: none is left, or the run is over (nothing runs any more;
        a paced loop that kept waking for a past event once the run was over spun at SCHED_FIFO and
        starved, on a one-core host, the DUT it was stopping: the run never ended)."""
        return None if self.over else self.events.first_ns()

    def verdict(self, returncode: int | None, sim_s: float, reached: bool, allow_no_devices: bool,
                interrupted: bool) -> tuple[str, int, str | None]:
        """How the run ended: ("ok" | "failed" | "error" | "interrupted", exit code, error). ``reached``:
        the command reached the session at least once."""
        if self.error is not None:
            code, error = self.error
            return "interrupted" if interrupted else "error", code, error
        if self.ended_by_duration:
            return "ok", 0, None
        if returncode is not None and returncode < 0:
            sig = signal.Signals(-returncode).name
            return "error", 128 - returncode, f"the command was killed by {sig} at sim t={sim_s:.3f} s"
        if not reached and not allow_no_devices:
            if returncode:  # it ran and gave up: its own words (stderr) say why, not a guess of ours
                return ("error", EXIT_RIG_ERROR,
                        f"the command exited with status {returncode} before touching the emulated devices")
            return ("error", EXIT_RIG_ERROR,
                    "the command exited without touching the emulated devices (no I2C, PWM or wait "
                    "reached the session: is it statically linked, setuid, or using other device paths?)")
        if self.duration is not None:
            return ("error", EXIT_RIG_ERROR, f"the command exited early, with status {returncode}, at sim "
                                             f"t={sim_s:.3f} s of a {self.duration:g} s run")
        if returncode:
            return "failed", returncode, None
        return "ok", 0, None

    def lateness(self) -> tuple[int, int, float, float, float]:
        """Real time: events run, how many ran over 1 ms late, the worst, the 99th percentile and the
        median (s)."""
        late = sorted(self.lateness_ns) or [0]
        return (len(self.lateness_ns), sum(x > LATE_NS for x in late), late[-1] / NS,
                late[int(0.99 * (len(late) - 1))] / NS, late[(len(late) - 1) // 2] / NS)


def round_half_even(x: float) -> int:
    """``round(x)``, the same integer for every float (halves to even; NaN and infinities raise as it
    does), in the few operations mypyc compiles inline: an event is scheduled at every frame, wind
    update and recorder row, and the builtin's method lookup was 1.3 k of the 3.1 k instructions that
    scheduling one cost (tests/rig/test_scheduler.py checks it against the builtin)."""
    f = int(x)
    if f > x:  # (int() truncates: floor for negative x)
        f -= 1
    d = x - f  # exact: a float's fractional part is representable
    if d > 0.5 or (d == 0.5 and f & 1):
        f += 1
    return f


def fmt(t_ns: int) -> str:
    """Sim time as seconds with nine decimals, exactly (the log's stamp)."""
    return f"{t_ns // NS}.{t_ns % NS:09d}"
