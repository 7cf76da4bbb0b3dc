"""The bench's CAN capture reader (rig/bridge/can_capture.py) on python-can's real slcan interface over a
real pty, fed what a capture device and a bad cable send: good frames move the motors, every bad one
(an unparsable line, an unknown id, a short frame, a wrong CRC) is counted and moves nothing, a lost
frame shows as a sequence gap. The frames are the DBC's, made by the lockstep capture's codec."""

from __future__ import annotations

import contextlib
import os
import random
import time
import tty
from collections.abc import Callable, Iterator

import can
import pytest
from can.interfaces.slcan import slcanBus

from rig.bridge.can_capture import BatchedSlcan, CanPulses, parse
from rig.bridge.esc import ESC_PROTOCOLS
from rig.bridge.port import BridgeError
from rig.emulators.pwm_capture import CanCodec
from rig.world import World
from tests.waits import BOUND_S


def slcan(fid: int, data: bytes) -> bytes:
    return f"t{fid:03X}{len(data)}{data.hex().upper()}\r".encode()


@pytest.fixture
def wire() -> Iterator[tuple[int, str]]:
    master, slave = os.openpty()
    tty.setraw(slave)
    name = os.ttyname(slave)
    os.close(slave)
    yield master, name
    os.close(master)


@pytest.fixture
def world() -> Iterator[World]:
    w = World.at_rest(seed=0)
    w.direct_pwm = False
    yield w
    w.close()


def motors(world: World) -> list[float]:
    return [world.plant.u[world.plant.u_index[f"pwm{m}_us"]] for m in range(1, 5)]


def pump(cap: CanPulses, world: World, applied: int, rejected: int, to_pwm_us: float = 1.0) -> None:
    """Polls until so many frames were applied and rejected (a pty hands bytes over asynchronously)."""
    deadline = time.monotonic() + BOUND_S
    while (cap.figures.applied, cap.figures.rejected) < (applied, rejected) and time.monotonic() < deadline:
        cap.poll(world, to_pwm_us)


def test_good_frames_move_the_motors_and_bad_ones_are_counted_and_ignored(wire: tuple[int, str],
                                                                          world: World) -> None:
    master, name = wire
    codec = CanCodec()
    cap = CanPulses("slcan", name)
    try:
        good = codec.encode(7, [1100.0, 1200.0, 1300.0, 1400.0])
        os.write(master, b"".join(slcan(fid, data) for fid, data in good))
        pump(cap, world, 2, 0)
        assert motors(world) == pytest.approx([1100.0, 1200.0, 1300.0, 1400.0])
        fid, data = codec.encode(8, [1900.0, 1900.0, 1900.0, 1900.0])[0]
        bad_crc = bytes(data[:6]) + bytes([data[6] ^ 0x01, data[7]])
        os.write(master, slcan(fid, bad_crc) + slcan(0x123, bytes(data)) + slcan(fid, bytes(data[:5]))
                 + b"tZZZ8\r" + b"t21\r")
        pump(cap, world, 2, 5)
        assert motors(world) == pytest.approx([1100.0, 1200.0, 1300.0, 1400.0])  # nothing applied
        assert cap.figures.applied == 2
        assert cap.figures.rejected == 5, cap.figures.reasons
        assert any("CRC" in r for r in cap.figures.reasons)
        assert any("unknown CAN id" in r for r in cap.figures.reasons)
        # seq 8 never arrived whole: the next report (9) is a gap for both frames
        os.write(master, b"".join(slcan(f, d) for f, d in codec.encode(9, [1500.0] * 4)))
        pump(cap, world, 4, 5)
        assert motors(world) == pytest.approx([1500.0] * 4)
        assert cap.figures.seq_gaps == 2
    finally:
        cap.close()


def test_oneshot125_widths_from_can_are_scaled_into_the_plants_pwm(wire: tuple[int, str],
                                                                   world: World) -> None:
    master, name = wire
    cap = CanPulses("slcan", name)
    try:  # OneShot125's 125..250 us is standard PWM's 1000..2000 us divided by eight
        os.write(master, b"".join(slcan(f, d) for f, d in CanCodec().encode(1, [125.0, 150.0, 187.5, 250.0])))
        pump(cap, world, 2, 0, ESC_PROTOCOLS["oneshot125"].to_pwm_us)
        assert motors(world) == pytest.approx([1000.0, 1200.0, 1500.0, 2000.0], abs=0.8)
    finally:
        cap.close()


def test_a_capture_interface_that_cannot_open_is_a_clear_error(tmp_path: pytest.TempPathFactory) -> None:
    with pytest.raises(BridgeError, match="cannot open 'slcan' channel"):
        CanPulses("slcan", "/nonexistent/ttyCAN")
    with pytest.raises(ValueError, match="INTERFACE:CHANNEL"):
        parse("can0")


def _read_all(bus: can.BusABC, want: int) -> list[object]:
    """What ``want`` reads of ``bus`` gave: (id, data) of each frame, or the error's type (bounded wait)."""
    got: list[object] = []
    deadline = time.monotonic() + BOUND_S
    while len(got) < want and time.monotonic() < deadline:
        try:
            msg = bus.recv(timeout=0.0)
        except can.CanError as e:
            got.append(type(e).__name__)
            continue
        if msg is not None:
            got.append((msg.arbitration_id, bytes(msg.data), msg.is_extended_id, msg.is_remote_frame))
    return got


@contextlib.contextmanager
def _pty_bus(make: Callable[[str], can.BusABC]) -> Iterator[tuple[int, can.BusABC]]:
    master, slave = os.openpty()
    tty.setraw(slave)
    bus = make(os.ttyname(slave))
    try:
        yield master, bus
    finally:
        bus.shutdown()
        os.close(master)
        os.close(slave)


def _batched(name: str) -> can.BusABC:
    return BatchedSlcan(channel=name, sleep_after_open=0.0, timeout=0.0)


def test_the_batched_slcan_reader_reads_what_python_cans_own_reads() -> None:
    """BatchedSlcan reads the port a batch at a time (the interface's own read took a byte per call, and
    waited 1 ms for a line not yet whole); python-can's own slcanBus, the second implementation, reads
    the same bytes, written in pieces that cut lines anywhere: the same frames, the same errors."""
    rng = random.Random(11)
    codec = CanCodec()
    lines = [slcan(f, d) for s in range(40) for f, d in codec.encode(s, [1000.0 + 10 * s] * 4)]
    lines += [b"T1234567F4DEADBEEF\r", b"r1230\r", b"\a", b"t1FF0\r", b"t0018" + b"00" * 8 + b"\r"]
    rng.shuffle(lines)
    stream = b"".join(lines)
    cuts = sorted(rng.sample(range(1, len(stream)), 60))
    pieces = [stream[a:b] for a, b in zip([0, *cuts], [*cuts, len(stream)], strict=True)]
    results = []
    for make in (_batched, lambda name: slcanBus(channel=name, sleep_after_open=0.0)):
        with _pty_bus(make) as (master, bus):
            got: list[object] = []
            for piece in pieces:  # (each piece read before the next: a line cut anywhere)
                os.write(master, piece)
                got += _read_all(bus, piece.count(b"\r"))  # (a BEL line is an error reply, no frame)
            results.append(got)
    ours, theirs = results
    assert ours == theirs
    assert len(ours) == len(lines) - 1  # (every line but the BEL)
    ids = {f for f, _ in codec.encode(0, [1000.0] * 4)}
    assert sum(isinstance(r, tuple) and r[0] in ids for r in ours) == 80


def test_a_line_that_is_not_text_costs_only_itself() -> None:
    """A line of bytes that are not UTF-8 is an error, and the next line is read as it is (python-can's
    own read kept such bytes in its buffer, and the next line failed with them)."""
    fid, data = CanCodec().encode(3, [1200.0] * 4)[0]
    with _pty_bus(_batched) as (master, bus):
        os.write(master, b"t10\xff\xfe2\r" + slcan(fid, bytes(data)))
        assert _read_all(bus, 2) == ["CanOperationError", (fid, bytes(data), False, False)]
