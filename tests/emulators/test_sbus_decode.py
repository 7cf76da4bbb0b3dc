"""The SBUS decoder is the encoder's exact inverse (the bench host decodes the stick emulator's frames
and the bridge encodes them again), and refuses what is not a frame."""

from __future__ import annotations

import random

import pytest

from rig.emulators.sbus import FLAG_FAILSAFE, FLAG_FRAME_LOST, decode, encode


@pytest.mark.parametrize("seed", range(20))
def test_decode_inverts_encode(seed: int) -> None:
    rnd = random.Random(seed)
    channels = [rnd.randrange(2048) for _ in range(16)]
    lost, failsafe = rnd.random() < 0.5, rnd.random() < 0.5
    got, flags = decode(encode(channels, frame_lost=lost, failsafe=failsafe))
    assert got == channels
    assert flags == (FLAG_FRAME_LOST if lost else 0) | (FLAG_FAILSAFE if failsafe else 0)


def test_the_extreme_bits_of_the_packing() -> None:
    """Channel 1's low bit is byte 1's bit 0; channel 16's top bit is byte 22's bit 7."""
    frame = bytearray(encode([0] * 16))
    frame[1] |= 0x01
    frame[22] |= 0x80
    channels, _ = decode(bytes(frame))
    assert channels[0] == 1 and channels[15] == 0x400 and channels[1:15] == [0] * 14


@pytest.mark.parametrize("frame", [b"", bytes(25), encode([992] * 16)[:-1], encode([992] * 16) + b"\0",
                                   b"\x0f" + bytes(23) + b"\x01"])
def test_what_is_not_a_frame_is_refused(frame: bytes) -> None:
    with pytest.raises(ValueError, match="not an SBUS frame"):
        decode(frame)
