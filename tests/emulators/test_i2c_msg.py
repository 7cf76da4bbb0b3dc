"""A transfer's message (emulators/i2c_bus.Msg) refuses what no I2C_RDWR message can be, and compares by
value (traces and tests compare the messages they parse)."""

from __future__ import annotations

import pytest

from rig.emulators.i2c_bus import Msg, read, write


@pytest.mark.parametrize(("args", "why"), [
    ((0x80,), "0x80 is not a 7-bit address"),
    ((-1,), "is not a 7-bit address"),
    ((0x68, True, b"\x3b", 1), "a read message has a length and no data"),
    ((0x68, True, b"", -1), "a read message has a length and no data"),
    ((0x68, False, b"\x3b", 0, True), "only a read message can take its length"),
])
def test_impossible_messages_are_refused(args: tuple, why: str) -> None:
    with pytest.raises(ValueError, match=why):
        Msg(*args)


def test_messages_compare_and_hash_by_value() -> None:
    assert write(0x68, 0x3B) == Msg(0x68, False, b"\x3b")
    assert read(0x68, 14) == Msg(0x68, True, b"", 14)
    assert read(0x68, 14) != read(0x68, 6)
    assert Msg(0x50, True, b"", 0, True) != Msg(0x50, True, b"", 0, False)
    assert write(0x1E, 0x03) != (0x1E, False, b"\x03", 0, False)  # not a tuple any more
    assert len({write(0x68, 1), write(0x68, 1), read(0x68, 1)}) == 2
    assert repr(read(0x1E, 6)) == "Msg(addr=0x1e, read=True, data=b'', length=6, recv_len=False)"
