"""run.mcap's container: the bytes the ``mcap`` package's ``Writer`` writes with its defaults (zstd chunks
of about 1 MiB, every index, the statistics, summary offsets and CRCs) for the calls reports/mcap.py
makes, with a message's record made in one ``struct.pack``.

Why: the package's ``Writer.add_message`` builds each message through a dataclass, its chunk builder
and a dozen small writes, about 43 k instructions a message (cachegrind), and a run has about 12 000
(every I2C transfer and the sensor readings decoded from them): the larger half of writing run.mcap,
itself as large a part of a sweep's run as the flight. Everything but the messages and their indexes is
written with the package's own record types (``mcap.records``), in the order its ``Writer`` writes
them. tests/scenarios/test_mcap_container.py makes the same calls on both and compares the bytes, so
a file from here is one the package would have written.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Iterable
from typing import IO, Final

import zstandard
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    McapRecord,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)
from mcap.writer import MCAP0_MAGIC

#: a Message record's head: opcode, record length, channel id, sequence, log time, publish time
_MESSAGE: Final = struct.Struct("<BQHIQQ")
_MESSAGE_BODY: Final = _MESSAGE.size - 9  # (the record length counts from the channel id)
#: a MessageIndex record's head: opcode, record length, channel id, length of its (time, offset) pairs
_INDEX_HEAD: Final = struct.Struct("<BQHI")
CHUNK_SIZE: Final = 1024 * 1024  # (the package's default)


def _record(record: McapRecord) -> bytes:
    """The bytes of one of the package's records."""
    builder = RecordBuilder()
    record.write(builder)
    return builder.end()


class ContainerWriter:
    """``mcap.writer.Writer``'s ``start``, ``register_schema``, ``register_channel``, ``add_message``,
    ``add_metadata`` and ``finish`` with its default options: the same file, byte for byte; and
    ``add_messages``, many ``add_message`` calls in one."""

    def __init__(self, out: IO[bytes], chunk_size: int = CHUNK_SIZE) -> None:
        self._out = out
        self._pos = out.tell()
        self._chunk_size = chunk_size
        self._schemas: list[Schema] = []
        self._channels: list[Channel] = []
        # the chunk being built: its records, their length, its messages' index by channel (empty: no
        # message yet), their times
        self._chunk: list[bytes] = []
        self._chunk_len = 0
        self._index: dict[int, list[int]] = {}  # channel -> flat (log time, offset in the chunk) pairs
        self._chunk_times = (0, 0)
        self._chunk_indexes: list[ChunkIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self._counts: dict[int, int] = {}  # messages by channel, in the order channels first had one
        self._times = (0, 0)

    def _write(self, data: bytes) -> None:
        self._out.write(data)
        self._pos += len(data)

    def start(self, profile: str, library: str) -> None:
        self._write(MCAP0_MAGIC)
        self._write(_record(Header(profile, library)))

    def _to_chunk(self, record: bytes) -> None:
        self._chunk.append(record)
        self._chunk_len += len(record)
        if self._chunk_len > self._chunk_size:
            self._finish_chunk()

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        schema = Schema(id=len(self._schemas) + 1, data=data, encoding=encoding, name=name)
        self._schemas.append(schema)
        self._to_chunk(_record(schema))
        return schema.id

    def register_channel(self, topic: str, message_encoding: str, schema_id: int) -> int:
        channel = Channel(id=len(self._channels) + 1, topic=topic, message_encoding=message_encoding,
                          schema_id=schema_id, metadata={})
        self._channels.append(channel)
        self._to_chunk(_record(channel))
        return channel.id

    def add_message(self, channel_id: int, log_time: int, data: bytes, publish_time: int,
                    sequence: int) -> None:
        self.add_messages(((channel_id, log_time, data, publish_time, sequence),))

    def add_messages(self, messages: Iterable[tuple[int, int, bytes, int, int]]) -> None:
        """``add_message`` for each (channel id, log time, data, publish time, sequence), in one loop:
        a call per message, with its two time windows widened by a function each, was about half of
        the container's cost."""
        pack, opcode, limit = _MESSAGE.pack, Opcode.MESSAGE, self._chunk_size
        counts = self._counts
        for channel_id, t, data, published, sequence in messages:
            if counts:
                start, end = self._times
                self._times = (t if t < start else start, t if t > end else end)
            else:
                self._times = (t, t if t > self._times[1] else self._times[1])
            counts[channel_id] = counts.get(channel_id, 0) + 1
            index = self._index
            if index:
                start, end = self._chunk_times
                self._chunk_times = (t if t < start else start, t if t > end else end)
            else:
                self._chunk_times = (t, t if t > self._chunk_times[1] else self._chunk_times[1])
            pairs = index.get(channel_id)
            if pairs is None:
                pairs = index[channel_id] = []
            pairs += (t, self._chunk_len)
            record = pack(opcode, _MESSAGE_BODY + len(data), channel_id, sequence, t, published) + data
            self._chunk.append(record)
            self._chunk_len += len(record)
            if self._chunk_len > limit:
                self._finish_chunk()

    def _finish_chunk(self) -> None:
        if not self._index:  # (no message: its schemas and channels wait for one, as the package's do)
            return
        data = b"".join(self._chunk)
        packed = zstandard.compress(data)
        first, last = self._chunk_times
        chunk = Chunk(compression="zstd", data=packed, message_start_time=first, message_end_time=last,
                      uncompressed_crc=zlib.crc32(data), uncompressed_size=len(data))
        start = self._pos
        self._write(_record(chunk))
        index = ChunkIndex(message_start_time=first, message_end_time=last, chunk_start_offset=start,
                           chunk_length=self._pos - start, message_index_offsets={}, message_index_length=0,
                           compression="zstd", compressed_size=len(packed), uncompressed_size=len(data))
        indexes_start = self._pos
        for channel_id, pairs in self._index.items():
            index.message_index_offsets[channel_id] = self._pos
            self._write(_INDEX_HEAD.pack(Opcode.MESSAGE_INDEX, 6 + 8 * len(pairs), channel_id, 8 * len(pairs))
                        + struct.pack(f"<{len(pairs)}Q", *pairs))
        index.message_index_length = self._pos - indexes_start
        self._chunk_indexes.append(index)
        self._chunk, self._chunk_len, self._index, self._chunk_times = [], 0, {}, (0, 0)

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        start = self._pos
        self._write(_record(Metadata(name=name, metadata=data)))
        self._metadata_indexes.append(MetadataIndex(offset=start, length=self._pos - start, name=name))

    def finish(self) -> None:
        self._finish_chunk()
        self._write(_record(DataEnd(0)))
        summary_start = self._pos
        summary = RecordBuilder()
        offsets: list[SummaryOffset] = []
        statistics = Statistics(attachment_count=0, channel_count=len(self._channels),
                                channel_message_counts=self._counts, chunk_count=len(self._chunk_indexes),
                                message_count=sum(self._counts.values()), message_start_time=self._times[0],
                                message_end_time=self._times[1], metadata_count=len(self._metadata_indexes),
                                schema_count=len(self._schemas))
        groups: tuple[tuple[Opcode, list[Schema] | list[Channel] | list[Statistics] | list[ChunkIndex]
                            | list[MetadataIndex]], ...] = (
            (Opcode.SCHEMA, self._schemas), (Opcode.CHANNEL, self._channels),
            (Opcode.STATISTICS, [statistics]), (Opcode.CHUNK_INDEX, self._chunk_indexes),
            (Opcode.ATTACHMENT_INDEX, []), (Opcode.METADATA_INDEX, self._metadata_indexes))
        for opcode, records in groups:
            group_start = summary.count
            for rec in records:
                rec.write(summary)
            offsets.append(SummaryOffset(group_opcode=opcode, group_start=summary_start + group_start,
                                         group_length=summary.count - group_start))
        offsets_start = summary_start + summary.count
        for offset in offsets:
            offset.write(summary)
        data = summary.end()
        footer_start = summary_start if data else 0
        footer_head = struct.pack("<BQQQ", Opcode.FOOTER, 20, footer_start, offsets_start)
        crc = zlib.crc32(footer_head, zlib.crc32(data))  # (the summary's and the footer's own head)
        self._write(data)
        self._write(_record(Footer(summary_start=footer_start, summary_offset_start=offsets_start,
                                   summary_crc=crc)))
        self._write(MCAP0_MAGIC)


__all__ = ["CHUNK_SIZE", "ContainerWriter"]
