"""The host's end of the link over a real pty: the test holds the other end and plays the bridge's wire
with the real codec (the virtual bridge's own tests run the real bridge)."""

from __future__ import annotations

import os
import pty
from collections.abc import Iterator

import pytest

from rig.bridge.link import Decoded, Receiver, encode
from rig.bridge.messages import PROTOCOL_VERSION
from rig.bridge.port import BridgeError, BridgePort, bridge_id


class FakeClock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def wire() -> Iterator[tuple[int, str]]:
    master, slave = pty.openpty()
    name = os.ttyname(slave)
    os.close(slave)
    yield master, name
    os.close(master)


def read_down(master: int) -> list[Decoded]:
    rx = Receiver("down")
    msgs: list[Decoded] = []
    while not msgs:
        msgs = rx.feed(os.read(master, 4096))
    return msgs


def test_hello_returns_the_bridges_identity(wire: tuple[int, str]) -> None:
    master, name = wire
    port = BridgePort(name)
    # the reply is written before hello() reads, so it waits for nothing
    os.write(master, encode("HELLO_REPLY", 0, version=PROTOCOL_VERSION, nonce=0, bridge_id=b"wrong-nonce"))
    port.send("HEARTBEAT")
    assert [m.name for m in read_down(master)] == ["HEARTBEAT"]

    # answer the HELLO the port sends, from another thread of control: a child process
    pid = os.fork()
    if pid == 0:  # the bridge
        try:
            hello = read_down(master)[0]
            os.write(master, encode("HELLO_REPLY", 0, version=PROTOCOL_VERSION,
                                    nonce=hello.values["nonce"], bridge_id=b"vbridge-test"))
        finally:
            os._exit(0)
    reply = port.hello(timeout_s=5.0)
    os.waitpid(pid, 0)
    assert bridge_id(reply) == "vbridge-test"
    port.close()


def test_a_bridge_speaking_another_protocol_is_refused(wire: tuple[int, str]) -> None:
    master, name = wire
    port = BridgePort(name)
    pid = os.fork()
    if pid == 0:
        try:
            hello = read_down(master)[0]
            os.write(master, encode("HELLO_REPLY", 0, version=PROTOCOL_VERSION + 1,
                                    nonce=hello.values["nonce"]))
        finally:
            os._exit(0)
    with pytest.raises(BridgeError, match=f"speaks protocol {PROTOCOL_VERSION + 1}"):
        port.hello(timeout_s=5.0)
    os.waitpid(pid, 0)
    port.close()


def test_no_answer_is_an_error_naming_the_port(wire: tuple[int, str]) -> None:
    _, name = wire
    port = BridgePort(name)
    with pytest.raises(BridgeError, match=f"no bridge answered on {name}"):
        port.hello(timeout_s=0.2)
    port.close()


def test_a_bridge_that_falls_silent_is_an_error_after_the_limit(wire: tuple[int, str]) -> None:
    master, name = wire
    clock = FakeClock()
    port = BridgePort(name, silent_after_s=0.5, clock=clock)
    os.write(master, encode("STATUS", 0))
    assert [m.name for m in port.poll(5.0)] == ["STATUS"]
    clock.t += 0.4
    assert port.poll() == []  # quiet, but not yet for long
    os.write(master, b"\x11\x22\x00")  # noise is not a sign of life
    clock.t += 0.2
    with pytest.raises(BridgeError, match=r"no valid frame for 0\.60 s \(1 bad frames\)"):
        port.poll(5.0)
    port.close()


def test_a_bridge_that_hangs_up_is_an_error_at_once() -> None:
    # a pty of its own, not the fixture's: the fixture would close the master a second time, and that
    # number may be another descriptor's by then
    master, slave = pty.openpty()
    name = os.ttyname(slave)
    os.close(slave)
    port = BridgePort(name)
    os.close(master)
    with pytest.raises(BridgeError, match="hung up"):
        port.poll(5.0)
    port.close()


def test_a_port_that_does_not_exist() -> None:
    with pytest.raises(BridgeError, match="cannot open the bridge's port /dev/no-such-tty"):
        BridgePort("/dev/no-such-tty")


def test_a_send_after_close_is_an_error_and_writes_nowhere(wire: tuple[int, str]) -> None:
    """send writes to the port's descriptor itself: once the port is closed that number may be another
    file's (here a pipe's, put there after), and a frame sent then must not reach it."""
    _, name = wire
    port = BridgePort(name)
    fd = port.fileno()
    r, w = os.pipe()
    port.close()
    os.dup2(w, fd)  # (the number the port had, now the pipe's writing end)
    try:
        with pytest.raises(BridgeError, match="failed sending IMU_SAMPLE"):
            port.send("IMU_SAMPLE", valid_us=1)
        os.set_blocking(r, False)
        with pytest.raises(BlockingIOError):
            os.read(r, 100)
    finally:
        for k in (r, w, fd):
            os.close(k)
