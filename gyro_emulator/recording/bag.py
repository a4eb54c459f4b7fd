"""
rosbag2-compatible MCAP bags: a crash-safe writer, a reader and recovery.

A bag is a directory holding ``<name>_0.mcap`` and ``metadata.yaml``, the
layout ``ros2 bag record -s mcap`` produces (rosbag2 metadata version 9):

- the MCAP file has profile ``ros2``; each topic is a channel with
  ``cdr`` message encoding and a ``ros2msg`` schema, the message definition
  with its dependencies concatenated as rosbag2 does
  (rosbag2 ``docs/message_definition_encoding.md``); channel metadata carries
  ``offered_qos_profiles`` and ``topic_type_hash`` (RIHS01);
- ``metadata.yaml`` lists the topics, counts, start time and duration.

Crash safety. Schemas and channels are written in the data section as soon
as a topic is added; messages go into small chunks that are closed, written
and flushed to the operating system when they reach ``chunk_size`` bytes or
when ``flush_interval_s`` of wall time has passed (``flush_if_due``), so a
process killed with SIGKILL loses at most the open chunk. The summary, footer
and ``metadata.yaml`` are written by :meth:`BagWriter.finish`; a file without
them is read by the tolerant scanner (:func:`scan_mcap`) and rewritten whole
by :func:`repair_bag`.

All times are integer nanoseconds (``log_time`` is the receive time,
``publish_time`` the send time, both since the Unix epoch or the sim clock).
"""

from array import array
from dataclasses import dataclass, field
import heapq
import io
import json
import os
import struct
import sys
import time
from typing import NamedTuple
import zlib

from gyro_emulator import __version__
from gyro_emulator.recording import cdr
from gyro_emulator.validation import check_choice, check_range
from mcap.data_stream import ReadDataStream, RecordBuilder
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import (Channel, Chunk, ChunkIndex, DataEnd, Footer, Header, Message,
                          Metadata, MetadataIndex, Schema, Statistics, SummaryOffset)
from mcap.stream_reader import breakup_chunk
import numpy as np
import yaml

#: rosbag2 metadata.yaml format version written (Jazzy).
ROSBAG2_VERSION = 9
ROS_DISTRO = 'jazzy'
METADATA_FILE = 'metadata.yaml'
MCAP_MAGIC = b'\x89MCAP0\r\n'
COMPRESSIONS = ('zstd', 'lz4', 'none')
#: Default chunk size, bytes: about a second of 200 Hz Imu plus temperature.
DEFAULT_CHUNK_SIZE = 64 * 1024
#: Default wall-time bound on the age of unflushed messages, s.
DEFAULT_FLUSH_INTERVAL_S = 0.5

_MESSAGE_HEAD = struct.Struct('<BQHIQQ')
_RECORD_HEAD = struct.Struct('<BQ')
_VALID_OPCODES = frozenset(int(op) for op in Opcode)
_PRIMITIVES = frozenset((
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
    'int32', 'uint32', 'int64', 'uint64', 'string', 'wstring'))


# --------------------------------------------------------------------------
# Message definitions (ros2msg schemas) from the installed .msg files
# --------------------------------------------------------------------------

def _share_prefixes():
    """Return the install prefixes to search: AMENT_PREFIX_PATH, then sys.prefix."""
    prefixes = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    if sys.prefix not in prefixes:
        prefixes.append(sys.prefix)
    return prefixes


def _split_type_name(type_name):
    """Return (package, namespace, name) of ``pkg/msg/Name`` or ``pkg/Name``."""
    parts = type_name.split('/')
    if len(parts) == 2 and all(parts):
        return parts[0], 'msg', parts[1]
    if len(parts) == 3 and all(parts):
        return tuple(parts)
    raise ValueError(
        f'message type {type_name!r} is not understood: expected package/msg/Name')


def _interface_file(type_name, extension):
    package, namespace, name = _split_type_name(type_name)
    for prefix in _share_prefixes():
        path = os.path.join(prefix, 'share', package, namespace, name + extension)
        if os.path.isfile(path):
            return path
    return None


def _msg_dependencies(text, package):
    """
    Return the sorted non-primitive field types named in a .msg text.

    Field types are the first token of each non-comment line (array suffixes
    stripped); names without a package refer to ``package``, as in rosbag2's
    LocalMessageDefinitionSource.
    """
    deps = set()
    for line in text.splitlines():
        line = line.split('#', 1)[0].strip()
        if not line:
            continue
        token = line.split()[0]
        if len(line.split()) < 2 or '=' in token:
            continue
        base = token.split('[', 1)[0].split('<=', 1)[0]
        if base in _PRIMITIVES:
            continue
        deps.add(base if '/' in base else f'{package}/{base}')
    return sorted(deps)


_DEFINITION_CACHE = {}


def message_definition(type_name):
    """
    Return the ``ros2msg`` schema text of a message type.

    The text of ``share/<pkg>/msg/<Name>.msg`` comes first; each dependency,
    depth first and in sorted order, follows once after a line of 80 ``=``
    and ``MSG: <pkg>/<Name>`` (rosbag2's LocalMessageDefinitionSource layout,
    which mcap-ros2-support and rosbags parse).

    Parameters
    ----------
    type_name : str
        ``package/msg/Name``.

    Raises
    ------
    ValueError
        If the .msg file of the type or of a dependency is not installed.

    """
    if type_name in _DEFINITION_CACHE:
        return _DEFINITION_CACHE[type_name]
    seen = set()

    def text_of(name):
        path = _interface_file(name, '.msg')
        if path is None:
            raise ValueError(
                f'no .msg definition for {name!r} under share/ of '
                f'{os.pathsep.join(_share_prefixes())}')
        with open(path, encoding='utf-8') as handle:
            return handle.read()

    def append(name, depth):
        if depth > 32:
            raise ValueError(f'message definition of {type_name!r} nests too deeply')
        text = text_of(name)
        out = text
        for dep in _msg_dependencies(text, _split_type_name(name)[0]):
            if dep not in seen:
                seen.add(dep)
                out += '\n' + '=' * 80 + '\nMSG: ' + dep + '\n' + append(dep, depth + 1)
        return out

    result = append(type_name, 0)
    _DEFINITION_CACHE[type_name] = result
    return result


def type_hash(type_name):
    """
    Return the RIHS01 type hash of ``type_name`` ('' if not installed).

    Read from the ``share/<pkg>/msg/<Name>.json`` type description that
    rosidl generates (REP 2011).
    """
    path = _interface_file(type_name, '.json')
    if path is None:
        return ''
    try:
        with open(path, encoding='utf-8') as handle:
            hashes = json.load(handle).get('type_hashes', [])
    except (OSError, ValueError):
        return ''
    package, namespace, name = _split_type_name(type_name)
    full = f'{package}/{namespace}/{name}'
    for entry in hashes:
        if entry.get('type_name') == full:
            return entry.get('hash_string', '')
    return ''


# --------------------------------------------------------------------------
# QoS profiles as rosbag2 metadata version 9 writes them
# --------------------------------------------------------------------------

def qos_profile(reliability='reliable', durability='volatile', history='keep_last',
                depth=10, liveliness='automatic'):
    """
    Return one offered QoS profile as a rosbag2 v9 metadata mapping.

    Parameters
    ----------
    reliability : str
        ``reliable`` or ``best_effort``.
    durability : str
        ``volatile`` or ``transient_local``.
    history : str
        ``keep_last`` or ``keep_all``.
    depth : int
        History depth.
    liveliness : str
        ``automatic`` or ``manual_by_topic``.

    """
    default = {'sec': 0, 'nsec': 0}      # 0 = unspecified: the rmw default (infinite)
    return {
        'history': history, 'depth': int(depth), 'reliability': reliability,
        'durability': durability, 'deadline': dict(default), 'lifespan': dict(default),
        'liveliness': liveliness, 'liveliness_lease_duration': dict(default),
        'avoid_ros_namespace_conventions': False,
    }


def _dump_qos(profiles):
    return yaml.safe_dump(list(profiles), sort_keys=False).strip() if profiles else ''


def _load_qos(text):
    if not text:
        return []
    try:
        loaded = yaml.safe_load(text)
    except yaml.YAMLError:
        return []
    return loaded if isinstance(loaded, list) else []


# --------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------

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
        check_range('BagWriter', 'flush_interval_s', flush_interval_s, 0.0, 3600.0, 's')
        if compression == 'lz4':
            import lz4.frame
            self._compress = lz4.frame.compress
        elif compression == 'zstd':
            import zstandard
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
        chunk += _MESSAGE_HEAD.pack(Opcode.MESSAGE, 22 + len(data), channel_id,
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

    def topic_records(self):
        """Return [(Channel, Schema, count)] in channel id order."""
        return [(s.channel, s.schema, s.count) for s in self._channels.values()]


class BagWriter:
    """
    Write a rosbag2 bag directory (one MCAP file plus ``metadata.yaml``).

    Use as a context manager; leaving the block (also by an exception)
    finishes the bag. :meth:`finish` is safe to call twice.

    Parameters
    ----------
    path : str
        Bag directory to create. It must not exist or be empty, unless
        ``overwrite`` (which removes its .mcap files and metadata.yaml only).
    compression : str
        Chunk compression inside the MCAP file: ``zstd`` (default), ``lz4``
        or ``none``. rosbag2 reads all three.
    chunk_size : int
        Close a chunk at this many uncompressed bytes.
    flush_interval_s : float
        Upper bound on the wall-time age of unflushed messages, s: what a
        SIGKILL can lose (call :meth:`flush_if_due` from a timer when
        messages may stop arriving).
    custom_data : dict of str to str, optional
        rosbag2 ``custom_data``; also stored in the MCAP file at the start so
        :func:`repair_bag` restores it.
    overwrite : bool
        Replace an existing bag in ``path``.
    fsync : bool
        ``os.fsync`` on each flush.

    Examples
    --------
    >>> with BagWriter('out/run1') as bag:                      # doctest: +SKIP
    ...     bag.add_topic('/imu/data_raw', 'sensor_msgs/msg/Imu')
    ...     bag.write('/imu/data_raw', payload, log_time_ns)

    """

    def __init__(self, path, compression='zstd', chunk_size=DEFAULT_CHUNK_SIZE,
                 flush_interval_s=DEFAULT_FLUSH_INTERVAL_S, custom_data=None,
                 overwrite=False, fsync=False):
        path = os.path.abspath(path)
        if os.path.exists(path) and not os.path.isdir(path):
            raise FileExistsError(f'bag path {path} exists and is not a directory')
        if os.path.isdir(path) and os.listdir(path):
            if not overwrite:
                raise FileExistsError(
                    f'bag directory {path} already exists and is not empty '
                    '(choose a new directory or pass overwrite)')
            for name in os.listdir(path):
                if name.endswith('.mcap') or name == METADATA_FILE:
                    os.remove(os.path.join(path, name))
        os.makedirs(path, exist_ok=True)
        self.path = path
        self.custom_data = {str(k): str(v) for k, v in (custom_data or {}).items()}
        name = os.path.basename(path.rstrip(os.sep)) or 'bag'
        self.file_name = f'{name}_0.mcap'
        self._file = McapFileWriter(os.path.join(path, self.file_name), compression,
                                    chunk_size, flush_interval_s, fsync)
        if self.custom_data:
            self._file.add_metadata('gyro_emulator', self.custom_data)
            self._file.flush()
        self._topics = {}
        self._schema_ids = {}
        self._qos = {}
        self._hash = {}

    # -- topics ---------------------------------------------------------------
    def add_topic(self, topic, type_name, schema_text=None, qos_profiles=(),
                  type_description_hash=None):
        """
        Register a topic once; return its channel id.

        Parameters
        ----------
        topic : str
            Topic name (absolute, e.g. ``/imu/data_raw``).
        type_name : str
            ``package/msg/Name``.
        schema_text : str, optional
            ros2msg definition; read from the installed .msg files if omitted.
        qos_profiles : sequence of dict
            Offered QoS profiles (:func:`qos_profile` mappings).
        type_description_hash : str, optional
            RIHS01 hash; read from the installed type description if omitted.

        Raises
        ------
        ValueError
            If the topic was registered with another type.

        """
        if topic in self._topics:
            known = self._file.topic_records()[self._topics[topic] - 1][1].name
            if known != type_name:
                raise ValueError(
                    f'topic {topic} is already recorded as {known}, not {type_name}')
            return self._topics[topic]
        if type_name not in self._schema_ids:
            text = message_definition(type_name) if schema_text is None else schema_text
            self._schema_ids[type_name] = self._file.add_schema(type_name, text)
        digest = type_hash(type_name) if type_description_hash is None \
            else type_description_hash
        profiles = [dict(p) for p in qos_profiles]
        cid = self._file.add_channel(topic, self._schema_ids[type_name], {
            'offered_qos_profiles': _dump_qos(profiles), 'topic_type_hash': digest})
        self._topics[topic] = cid
        return cid

    @property
    def topics(self):
        """Return {topic: channel id} of the registered topics."""
        return dict(self._topics)

    def channel_id(self, topic):
        """Return the channel id of a registered topic (ValueError otherwise)."""
        try:
            return self._topics[topic]
        except KeyError:
            raise ValueError(f'topic {topic} was not added to the bag '
                             '(call add_topic first)') from None

    # -- messages -------------------------------------------------------------
    def write(self, topic, data, log_time_ns, publish_time_ns=None, sequence=0):
        """
        Write one serialised message.

        Parameters
        ----------
        topic : str or int
            Topic name or the channel id :meth:`add_topic` returned.
        data : bytes
            CDR-serialised message (as rclpy ``serialize_message`` returns).
        log_time_ns : int
            Receive time, ns.
        publish_time_ns : int, optional
            Send time, ns (default: ``log_time_ns``).
        sequence : int
            Publisher sequence number, if known.

        """
        cid = topic if isinstance(topic, int) else self.channel_id(topic)
        self._file.write(cid, data, log_time_ns, publish_time_ns, sequence)

    def write_batches(self, batches):
        """
        Write several topics' messages interleaved in log-time order.

        Parameters
        ----------
        batches : iterable of (topic, payloads, log_times_ns)
            Each batch is a topic, a sequence of serialised messages and
            their integer-nanosecond log times. Ties keep batch order.

        """
        ids, datas, times = [], [], []
        for topic, payloads, log_times in batches:
            log_times = np.asarray(log_times, dtype=np.int64).reshape(-1)
            if len(payloads) != len(log_times):
                raise ValueError(f'{topic}: {len(payloads)} payloads but '
                                 f'{len(log_times)} log times')
            cid = topic if isinstance(topic, int) else self.channel_id(topic)
            ids.append(np.full(len(log_times), cid, dtype=np.int64))
            datas.extend(payloads)
            times.append(log_times)
        if not datas:
            return
        all_times = np.concatenate(times)
        all_ids = np.concatenate(ids)
        order = np.argsort(all_times, kind='stable')
        write = self._file.write
        for i, cid, t in zip(order.tolist(), all_ids[order].tolist(),
                             all_times[order].tolist()):
            write(cid, datas[i], t)

    def flush_if_due(self):
        """Flush the open chunk if older than ``flush_interval_s`` (call from a timer)."""
        self._file.flush_if_due()

    def flush(self):
        """Close and flush the open chunk now."""
        self._file.flush()

    @property
    def message_count(self):
        """Return the number of messages written."""
        return self._file.message_count

    def set_custom_data(self, key, value):
        """Set one rosbag2 ``custom_data`` entry (written by :meth:`finish`)."""
        self.custom_data[str(key)] = str(value)

    # -- closing ----------------------------------------------------------------
    def finish(self):
        """Finish the MCAP file and write ``metadata.yaml``. Safe to call twice."""
        if self._file.finished:
            return
        info = _file_info_from_writer(self._file)
        text = metadata_yaml(self.path, [info], self.custom_data)
        try:
            self._file.add_metadata('rosbag2', {
                'serialized_metadata': text, 'ROS_DISTRO': ROS_DISTRO})
        finally:
            self._file.finish()
        _write_text_atomic(os.path.join(self.path, METADATA_FILE), text)

    def __enter__(self):
        """Return the writer."""
        return self

    def __exit__(self, *exc):
        """Finish the bag, also when the block raised."""
        self.finish()
        return False


def _write_text_atomic(path, text):
    tmp = path + '.tmp'
    with open(tmp, 'w', encoding='utf-8') as handle:
        handle.write(text)
        handle.flush()
    os.replace(tmp, path)


# --------------------------------------------------------------------------
# File summaries and metadata.yaml
# --------------------------------------------------------------------------

@dataclass
class TopicInfo:
    """
    One topic of a bag.

    Attributes
    ----------
    name : str
        Topic name.
    type_name : str
        ``package/msg/Name``.
    message_count : int
        Messages on the topic.
    schema_text : str
        The ros2msg definition stored in the bag.
    serialization_format : str
        ``cdr``.
    qos_profiles : list of dict
        Offered QoS profiles recorded with the topic.
    type_description_hash : str
        RIHS01 hash ('' if unknown).

    """

    name: str
    type_name: str
    message_count: int = 0
    schema_text: str = ''
    serialization_format: str = 'cdr'
    qos_profiles: list = field(default_factory=list)
    type_description_hash: str = ''


@dataclass
class FileInfo:
    """Summary of one MCAP file of a bag."""

    path: str
    topics: dict
    message_count: int
    start_time_ns: int
    end_time_ns: int
    complete: bool = True
    custom_data: dict = field(default_factory=dict)
    scan: object = None
    summary: object = None


def _topic_from(channel, schema, count):
    return TopicInfo(
        name=channel.topic,
        type_name=schema.name if schema is not None else '',
        message_count=int(count),
        schema_text=schema.data.decode('utf-8', 'replace') if schema is not None else '',
        serialization_format=channel.message_encoding,
        qos_profiles=_load_qos(channel.metadata.get('offered_qos_profiles', '')),
        type_description_hash=channel.metadata.get('topic_type_hash', ''))


def _file_info_from_writer(writer):
    topics = {}
    for channel, schema, count in writer.topic_records():
        topics[channel.topic] = _topic_from(channel, schema, count)
    start = writer.start_time_ns or 0
    return FileInfo(writer.path, topics, writer.message_count, start,
                    max(writer.end_time_ns, start))


def metadata_yaml(bag_dir, files, custom_data=None):
    """
    Return the rosbag2 ``metadata.yaml`` text (version 9) for ``files``.

    Parameters
    ----------
    bag_dir : str
        The bag directory (file paths are stored relative to it).
    files : list of FileInfo
        The MCAP files of the bag, in order.
    custom_data : dict, optional
        rosbag2 ``custom_data``.

    """
    counted = [f for f in files if f.message_count]
    start = min((f.start_time_ns for f in counted), default=0)
    end = max((f.end_time_ns for f in counted), default=start)
    topics = {}
    for info in files:
        for name, topic in info.topics.items():
            if name in topics:
                topics[name].message_count += topic.message_count
            else:
                topics[name] = TopicInfo(**{**topic.__dict__})
    data = {'rosbag2_bagfile_information': {
        'version': ROSBAG2_VERSION,
        'storage_identifier': 'mcap',
        'duration': {'nanoseconds': int(end - start)},
        'starting_time': {'nanoseconds_since_epoch': int(start)},
        'message_count': int(sum(f.message_count for f in files)),
        'topics_with_message_count': [{
            'topic_metadata': {
                'name': t.name, 'type': t.type_name,
                'serialization_format': t.serialization_format,
                'offered_qos_profiles': t.qos_profiles,
                'type_description_hash': t.type_description_hash},
            'message_count': int(t.message_count)} for t in topics.values()],
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': [os.path.relpath(f.path, bag_dir) for f in files],
        'files': [{
            'path': os.path.relpath(f.path, bag_dir),
            'starting_time': {'nanoseconds_since_epoch': int(f.start_time_ns)},
            'duration': {'nanoseconds': int(f.end_time_ns - f.start_time_ns)},
            'message_count': int(f.message_count)} for f in files],
        'custom_data': dict(custom_data) if custom_data else None,
        'ros_distro': ROS_DISTRO,
    }}
    return yaml.safe_dump(data, sort_keys=False, default_flow_style=False)


# --------------------------------------------------------------------------
# Tolerant scanning
# --------------------------------------------------------------------------

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
        Why the scan stopped early, if it did.
    messages : int
        Messages recovered.
    bad_chunks : int
        Chunks skipped because they failed to decompress or their CRC.
    last_log_time_ns : int or None
        Log time of the last recovered message.

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

    def describe(self):
        """Return a one-line human summary."""
        if self.complete and not self.problem:
            return f'{self.path}: complete, {self.messages} messages'
        state = 'data section intact, summary missing' if self.data_end else (
            self.problem or 'incomplete')
        lost = self.size_bytes - self.good_bytes
        return (f'{self.path}: {state}; recovered {self.messages} messages'
                f'{f", skipped {self.bad_chunks} corrupt chunks" if self.bad_chunks else ""}'
                f'{f", discarded {lost} trailing bytes" if lost > 0 else ""}')


def _parse_record(opcode, body):
    stream = ReadDataStream(io.BytesIO(body))
    if opcode == Opcode.MESSAGE:
        return Message.read(stream, len(body))
    reader = {Opcode.SCHEMA: Schema, Opcode.CHANNEL: Channel, Opcode.CHUNK: Chunk,
              Opcode.METADATA: Metadata, Opcode.HEADER: Header,
              Opcode.FOOTER: Footer, Opcode.DATA_END: DataEnd}.get(opcode)
    return reader.read(stream) if reader else None


def scan_mcap(path, report=None):
    """
    Yield the Schema, Channel, Message and Metadata records of an MCAP file.

    Reads sequentially and tolerates what a killed writer leaves: a missing
    summary, footer or magic, or a truncated final record. A chunk that fails
    to decompress or whose CRC does not match is skipped and counted; an
    unknown opcode or a length running past the end stops the scan. The
    outcome is recorded in ``report`` (a :class:`ScanReport`).

    Parameters
    ----------
    path : str
        MCAP file.
    report : ScanReport, optional
        Filled in as the scan proceeds.

    Raises
    ------
    ValueError
        If the file does not start with the MCAP magic.

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
        if magic != MCAP_MAGIC:
            raise ValueError(f'{path} is not an MCAP file (it does not start with the '
                             f'MCAP magic; {size} bytes)')
        position = len(MCAP_MAGIC)
        report.good_bytes = position
        while True:
            head = handle.read(9)
            if not head:
                report.problem = report.problem or 'the file ends without a footer'
                return
            if len(head) < 9:
                report.problem = f'truncated record header at byte {position}'
                return
            opcode, length = _RECORD_HEAD.unpack(head)
            if opcode not in _VALID_OPCODES:
                report.problem = f'corrupt record (opcode 0x{opcode:02x}) at byte {position}'
                return
            if length > size - position - 9:
                name = Opcode(opcode).name.lower()
                report.problem = (f'truncated {name} record at byte {position} '
                                  f'({size - position - 9} of {length} bytes present)')
                return
            body = handle.read(length)
            try:
                record = _parse_record(opcode, body)
                inner = breakup_chunk(record, validate_crc=True) \
                    if opcode == Opcode.CHUNK else None
            except Exception as exc:  # noqa: B902 - any decoder error means corrupt data
                if opcode == Opcode.CHUNK:
                    report.bad_chunks += 1
                    report.problem = (f'corrupt chunk at byte {position} skipped '
                                      f'({type(exc).__name__}: {exc})')
                    position += 9 + length
                    continue
                report.problem = (f'corrupt {Opcode(opcode).name.lower()} record at byte '
                                  f'{position} ({type(exc).__name__}: {exc})')
                return
            position += 9 + length
            report.good_bytes = position
            if opcode == Opcode.FOOTER:
                report.complete = handle.read(len(MCAP_MAGIC)) == MCAP_MAGIC
                if report.complete:
                    report.good_bytes = size
                else:
                    report.problem = 'the closing magic after the footer is missing'
                return
            if opcode == Opcode.DATA_END:
                report.data_end = True
                continue
            if report.data_end:
                continue        # summary section: repeated schemas/channels, indexes
            for item in (inner if inner is not None else (record,)):
                if isinstance(item, Message):
                    report.messages += 1
                    report.last_log_time_ns = item.log_time
                if isinstance(item, (Schema, Channel, Message, Metadata)):
                    yield item


# --------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------

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


def _resolve_files(path):
    """Return (bag_dir, [mcap files], metadata dict or None)."""
    path = os.path.abspath(path)
    if os.path.isfile(path):
        if path.endswith(METADATA_FILE):
            path = os.path.dirname(path)
        else:
            return os.path.dirname(path), [path], None
    if not os.path.isdir(path):
        raise FileNotFoundError(f'no bag at {path} (expected a bag directory or .mcap file)')
    meta = None
    meta_path = os.path.join(path, METADATA_FILE)
    if os.path.isfile(meta_path):
        try:
            with open(meta_path, encoding='utf-8') as handle:
                loaded = yaml.safe_load(handle)
            meta = loaded['rosbag2_bagfile_information']
        except (yaml.YAMLError, KeyError, TypeError) as exc:
            raise ValueError(f'{meta_path} is not rosbag2 metadata: {exc}') from None
    files = []
    if meta is not None and meta.get('relative_file_paths'):
        for rel in meta['relative_file_paths']:
            full = os.path.join(path, rel)
            if not os.path.isfile(full):
                raise FileNotFoundError(f'{meta_path} lists {rel}, which is missing')
            files.append(full)
    else:
        files = sorted(os.path.join(path, n) for n in os.listdir(path) if n.endswith('.mcap'))
    if not files:
        raise FileNotFoundError(f'no .mcap file in bag directory {path}')
    return path, files, meta


def _index_file(path, tolerant):
    """Return the FileInfo of one MCAP file, scanning it when it has no summary."""
    problem = None
    try:
        with open(path, 'rb') as handle:
            reader = make_reader(handle)
            summary = reader.get_summary()
            if summary is not None and summary.statistics is not None:
                stats = summary.statistics
                topics = {}
                for cid, channel in summary.channels.items():
                    topics[channel.topic] = _topic_from(
                        channel, summary.schemas.get(channel.schema_id),
                        stats.channel_message_counts.get(cid, 0))
                custom = {}
                for meta in reader.iter_metadata():
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
    if not report.complete and not tolerant:
        raise ValueError(
            f'{path} is an incomplete MCAP file ({report.problem or problem}); the '
            'recorder was probably killed. Recover it with: gyro-emulator bag repair '
            f'{os.path.dirname(path)}')
    topics = {c.topic: _topic_from(c, schemas.get(c.schema_id), counts.get(cid, 0))
              for cid, c in channels.items()}
    return FileInfo(path, topics, sum(counts.values()), start or 0, max(end, start or 0),
                    complete=report.complete, custom_data=custom, scan=report)


def _decompressor(compression):
    if compression == 'zstd':
        import zstandard
        dctx = zstandard.ZstdDecompressor()
        return lambda data, size: dctx.decompress(data, max_output_size=size)
    if compression == 'lz4':
        import lz4.frame
        return lambda data, size: lz4.frame.decompress(data)
    if compression == '':
        return lambda data, size: data
    raise ValueError(f'unsupported chunk compression {compression!r}')


def _chunks_in_order(summary):
    """Return the chunk indexes sorted by start time if they do not overlap, else None."""
    chunks = sorted(summary.chunk_indexes, key=lambda c: (c.message_start_time,
                                                          c.chunk_start_offset))
    for before, after in zip(chunks, chunks[1:]):
        if after.message_start_time < before.message_end_time:
            return None
    return chunks


def _iter_chunk_messages(handle, summary, chunks, channel_ids, start_ns, end_ns):
    """
    Yield (log_time, channel_id, publish_time, sequence, data) from indexed chunks.

    The fast path for complete files whose chunks do not overlap in time:
    each wanted chunk is read and decompressed once and its message records
    are unpacked with ``struct``; a chunk whose messages are out of order is
    sorted by log time (stable).
    """
    decompressors = {}
    unpack_head = _RECORD_HEAD.unpack_from
    unpack_msg = struct.Struct('<HIQQ').unpack_from
    for index in chunks:
        if start_ns is not None and index.message_end_time < start_ns:
            continue
        if end_ns is not None and index.message_start_time >= end_ns:
            continue
        if channel_ids is not None and index.message_index_offsets and not (
                channel_ids & index.message_index_offsets.keys()):
            continue
        handle.seek(index.chunk_start_offset + 9)
        record = Chunk.read(ReadDataStream(handle))
        decompress = decompressors.get(record.compression)
        if decompress is None:
            decompress = decompressors[record.compression] = _decompressor(record.compression)
        buf = decompress(record.data, record.uncompressed_size)
        out = []
        pos, end = 0, len(buf)
        while pos < end:
            opcode, length = unpack_head(buf, pos)
            if opcode == 5:
                cid, seq, log_time, pub_time = unpack_msg(buf, pos + 9)
                if ((channel_ids is None or cid in channel_ids)
                        and (start_ns is None or log_time >= start_ns)
                        and (end_ns is None or log_time < end_ns)):
                    out.append((log_time, cid, pub_time, seq, buf[pos + 31:pos + 9 + length]))
            pos += 9 + length
        if any(a[0] > b[0] for a, b in zip(out, out[1:])):
            out.sort(key=lambda item: item[0])
        yield from out


class BagReader:
    """
    Read a rosbag2 MCAP bag directory (or a single .mcap file).

    Parameters
    ----------
    path : str
        Bag directory (with or without ``metadata.yaml``) or ``.mcap`` file.
    tolerant : bool
        Read files without summary/footer or with a truncated tail (what a
        SIGKILL leaves) by scanning them; :attr:`problems` then says what was
        recovered. Without it such a file raises ``ValueError`` naming
        ``gyro-emulator bag repair``.

    Attributes
    ----------
    topics : dict of str to TopicInfo
        The topics, with message counts.
    message_count, start_time_ns, end_time_ns : int
        Totals over all files (times of the first and last message, ns).
    problems : list of str
        Recovery notes of incomplete files ([] for a complete bag).

    """

    def __init__(self, path, tolerant=False):
        self.path, self.files, self.metadata = _resolve_files(path)
        self.tolerant = tolerant
        self._infos = [_index_file(f, tolerant) for f in self.files]
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
        self.problems = [i.scan.describe() for i in self._infos if not i.complete]

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
                        handle, summary, chunks, ids, start_ns, end_ns):
                    topic, type_name = names[cid]
                    yield BagMessage(topic, type_name, log_time, pub, data, seq)
            return
        if info.complete and info.scan is None:
            with open(info.path, 'rb') as handle:
                reader = make_reader(handle)
                for schema, channel, msg in reader.iter_messages(
                        topics=topics, starting_at=start_ns, ending_before=end_ns,
                        log_time_order=True):
                    yield BagMessage(channel.topic, schema.name if schema else '',
                                     msg.log_time, msg.publish_time, msg.data, msg.sequence)
            return
        schemas, channels = {}, {}
        wanted = None if topics is None else set(topics)
        for record in scan_mcap(info.path):
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
        from mcap_ros2.decoder import DecoderFactory
        topics = self._check_topics(topics)
        factory = DecoderFactory()
        for info in self._infos:
            if info.complete and info.scan is None:
                with open(info.path, 'rb') as handle:
                    reader = make_reader(handle, decoder_factories=[factory])
                    for schema, channel, msg, decoded in reader.iter_decoded_messages(
                            topics=topics, starting_at=start_ns, ending_before=end_ns):
                        yield BagMessage(channel.topic, schema.name if schema else '',
                                         msg.log_time, msg.publish_time, msg.data,
                                         msg.sequence), decoded
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
                                                 ids, start_ns, end_ns):
                    times.append(item[0])
                    payloads.append(item[4])
        else:
            for item in self.messages(topic, start_ns, end_ns):
                times.append(item.log_time_ns)
                payloads.append(item.data)
        return TopicArrays(topic, np.asarray(times, dtype=np.int64),
                           cdr.decode(type_name, payloads))

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
            lines.append(f'Incomplete:       {note}')
        if self.metadata is None:
            lines.append('Note:             metadata.yaml is missing '
                         '(gyro-emulator bag repair writes it)')
        return '\n'.join(lines)


def read_messages(path, topics=None, start_ns=None, end_ns=None, tolerant=False):
    """Yield the :class:`BagMessage` of a bag (see :meth:`BagReader.messages`)."""
    yield from BagReader(path, tolerant=tolerant).messages(topics, start_ns, end_ns)


# --------------------------------------------------------------------------
# Repair
# --------------------------------------------------------------------------

@dataclass
class RepairReport:
    """
    What :func:`repair_bag` did.

    Attributes
    ----------
    bag_dir : str
        The repaired bag directory.
    scans : list of ScanReport
        One per MCAP file.
    rewritten : list of str
        Files rewritten from recovered records.
    backups : list of str
        Originals kept beside the repaired files.
    topics : dict of str to int
        Messages per topic in the repaired bag.
    start_time_ns, end_time_ns : int
        Span of the recovered messages, ns.

    """

    bag_dir: str
    scans: list = field(default_factory=list)
    rewritten: list = field(default_factory=list)
    backups: list = field(default_factory=list)
    topics: dict = field(default_factory=dict)
    start_time_ns: int = 0
    end_time_ns: int = 0

    @property
    def message_count(self):
        """Return the total recovered messages."""
        return sum(self.topics.values())

    def describe(self):
        """Return a human summary, one line per file and per topic."""
        lines = [s.describe() for s in self.scans]
        if self.rewritten:
            lines.append('rewrote ' + ', '.join(os.path.basename(p) for p in self.rewritten)
                         + ' with summary and footer')
        for path in self.backups:
            lines.append(f'kept the original as {os.path.basename(path)}')
        for name in sorted(self.topics):
            lines.append(f'  {name}: {self.topics[name]} messages')
        span = (self.end_time_ns - self.start_time_ns) / 1e9
        lines.append(f'{self.message_count} messages over {span:.3f} s; wrote '
                     f'{os.path.join(self.bag_dir, METADATA_FILE)}')
        return '\n'.join(lines)


def _rewrite(source, target, compression):
    """Copy the recovered records of ``source`` into a complete file ``target``."""
    report = ScanReport(source)
    writer = McapFileWriter(target, compression=compression, flush_interval_s=3600.0)
    schema_ids, channel_ids, custom = {}, {}, {}
    try:
        for record in scan_mcap(source, report):
            if isinstance(record, Message):
                cid = channel_ids.get(record.channel_id)
                if cid is not None:
                    writer.write(cid, record.data, record.log_time, record.publish_time,
                                 record.sequence)
            elif isinstance(record, Schema):
                if record.id not in schema_ids:
                    schema_ids[record.id] = writer.add_schema(record.name, record.data,
                                                              record.encoding)
            elif isinstance(record, Channel):
                if record.id not in channel_ids and record.schema_id in schema_ids:
                    channel_ids[record.id] = writer.add_channel(
                        record.topic, schema_ids[record.schema_id], record.metadata,
                        record.message_encoding)
            elif isinstance(record, Metadata) and record.name == 'gyro_emulator':
                custom = dict(record.metadata)
                writer.add_metadata(record.name, record.metadata)
    finally:
        writer.finish()
    info = _file_info_from_writer(writer)
    info.custom_data = custom
    return report, info


def repair_bag(path, out_dir=None, backup=True, compression='zstd'):
    """
    Make a bag whole again after its recorder was killed.

    Every MCAP file without a valid summary and footer is scanned
    (:func:`scan_mcap`) and rewritten with all recovered messages; then
    ``metadata.yaml`` is regenerated from the files. A complete bag only gets
    its ``metadata.yaml`` rewritten.

    Parameters
    ----------
    path : str
        Bag directory (or one .mcap file).
    out_dir : str, optional
        Write the repaired bag here instead of in place (must not exist).
    backup : bool
        In place, keep each rewritten original as ``<file>.orig``.
    compression : str
        Chunk compression of rewritten files.

    Returns
    -------
    RepairReport

    Raises
    ------
    ValueError
        If a file is not MCAP at all (bad magic).

    """
    bag_dir, files, meta = _resolve_files(path)
    if out_dir is not None:
        out_dir = os.path.abspath(out_dir)
        if os.path.exists(out_dir) and os.listdir(out_dir):
            raise FileExistsError(f'output directory {out_dir} exists and is not empty')
        os.makedirs(out_dir, exist_ok=True)
    target_dir = out_dir or bag_dir
    report = RepairReport(target_dir)
    infos = []
    custom = dict((meta or {}).get('custom_data') or {})
    for source in files:
        target = os.path.join(target_dir, os.path.basename(source))
        try:
            info = _index_file(source, tolerant=False)
        except ValueError:
            info = None
        if info is not None:
            scan = ScanReport(source, size_bytes=os.path.getsize(source),
                              good_bytes=os.path.getsize(source), complete=True,
                              messages=info.message_count)
            if target != source:
                import shutil
                shutil.copyfile(source, target)
                info.path = target
            report.scans.append(scan)
        else:
            tmp = target + '.repair-tmp'
            scan, info = _rewrite(source, tmp, compression)
            report.scans.append(scan)
            if target == source and backup:
                os.replace(source, source + '.orig')
                report.backups.append(source + '.orig')
            os.replace(tmp, target)
            info.path = target
            report.rewritten.append(target)
        for key, value in info.custom_data.items():
            custom.setdefault(key, value)
        infos.append(info)
    for info in infos:
        for name, topic in info.topics.items():
            report.topics[name] = report.topics.get(name, 0) + topic.message_count
    counted = [i for i in infos if i.message_count]
    report.start_time_ns = min((i.start_time_ns for i in counted), default=0)
    report.end_time_ns = max((i.end_time_ns for i in counted), default=0)
    _write_text_atomic(os.path.join(target_dir, METADATA_FILE),
                       metadata_yaml(target_dir, infos, custom))
    return report
