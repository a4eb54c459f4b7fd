"""
A crash-safe MCAP file writer (profile ``ros2``, ``cdr`` messages, ``ros2msg`` schemas).

Schemas and channels are written in the data section as soon as a topic is
added; messages go into small chunks that are closed, written and flushed to
the operating system when they reach ``chunk_size`` bytes or when
``flush_interval_s`` of wall time has passed, so a process killed with
SIGKILL loses at most the open chunk. The summary and footer are written by
``finish``; a file without them is read by the tolerant scanner
(:mod:`gyro_emulator.recording.repair`).

The file is not staged and renamed (:mod:`gyro_emulator.atomic`), on
purpose: a live recording streams to its final name so that whatever was
flushed survives a crash (a staged file would lose it all), and
``bag repair`` completes a file cut short. A bag written offline in one go
is staged by its caller (a temporary directory renamed when whole).
"""

from array import array
from dataclasses import dataclass
import os
import struct
import sys
import time
import zlib

from gyro_emulator import __version__
from gyro_emulator.validation import check_choice, check_range
import lz4.frame
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (Channel, Chunk, ChunkIndex, DataEnd, Footer, Header, Metadata,
                          MetadataIndex, Schema, Statistics, SummaryOffset)
import numpy as np
import zstandard

MCAP_MAGIC = b'\x89MCAP0\r\n'


COMPRESSIONS = ('zstd', 'lz4', 'none')


#: Default chunk size, bytes: about a second of 200 Hz Imu plus temperature.
DEFAULT_CHUNK_SIZE = 64 * 1024


#: Default wall-time bound on the age of unflushed messages, s.
DEFAULT_FLUSH_INTERVAL_S = 0.5
#: Longest flush interval allowed, s (the range is (0, this]).
MAX_FLUSH_INTERVAL_S = 3600.0


MESSAGE_HEAD = struct.Struct('<BQHIQQ')


RECORD_HEAD = struct.Struct('<BQ')


@dataclass
class _ChannelStats:
    """Counts of one channel while writing or scanning."""

    channel: Channel
    schema: Schema
    count: int = 0


class McapFileWriter:
    """
    One chunked, indexed MCAP file with profile ``ros2``, written crash-safe.

    Parameters
    ----------
    path : str
        File to create (truncated if it exists).
    compression : str
        Chunk compression: ``zstd``, ``lz4`` or ``none``.
    chunk_size : int
        Close a chunk once its uncompressed records reach this size, bytes.
    flush_interval_s : float
        Close and flush the open chunk once it holds messages this old
        (wall time, s); checked on every write and by :meth:`flush_if_due`.
    fsync : bool
        Also ``os.fsync`` on every flush (survives power loss, not only SIGKILL).

    """

    def __init__(self, path, compression='zstd', chunk_size=DEFAULT_CHUNK_SIZE,
                 flush_interval_s=DEFAULT_FLUSH_INTERVAL_S, fsync=False):
        check_choice('BagWriter', 'compression', compression, COMPRESSIONS)
        check_range('BagWriter', 'chunk_size', chunk_size, 0, 1 << 30, 'bytes')
        check_range('BagWriter', 'flush_interval_s', flush_interval_s, 0.0, MAX_FLUSH_INTERVAL_S,
                    's')
        if compression == 'lz4':
            self._compress = lz4.frame.compress
        elif compression == 'zstd':
            self._compress = zstandard.ZstdCompressor(level=1).compress
        else:
            self._compress = None
        self.path = path
        self.compression = '' if compression == 'none' else compression
        self.chunk_size = int(chunk_size)
        self.flush_interval_s = float(flush_interval_s)
        self.fsync = fsync
        self._file = open(path, 'wb')
        self._schemas = {}
        self._channels = {}
        self._chunk = bytearray()
        self._chunk_index = {}
        self._chunk_start = None
        self._chunk_end = 0
        self._chunk_opened = 0.0
        self._chunk_indexes = []
        self._metadata_indexes = []
        self.message_count = 0
        self.start_time_ns = None
        self.end_time_ns = 0
        self.finished = False
        self._write_records(lambda b: Header(
            'ros2', f'gyro_emulator/{__version__} (rosbag2-compatible)').write(b),
            prefix=MCAP_MAGIC)
        self._file.flush()

    # -- records outside chunks ------------------------------------------------
    def _write_records(self, build, prefix=b''):
        builder = RecordBuilder()
        build(builder)
        self._file.write(prefix + builder.end())

    def add_schema(self, name, data, encoding='ros2msg'):
        """Write a schema record now; return its id."""
        schema = Schema(id=len(self._schemas) + 1, name=name, encoding=encoding,
                        data=data.encode('utf-8') if isinstance(data, str) else bytes(data))
        self._schemas[schema.id] = schema
        self._write_records(schema.write)
        self._file.flush()
        return schema.id

    def add_channel(self, topic, schema_id, metadata=None, message_encoding='cdr'):
        """Write a channel record now; return its id (1, 2, ...)."""
        if len(self._channels) >= 65535:
            raise ValueError('an MCAP file holds at most 65535 channels')
        channel = Channel(id=len(self._channels) + 1, topic=topic,
                          message_encoding=message_encoding, schema_id=schema_id,
                          metadata=dict(metadata or {}))
        self._channels[channel.id] = _ChannelStats(channel, self._schemas[schema_id])
        self._write_records(channel.write)
        self._file.flush()
        return channel.id

    def add_metadata(self, name, data):
        """Write a metadata record (str -> str map) now."""
        offset = self._file.tell()
        builder = RecordBuilder()
        Metadata(name=name, metadata=dict(data)).write(builder)
        raw = builder.end()
        self._file.write(raw)
        self._metadata_indexes.append(MetadataIndex(offset=offset, length=len(raw), name=name))

    # -- messages ---------------------------------------------------------------
    def write(self, channel_id, data, log_time_ns, publish_time_ns=None, sequence=0):
        """Append one serialised message to the open chunk."""
        log_time = int(log_time_ns)
        publish = log_time if publish_time_ns is None else int(publish_time_ns)
        if log_time < 0 or publish < 0:
            raise ValueError(f'message times must be >= 0 ns, got {log_time}, {publish}')
        stats = self._channels.get(channel_id)
        if stats is None:
            raise ValueError(f'unknown channel id {channel_id}')
        chunk = self._chunk
        if self._chunk_start is None:
            self._chunk_start = log_time
            self._chunk_end = log_time
            self._chunk_opened = time.monotonic()
        elif log_time < self._chunk_start:
            self._chunk_start = log_time
        if log_time > self._chunk_end:
            self._chunk_end = log_time
        index = self._chunk_index.get(channel_id)
        if index is None:
            index = self._chunk_index[channel_id] = array('Q')
        index.append(log_time)
        index.append(len(chunk))
        chunk += MESSAGE_HEAD.pack(Opcode.MESSAGE, 22 + len(data), channel_id,
                                   sequence & 0xFFFFFFFF, log_time, publish)
        chunk += data
        stats.count += 1
        self.message_count += 1
        if self.start_time_ns is None or log_time < self.start_time_ns:
            self.start_time_ns = log_time
        if log_time > self.end_time_ns:
            self.end_time_ns = log_time
        if (len(chunk) >= self.chunk_size
                or time.monotonic() - self._chunk_opened >= self.flush_interval_s):
            self.flush()

    def flush_if_due(self):
        """Flush the open chunk if it is older than ``flush_interval_s``."""
        if (self._chunk_start is not None
                and time.monotonic() - self._chunk_opened >= self.flush_interval_s):
            self.flush()

    def flush(self):
        """Close the open chunk, write it with its message indexes and flush the file."""
        if self._chunk_start is not None:
            self._close_chunk()
        self._file.flush()
        if self.fsync:
            os.fsync(self._file.fileno())

    def _close_chunk(self):
        raw = bytes(self._chunk)
        data = self._compress(raw) if self._compress else raw
        chunk = Chunk(compression=self.compression, data=data,
                      message_start_time=self._chunk_start,
                      message_end_time=self._chunk_end,
                      uncompressed_crc=zlib.crc32(raw), uncompressed_size=len(raw))
        builder = RecordBuilder()
        chunk.write(builder)
        chunk_bytes = builder.end()
        start = self._file.tell()
        index_start = start + len(chunk_bytes)
        parts = [chunk_bytes]
        offsets = {}
        position = index_start
        for channel_id, entries in self._chunk_index.items():
            body = entries.tobytes() if sys.byteorder == 'little' else (
                np.frombuffer(entries, '=u8').astype('<u8').tobytes())
            head = struct.pack('<BQHI', Opcode.MESSAGE_INDEX, 6 + len(body), channel_id,
                               len(body))
            offsets[channel_id] = position
            parts.append(head)
            parts.append(body)
            position += len(head) + len(body)
        self._file.write(b''.join(parts))
        self._chunk_indexes.append(ChunkIndex(
            message_start_time=self._chunk_start, message_end_time=self._chunk_end,
            chunk_start_offset=start, chunk_length=len(chunk_bytes),
            message_index_offsets=offsets, message_index_length=position - index_start,
            compression=self.compression, compressed_size=len(data),
            uncompressed_size=len(raw)))
        self._chunk = bytearray()
        self._chunk_index = {}
        self._chunk_start = None

    # -- closing ------------------------------------------------------------------
    @property
    def channel_counts(self):
        """Return {channel id: message count}."""
        return {cid: s.count for cid, s in self._channels.items()}

    def finish(self):
        """Write the last chunk, the summary and the footer; close. Safe to call twice."""
        if self.finished:
            return
        self.finished = True
        try:
            self.flush()
            self._write_records(DataEnd(0).write)
            summary_start = self._file.tell()
            builder = RecordBuilder()
            groups = []

            def group(opcode, records):
                begin = builder.count
                for record in records:
                    record.write(builder)
                if records:
                    groups.append(SummaryOffset(opcode, summary_start + begin,
                                                builder.count - begin))

            group(Opcode.SCHEMA, list(self._schemas.values()))
            group(Opcode.CHANNEL, [s.channel for s in self._channels.values()])
            group(Opcode.STATISTICS, [Statistics(
                message_count=self.message_count, schema_count=len(self._schemas),
                channel_count=len(self._channels), attachment_count=0,
                metadata_count=len(self._metadata_indexes),
                chunk_count=len(self._chunk_indexes),
                message_start_time=self.start_time_ns or 0,
                message_end_time=self.end_time_ns,
                channel_message_counts=self.channel_counts)])
            group(Opcode.CHUNK_INDEX, self._chunk_indexes)
            group(Opcode.METADATA_INDEX, self._metadata_indexes)
            offsets_start = summary_start + builder.count
            for offset in groups:
                offset.write(builder)
            summary = builder.end()
            crc = zlib.crc32(summary)
            crc = zlib.crc32(struct.pack('<BQQQ', Opcode.FOOTER, 20, summary_start,
                                         offsets_start), crc)
            footer = RecordBuilder()
            Footer(summary_start=summary_start, summary_offset_start=offsets_start,
                   summary_crc=crc).write(footer)
            self._file.write(summary + footer.end() + MCAP_MAGIC)
            self._file.flush()
            if self.fsync:
                os.fsync(self._file.fileno())
        finally:
            self._file.close()

    def abort(self):
        """Close the file without a summary (after a write failed); the caller removes it."""
        if self.finished:
            return
        self.finished = True
        try:
            self._file.close()
        except OSError:
            pass

    def topic_records(self):
        """Return [(Channel, Schema, count)] in channel id order."""
        return [(s.channel, s.schema, s.count) for s in self._channels.values()]
