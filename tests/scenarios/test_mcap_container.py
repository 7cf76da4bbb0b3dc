"""reports/mcap_container.py against the ``mcap`` package's own ``Writer`` (the second implementation):
the same calls on both give the same bytes (ours also with its messages added many to a call), over
one chunk and many, schemas and channels that fill a chunk before any message, metadata between
messages, times out of order and at the ends of their range, and empty messages; and the package's
reader reads the file back with its CRCs checked."""

from __future__ import annotations

import io
import random
from collections.abc import Callable
from typing import Any

import pytest
from mcap.reader import make_reader
from mcap.writer import Writer

from rig.reports.mcap_container import CHUNK_SIZE, ContainerWriter

Call = tuple[str, tuple[Any, ...]]


def _calls(seed: int, messages: int, big: bool) -> list[Call]:
    rng = random.Random(seed)
    calls: list[Call] = [("start", ("", "rig test"))]
    for k in range(1, 4):
        calls.append(("register_schema", (f"s{k}", "jsonschema", rng.randbytes(300))))
    for k in range(1, 6):
        calls.append(("register_channel", (f"/t{k}", "json", rng.randint(1, 3))))
    seq = [0] * 6
    for i in range(messages):
        if rng.random() < 0.002:
            calls.append(("add_metadata", (f"m{i}", {"k": str(i), "e": ""})))
        ch = rng.randint(1, 5)
        t = rng.choice([0, 2**64 - 1, rng.randrange(10**10), 10**6 * i])
        size = rng.choice([0, 1, 40, 160]) if not big else rng.randrange(2000, 9000)
        calls.append(("add_message", (ch, t, rng.randbytes(size), t, seq[ch])))
        seq[ch] += 1
    calls.append(("add_metadata", ("result", {"a": "1"})))
    calls.append(("finish", ()))
    return calls


def _batched(calls: list[Call], seed: int) -> list[Call]:
    """The same calls with runs of ``add_message`` made as ``add_messages`` of random lengths (1-500)."""
    rng = random.Random(seed)
    out: list[Call] = []
    for name, args in calls:
        open_batch = out and out[-1][0] == "add_messages" and len(out[-1][1][0]) < rng.randint(1, 500)
        if name == "add_message" and open_batch:
            out[-1][1][0].append(args)
        elif name == "add_message":
            out.append(("add_messages", ([args],)))
        else:
            out.append((name, args))
    return out


def _write(make: Callable[[io.BytesIO], Any], calls: list[Call]) -> bytes:
    out = io.BytesIO()
    w = make(out)
    for name, args in calls:
        getattr(w, name)(*args)
    return out.getvalue()


@pytest.mark.parametrize(("seed", "messages", "big", "chunk_size"), [
    (0, 1, False, CHUNK_SIZE),      # one message, one chunk
    (1, 3000, False, CHUNK_SIZE),   # one chunk
    (2, 3000, False, 2000),         # many small chunks; the schemas and channels alone overflow the first
    (3, 800, True, CHUNK_SIZE),     # several chunks of the default size
])
def test_the_container_is_the_package_writer_s_byte_for_byte(seed: int, messages: int, big: bool,
                                                            chunk_size: int) -> None:
    calls = _calls(seed, messages, big)
    ours = _write(lambda out: ContainerWriter(out, chunk_size=chunk_size), calls)
    theirs = _write(lambda out: Writer(out, chunk_size=chunk_size), calls)
    assert ours == theirs
    batched = _batched(calls, seed)
    batches = sum(name == "add_messages" for name, _ in batched)
    assert batches < messages or messages == 1
    assert _write(lambda out: ContainerWriter(out, chunk_size=chunk_size), batched) == theirs
    reader = make_reader(io.BytesIO(ours), validate_crcs=True)
    summary = reader.get_summary()
    assert summary is not None and summary.statistics is not None
    assert summary.statistics.message_count == messages
    chunks = len(summary.chunk_indexes)
    assert chunks == 1 if chunk_size == CHUNK_SIZE and not big else chunks > 2
    got = [(m.channel_id, m.sequence, m.data) for _, _, m in reader.iter_messages(log_time_order=False)]
    sent = [(a[0], a[4], a[2]) for name, a in calls if name == "add_message"]
    assert got == sent
