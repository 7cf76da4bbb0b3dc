"""The bridge link (docs/design.md §8 "Link"), its two implementations held against each other: the
host's codec (rig/bridge/link.py) and the bridge's (bridge/core/link.c, with the header generated from
the same table). Every message of the table round-trips through both with the same values and the same
bytes; streams of random and mutated frames are rejected and counted, identically, and nothing that was
not sent is ever decoded. Every test runs on the host and on a Cortex-M4 under QEMU (the STM32G431's
core), whose output must equal the host build's byte for byte (tests/bridge/tools.py)."""

from __future__ import annotations

import json
import random
import struct

import pytest

from rig.bridge.link import Receiver, crc16, encode, encode_flat
from rig.bridge.messages import MESSAGES, Direction, Message
from tests.bridge.tools import Tool, link_tools


@pytest.fixture(scope="module", params=["host", "cortex-m4"])
def tool(request: pytest.FixtureRequest) -> Tool:
    return link_tools(request.param)


def c_side(tool: Tool, mode: str, direction: str, wire: bytes) -> list[str]:
    return tool.run_bytes(wire, (mode, direction)).decode().splitlines()


def f32(x: float) -> float:
    return struct.unpack("<f", struct.pack("<f", x))[0]


def parsed(line: str) -> dict[str, object]:
    """A C-printed message; its floats (printed with 9 digits, enough for a binary32) read back exactly."""
    out = json.loads(line)
    msg = next(m for m in MESSAGES if m.name == out["name"])
    for f in msg.fields:
        if f.type == "f32":
            out[f.name] = [f32(v) for v in out[f.name]] if f.count > 1 else f32(out[f.name])
    return out


def random_values(msg: Message, rng: random.Random) -> dict[str, object]:
    def one(t: str) -> object:
        if t == "f32":
            return f32(rng.uniform(-1e4, 1e4))
        bits = {"u8": 8, "u16": 16, "u32": 32, "u64": 64, "i16": 16, "i32": 32}[t]
        if t.startswith("i"):
            return rng.randrange(-(1 << (bits - 1)), 1 << (bits - 1))
        return rng.randrange(1 << bits)
    return {f.name: [one(f.type) for _ in range(f.count)] if f.count > 1 else one(f.type) for f in msg.fields}


def test_the_crc_is_ccitt_false() -> None:
    assert crc16(b"123456789") == 0x29B1


def test_the_flat_encoder_makes_the_same_bytes_and_refuses_a_short_sample() -> None:
    """The stream's samples skip ``encode``'s checks by name (link.encode_flat): the same frames."""
    rng = random.Random(20261129)
    for msg in MESSAGES:
        for seq in (0, 7, 255, 300):
            values = random_values(msg, rng)
            flat: list[object] = []
            for f in msg.fields:
                v = values[f.name]
                flat += v if isinstance(v, list) else [v]
            assert encode_flat(msg, seq, flat) == encode(msg.name, seq, **values), msg.name
    imu = next(m for m in MESSAGES if m.name == "IMU_SAMPLE")
    with pytest.raises(struct.error):
        encode_flat(imu, 0, [1, 0.0, 0.0, 9.8, 0.0, 0.0])  # no gyro z, no temperature


@pytest.mark.parametrize("direction", ["down", "up"])
def test_every_message_means_the_same_on_both_sides(tool: Tool, direction: Direction) -> None:
    rng = random.Random(20261123)
    sent = []
    wire = b""
    for seq in range(300):
        msg = rng.choice([m for m in MESSAGES if m.direction == direction])
        values = random_values(msg, rng)
        sent.append({"name": msg.name, "seq": seq & 0xFF, **values})
        wire += encode(msg.name, seq, **values)
    *lines, counters = c_side(tool, "decode", direction, wire)
    assert [parsed(line) for line in lines] == sent  # the generated C decodes the table's layout
    assert json.loads(counters)["ok"] == 300 and json.loads(counters)["bad"] == 0
    # the bridge's encoder gives back the very bytes the host's encoder made
    assert bytes.fromhex("".join(c_side(tool, "reframe", direction, wire)[:-1])) == wire
    got = Receiver(direction).feed(wire)  # and the host decodes them back
    assert [{"name": m.name, "seq": m.seq, **m.values} for m in got] == sent


def mutate(frames: list[bytes], rng: random.Random) -> bytes:
    """Frames as a bad cable delivers them: bits flipped, bytes dropped or doubled, frames cut short,
    runs of noise, delimiters lost or added."""
    out = bytearray()
    for frame in frames:
        f = bytearray(frame)
        action = rng.randrange(8)
        if action == 0:
            f[rng.randrange(len(f))] ^= 1 << rng.randrange(8)
        elif action == 1:
            del f[rng.randrange(len(f))]
        elif action == 2:
            f.insert(rng.randrange(len(f)), rng.randrange(256))
        elif action == 3:
            f = f[: rng.randrange(1, len(f))] + b"\x00"
        elif action == 4:
            f = bytearray(rng.randbytes(rng.randrange(1, 300))) + f
        elif action == 5 and f[-1] == 0:
            f = f[:-1]  # the delimiter lost: two frames run together
        out += f
    return bytes(out)


@pytest.mark.parametrize("direction", ["down", "up"])
def test_random_and_mutated_frames_are_rejected_counted_and_never_applied(tool: Tool,
                                                                         direction: Direction) -> None:
    rng = random.Random(7)
    frames, sent = [], set()
    for seq in range(2000):
        msg = rng.choice([m for m in MESSAGES if m.direction == direction])
        values = random_values(msg, rng)
        frames.append(encode(msg.name, seq, **values))
        sent.add(json.dumps({"name": msg.name, "seq": seq & 0xFF, **values}, sort_keys=True))
    wire = mutate(frames, rng) + rng.randbytes(5000) + b"\x00"
    *lines, counters = c_side(tool, "decode", direction, wire)
    c_got = [json.dumps(parsed(line), sort_keys=True) for line in lines]
    host = Receiver(direction)
    py_got = [json.dumps({"name": m.name, "seq": m.seq, **m.values}, sort_keys=True) for m in host.feed(wire)]
    stats = json.loads(counters)
    assert set(c_got) <= sent and set(py_got) <= sent  # nothing decoded that was not sent
    assert c_got == py_got  # the two decoders agree frame by frame
    assert 200 < stats["ok"] < 2000 and stats["bad"] > 300  # good frames survive among the bad
    assert stats["ok"] == host.ok and stats["seq_gaps"] == host.seq_gaps


def test_a_frame_going_the_wrong_way_is_refused(tool: Tool) -> None:
    wire = encode("PULSES", 0, t_us=1, width_tenth_us=[15000, 15000, 15000, 15000])  # an up message
    *lines, counters = c_side(tool, "decode", "down", wire)
    assert lines == [] and json.loads(counters)["bad_direction"] == 1
    host = Receiver("down")
    assert host.feed(wire) == [] and host.reasons == ["PULSES goes up, not down"]
