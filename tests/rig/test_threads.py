"""Many DUT threads in one virtual time: a C DUT with ArduPilot's shape (tests/rig/device_clients/
threaded_fc.c: a SCHED_FIFO timer thread, an I2C bus thread on timerfds in epoll_wait, a 400 Hz main
loop on clock_nanosleep, a UART thread polling a pty and a timerfd, condition variables, a semaphore,
epoll_pwait and select with timeouts, a pipe between threads, setitimer, PWM through dprintf) reads
its sensors at its timers' rates in virtual time, the same bytes every run; a thread that spins is
caught and named."""

from __future__ import annotations

from pathlib import Path

import pytest

from rig.scheduler import EXIT_WATCHDOG, MONO_BASE_NS, NS
from rig.session import Session, SessionConfig
from rig.world import World
from tests.rig.helpers import DUTS, PY, Run, build_client, rig_exec

SECONDS = 2          # threaded_fc.c's run, in virtual time
OPTIONS = ("--topology", "direct", "--serial", "/dev/ttyRC0", "--wall-timeout", "120")


@pytest.fixture(scope="module")
def dut(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_client(tmp_path_factory, "threaded_fc", "-pthread")


@pytest.fixture(scope="module")
def runs(dut: Path, tmp_path_factory: pytest.TempPathFactory) -> list[tuple[Run, bytes]]:
    out = []
    for i in range(2):
        tmp = tmp_path_factory.mktemp(f"threaded{i}")
        log = tmp / "log"
        run = rig_exec(tmp, str(dut), options=(*OPTIONS, "--log", str(log)))
        assert run.returncode == 0, run.stderr
        out.append((run, log.read_bytes()))
    return out


def tallies_of(text: str) -> dict[str, tuple[int, int, int]]:
    return {name: (int(n), int(first), int(last))
            for name, n, first, last in (line.split() for line in text.splitlines())}


def transfer_times(log: bytes, transfer: str) -> list[int]:
    """Sim times (ns) of the session's log lines of this transfer (its write and read, as logged)."""
    times = []
    for line in log.decode().splitlines():
        stamp, _, rest = line.split(" ", 2)
        if rest.startswith("i2c-1 " + transfer):
            seconds, _, frac = stamp.partition(".")
            times.append(int(seconds) * NS + int(frac))
    return times


@pytest.mark.parametrize(("transfer", "period_ns"), [
    ("W68:43 R68[2]", 1_000_000),      # gyro X, the 1 kHz timerfd
    ("W77:00 R77[3]", 10_000_000),     # MS5611 ADC read, the 100 Hz timerfd
    ("W1e:03 R1e[6]", 13_333_333),     # HMC5883L data, the 75 Hz timerfd
])
def test_the_bus_thread_reads_each_sensor_at_its_timers_rate(runs: list[tuple[Run, bytes]], transfer: str,
                                                             period_ns: int) -> None:
    times = transfer_times(runs[0][1], transfer)
    # one read per expiry over the main loop's 2 s (the last expiry may fall after it ends)
    assert SECONDS * NS // period_ns - 1 <= len(times) <= SECONDS * NS // period_ns, len(times)
    # the timers are armed in the first microseconds, so the k-th expiry is at k periods (and a few
    # clock reads): each read comes within one period of its expiry
    for k, t in enumerate(times, start=1):
        assert 0 <= t - k * period_ns < period_ns, (k, t)


def test_every_thread_keeps_its_own_time(runs: list[tuple[Run, bytes]]) -> None:
    got = tallies_of(runs[0][0].stdout)
    periods = {"main_loop": 2_500_000, "timer": 1_000_000, "imu": 1_000_000, "baro": 10_000_000,
               "compass": 13_333_333, "uart_timer": 20_000_000, "alarm": 50_000_000}
    for name, period in periods.items():
        n, first, last = got[name]
        assert abs(n - SECONDS * NS // period) <= 1, (name, n)
        assert first - MONO_BASE_NS < period + 100_000, name      # the first event within a period
        # n events a period apart, each late by at most a few clock reads: their span is (n-1) periods
        assert abs((last - first) - (n - 1) * period) < 100_000, name
    # all eight threads met at a barrier first, and exactly one went on as its serial thread
    assert got["barrier_serial"][0] == 1
    # the barometer's condition variable wakes the EKF thread once per read, never by its timeout
    assert got["ekf_wakes"][0] == got["baro"][0] and got["ekf_timeouts"][0] == 0
    # the semaphore posted every 40 main cycles (10 Hz): all but the last post taken before the end
    assert got["logger"][0] == SECONDS * 10 - 1
    # epoll_pwait's 100 ms timeouts on an empty epoll, back to back: 19 end within the 2 s
    assert got["watchdog"][0] == SECONDS * 10 - 1
    # a byte down a pipe every 100 main cycles (0.25 s): select wakes its thread at the cycle that wrote
    # it (main_loop's first event is cycle 1; all but the last byte read before the end)
    n, first, _ = got["telemetry"]
    assert n == SECONDS * 4 - 1 and 0 <= first - (got["main_loop"][1] + 99 * 2_500_000) < 100_000


def test_two_runs_are_byte_identical(runs: list[tuple[Run, bytes]]) -> None:
    (a, log_a), (b, log_b) = runs
    assert a.stdout == b.stdout
    assert log_a == log_b and log_a.count(b" i2c-1 ") > 2000
    assert a.summary["transactions"] == b.summary["transactions"]


def test_priorities_are_recorded_not_applied(runs: list[tuple[Run, bytes]]) -> None:
    notes = runs[0][0].summary["notes"]
    assert "mlockall recorded, not applied (lockstep: no real deadline to miss)" in notes
    asked = "pthread_create SCHED_FIFO priority 15 for a thread created by 'main-loop'"
    assert any(asked in n for n in notes)


@pytest.mark.parametrize(("mode", "options", "said"), [
    ("spin", (), "thread 'spinner' (number 9 in the order the shim saw threads start) spins: it ran on "
                 "for 1.000 s of virtual time without a wait the shim knows while thread"),
    ("spin-quiet", ("--stall-timeout", "1"), "the command stopped answering: no request and no clock read"),
])
def test_a_spinning_thread_is_caught_and_named(tmp_path: Path, dut: Path, mode: str, options: tuple[str, ...],
                                               said: str) -> None:
    run = rig_exec(tmp_path, str(dut), mode, options=(*OPTIONS, *options))
    assert run.returncode == EXIT_WATCHDOG
    assert said in run.summary["error"] and "'spinner'" in run.summary["error"], run.summary["error"]


def test_the_session_writing_a_pty_wakes_the_thread_that_polls_it(tmp_path: Path, dut: Path) -> None:
    """The UART thread polls the pty and a timerfd together, with no timeout, while the others run and
    wait: bytes the session writes at 0.5 s are read then, not at the timer's next tick."""
    out = tmp_path / "out.txt"
    with open(out, "w") as f:
        cfg = SessionConfig(command=[str(dut)], serial=["/dev/ttyRC0"], stdout=f)
        session = Session(cfg, World.at_rest(topology="direct"))
        session.at(0.5, lambda s: s.serial_write("/dev/ttyRC0", b"sbus"))
        outcome = session.run()
    assert outcome.verdict == "ok", outcome.error
    n, first, _ = tallies_of(out.read_text())["uart_reads"]
    assert n == 1 and 0 <= first - MONO_BASE_NS - NS // 2 < 100_000   # within 0.1 ms of the write


def test_python_threads_keep_virtual_time_through_the_gil(tmp_path: Path) -> None:
    """CPython hands its GIL over with a mutex and a condition variable with a deadline: under the rule
    its threads sleep in virtual time and meet through a queue, the same way every run."""
    logs = []
    for i in range(2):
        log = tmp_path / f"log{i}"
        run = rig_exec(tmp_path, PY, str(DUTS / "python_threads.py"),
                       options=("--allow-no-devices", "--log", str(log)))
        assert run.returncode == 0, run.stderr
        got = run.json_out()
        assert got["ticks"] == {"fast": 100, "slow": 20} and got["got"] == 120
        assert NS <= got["elapsed_ns"] < NS + NS // 1000    # 1 s of sleeps, plus clock reads
        logs.append(log.read_bytes())
    assert logs[0] == logs[1]


def test_a_lock_held_across_a_sleep_is_had_when_it_is_let_go(tmp_path_factory: pytest.TempPathFactory,
                                                              tmp_path: Path) -> None:
    """A thread takes a mutex or a read-write lock and sleeps; another asks for it 1 ms later and has
    it when the sleep ends, or gives up at its timed lock's deadline, to the clock read."""
    locks = build_client(tmp_path_factory, "locks", "-pthread")
    run = rig_exec(tmp_path, str(locks), options=("--allow-no-devices",))
    assert run.returncode == 0, run.stderr
    out = {name: (result, int(ns)) for name, result, ns in (line.split() for line in run.stdout.splitlines())}
    quantum = 1000
    assert out == {"mutex": ("0", 10_000_000 + quantum),                 # held for 10 ms
                   "mutex_timedlock": ("ETIMEDOUT", 5_000_000 + 2 * quantum),  # gives up at 5 ms
                   "rwlock_read": ("0", 20_000_000 + quantum)}           # written for 20 ms
