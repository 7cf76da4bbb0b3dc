"""The lockstep fast path (rig/lockstep) against the Python handler, its reference: the same messages
through a session, once each way (RIG_PY_PATH=1 is the handler alone), must give the DUT the same bytes
and leave the same world, clock, counts and transfer log. A flight of a library scenario each way must
write the same results."""

from __future__ import annotations

import ctypes
import json
import os
import select
import selectors
import socket
import struct
import tty
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

import rig.protocol as P
from rig import lockstep
from rig.connection import Conn
from rig.emulators import native
from rig.emulators.chips.board import CHIP_HMC
from rig.session import Session, SessionConfig, _pending_input, _Pty
from rig.world import World

CYCLE_NS = 4_000_000


def _msg(t_ns: int, payload: bytes, mtype: int) -> bytes:
    return P.HEADER.pack(len(payload), mtype, 0, t_ns) + payload


def _i2c(t_ns: int, parts: list[tuple[int, int, int, bytes]], bus: int = 1) -> bytes:
    descs = b"".join(P.I2C_MSG.pack(addr, flags, n, 0) for addr, flags, n, _ in parts)
    return _msg(t_ns, P.I2C_HEAD.pack(bus, len(parts)) + descs + b"".join(d for *_, d in parts), P.MSG_I2C)


def _pwm(t_ns: int, channel: int, attr: int, value: int) -> bytes:
    return _msg(t_ns, P.PWM_MSG.pack(0, channel, attr, 0, value), P.MSG_PWM)


def _wait(t_ns: int, wake: int, kind: int) -> bytes:
    return _msg(t_ns, P.WAIT_MSG.pack(wake, kind, 0), P.MSG_WAIT)


def _script() -> list[bytes]:
    """A flight controller's set-up and cycles, with the cases the fast path must get right or leave
    to the handler: a NACK, another bus, a block read with an impossible count, a 10-bit address, every
    kind of wait, other PWM attributes (a channel unexported and exported again among them: the fast path
    keeps the channels' settings), the MPU's rate changed, reset and woken (the fast path keeps what it
    read of the IMU's producer), an event due mid-cycle, and a malformed message at the end."""
    rd = P.I2C_M_RD
    out = [_msg(0, P.HELLO_MSG.pack(P.PROTOCOL_VERSION, 1234), P.MSG_HELLO)]
    out += [_i2c(0, [(0x68, 0, 2, bytes(rv))]) for rv in ((0x6B, 0x00), (0x1A, 0x03), (0x19, 0x00))]
    for ch in range(4):
        out += [_pwm(0, ch, P.PWM_EXPORT, 0), _pwm(0, ch, P.PWM_PERIOD, 2_500_000),
                _pwm(0, ch, P.PWM_DUTY, 1_000_000), _pwm(0, ch, P.PWM_ENABLE, 1)]
    t = 10_000_000
    for k in range(60):
        out.append(_i2c(t, [(0x68, 0, 1, b"\x3b"), (0x68, rd, 14, b"")]))
        if k % 7 == 0:
            out.append(_i2c(t + 10, [(0x1E, 0, 1, b"\x03"), (0x1E, rd, 6, b"")]))  # behind the MPU: NACK
            out.append(_i2c(t + 20, [(0x68, rd, 1, b"")], bus=2))                     # no such bus
            out.append(_i2c(t + 30, [(0x68, 0, 1, b"\x75"), (0x68, rd | P.I2C_M_RECV_LEN, 0, b"")]))
            out.append(_i2c(t + 40, [(0x68, P.I2C_M_TEN, 1, b"\x00")]))               # 10-bit: nobody
            out.append(_i2c(t + 50, [(0x77, 0, 1, b"\x48")]))                         # baro: convert D1
        out += [_pwm(t + 1000, ch, P.PWM_DUTY, 1_100_000 + 10_000 * k + 1000 * ch) for ch in range(4)]
        # the IMU's producer moved by Python between C's cycles: a new sample rate and back, a reset (new
        # filters, 8 kHz) and a wake-up (a new sample clock): C must not go on with what it kept before
        writes = {20: (0x19, 0x01), 24: (0x19, 0x00), 25: (0x6B, 0x80), 26: (0x6B, 0x00), 28: (0x1A, 0x03)}
        if k in writes:
            out.append(_i2c(t + 1200, [(0x68, 0, 2, bytes(writes[k]))]))
        if k == 30:
            out.append(_pwm(t + 1500, 0, P.PWM_POLARITY, 0))  # (the handler's)
        if k == 40:  # channel 1 inversed, channel 2 off: the duty writes after it act differently
            out += [_pwm(t + 1500, 1, P.PWM_POLARITY, 1), _pwm(t + 1500, 2, P.PWM_ENABLE, 0)]
        if k == 50:  # channel 3 gone (a new channel object), then back with another period
            out.append(_pwm(t + 1500, 3, P.PWM_UNEXPORT, 0))
        if k == 53:
            out += [_pwm(t + 1500, 3, P.PWM_EXPORT, 0), _pwm(t + 1500, 3, P.PWM_PERIOD, 2_000_000),
                    _pwm(t + 1500, 3, P.PWM_ENABLE, 1)]
        if k % 3 == 0:
            out.append(_wait(t + 2000, t + CYCLE_NS, P.WAIT_AHEAD))
        elif k % 3 == 1:
            out.append(_wait(t + 2000, t + CYCLE_NS, P.WAIT_SLEEP))
        else:
            out.append(_wait(t + 2000, P.WAIT_FOREVER, P.WAIT_POLL))
        t += CYCLE_NS if k % 3 != 2 else 10_002_000
    out.append(_wait(t, t + 1, 9))  # malformed: the connection goes
    return out


RC = "/dev/ttyRC0"


def _ticking(session: Session, fail_at: float | None) -> tuple[list[tuple[Any, ...]], list[int]]:
    """Events as a flight has them: a recorder at 100 Hz (what it saw: the event's time, the world's, the
    clock's, the plant), frames to the DUT's serial port every 7 ms (a polling wait wakes at each), and
    with ``fail_at``, an event that raises then (the run ends with the rig's error). Returns what the
    recorder saw and, after each frame, the bytes the DUT's side must have readable once it runs again."""
    seen: list[tuple[Any, ...]] = []
    readable: list[int] = []
    master, slave = os.openpty()
    tty.setraw(slave)
    os.set_blocking(master, False)
    os.set_blocking(slave, False)
    session._ptys[RC] = _Pty(RC, master, slave)

    def record(s: Session, k: int) -> None:
        assert s.page is not None
        seen.append((s.now_ns, s.world.time_ns, s.page.now(), tuple(s.world.outputs().values())))
        s.at((k + 1) * 0.01 + 0.0013, lambda s: record(s, k + 1))

    def frame(s: Session, k: int) -> None:
        s.serial_write(RC, bytes([k % 256]) * 25)
        readable.append(s.in_flight[slave])
        s.at((k + 1) * 0.007, lambda s: frame(s, k + 1))

    def fail(s: Session) -> None:
        raise RuntimeError("a scenario's event went wrong")

    session.at(0.0013, lambda s: record(s, 0))
    session.at(0.0, lambda s: frame(s, 0))
    if fail_at is not None:
        session.at(fail_at, fail)
    return seen, readable


def _fly(monkeypatch: pytest.MonkeyPatch, tmp_path: Path, py_path: bool, clock_hz: int,
         script: list[bytes] | None = None, pump: bool = False, events: bool = False,
         fail_at: float | None = None, world: Callable[[], World] = lambda: World.at_rest(seed=3),
         prepare: Callable[[Session], None] | None = None) -> dict[str, Any]:
    """The script through a session's _on_readable, a message at a time. ``pump``: with the loop's
    epoll set, so the fast path reads the connection itself (FastPath.pump); a pipe that is always
    readable beside it makes pump return as soon as the connection has nothing more. ``events``: the
    events of ``_ticking`` too, and the bytes they wrote to the DUT's port are returned."""
    monkeypatch.setenv(lockstep.PY_PATH_ENV, "1" if py_path else "0")
    cfg = SessionConfig(command=["true"], duration=100.0, i2c_clock_hz=clock_hz)
    session = Session(cfg, world())
    if prepare is not None:  # (what a test sets up once the session, and its fast path, are made)
        prepare(session)
    session.open_page(tmp_path / f"shm-{py_path}-{clock_hz}-{pump}")
    assert (session.fast is None) == py_path
    assert session.fast is None or session.fast.imu_in_c  # the MPU's samples made in C too
    session.at(0.2, lambda s: s.world.set_input("wind_n", 2.0))  # an event between two cycles
    seen, readable = _ticking(session, fail_at) if events else ([], [])
    ours, dut = socket.socketpair()
    conn = Conn(ours, 1)
    received = bytearray()
    sel = selectors.EpollSelector()
    pumped: list[int] = []  # what each pump call received
    other_r, other_w = os.pipe()
    os.write(other_w, b"x")
    if pump:
        sel.register(ours, selectors.EVENT_READ, conn)
        sel.register(other_r, selectors.EVENT_READ, "other")
        session._pump_fd = sel.fileno()
        assert session.fast is not None
        real_pump = session.fast.pump

        def counted(*args: Any) -> int:
            got = real_pump(*args)
            pumped.append(got)
            return got
        monkeypatch.setattr(session.fast, "pump", counted)
    with ours, dut, sel:
        for m in script if script is not None else _script():
            dut.sendall(m)
            session._on_readable(conn, sel)  # (conn is not among the session's: never dropped from sel)
            if readable and not session.sched.over:  # the frames written so far were handed over before
                # the DUT's next message (a run that is over lets the DUT run no more)
                assert not session.in_flight
                assert _pending_input(session._ptys[RC].slave) >= readable[-1]
            dut.setblocking(False)
            try:
                while chunk := dut.recv(1 << 16):
                    received += chunk
            except BlockingIOError:
                pass
            dut.setblocking(True)
    os.close(other_r)
    os.close(other_w)
    serial = b""
    for pty in session._ptys.values():
        try:
            serial = os.read(pty.slave, 1 << 16)
        except BlockingIOError:
            pass
        os.close(pty.master)
        os.close(pty.slave)
    handler = session.handler
    assert handler is not None and session.page is not None
    board = session.world.board
    sampler = board._imu._sampler
    return {"received": bytes(received), "counts": session.message_counts(),
            "log": list(handler.i2c_log), "clock": session.page.now(), "world": session.world.outputs(),
            "plant_ns": session.world.time_ns, "malformed": len(session.malformed),
            "why": list(session.malformed),
            "pwm": [(c.exported, c.period_ns, c.duty_ns, c.enabled, c.inversed) for c in session.world.pwm],
            "handled": session.fast.handled if session.fast else 0,
            "fast_waits": session.fast.counts[1] if session.fast else 0,
            "events": seen, "serial": serial, "error": session.sched.error,
            "pumped": sum(n for n in pumped if n > 0),
            # the chip core's whole state (its samples as float64, to the bit) and the IMU producer's
            "board": ctypes.string_at(board.addr, native.chips().rig_chip_board_size()),
            "block": sampler.block.tobytes(), "next_t": sampler.next_t,
            "mag": tuple(getattr(board.feeds[CHIP_HMC], a) for a in ("_anchor", "_index", "_next_t")),
            "made_here": session.fast.made_here if session.fast else (0, 0, 0)}


@pytest.mark.parametrize("clock_hz", [0, 400_000])
@pytest.mark.parametrize("pump", [False, True])
def test_the_fast_path_answers_as_the_handler_does(monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
                                                   clock_hz: int, pump: bool) -> None:
    py = _fly(monkeypatch, tmp_path, True, clock_hz)
    fast = _fly(monkeypatch, tmp_path, False, clock_hz, pump=pump)
    assert fast["handled"] > 300  # most of the 60 cycles' messages went through C
    assert py["handled"] == 0
    assert py["malformed"] == fast["malformed"] == 1
    statuses = _i2c_statuses(py["received"])
    assert {0, 6, 19, 71} <= set(statuses)  # ok, ENXIO, ENODEV, EPROTO: each case was met
    assert [r.ok for r in fast["log"]] == [status == 0 for status in statuses]  # the log's rows, one a reply
    assert all(r.register == (r.wrote[0] if r.wrote else None) for r in fast["log"])
    _same(py, fast)
    assert (fast["pumped"] > len(b"".join(_script())) // 2) == pump  # pump read most of it
    # the IMU's samples made in C in most of the 60 cycles, after the rate change, the reset and the
    # wake-up too (54 and 64 blocks by the two clocks; a producer's state read once and kept makes none)
    assert fast["made_here"][2] > 45


def test_pump_takes_messages_in_pieces_and_leaves_the_handlers(monkeypatch: pytest.MonkeyPatch,
                                                               tmp_path: Path) -> None:
    """Bytes split anywhere, several messages in one read, a message for the handler among them: the
    DUT gets the same bytes as from the handler alone, and pump's reads covered every message."""
    script = _script()
    stream = b"".join(script)
    cuts = [b"".join(script[:k]) for k in range(0, len(script), 5)]
    # pieces: five messages at a time, each cut 3 bytes into the next
    pieces = [stream[max(0, len(c) - 3):len(n) - 3] for c, n in zip(cuts, cuts[1:], strict=False)]
    pieces.append(stream[len(cuts[-1]) - 3:])
    assert b"".join(pieces) == stream
    py = _fly(monkeypatch, tmp_path, True, 0)
    pumped = _fly(monkeypatch, tmp_path, False, 0, script=pieces, pump=True)
    assert pumped["handled"] > 300
    assert pumped["pumped"] > len(stream) // 2
    _same(py, pumped)


def _i2c_statuses(replies: bytes) -> list[int]:
    """The status of each I2C reply, from the bytes the DUT received."""
    statuses, off = [], 0
    while off < len(replies):
        length, mtype, status, _ = P.HEADER.unpack_from(replies, off)
        if mtype == P.MSG_I2C:
            statuses.append(status)
        off += P.HEADER.size + length
    return statuses


def _wake_reasons(replies: bytes) -> list[int]:
    """Why each WAIT reply woke the DUT, from the bytes it received."""
    reasons, off = [], 0
    while off < len(replies):
        length, mtype, _, _ = P.HEADER.unpack_from(replies, off)
        if mtype == P.MSG_WAIT:
            reasons.append(struct.unpack_from("<I", replies, off + P.HEADER.size)[0])
        off += P.HEADER.size + length
    return reasons


def _same(py: dict[str, Any], fast: dict[str, Any]) -> None:
    for key in py:
        if key not in ("handled", "pumped", "fast_waits", "made_here"):
            assert fast[key] == py[key], key


@pytest.mark.parametrize("pump", [False, True])
def test_events_a_wait_crosses_run_as_the_handler_runs_them(monkeypatch: pytest.MonkeyPatch,
                                                            tmp_path: Path, pump: bool) -> None:
    """A recorder and serial frames in sim time, as in a flight: the waits that cross them stay the fast
    path's (every one of the 60), and the events see, and the DUT gets, what they do from the handler:
    the same times, the same world, the same frames, a polling wait woken at the same frame."""
    py = _fly(monkeypatch, tmp_path, True, 0, events=True)
    fast = _fly(monkeypatch, tmp_path, False, 0, events=True, pump=pump)
    assert len(py["events"]) > 30 and len(py["serial"]) > 25 * 40 and py["error"] is None
    assert P.WAKE_EVENT in _wake_reasons(py["received"])  # a polling wait woke at a frame
    _same(py, fast)
    assert fast["fast_waits"] == 60


def test_an_event_that_fails_in_a_fast_wait_ends_the_run_as_in_the_handler(monkeypatch: pytest.MonkeyPatch,
                                                                          tmp_path: Path) -> None:
    py = _fly(monkeypatch, tmp_path, True, 0, events=True, fail_at=0.1)
    fast = _fly(monkeypatch, tmp_path, False, 0, events=True, fail_at=0.1, pump=True)
    assert py["error"] is not None and "a scenario's event went wrong" in py["error"][1]
    _same(py, fast)
    assert py["counts"][1] < 30  # the run ended at 0.1 s: the waits after it were not answered


def test_the_world_moved(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """(The comparison above is not of two idle worlds: the motors ran and the clock went on.)"""
    fast = _fly(monkeypatch, tmp_path, False, 0)
    assert fast["plant_ns"] > 300_000_000 and fast["clock"] >= fast["plant_ns"]
    assert fast["pwm"][1][2] == 1_100_000 + 10_000 * 59 + 1000
    assert fast["pwm"][1][4] and not fast["pwm"][2][3]


BAD = {
    "no messages": _msg(20_000_000, P.I2C_HEAD.pack(1, 0), P.MSG_I2C),
    "43 messages": _msg(20_000_000, P.I2C_HEAD.pack(1, 43) + P.I2C_MSG.pack(0x68, 0, 0, 0) * 43, P.MSG_I2C),
    "short write": _msg(20_000_000, P.I2C_HEAD.pack(1, 1) + P.I2C_MSG.pack(0x68, 0, 3, 0) + b"\x3b",
                        P.MSG_I2C),
    "bytes after": _msg(20_000_000, _i2c(0, [(0x68, 0, 1, b"\x3b")])[P.HEADER.size:] + b"\x00", P.MSG_I2C),
    "read too long": _i2c(20_000_000, [(0x68, P.I2C_M_RD, P.I2C_MAX_LEN + 1, b"")]),
    "pwm short": _msg(20_000_000, P.PWM_MSG.pack(0, 0, P.PWM_DUTY, 0, 5)[:-1], P.MSG_PWM),
    "pwm channel": _pwm(20_000_000, 9, P.PWM_DUTY, 1_000_000),
    "ahead forever": _wait(20_000_000, P.WAIT_FOREVER, P.WAIT_AHEAD),
    "wait short": _msg(20_000_000, P.WAIT_MSG.pack(0, P.WAIT_SLEEP, 0)[:-4], P.MSG_WAIT),
    "type 9": _msg(20_000_000, b"", 9),
}


@pytest.mark.parametrize("name", sorted(BAD))
def test_malformed_messages_are_the_handlers(monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
                                             name: str) -> None:
    """What the fast path does not take goes to the handler, which drops the connection and says why."""
    script = _script()[:60] + [BAD[name]]
    py = _fly(monkeypatch, tmp_path, True, 0, script)
    fast = _fly(monkeypatch, tmp_path, False, 0, script)
    assert len(py["why"]) == 1 and fast["why"] == py["why"]
    assert fast["received"] == py["received"] and fast["log"] == py["log"]


def test_the_entry_points_refuse_wrong_arguments(tmp_path: Path) -> None:
    m = lockstep.module()
    with pytest.raises(TypeError, match="16 arguments"):
        m.setup(1, 2)
    with pytest.raises(ValueError, match="PyCapsule"):  # not a fast path's state
        m.handle(object(), 0, bytearray(), 0)
    session = Session(SessionConfig(command=["true"]), World.at_rest())
    session.open_page(tmp_path / "shm")
    assert session.fast is not None
    state = session.fast._state
    with pytest.raises(TypeError, match="bytearray"):
        m.handle(state, 0, b"", 0)
    with pytest.raises(ValueError, match="outside the buffer"):
        m.handle(state, 0, bytearray(4), 5)
    with pytest.raises(TypeError, match="6 arguments"):
        m.pump(state, 0)
    with pytest.raises(TypeError, match="3 arguments"):
        m.setup_events(state)
    with pytest.raises(TypeError, match="run_next and a dict"):
        m.setup_events(state, print, [])
    with pytest.raises(TypeError, match="bytearray"):
        m.pump(state, 0, 0, b"", (), 0)
    with pytest.raises(OverflowError):
        m.pump(state, 0, 0, bytearray(), (), -1)  # (a spin of negative time)
    bad: list[Any] = [[], ((0, b""),), ((0,),), (("0", bytearray()),)]
    for ptys in bad:
        with pytest.raises(TypeError, match=r"\(fd, bytearray\) pairs"):
            m.pump(state, 0, 0, bytearray(), ptys, 0)
    with pytest.raises(TypeError, match="19 arguments"):
        m.setup_mag(state)
    with pytest.raises(TypeError, match="13 arguments"):
        m.setup_baro(state)
    with pytest.raises(TypeError, match="fault list is a list"):
        m.setup_mag(state, *[0] * 18)
    with pytest.raises(TypeError, match="fault list is a list"):
        m.setup_baro(state, *[0] * 12)
    with pytest.raises(ValueError, match="2 columns and 10 conversion times"):
        m.setup_baro(state, 0, 0, [], 0, 0, 256, 1, 1, 1, [0], [0.0] * 10, 1)
    with pytest.raises(ValueError, match="history and step must be set"):
        m.setup_baro(state, 0, 0, [], 0, 0, 256, 0, 8, 1_000_000, [0, 1], [1e-3] * 10, 1)
    with pytest.raises(AttributeError, match="addr"):  # (a channel that is none)
        m.setup_mag(state, 0, 0, [], 0, 0, 256, 1, 8, 1_000_000, 0, [75.0] * 8, [0, 1, 2], [0.0] * 3,
                    0.0, 0.0, 1, 1, 1)
    with pytest.raises(ValueError, match="PyCapsule"):
        m.made_here(object())
    assert m.made_here(state) == (0, 0, 0)  # (nothing read yet)
    a, b = socket.socketpair()
    with a, b:
        b.close()  # the connection ended before anything came: the loop's own read takes it
        buf = bytearray(b"abc")
        assert m.pump(state, a.fileno(), -1, buf, (), 0) == -1 and buf == b"abc"


def test_the_pending_count_is_the_ptys_own() -> None:
    """lockstep.pending_input (C, what serial_write asks in lockstep) against the session's Python
    count over a pty's bytes as they are written and read; a closed descriptor and a non-int refused."""
    pending = lockstep.pending_input()
    master, slave = os.openpty()
    try:
        tty.setraw(slave)
        for written in (0, 25, 125):
            os.write(master, b"x" * (written - _pending_input(slave)))
            # the pty hands bytes over asynchronously: between two Python counts the C one lies between
            before = _pending_input(slave)
            ours = pending(slave)
            assert before <= ours <= _pending_input(slave)
            for _ in range(100_000):  # (until the handover is done, as Session.deliver_serial waits)
                if _pending_input(slave) == written:
                    break
                os.sched_yield()
            assert pending(slave) == _pending_input(slave) == written
        os.read(slave, 30)
        assert pending(slave) == _pending_input(slave) == 95
    finally:
        os.close(master)
        os.close(slave)
    with pytest.raises(OSError):
        pending(slave)
    with pytest.raises(OSError):
        pending(-1)
    with pytest.raises(TypeError):
        pending("0")  # type: ignore[arg-type]


def test_pump_reads_the_duts_ptys_in_the_loops_place(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """The DUT writes a line to its pty while pump reads its connection: pump reads the line into the
    pty's bytes not yet stamped, after those there already, and goes on with the connection (it went back
    to the loop for it before: a wake of the loop about every third FC cycle of the reference FC). The
    DUT's replies are the handler's."""
    lines = [b"t=0.010 roll=0.1\n", b"t=0.014 roll=0.2\n"]
    cycles = [_i2c(10_000_000 + k * CYCLE_NS, [(0x68, 0, 1, b"\x3b"), (0x68, P.I2C_M_RD, 14, b"")])
              for k in range(2)]
    replies = []
    for py_path in (True, False):
        monkeypatch.setenv(lockstep.PY_PATH_ENV, "1" if py_path else "0")
        session = Session(SessionConfig(command=["true"]), World.at_rest(seed=3))
        session.open_page(tmp_path / f"shm-{py_path}")
        fast = session.fast
        assert (fast is None) == py_path
        master, slave = os.openpty()
        tty.setraw(slave)
        os.set_blocking(master, False)
        pending = bytearray(b"earlier ")
        ours, dut = socket.socketpair()
        with ours, dut, selectors.EpollSelector() as sel:
            sel.register(ours, selectors.EVENT_READ, "conn")
            sel.register(master, selectors.EVENT_READ, "pty")
            got = bytearray()
            for cycle, line in zip(cycles, lines, strict=True):
                dut.sendall(cycle)
                os.write(slave, line)
                select.select([master], [], [], 10.0)  # (the pty hands bytes over in a kernel worker)
                if fast is None:
                    handler = session.handler
                    assert handler is not None
                    hdr = P.Header.parse(cycle, 0)
                    handler.handle(Conn(ours, 1, hello=True), hdr, cycle[P.HEADER.size:])
                else:
                    buf = bytearray()
                    # the cycle's bytes, and the line read in C: pump returned for neither
                    assert fast.pump(ours.fileno(), sel.fileno(), buf, ((master, pending),)) == len(cycle)
                    assert buf == b""
                got += dut.recv(1 << 16)
            replies.append(bytes(got))
        os.close(master)
        os.close(slave)
    assert pending == b"earlier " + b"".join(lines)
    assert replies[0] == replies[1] and len(replies[0]) > 2 * 14


def _result(run_dir: Path) -> dict[str, Any]:
    data: dict[str, Any] = json.loads((run_dir / "result.json").read_text())
    meta = data["metadata"]
    for volatile in ("started", "wall_time", "realtime_factor"):
        meta.pop(volatile, None)
    return data


def test_a_flight_is_the_same_either_way(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    from rig import api

    results = []
    for py_path in (True, False):
        monkeypatch.setenv(lockstep.PY_PATH_ENV, "1" if py_path else "0")
        before = lockstep.handled_total()
        r = api.run("fault_mag_nack", seed=2, out=tmp_path / f"py{py_path}")
        went_fast = lockstep.handled_total() - before
        assert (went_fast == 0) if py_path else (went_fast > 1000)
        results.append((_result(r.run_dir), (r.run_dir / "telemetry.csv").read_bytes()))
    (py_json, py_csv), (fast_json, fast_csv) = results
    # how the messages came differs, and says so: only the fast path serves a mailbox
    py_way, fast_way = py_json["metadata"].pop("transport"), fast_json["metadata"].pop("transport")
    assert (py_way["mailboxes"], fast_way["mailboxes"]) == (0, fast_way["connections"])
    for data in (py_json, fast_json):  # (the folders differ by name)
        meta = data["metadata"]
        data["metadata"] = {k: v for k, v in meta.items() if not isinstance(v, str) or "/py" not in v}
    assert fast_json == py_json
    assert fast_csv == py_csv


def test_status_numbers() -> None:
    """(The statuses asserted above by number are Linux's errnos.)"""
    import errno

    assert (errno.ENXIO, errno.ENODEV, errno.EPROTO) == (6, 19, 71)
    assert struct.calcsize("<IHHQ") == P.HEADER.size


def test_attributes_read_by_their_descriptor_are_what_getattr_reads() -> None:
    """The fast path reads the attributes it needs each cycle through their type's getset descriptor,
    cached per type and name (attrs.c): the same values as getattr for a compiled class's attributes,
    plain objects, properties and __getattr__, and a class changed after a read is read anew (a cache
    that ignored the type's version would still give the old route's value)."""
    attr = lockstep.module().attr
    world = World.at_rest(noise=False)
    try:
        world.advance_to(8_000_000)
        for name in ("_k", "step_ns", "direct_pwm", "pwm"):
            assert attr(world, name) == getattr(world, name)
            assert attr(world, name) == getattr(world, name)  # (now from the cache)
    finally:
        world.close()

    class Plain:
        def __init__(self) -> None:
            self.x = 1

        @property
        def doubled(self) -> int:
            return 2 * self.x

    class Lazy:
        def __getattr__(self, name: str) -> str:
            return name.upper()

    p = Plain()
    assert (attr(p, "x"), attr(p, "doubled"), attr(Lazy(), "abc")) == (1, 2, "ABC")
    assert attr(p, "__weakref__") is None  # a getset descriptor of a Python class: the cached route
    setattr(Plain, "__weakref__", property(lambda self: "replaced"))  # noqa: B010 (a test's patch)
    assert getattr(p, "__weakref__") == "replaced" and attr(p, "__weakref__") == "replaced"  # noqa: B009
    with pytest.raises(AttributeError):
        attr(p, "missing")
    with pytest.raises(TypeError, match="an object and a name"):
        attr(p, 5)
