"""How the host reads the virtual bridge's start line (the bridge itself: tests/bridge/test_vbridge.py)."""

from __future__ import annotations

import pytest

from rig.bridge.port import BridgeError
from rig.bridge.vbridge import Endpoints, parse_endpoints


def test_the_endpoints_line() -> None:
    line = "vbridge link=/dev/pts/7 board=/tmp/vb/board.sock shm=/tmp/vb/shm rc=/dev/pts/8\n"
    assert parse_endpoints(line) == Endpoints("/dev/pts/7", "/tmp/vb/board.sock", "/tmp/vb/shm", "/dev/pts/8")


@pytest.mark.parametrize(("line", "why"), [
    ("", "not its endpoints"),
    ("listening on /dev/pts/7", "not its endpoints"),
    ("vbridge link=/dev/pts/7 board=/tmp/b", "did not name its shm, rc"),
    ("vbridge link= board=x shm=y rc=z", "did not name its link"),
])
def test_a_line_that_is_not_one_is_refused(line: str, why: str) -> None:
    with pytest.raises(BridgeError, match=why):
        parse_endpoints(line)
