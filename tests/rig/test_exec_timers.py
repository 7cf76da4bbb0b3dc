"""Virtual timers in a single-threaded program: timerfd (read blocking or not, in poll, gettime,
expirations that pile up), alarm and setitimer ending waits with EINTR, all exactly on the session's
clock; the expected values follow from the timers' settings and the 1 us a clock read costs."""

from __future__ import annotations

from pathlib import Path

from tests.rig.helpers import build_client, rig_exec

QUANTUM = 1000   # ns per clock read
MS = 1_000_000


def test_timerfd_alarm_and_setitimer_follow_the_virtual_clock(tmp_path_factory, tmp_path: Path) -> None:
    dut = build_client(tmp_path_factory, "timers")
    run = rig_exec(tmp_path, str(dut), options=("--allow-no-devices",))
    assert run.returncode == 0, run.stderr
    out = {name: rest for name, *rest in (line.split() for line in run.stdout.splitlines())}
    # a 10 ms periodic timer: each blocking read returns one expiration, at k * 10 ms (+ the clock read
    # that measured it; the timer was armed one read after t0)
    for k in range(3):
        assert out[f"read{k}"] == ["8", "1", str((k + 1) * 10 * MS + QUANTUM)]
    assert out["gettime"] == [str(10 * MS - QUANTUM), str(10 * MS)]   # one read after the 3rd expiry
    assert out["after_sleep"] == ["3"]            # 35 ms of sleep: 3 expirations in one read
    assert out["short_read"] == ["-1", "EINVAL"]  # fewer than 8 bytes, as timerfd_read
    assert out["nonblocking"] == ["-1", "EAGAIN"]
    assert out["poll_abs"] == ["1", str(1000 * MS)]   # armed 1 s ahead on the clock read before t
    # alarm(1) ends sleep(5) after exactly 1 s (no clock read between them): 4 s left, in whole
    # seconds as glibc's sleep returns them
    assert out["alarm_sleep"] == ["4", str(1000 * MS + QUANTUM)]
    assert out["getitimer"] == ["0", "250000"]
    code, err, slept, rem = out["nanosleep_interrupted"]
    assert (code, err, int(slept)) == ("-1", "EINTR", 250 * MS)
    assert 750 * MS <= int(rem) <= 750 * MS + 2 * QUANTUM
    # pause() ends at the interval's next expiry, 250 ms after the one that ended the nanosleep
    code, err, paused = out["pause"]
    assert (code, err) == ("-1", "EINTR") and 250 * MS - 2 * QUANTUM <= int(paused) <= 250 * MS
