"""The stick emulator's frames (rig/rc.py) as sim time runs: each is the SBUS encoding of the sticks and
link of its instant, checked against emulators/sbus.py's decoder, through changes of the sticks, a
failsafe and a lost link (a frame is encoded again only when what it carries changed)."""

from __future__ import annotations

from collections.abc import Callable

from rig.emulators.sbus import FLAG_FAILSAFE, FLAG_FRAME_LOST, PERIOD_S, Sticks, decode
from rig.host import Host
from rig.rc import StickEmulator
from rig.scheduler import Scheduler
from rig.world import World


class _Port:
    """A host whose serial port keeps what was sent, with the scheduler's time (events run in a real
    Scheduler over a real World)."""

    def __init__(self) -> None:
        self.world = World.at_rest()
        self.sched = Scheduler(self.world, self, duration=1.0, sim_timeout=10.0)
        self.sent: list[tuple[int, bytes]] = []
        self.silent: list[int] = []

    @property
    def now_ns(self) -> int:
        return self.sched.event_ns or 0

    def at(self, t: float, fn: Callable[[Host], None]) -> None:
        self.sched.at(t, fn)

    def serial_write(self, path: str, data: bytes) -> None:
        self.sent.append((self.now_ns, data))

    def serial_silence(self, path: str) -> None:
        self.silent.append(self.now_ns)

    def serial_output(self, path: str) -> bytes:
        return b""


def test_each_frame_carries_the_sticks_and_link_of_its_instant() -> None:
    host = _Port()
    rc = StickEmulator("/dev/ttyRC0")
    rc.start(host)
    expected: list[tuple[tuple[int, ...], bool]] = []

    def change(t: float, sticks: Sticks | None, link: str) -> None:
        def fn(_: Host) -> None:
            if sticks is not None:
                rc.sticks = sticks
            rc.link = link
        host.at(t, fn)

    change(0.2, Sticks(roll=0.5, throttle=0.4, arm=True), "ok")
    change(0.4, None, "failsafe")
    change(0.5, None, "lost")
    change(0.6, Sticks(yaw=-1.0, throttle=0.7, arm=True, mode="althold"), "ok")
    change(0.8, Sticks(yaw=-1.0, throttle=0.7, arm=True, mode="althold"), "ok")  # equal sticks, a new object
    host.sched.advance(999_000_000)
    assert len(host.sent) + len(host.silent) == int(0.999 / PERIOD_S) + 1
    assert host.silent and all(500_000_000 <= t < 600_000_000 for t in host.silent)
    for (t, frame), (t_rc, channels, failsafe) in zip(host.sent, rc.frames, strict=True):
        decoded, flags = decode(frame)
        assert t == t_rc and tuple(decoded) == channels
        assert bool(flags & FLAG_FAILSAFE) == bool(flags & FLAG_FRAME_LOST) == failsafe
        expected.append((channels, failsafe))
    by_time = {t: decode(frame)[0] for t, frame in host.sent}
    assert by_time[min(t for t in by_time if t > 200_000_000)][2] == round(992 + (2 * 0.4 - 1) * 819)
    assert any(f for _, f in expected) and {c[3] for c, _ in expected} >= {992, 173}  # yaw centred, then -1


def test_sticks_changed_in_place_reach_the_next_frame() -> None:
    """A scenario's timeline sets the sticks' fields on the same object (rig/runner.py): each frame
    carries the channels of a fresh copy of the sticks at its instant, whatever the emulator kept."""
    host = _Port()
    rc = StickEmulator("/dev/ttyRC0")
    rc.start(host)
    changes: list[tuple[int, Sticks]] = [(0, Sticks())]

    def set_field(t: float, name: str, value: float | bool) -> None:
        def fn(_: Host) -> None:
            setattr(rc.sticks, name, value)
            changes.append((host.now_ns, Sticks(*rc.sticks.setting())))
        host.at(t, fn)

    timeline = ((0.1, "arm", True), (0.2, "throttle", 0.55), (0.3, "roll", -0.25), (0.4, "roll", -0.25),
                (0.5, "alt_offset", 0.3), (0.6, "roll", -0.0), (0.7, "yaw", 1.0))
    for t, name, value in timeline:
        set_field(t, name, value)
    host.sched.advance(999_000_000)
    assert len(host.sent) == int(0.999 / PERIOD_S) + 1
    for t, frame in host.sent:
        sticks = [s for when, s in changes if when <= t][-1]
        assert decode(frame) == (sticks.channels(), 0)
    assert {decode(f)[0][0] for _, f in host.sent} == {992, round(992 - 0.25 * 819)}
