"""
Tolerant scanning of MCAP files, record by record.

:func:`scan_mcap` walks the records of a file that may lack its summary and
footer (a recording cut short by a crash) and reports what it holds and
where it stops.
"""

import bisect
from dataclasses import dataclass
import io
import os
import struct
import zlib

from gyro_emulator.recording.mcap_writer import MCAP_MAGIC, RECORD_HEAD
from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, DataEnd, Footer, Header, Message, Metadata, Schema
import numpy as np
import zstandard

_VALID_OPCODES = frozenset(int(op) for op in Opcode)
#: The footer record: opcode, length, summary_start, summary_offset_start, summary_crc.
_FOOTER = struct.Struct('<BQQQI')
#: The fixed fields of a chunk record after its head: start, end, uncompressed size, CRC,
#: compression string length.
_CHUNK_FIELDS = struct.Struct('<QQQII')
_COMPRESSIONS = (b'', b'zstd', b'lz4')


def summary_crc_problem(handle, size):
    """
    Return why a finished file cannot be trusted as it is (its CRC fails), or None.

    The footer's ``summary_crc`` covers every byte from the summary start
    through the footer's ``summary_offset_start`` (MCAP specification); 0
    means the writer stored none, which is accepted. A damaged leading
    magic is said too (:func:`head_problem`): the records and the summary
    may be intact, but ``mcap`` and ``rosbags`` refuse the file. A file
    without a footer and closing magic is left to the caller (None).
    """
    footer_at = size - len(MCAP_MAGIC) - _FOOTER.size
    if footer_at < len(MCAP_MAGIC):
        return None
    handle.seek(footer_at)
    tail = handle.read(_FOOTER.size + len(MCAP_MAGIC))
    if tail[_FOOTER.size:] != MCAP_MAGIC:
        return None
    damaged = head_problem(handle)
    if damaged is not None:
        return damaged
    opcode, length, summary_start, _, crc = _FOOTER.unpack(tail[:_FOOTER.size])
    if opcode != Opcode.FOOTER or length != _FOOTER.size - 9:
        return f'the footer at byte {footer_at} is corrupt'
    if crc == 0:
        return None
    begin = summary_start or footer_at
    if not len(MCAP_MAGIC) <= begin <= footer_at:
        return (f'the footer puts the summary at byte {summary_start}, outside the file '
                f'({size} bytes)')
    handle.seek(begin)
    computed = zlib.crc32(handle.read(footer_at + _FOOTER.size - 4 - begin))
    if computed != crc:
        return f'summary CRC mismatch (stored 0x{crc:08x}, computed 0x{computed:08x})'
    return None


def head_problem(handle):
    """Return why the leading MCAP magic of an open file is wrong, or None when it is right."""
    handle.seek(0)
    magic = handle.read(len(MCAP_MAGIC))
    if magic == MCAP_MAGIC:
        return None
    return (f'the leading MCAP magic is damaged ({magic!r}): mcap and rosbags refuse the '
            'file')


def _finished(handle, size):
    """Return whether an open file ends with the MCAP magic (a footer was written)."""
    if size < 2 * len(MCAP_MAGIC):
        return False
    handle.seek(size - len(MCAP_MAGIC))
    return handle.read(len(MCAP_MAGIC)) == MCAP_MAGIC


@dataclass
class ScanReport:
    """
    What a sequential scan of one MCAP file found.

    Attributes
    ----------
    path : str
        The file.
    size_bytes : int
        File size.
    good_bytes : int
        Bytes up to the end of the last intact record.
    complete : bool
        A footer and closing magic were found.
    data_end : bool
        The data section ended cleanly (everything after it is summary).
    problem : str or None
        Why the scan stopped early or skipped data, if it did.
    messages : int
        Messages recovered.
    bad_chunks : int
        Chunks skipped because they failed to decompress or their CRC.
    last_log_time_ns : int or None
        Log time of the last recovered message.
    summary_problem : str or None
        Why the file's summary cannot be trusted (its CRC fails).
    skipped_bytes : int
        Unreadable bytes in the data section skipped to reach the next intact chunk.
    repeated_chunks, repeated_messages : int
        Chunks holding repeats of earlier messages (a chunk written twice,
        or overlapping an earlier one), and the repeated messages; dropped.

    """

    path: str
    size_bytes: int = 0
    good_bytes: int = 0
    complete: bool = False
    data_end: bool = False
    problem: str = None
    messages: int = 0
    bad_chunks: int = 0
    last_log_time_ns: int = None
    summary_problem: str = None
    skipped_bytes: int = 0
    repeated_chunks: int = 0
    repeated_messages: int = 0

    @property
    def sound(self):
        """Return True when the file is complete and nothing was skipped or dropped."""
        return (self.complete and not self.problem and not self.summary_problem
                and not self.repeated_messages)

    def describe(self):
        """Return a one-line human summary."""
        if self.sound:
            return f'{self.path}: complete, {self.messages} messages'
        if self.summary_problem:
            state = f'{self.summary_problem}; the index was rebuilt from the data section'
        elif self.complete:
            state = self.problem or 'complete'
        elif self.data_end:
            state = 'data section intact, summary missing'
        else:
            state = self.problem or 'incomplete'
        lost = self.size_bytes - self.good_bytes
        parts = [f'recovered {self.messages} messages']
        if self.bad_chunks:
            parts.append(f'skipped {self.bad_chunks} corrupt chunks')
        if self.skipped_bytes:
            parts.append(f'skipped {self.skipped_bytes} unreadable bytes')
        if self.repeated_messages:
            parts.append(f'dropped {self.repeated_messages} repeated messages '
                         f'of {self.repeated_chunks} duplicated chunks')
        if lost > 0:
            parts.append(f'discarded {lost} trailing bytes')
        return f'{self.path}: {state}; ' + ', '.join(parts)


#: The records the scanner reads (others, such as indexes, are skipped unparsed).
_READERS = {Opcode.SCHEMA: Schema, Opcode.CHANNEL: Channel, Opcode.METADATA: Metadata,
            Opcode.HEADER: Header, Opcode.FOOTER: Footer, Opcode.DATA_END: DataEnd}
_PARSED = frozenset(_READERS) | {Opcode.CHUNK, Opcode.MESSAGE}


def _parse_record(opcode, body):
    if opcode == Opcode.CHUNK:
        return _chunk(body)
    if opcode == Opcode.MESSAGE:
        return Message.read(ReadDataStream(io.BytesIO(body)), len(body))
    reader = _READERS.get(opcode)
    return reader.read(ReadDataStream(io.BytesIO(body))) if reader else None


#: A message record's fixed fields: channel id, sequence, log time, publish time.
_MESSAGE_FIELDS = struct.Struct('<HIQQ')
_ZSTD = zstandard.ZstdDecompressor()


def _chunk(body):
    """Return the Chunk record of ``body`` (its fields unpacked with ``struct``)."""
    start, end, size, crc, name_len = _CHUNK_FIELDS.unpack_from(body, 0)
    at = _CHUNK_FIELDS.size
    compression = str(body[at:at + name_len], 'utf-8')
    data_len, = struct.unpack_from('<Q', body, at + name_len)
    at += name_len + 8
    if at + data_len > len(body):
        raise ValueError(f'the chunk data ({data_len} bytes) runs past its record')
    return Chunk(compression=compression, data=body[at:at + data_len], message_end_time=end,
                 message_start_time=start, uncompressed_crc=crc, uncompressed_size=size)


def chunk_records(chunk):
    """
    Return the Schema, Channel and Message records of a chunk; raise if it is damaged.

    Decompresses (zstd, lz4 or none), checks the CRC when the writer stored
    one, and unpacks the message records with ``struct`` (what
    ``mcap.stream_reader.breakup_chunk`` does, a record at a time); records of
    other kinds are skipped, as there.
    """
    if chunk.compression == 'zstd':
        buf = _ZSTD.decompress(chunk.data, max_output_size=chunk.uncompressed_size)
    elif chunk.compression == 'lz4':
        import lz4.frame

        buf = lz4.frame.decompress(chunk.data)
    elif chunk.compression == '':
        buf = chunk.data
    else:
        raise ValueError(f'unsupported chunk compression {chunk.compression!r}')
    if chunk.uncompressed_crc and zlib.crc32(buf) != chunk.uncompressed_crc:
        raise ValueError('CRC mismatch')
    records, pos, end = [], 0, len(buf)
    unpack_head, unpack_msg = RECORD_HEAD.unpack_from, _MESSAGE_FIELDS.unpack_from
    while pos < end:
        opcode, length = unpack_head(buf, pos)
        body_at, pos = pos + 9, pos + 9 + length
        if pos > end:
            raise ValueError(f'a record at chunk byte {body_at - 9} runs past the chunk end')
        if opcode == Opcode.MESSAGE:
            cid, seq, log_time, pub_time = unpack_msg(buf, body_at)
            records.append(Message(channel_id=cid, log_time=log_time,
                                   data=bytes(buf[body_at + 22:pos]), publish_time=pub_time,
                                   sequence=seq))
        elif opcode in (Opcode.SCHEMA, Opcode.CHANNEL):
            records.append(_parse_record(opcode, bytes(buf[body_at:pos])))
    return records


class Repeats:
    """
    Find chunks and messages that repeat earlier ones (a chunk written twice).

    A chunk whose time range, sizes and compressed bytes (CRC-32) equal an
    earlier chunk's is a repeat; in a chunk whose log-time range overlaps
    an earlier chunk's, each message equal to one of that chunk's (channel,
    sequence, log and publish time, data) is a repeat. Keeps a hash per
    message (8 bytes in a large chunk), and compares only chunks that overlap
    in time.

    The chunks a recorder writes come in order of their start times; among
    them the earlier chunks that overlap a new one are the tail after the
    first whose running maximum end reaches its start (a binary search),
    so a file of many tiny chunks costs a few comparisons per chunk, not one
    per earlier chunk. A chunk that starts before an earlier one (a chunk
    written twice, a writer restarted) is kept apart and compared with all.
    While every chunk so far is small, one set of all their keys screens a
    new chunk first: a message equal to an earlier one has its log time in
    both chunks, so they overlap, and a chunk none of whose keys is in the
    set has no repeat (the exact comparison runs only on a hit).
    """

    #: Up to this many keys, a chunk keeps them as a Python list and membership is a
    #: Python set (numpy's ``isin`` costs tens of microseconds a call, whatever the
    #: size); larger chunks keep an int64 array (8 bytes a message).
    SMALL = 256

    def __init__(self):
        self._chunks = set()
        # chunks in order of start time: starts, ends, running maximum of the ends, keys
        self._starts, self._ends, self._max_ends, self._keys = [], [], [], []
        self._late = []         # (start, end, keys) of chunks out of start order
        self._small_keys = set()    # the keys of every chunk while all are small, else None

    def _overlapping(self, start, end):
        """Return the key arrays of the earlier chunks whose time range meets [start, end]."""
        found = [keys for s, e, keys in self._late if s <= end and e >= start]
        starts, ends = self._starts, self._ends
        for k in range(bisect.bisect_left(self._max_ends, start), len(starts)):
            if starts[k] <= end and ends[k] >= start:
                found.append(self._keys[k])
        return found

    def _add(self, start, end, keys):
        if self._starts and start < self._starts[-1]:
            self._late.append((start, end, keys))
            return
        self._starts.append(start)
        self._ends.append(end)
        self._max_ends.append(max(end, self._max_ends[-1]) if self._max_ends else end)
        self._keys.append(keys)

    def _screened(self, keys):
        """Whether the small-chunk screen proves ``keys`` new (and takes them in)."""
        if self._small_keys is None:
            return False
        if len(keys) > self.SMALL:
            self._small_keys = None     # a large chunk: the exact comparison from now on
            return False
        new = self._small_keys.isdisjoint(keys)
        self._small_keys.update(keys)
        return new

    def drop(self, chunk, messages):
        """Return ``(kept messages, repeated count, whole chunk repeated)``."""
        key = (chunk.message_start_time, chunk.message_end_time, chunk.uncompressed_size,
               chunk.compression, len(chunk.data), zlib.crc32(chunk.data))
        if key in self._chunks:
            return [], len(messages), True
        self._chunks.add(key)
        keys = [hash((m.channel_id, m.sequence, m.log_time, m.publish_time, m.data))
                for m in messages]
        start, end = chunk.message_start_time, chunk.message_end_time
        if self._screened(keys):
            self._add(start, end, keys)
            return messages, 0, False
        earlier = self._overlapping(start, end)
        self._add(start, end, keys if len(keys) <= self.SMALL
                  else np.array(keys, dtype=np.int64))
        if not earlier:
            return messages, 0, False
        if len(keys) + sum(len(k) for k in earlier) <= self.SMALL:
            known = set()
            for k in earlier:
                known.update(k.tolist() if isinstance(k, np.ndarray) else k)
            seen = [k in known for k in keys]
        else:
            seen = np.isin(np.array(keys, dtype=np.int64), np.concatenate(
                [np.asarray(k, dtype=np.int64) for k in earlier])).tolist()
        repeated = sum(seen)
        if not repeated:
            return messages, 0, False
        return [m for m, s in zip(messages, seen) if not s], repeated, False


def _intact_chunk_at(buf, i, at, size):
    """Return whether a plausible chunk record head is at ``buf[i]`` (file byte ``at``)."""
    if i + 9 + _CHUNK_FIELDS.size + 4 + 8 > len(buf):
        return False
    opcode, length = RECORD_HEAD.unpack_from(buf, i)
    if opcode != Opcode.CHUNK or length > size - at - 9:
        return False
    start, end, _, _, name_len = _CHUNK_FIELDS.unpack_from(buf, i + 9)
    if start > end or name_len > 4:
        return False
    at_name = i + 9 + _CHUNK_FIELDS.size
    if bytes(buf[at_name:at_name + name_len]) not in _COMPRESSIONS:
        return False
    records, = struct.unpack_from('<Q', buf, at_name + name_len)
    return records == length - _CHUNK_FIELDS.size - name_len - 8


def next_intact_chunk(handle, start, size, window=1 << 20):
    """
    Return ``(offset, chunk, records)`` of the first intact chunk at or after byte ``start``.

    Intact: its head is consistent (opcode, lengths, compression) and its
    records decompress and pass their CRC. None when there is none.
    """
    position = start
    while position < size:
        handle.seek(position)
        buf = handle.read(window + 64)
        i = buf.find(b'\x06')
        while 0 <= i < min(window, len(buf)):
            at = position + i
            if _intact_chunk_at(buf, i, at, size):
                handle.seek(at)
                opcode, length = RECORD_HEAD.unpack(handle.read(9))
                try:
                    chunk = _parse_record(opcode, handle.read(length))
                    records = chunk_records(chunk)
                except Exception:  # noqa: B902 - not a chunk after all
                    records = None
                if records is not None and chunk.uncompressed_crc:
                    return at, 9 + length, chunk, records
            i = buf.find(b'\x06', i + 1)
        position += window
    return None


def _resync(handle, report, position, size, why):
    """Skip damaged bytes to the next intact chunk; return (position, records) or None."""
    found = next_intact_chunk(handle, position, size)
    if found is None:
        return None
    at, length, chunk, records = found
    report.skipped_bytes += at - position
    report.problem = f'{why}; resumed at the next intact chunk, byte {at}'
    return at + length, chunk, records


def _drop_repeats(repeats, chunk, records, report):
    """Return the records of ``chunk`` without repeated messages, counted in ``report``."""
    messages = [r for r in records if isinstance(r, Message)]
    kept, repeated, _ = repeats.drop(chunk, messages)
    if not repeated:
        return records
    report.repeated_messages += repeated
    report.repeated_chunks += 1
    kept = set(map(id, kept))
    return [r for r in records if not isinstance(r, Message) or id(r) in kept]


def scan_mcap(path, report=None):
    """
    Yield the Schema, Channel, Message and Metadata records of an MCAP file.

    Reads sequentially and tolerates what a killed writer leaves: a missing
    summary, footer or magic, or a truncated final record. A chunk that fails
    to decompress or whose CRC does not match is skipped and counted; an
    unreadable record head in the data section (an unknown opcode, a length
    past the end) is skipped up to the next intact chunk, else the scan
    stops there. Chunks and messages repeating earlier ones are dropped and
    counted (:class:`Repeats`); the summary's CRC is checked. The outcome is
    recorded in ``report`` (a :class:`ScanReport`).

    Parameters
    ----------
    path : str
        MCAP file.
    report : ScanReport, optional
        Filled in as the scan proceeds.

    Raises
    ------
    ValueError
        If the file does not start with the MCAP magic (nor end with it: a
        finished file whose leading magic alone is damaged is read).

    """
    report = report if report is not None else ScanReport(path)
    report.path = path
    with open(path, 'rb') as handle:
        size = os.fstat(handle.fileno()).st_size
        report.size_bytes = size
        magic = handle.read(len(MCAP_MAGIC))
        if len(magic) < len(MCAP_MAGIC) and MCAP_MAGIC.startswith(magic):
            report.problem = f'the file is truncated to {size} bytes, before any record'
            return
        if magic != MCAP_MAGIC and not _finished(handle, size):
            raise ValueError(f'{path} is not an MCAP file (it does not start with the '
                             f'MCAP magic; {size} bytes)')
        # a finished file whose head alone is damaged: its records are read, the damage
        # said at the footer (summary_crc_problem)
        handle.seek(len(MCAP_MAGIC))
        yield from _scan_records(handle, report, size)


def _scan_records(handle, report, size):
    """Walk the records of an open MCAP file after its magic (:func:`scan_mcap`)."""
    position = len(MCAP_MAGIC)
    report.good_bytes = position
    repeats = Repeats()
    while True:
        head = handle.read(9)
        if not head:
            report.problem = report.problem or 'the file ends without a footer'
            return
        opcode, length = RECORD_HEAD.unpack(head) if len(head) == 9 else (None, 0)
        why = None
        if len(head) < 9:
            why = f'truncated record header at byte {position}'
        elif opcode not in _VALID_OPCODES:
            why = f'corrupt record (opcode 0x{opcode:02x}) at byte {position}'
        elif length > size - position - 9:
            why = (f'truncated {Opcode(opcode).name.lower()} record at byte {position} '
                   f'({size - position - 9} of {length} bytes present)')
        record = inner = None
        if why is None and opcode not in _PARSED:     # an index or the like: not read
            handle.seek(length, os.SEEK_CUR)
        elif why is None:
            body = handle.read(length)
            try:
                record = _parse_record(opcode, body)
                inner = chunk_records(record) if opcode == Opcode.CHUNK else None
            except Exception as exc:  # noqa: B902 - any decoder error means corrupt data
                if opcode == Opcode.CHUNK:
                    report.bad_chunks += 1
                    report.problem = (f'corrupt chunk at byte {position} skipped '
                                      f'({type(exc).__name__}: {exc})')
                    position += 9 + length
                    continue
                why = (f'corrupt {Opcode(opcode).name.lower()} record at byte '
                       f'{position} ({type(exc).__name__}: {exc})')
        if why is not None:
            found = None if report.data_end else _resync(handle, report, position, size, why)
            if found is None:
                report.problem = why
                if report.data_end:
                    report.summary_problem = f'unreadable summary: {why}'
                return
            position, record, inner = found
            opcode = Opcode.CHUNK
            handle.seek(position)
        else:
            position += 9 + length
        report.good_bytes = position
        if opcode == Opcode.FOOTER:
            report.complete = handle.read(len(MCAP_MAGIC)) == MCAP_MAGIC
            if report.complete:
                report.good_bytes = size
                report.summary_problem = summary_crc_problem(handle, size)
            else:
                report.problem = 'the closing magic after the footer is missing'
            return
        if opcode == Opcode.DATA_END:
            report.data_end = True
            continue
        if report.data_end:
            continue        # summary section: repeated schemas/channels, indexes
        if inner is None:
            if isinstance(record, (Schema, Channel, Message, Metadata)):
                if isinstance(record, Message):
                    report.messages += 1
                    report.last_log_time_ns = record.log_time
                yield record
            continue
        inner = _drop_repeats(repeats, record, inner, report)
        for item in inner:          # a chunk holds schemas, channels and messages only
            if type(item) is Message:
                report.messages += 1
                report.last_log_time_ns = item.log_time
            yield item
