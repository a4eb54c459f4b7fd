"""Reading bags: messages in time order and decoded numpy columns."""

from dataclasses import dataclass
import heapq
import io
import os
import struct
from typing import NamedTuple
import zlib

from gyro_emulator.recording import cdr
from gyro_emulator.recording.files import resolve_bag
from gyro_emulator.recording.mcap_writer import MCAP_MAGIC, RECORD_HEAD
from gyro_emulator.recording.metadata import FileInfo, METADATA_FILE, TopicInfo, topics_from
from gyro_emulator.recording.scan import scan_mcap, ScanReport, summary_crc_problem
import lz4.frame
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import (Channel, Chunk, ChunkIndex, Message, Metadata, MetadataIndex, Schema,
                          Statistics)
from mcap.summary import Summary
from mcap_ros2.decoder import DecoderFactory
import numpy as np
import zstandard


class BagMessage(NamedTuple):
    """
    One message read from a bag.

    Attributes
    ----------
    topic : str
        Topic name.
    type_name : str
        ``package/msg/Name``.
    log_time_ns : int
        Receive time, ns.
    publish_time_ns : int
        Send time, ns.
    data : bytes
        The CDR-serialised message.
    sequence : int
        Publisher sequence number (0 if unknown).

    """

    topic: str
    type_name: str
    log_time_ns: int
    publish_time_ns: int
    data: bytes
    sequence: int = 0


@dataclass(frozen=True)
class TopicArrays:
    """
    A fixed-layout topic decoded into numpy columns (see :mod:`gyro_emulator.recording.cdr`).

    Attributes
    ----------
    topic : str
        Topic name.
    log_time_ns : numpy.ndarray of int64
        Receive times, ns.
    decoded : gyro_emulator.recording.cdr.Decoded
        Header stamps, frame ids and float64 fields.

    """

    topic: str
    log_time_ns: np.ndarray
    decoded: cdr.Decoded

    @property
    def stamp_ns(self):
        """Return the header stamps, ns."""
        return self.decoded.stamp_ns

    def field(self, name):
        """Return a float64 column or block, e.g. ``angular_velocity``."""
        return self.decoded.field(name)


def resolve_files(path):
    """Return (bag_dir, [mcap files], metadata dict or None) (see :func:`resolve_bag`)."""
    found = resolve_bag(path)
    return found.bag_dir, found.files, found.metadata


def index_file(path, tolerant):
    """Return the FileInfo of one MCAP file, scanning it when it has no summary."""
    problem = None
    try:
        with open(path, 'rb') as handle:
            problem = summary_crc_problem(handle, os.fstat(handle.fileno()).st_size)
            if problem is not None:
                raise ValueError(problem)
            summary, metadata = read_summary(handle)
            if summary is not None and summary.statistics is not None:
                stats = summary.statistics
                topics = topics_from(summary.channels, summary.schemas,
                                     stats.channel_message_counts)
                custom = {}
                for meta in metadata:
                    if meta.name == 'gyro_emulator':
                        custom = dict(meta.metadata)
                return FileInfo(path, topics, stats.message_count,
                                stats.message_start_time, stats.message_end_time,
                                custom_data=custom, summary=summary)
    except Exception as exc:  # noqa: B902 - any failure here means: scan instead
        problem = f'{type(exc).__name__}: {exc}'
    report = ScanReport(path)
    schemas, channels, counts, custom = {}, {}, {}, {}
    start, end = None, 0
    for record in scan_mcap(path, report):
        if isinstance(record, Message):
            counts[record.channel_id] = counts.get(record.channel_id, 0) + 1
            start = record.log_time if start is None else min(start, record.log_time)
            end = max(end, record.log_time)
        elif isinstance(record, Schema):
            schemas[record.id] = record
        elif isinstance(record, Channel):
            channels[record.id] = record
        elif isinstance(record, Metadata) and record.name == 'gyro_emulator':
            custom = dict(record.metadata)
    if report.summary_problem and not tolerant:
        raise ValueError(
            f'{path}: {report.summary_problem}: the summary cannot be trusted. Read it '
            f'tolerantly or rebuild it with: gyro-emulator bag repair {os.path.dirname(path)}')
    if not report.complete and not tolerant:
        raise ValueError(
            f'{path} is an incomplete MCAP file ({report.problem or problem}); the '
            'recorder was probably killed. Recover it with: gyro-emulator bag repair '
            f'{os.path.dirname(path)}')
    topics = topics_from(channels, schemas, counts)
    return FileInfo(path, topics, sum(counts.values()), start or 0, max(end, start or 0),
                    complete=report.complete and not report.summary_problem,
                    custom_data=custom, scan=report)


#: The fixed fields of a chunk index after its head: start, end, chunk offset, chunk
#: length, and the byte length of its message-index offsets.
_CHUNK_INDEX_HEAD = struct.Struct('<QQQQI')
_FOOTER_FIELDS = struct.Struct('<QQ')
#: Summary records read with the mcap library (few); chunk indexes are unpacked here.
_SUMMARY_READERS = {Opcode.SCHEMA: Schema, Opcode.CHANNEL: Channel,
                    Opcode.STATISTICS: Statistics, Opcode.METADATA_INDEX: MetadataIndex}


def _chunk_index(body):
    """Return the ChunkIndex record of ``body`` (``struct``: a file may hold 1e5 of them)."""
    start, end, offset, length, map_len = _CHUNK_INDEX_HEAD.unpack_from(body, 0)
    at = _CHUNK_INDEX_HEAD.size
    offsets = dict(struct.iter_unpack('<HQ', body[at:at + map_len]))
    at += map_len
    index_len, name_len = struct.unpack_from('<QI', body, at)
    at += 12
    compression = str(body[at:at + name_len], 'utf-8')
    compressed, uncompressed = struct.unpack_from('<QQ', body, at + name_len)
    return ChunkIndex(chunk_length=length, chunk_start_offset=offset, compression=compression,
                      compressed_size=compressed, message_end_time=end,
                      message_index_length=index_len, message_index_offsets=offsets,
                      message_start_time=start, uncompressed_size=uncompressed)


def read_summary(handle):
    """
    Return ``(summary, metadata records)`` of an open MCAP file: ``(None, [])`` without one.

    What ``mcap``'s ``get_summary`` and ``iter_metadata`` give, read in one
    pass over the summary section; its chunk indexes, one per chunk, are
    unpacked with ``struct`` (a file of 1e5 tiny chunks: 0.1 s, not seconds).
    Raises on a malformed summary (the caller then scans the file).
    """
    size = handle.seek(0, os.SEEK_END)
    handle.seek(size - len(MCAP_MAGIC) - 9 - _FOOTER_FIELDS.size - 4)
    opcode, _ = RECORD_HEAD.unpack(handle.read(9))
    summary_start, _ = _FOOTER_FIELDS.unpack(handle.read(_FOOTER_FIELDS.size))
    if opcode != Opcode.FOOTER:
        raise ValueError('no footer before the closing magic')
    if summary_start == 0:
        return None, []
    handle.seek(summary_start)
    buf = handle.read(size - summary_start)
    summary, pos = Summary(), 0
    while pos + 9 <= len(buf):
        opcode, length = RECORD_HEAD.unpack_from(buf, pos)
        body = buf[pos + 9:pos + 9 + length]
        if len(body) != length:
            raise ValueError(f'a summary record at byte {summary_start + pos} is truncated')
        pos += 9 + length
        if opcode == Opcode.FOOTER:
            break
        if opcode == Opcode.CHUNK_INDEX:
            summary.chunk_indexes.append(_chunk_index(body))
        elif opcode in _SUMMARY_READERS:
            record = _SUMMARY_READERS[opcode].read(ReadDataStream(io.BytesIO(body)))
            if opcode == Opcode.SCHEMA:
                summary.schemas[record.id] = record
            elif opcode == Opcode.CHANNEL:
                summary.channels[record.id] = record
            elif opcode == Opcode.STATISTICS:
                summary.statistics = record
            else:
                summary.metadata_indexes.append(record)
    metadata = []
    for index in summary.metadata_indexes:
        handle.seek(index.offset)
        opcode, length = RECORD_HEAD.unpack(handle.read(9))
        if opcode == Opcode.METADATA:
            metadata.append(Metadata.read(ReadDataStream(io.BytesIO(handle.read(length)))))
    return summary, metadata


def _decompressor(compression):
    if compression == 'zstd':
        dctx = zstandard.ZstdDecompressor()
        return lambda data, size: dctx.decompress(data, max_output_size=size)
    if compression == 'lz4':
        return lambda data, size: lz4.frame.decompress(data)
    if compression == '':
        return lambda data, size: data
    raise ValueError(f'unsupported chunk compression {compression!r}')


def _chunks_in_order(summary):
    """
    Return the chunk indexes sorted by start time if they do not overlap, else None.

    An index listed twice (the same chunk offset) counts once; two indexes
    of the same time range and sizes at different offsets (a chunk written
    twice) overlap, so the file is read by the scanner, which drops repeats.
    """
    chunks = sorted({c.chunk_start_offset: c for c in summary.chunk_indexes}.values(),
                    key=lambda c: (c.message_start_time, c.chunk_start_offset))
    for before, after in zip(chunks, chunks[1:]):
        if after.message_start_time < before.message_end_time or (
                (after.message_start_time, after.message_end_time, after.compressed_size)
                == (before.message_start_time, before.message_end_time,
                    before.compressed_size)):
            return None
    return chunks


def indexed_message_count(handle, index, channel_ids=None):
    """
    Return the messages the message indexes of one chunk list, or None if they are unreadable.

    Counts the entries of the MessageIndex records after the chunk (16
    bytes each: log time and offset), for ``channel_ids`` or all channels.
    """
    total = 0
    for cid, offset in index.message_index_offsets.items():
        if channel_ids is not None and cid not in channel_ids:
            continue
        try:
            handle.seek(offset)
            opcode, length, channel, size = _INDEX_HEAD.unpack(handle.read(_INDEX_HEAD.size))
        except (OSError, ValueError, struct.error):
            return None
        if opcode != Opcode.MESSAGE_INDEX or channel != cid or size % 16 or length != size + 6:
            return None
        total += size // 16
    return total


_INDEX_HEAD = struct.Struct('<BQHI')


def _iter_chunk_messages(handle, summary, chunks, channel_ids, start_ns, end_ns,
                         on_corrupt=None):
    """
    Yield (log_time, channel_id, publish_time, sequence, data) from indexed chunks.

    The fast path for complete files whose chunks do not overlap in time:
    each wanted chunk is read and decompressed once, its CRC checked (when
    the writer stored one), and its message records unpacked with
    ``struct``; a chunk whose messages are out of order is sorted by log time
    (stable). A chunk that cannot be read is passed to ``on_corrupt(index,
    reason)`` and skipped (``on_corrupt`` may raise instead).
    """
    decompressors = {}
    for index in chunks:
        if start_ns is not None and index.message_end_time < start_ns:
            continue
        if end_ns is not None and index.message_start_time >= end_ns:
            continue
        if channel_ids is not None and index.message_index_offsets and not (
                channel_ids & index.message_index_offsets.keys()):
            continue
        try:
            out = _chunk_messages(handle, index, decompressors, channel_ids, start_ns, end_ns)
        except _CHUNK_ERRORS as exc:
            if on_corrupt is None:
                raise ValueError(f'corrupt chunk at byte {index.chunk_start_offset}: '
                                 f'{type(exc).__name__}: {exc}') from None
            on_corrupt(index, f'{type(exc).__name__}: {exc}')
            continue
        yield from out


#: What a damaged chunk raises on its way through the decoders.
_CHUNK_ERRORS = (ValueError, KeyError, IndexError, EOFError, struct.error, OSError,
                 RuntimeError, MemoryError, OverflowError, McapError)


def _chunk_messages(handle, index, decompressors, channel_ids, start_ns, end_ns):
    """Return the wanted messages of one chunk, in log-time order; raise if it is damaged."""
    unpack_head = RECORD_HEAD.unpack_from
    unpack_msg = _MESSAGE_FIELDS.unpack_from
    handle.seek(index.chunk_start_offset)
    opcode, length = unpack_head(handle.read(9))
    if opcode != Opcode.CHUNK or length != index.chunk_length - 9:
        raise ValueError(f'the record head (opcode 0x{opcode:02x}, {length} bytes) is not '
                         f'the chunk its index lists ({index.chunk_length - 9} bytes)')
    record = Chunk.read(ReadDataStream(handle))
    if ((record.message_start_time, record.message_end_time, record.uncompressed_size,
         record.compression, len(record.data))
            != (index.message_start_time, index.message_end_time, index.uncompressed_size,
                index.compression, index.compressed_size)):
        raise ValueError('the chunk header does not match its index (times, sizes or '
                         'compression differ)')
    decompress = decompressors.get(record.compression)
    if decompress is None:
        decompress = decompressors[record.compression] = _decompressor(record.compression)
    try:
        buf = decompress(record.data, record.uncompressed_size)
    except Exception as exc:  # noqa: B902 - zstd/lz4 raise their own error types
        raise ValueError(f'decompression failed ({type(exc).__name__}: {exc})') from None
    if len(buf) != record.uncompressed_size:
        raise ValueError(f'{len(buf)} bytes decompressed, {record.uncompressed_size} expected')
    if record.uncompressed_crc and zlib.crc32(buf) != record.uncompressed_crc:
        raise ValueError('CRC mismatch')
    out = []
    pos, end = 0, len(buf)
    while pos < end:
        opcode, length = unpack_head(buf, pos)
        if pos + 9 + length > end:
            raise ValueError(f'a record at chunk byte {pos} runs past the chunk end')
        if opcode == 5:
            cid, seq, log_time, pub_time = unpack_msg(buf, pos + 9)
            if ((channel_ids is None or cid in channel_ids)
                    and (start_ns is None or log_time >= start_ns)
                    and (end_ns is None or log_time < end_ns)):
                out.append((log_time, cid, pub_time, seq, buf[pos + 31:pos + 9 + length]))
        pos += 9 + length
    if any(a[0] > b[0] for a, b in zip(out, out[1:])):
        out.sort(key=lambda item: item[0])
    return out


_MESSAGE_FIELDS = struct.Struct('<HIQQ')


def _library_messages(path, topics, start_ns, end_ns):
    """Yield the messages of a complete file through the mcap library (strict)."""
    with open(path, 'rb') as handle:
        reader = make_reader(handle)
        try:
            for schema, channel, msg in reader.iter_messages(
                    topics=topics, starting_at=start_ns, ending_before=end_ns,
                    log_time_order=True):
                yield BagMessage(channel.topic, schema.name if schema else '',
                                 msg.log_time, msg.publish_time, msg.data, msg.sequence)
        except Exception as exc:  # noqa: B902 - the library raises many error types
            raise ValueError(f'{path}: unreadable data ({type(exc).__name__}: {exc}); '
                             'read it tolerantly or run gyro-emulator bag repair') from None


def _library_decoded(path, factory, topics, start_ns, end_ns):
    """Yield ``(BagMessage, decoded)`` of a complete file through the mcap library."""
    with open(path, 'rb') as handle:
        reader = make_reader(handle, decoder_factories=[factory])
        try:
            for schema, channel, msg, decoded in reader.iter_decoded_messages(
                    topics=topics, starting_at=start_ns, ending_before=end_ns):
                yield BagMessage(channel.topic, schema.name if schema else '',
                                 msg.log_time, msg.publish_time, msg.data,
                                 msg.sequence), decoded
        except (McapError, struct.error, EOFError) as exc:
            raise ValueError(f'{path}: unreadable data ({type(exc).__name__}: {exc}); '
                             'read it tolerantly or run gyro-emulator bag repair') from None


class BagReader:
    """
    Read a rosbag2 MCAP bag directory (or a single .mcap file).

    Parameters
    ----------
    path : str
        Bag directory (with or without ``metadata.yaml``) or ``.mcap`` file.
    tolerant : bool
        Read files without summary/footer or with a truncated tail (what a
        SIGKILL leaves) by scanning them, and skip chunks that fail their CRC
        or cannot be decompressed; :attr:`problems` and
        :attr:`corrupt_chunks` then say what was recovered and what was lost.
        Without it (strict) such a file raises a one-line ``ValueError``.

    Attributes
    ----------
    topics : dict of str to TopicInfo
        The topics, with message counts.
    message_count, start_time_ns, end_time_ns : int
        Totals over all files (times of the first and last message, ns).
    problems : list of str
        Recovery notes of incomplete files and of skipped chunks ([] for a
        sound bag).
    corrupt_chunks : list of dict
        Chunks skipped while reading: ``file``, ``offset`` (byte),
        ``start_ns``/``end_ns`` (the log-time range lost), ``messages`` (the
        count its message indexes give, None if unreadable) and ``reason``.
    repeated_messages : int
        Messages found repeated by :meth:`verify` (a chunk written twice).

    """

    def __init__(self, path, tolerant=False):
        found = resolve_bag(path)
        self.path, self.metadata = found.bag_dir, found.metadata
        self.files = [found.leftovers.get(f, f) for f in found.files]
        self.tolerant = tolerant
        self._infos = [index_file(f, tolerant) for f in self.files]
        self.topics = {}
        for info in self._infos:
            for name, topic in info.topics.items():
                if name in self.topics:
                    self.topics[name].message_count += topic.message_count
                else:
                    self.topics[name] = TopicInfo(**{**topic.__dict__})
        counted = [i for i in self._infos if i.message_count]
        self.message_count = sum(i.message_count for i in self._infos)
        self.start_time_ns = min((i.start_time_ns for i in counted), default=0)
        self.end_time_ns = max((i.end_time_ns for i in counted), default=0)
        self.custom_data = {}
        if self.metadata and self.metadata.get('custom_data'):
            self.custom_data = dict(self.metadata['custom_data'])
        for info in self._infos:
            for key, value in info.custom_data.items():
                self.custom_data.setdefault(key, value)
        self.problems = list(found.notes) + [
            i.scan.describe() for i in self._infos
            if not i.complete or (i.scan is not None and not i.scan.sound)]
        self.corrupt_chunks = []
        self.repeated_messages = 0

    def verify(self):
        """
        Read every chunk of every file once, checking CRCs; return what is lost.

        Returns ``(corrupt_chunks, messages_lost)``: the chunks that cannot
        be read (as :attr:`corrupt_chunks`, with their log-time ranges and
        message counts) and the number of messages the summaries count but
        no intact chunk delivers. Files without a summary, and files whose
        chunks overlap in time, are scanned: their losses and repeated
        messages are in :attr:`problems`, the repeats also in
        :attr:`repeated_messages`.
        """
        read = 0
        for info in self._infos:
            if (info.summary is not None and info.summary.chunk_indexes
                    and _chunks_in_order(info.summary) is not None):
                with open(info.path, 'rb') as handle:
                    read += sum(1 for _ in _iter_chunk_messages(
                        handle, info.summary, list(info.summary.chunk_indexes), None, None,
                        None, self._corrupt_handler(info.path, collect=True)))
                continue
            report = ScanReport(info.path)
            read += sum(1 for r in scan_mcap(info.path, report) if isinstance(r, Message))
            self.repeated_messages += report.repeated_messages
            if not report.sound and report.describe() not in self.problems:
                self.problems.append(report.describe())
        lost = self.message_count - read - self.repeated_messages
        return list(self.corrupt_chunks), max(0, lost)

    def _corrupt_handler(self, path, collect=False):
        """Return the ``on_corrupt`` callback of one file: record and skip, or raise."""
        def on_corrupt(index, reason):
            lost = {'file': os.path.basename(path), 'offset': int(index.chunk_start_offset),
                    'start_ns': int(index.message_start_time),
                    'end_ns': int(index.message_end_time), 'reason': reason,
                    'messages': None}
            span = (f'{(lost["start_ns"] - self.start_time_ns) / 1e9:.3f}..'
                    f'{(lost["end_ns"] - self.start_time_ns) / 1e9:.3f} s')
            if not (self.tolerant or collect):
                raise ValueError(f'{path}: corrupt chunk at byte {lost["offset"]} '
                                 f'(messages of {span} after the start): {reason}')
            if all(c['offset'] != lost['offset'] or c['file'] != lost['file']
                   for c in self.corrupt_chunks):
                with open(path, 'rb') as handle:
                    lost['messages'] = indexed_message_count(handle, index)
                count = ('an unknown number of' if lost['messages'] is None
                         else lost['messages'])
                self.corrupt_chunks.append(lost)
                self.problems.append(f'{lost["file"]}: corrupt chunk at byte '
                                     f'{lost["offset"]} skipped, {count} messages of {span} '
                                     f'after the start lost ({reason})')
        return on_corrupt

    def _check_count(self, topic, count, start_ns, end_ns):
        """Note a whole-topic read that gives other than the summary's count."""
        expected = self.topics[topic].message_count
        if start_ns is None and end_ns is None and count != expected:
            note = (f'{topic}: read {count} of the {expected} messages the bag counts'
                    f'{"" if count < expected else " (more than it holds)"}')
            if note not in self.problems:
                self.problems.append(note)

    @property
    def complete(self):
        """Return True when every file has its summary and footer."""
        return all(i.complete for i in self._infos)

    @property
    def duration_ns(self):
        """Return the time between the first and the last message, ns."""
        return self.end_time_ns - self.start_time_ns

    def _check_topics(self, topics):
        if topics is None:
            return None
        topics = [topics] if isinstance(topics, str) else list(topics)
        unknown = [t for t in topics if t not in self.topics]
        if unknown:
            raise ValueError(
                f'topic {", ".join(unknown)} is not in bag {self.path}: topics are '
                f'{", ".join(sorted(self.topics)) or "(none)"}')
        return topics

    def _file_messages(self, info, topics, start_ns, end_ns):
        chunks = None
        if info.summary is not None and info.summary.chunk_indexes:
            chunks = _chunks_in_order(info.summary)
        if chunks is not None:
            summary = info.summary
            ids = None if topics is None else {
                cid for cid, c in summary.channels.items() if c.topic in topics}
            names = {cid: (c.topic, summary.schemas[c.schema_id].name
                           if c.schema_id in summary.schemas else '')
                     for cid, c in summary.channels.items()}
            with open(info.path, 'rb') as handle:
                for log_time, cid, pub, seq, data in _iter_chunk_messages(
                        handle, summary, chunks, ids, start_ns, end_ns,
                        self._corrupt_handler(info.path)):
                    topic, type_name = names[cid]
                    yield BagMessage(topic, type_name, log_time, pub, data, seq)
            return
        if info.complete and info.scan is None and not self.tolerant:
            yield from _library_messages(info.path, topics, start_ns, end_ns)
            return
        schemas, channels = {}, {}
        wanted = None if topics is None else set(topics)
        report = ScanReport(info.path)
        for record in scan_mcap(info.path, report):
            if isinstance(record, Message):
                channel = channels.get(record.channel_id)
                if channel is None:
                    continue
                if wanted is not None and channel.topic not in wanted:
                    continue
                if start_ns is not None and record.log_time < start_ns:
                    continue
                if end_ns is not None and record.log_time >= end_ns:
                    continue
                schema = schemas.get(channel.schema_id)
                yield BagMessage(channel.topic, schema.name if schema else '',
                                 record.log_time, record.publish_time, record.data,
                                 record.sequence)
            elif isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                channels[record.id] = record
        note = report.describe()
        if not report.sound and note not in self.problems:
            self.problems.append(note)

    def messages(self, topics=None, start_ns=None, end_ns=None):
        """
        Yield :class:`BagMessage` in log-time order (file order for scanned files).

        Parameters
        ----------
        topics : str or iterable of str, optional
            Only these topics (ValueError for a topic not in the bag).
        start_ns, end_ns : int, optional
            Only messages with ``start_ns <= log_time_ns < end_ns``.

        """
        topics = self._check_topics(topics)
        streams = [self._file_messages(i, topics, start_ns, end_ns) for i in self._infos]
        if len(streams) == 1:
            yield from streams[0]
        else:
            yield from heapq.merge(*streams, key=lambda m: m.log_time_ns)

    def decoded_messages(self, topics=None, start_ns=None, end_ns=None):
        """
        Yield ``(BagMessage, message)`` with the message decoded from its schema.

        Complete files are read with ``mcap.reader.make_reader(...,
        decoder_factories=[mcap_ros2.decoder.DecoderFactory()])``; scanned
        files use the same factory. Decoded messages are mcap-ros2-support's
        dynamic objects (attribute access like rclpy messages).
        """
        topics = self._check_topics(topics)
        factory = DecoderFactory()
        for info in self._infos:
            if info.complete and info.scan is None:
                yield from _library_decoded(info.path, factory, topics, start_ns, end_ns)
                continue
            decoders, schemas = {}, {}
            for item in self._file_messages(info, topics, start_ns, end_ns):
                decoder = decoders.get(item.type_name)
                if decoder is None:
                    topic = self.topics[item.topic]
                    schemas[item.type_name] = Schema(
                        id=len(schemas) + 1, name=item.type_name, encoding='ros2msg',
                        data=topic.schema_text.encode('utf-8'))
                    decoder = decoders[item.type_name] = factory.decoder_for(
                        'cdr', schemas[item.type_name])
                yield item, decoder(item.data)

    def read_arrays(self, topic, start_ns=None, end_ns=None):
        """
        Decode a fixed-layout topic (Imu, Temperature, Vector3Stamped, ...) into columns.

        This is the fast path: the payloads are decoded together with numpy
        (:func:`gyro_emulator.recording.cdr.decode`), not message by message.

        Returns
        -------
        TopicArrays

        """
        self._check_topics(topic)
        type_name = self.topics[topic].type_name
        cdr.layout_of(type_name)
        times, payloads = [], []
        fast = [i for i in self._infos if i.summary is not None and i.summary.chunk_indexes
                and _chunks_in_order(i.summary) is not None]
        if len(self._infos) == 1 and fast:
            summary = fast[0].summary
            ids = {cid for cid, c in summary.channels.items() if c.topic == topic}
            with open(fast[0].path, 'rb') as handle:
                for item in _iter_chunk_messages(handle, summary, _chunks_in_order(summary),
                                                 ids, start_ns, end_ns,
                                                 self._corrupt_handler(fast[0].path)):
                    times.append(item[0])
                    payloads.append(item[4])
        else:
            for item in self.messages(topic, start_ns, end_ns):
                times.append(item.log_time_ns)
                payloads.append(item.data)
        self._check_count(topic, len(times), start_ns, end_ns)
        decoded = cdr.decode_any(type_name, payloads, self.topics[topic].schema_text, topic)
        return TopicArrays(topic, np.asarray(times, dtype=np.int64), decoded)

    def info_text(self):
        """Return a ``ros2 bag info``-like summary."""
        lines = [f'Bag:              {self.path}',
                 f'Files:            {", ".join(os.path.basename(f) for f in self.files)}',
                 f'Storage:          mcap (rosbag2 metadata version '
                 f'{self.metadata.get("version") if self.metadata else "missing"})',
                 f'Duration:         {self.duration_ns / 1e9:.3f} s',
                 f'Start:            {self.start_time_ns} ns',
                 f'Messages:         {self.message_count}']
        if self.custom_data:
            lines.append('Custom data:      ' + ', '.join(
                f'{k}={v}' for k, v in sorted(self.custom_data.items())))
        lines.append('Topics:')
        width = max((len(t) for t in self.topics), default=0)
        for name in sorted(self.topics):
            t = self.topics[name]
            lines.append(f'  {name:<{width}}  {t.type_name:<34} {t.message_count:>9} msgs')
        for note in self.problems:
            lines.append(f'Notice:           {note}')
        if self.metadata is None and os.path.isfile(os.path.join(self.path, METADATA_FILE)):
            lines.append('Note:             one file read alone: the metadata.yaml beside it '
                         'was not read (give the bag directory)')
        elif self.metadata is None:
            lines.append('Note:             metadata.yaml is missing '
                         '(gyro-emulator bag repair writes it)')
        return '\n'.join(lines)
