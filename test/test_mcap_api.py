"""
Pin of the ``mcap`` API that the recording layer builds on (docs/recording.md).

The writer, scanner and reader use mcap's record-level modules, not its
``Writer``; an upgrade that renames a symbol, reorders a record's fields or
changes a signature must fail here, not in a user's recording.
"""

import ast
import dataclasses
from importlib import import_module, metadata
import inspect
import io
import os
import re
import struct
import zlib

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: The versions this API was checked against (and requirements.txt pins).
CHECKED = {'mcap': '1.6.0', 'mcap-ros2-support': '0.6.0'}

#: Every symbol the package imports from mcap (grep 'from mcap' gyro_emulator/).
SYMBOLS = [('mcap.data_stream', 'RecordBuilder'), ('mcap.data_stream', 'ReadDataStream'),
           ('mcap.opcode', 'Opcode'), ('mcap.summary', 'Summary'),
           ('mcap.reader', 'make_reader'), ('mcap_ros2.decoder', 'DecoderFactory'),
           ('mcap.exceptions', 'McapError')] + [
    ('mcap.records', name) for name in (
        'Channel', 'Chunk', 'ChunkIndex', 'DataEnd', 'Footer', 'Header', 'Message',
        'Metadata', 'MetadataIndex', 'Schema', 'Statistics', 'SummaryOffset')]

#: Record fields in order (Header, DataEnd and SummaryOffset are built positionally).
FIELDS = {
    'Header': ['profile', 'library'],
    'Footer': ['summary_start', 'summary_offset_start', 'summary_crc'],
    'Schema': ['id', 'data', 'encoding', 'name'],
    'Channel': ['id', 'topic', 'message_encoding', 'metadata', 'schema_id'],
    'Message': ['channel_id', 'log_time', 'data', 'publish_time', 'sequence'],
    'Chunk': ['compression', 'data', 'message_end_time', 'message_start_time',
              'uncompressed_crc', 'uncompressed_size'],
    'ChunkIndex': ['chunk_length', 'chunk_start_offset', 'compression', 'compressed_size',
                   'message_end_time', 'message_index_length', 'message_index_offsets',
                   'message_start_time', 'uncompressed_size'],
    'Statistics': ['attachment_count', 'channel_count', 'channel_message_counts',
                   'chunk_count', 'message_count', 'message_end_time',
                   'message_start_time', 'metadata_count', 'schema_count'],
    'Metadata': ['name', 'metadata'],
    'MetadataIndex': ['offset', 'length', 'name'],
    'SummaryOffset': ['group_opcode', 'group_start', 'group_length'],
    'DataEnd': ['data_section_crc'],
}

#: MCAP spec opcodes; MESSAGE, MESSAGE_INDEX and FOOTER heads are packed by hand.
OPCODES = {'HEADER': 1, 'FOOTER': 2, 'SCHEMA': 3, 'CHANNEL': 4, 'MESSAGE': 5, 'CHUNK': 6,
           'MESSAGE_INDEX': 7, 'CHUNK_INDEX': 8, 'STATISTICS': 11, 'METADATA': 12,
           'METADATA_INDEX': 13, 'SUMMARY_OFFSET': 14, 'DATA_END': 15}


def _params(func):
    return inspect.signature(func).parameters


@pytest.mark.parametrize('package', sorted(CHECKED))
def test_the_installed_and_pinned_versions_are_the_checked_ones(package):
    with open(os.path.join(ROOT, 'requirements.txt')) as handle:
        pins = dict(re.findall(r'^([A-Za-z0-9_.-]+)==(\S+)', handle.read(), re.M))
    assert pins.get(package) == CHECKED[package], \
        f'requirements.txt pins {package} {pins.get(package)}: check docs/recording.md first'
    assert metadata.version(package) == CHECKED[package]


@pytest.mark.parametrize('module,name', SYMBOLS, ids=[f'{m}.{n}' for m, n in SYMBOLS])
def test_every_symbol_imports(module, name):
    assert hasattr(import_module(module), name)


def test_the_package_imports_no_other_mcap_symbol():
    found = set()
    for folder, _, files in os.walk(os.path.join(ROOT, 'gyro_emulator')):
        for name in files:
            if name.endswith('.py'):
                with open(os.path.join(folder, name)) as handle:
                    tree = ast.parse(handle.read())
                for node in ast.walk(tree):
                    if isinstance(node, ast.Import):
                        assert not any(a.name.startswith('mcap') for a in node.names), name
                    elif isinstance(node, ast.ImportFrom) and (
                            node.module or '').startswith('mcap'):
                        found |= {(node.module, a.name) for a in node.names}
    assert found == set(SYMBOLS)


@pytest.mark.parametrize('name', sorted(FIELDS))
def test_record_fields_read_and_write(name):
    record = getattr(import_module('mcap.records'), name)
    assert [f.name for f in dataclasses.fields(record)] == FIELDS[name]
    assert list(_params(record.write)) == ['self', 'stream']
    assert list(_params(record.read)) == (['stream', 'length'] if name == 'Message'
                                          else ['stream'])


def test_opcodes_are_the_spec_values():
    from mcap.opcode import Opcode
    assert {name: int(Opcode[name]) for name in OPCODES} == OPCODES


def test_reader_signatures():
    from mcap.data_stream import ReadDataStream, RecordBuilder
    from mcap.reader import make_reader, McapReader
    from mcap.stream_reader import breakup_chunk
    from mcap.summary import Summary
    from mcap_ros2.decoder import DecoderFactory
    assert isinstance(inspect.getattr_static(RecordBuilder, 'count'), property)
    assert callable(RecordBuilder().end)
    assert list(_params(ReadDataStream))[0] == 'stream'
    assert list(_params(breakup_chunk))[:2] == ['chunk', 'validate_crc']
    assert {'stream', 'decoder_factories'} <= set(_params(make_reader))
    for method in ('iter_messages', 'iter_decoded_messages'):
        assert {'topics', 'starting_at', 'ending_before', 'log_time_order'} <= set(
            _params(getattr(McapReader, method)))
    assert callable(McapReader.get_summary) and callable(McapReader.iter_metadata)
    assert {'statistics', 'schemas', 'channels', 'chunk_indexes'} <= set(vars(Summary()))
    assert list(_params(DecoderFactory.decoder_for))[1:] == ['message_encoding', 'schema']


def test_a_chunk_round_trips_through_builder_stream_and_breakup():
    """The writer's way (hand-packed message, RecordBuilder) read back the scanner's way."""
    from mcap.data_stream import ReadDataStream, RecordBuilder
    from mcap.opcode import Opcode
    from mcap.records import Chunk, Message
    from mcap.stream_reader import breakup_chunk
    payload = b'\x00\x01\x00\x00abc'
    raw = struct.pack('<BQHIQQ', Opcode.MESSAGE, 22 + len(payload), 3, 7, 10, 11) + payload
    builder = RecordBuilder()
    Chunk(compression='', data=raw, message_start_time=10, message_end_time=10,
          uncompressed_crc=zlib.crc32(raw), uncompressed_size=len(raw)).write(builder)
    assert builder.count == len(raw) + 9 + 8 + 8 + 8 + 4 + 4 + 8
    record = builder.end()
    assert record[0] == Opcode.CHUNK
    chunk = Chunk.read(ReadDataStream(io.BytesIO(record[9:])))
    (message,) = breakup_chunk(chunk, validate_crc=True)
    assert isinstance(message, Message)
    assert (message.channel_id, message.sequence, message.log_time, message.publish_time,
            message.data) == (3, 7, 10, 11, payload)
    # the scanner's own struct unpacking gives the library's records
    from gyro_emulator.recording.scan import _chunk, chunk_records
    assert _chunk(record[9:]) == chunk
    assert chunk_records(chunk) == breakup_chunk(chunk, validate_crc=True)


def test_the_summary_read_by_hand_is_the_library_summary(tmp_path):
    """read_summary (chunk indexes unpacked with struct) gives get_summary and iter_metadata."""
    from gyro_emulator.recording import bag, cdr
    from gyro_emulator.recording.reader import read_summary
    from mcap.reader import make_reader
    from mcap.writer import Writer
    import numpy as np
    imu = 'sensor_msgs/msg/Imu'
    ours = tmp_path / 'ours'
    stamps = 1_700_000_000_000_000_000 + np.arange(500, dtype=np.int64) * 5_000_000
    values = np.zeros((500, len(cdr.LAYOUTS[imu].fields)))
    with bag.BagWriter(str(ours), chunk_size=2000, custom_data={'seed': '3'}) as writer:
        writer.add_topic('/imu/data_raw', imu)
        writer.write_batches([('/imu/data_raw', cdr.encode(imu, stamps, values, 'imu'),
                               stamps)])
    library = tmp_path / 'library.mcap'
    with open(library, 'wb') as handle:
        writer = Writer(handle, chunk_size=500)
        writer.start('ros2', 'test')
        channel = writer.register_channel('/t', 'cdr', writer.register_schema(
            's', 'ros2msg', b'float64 x'))
        for i in range(300):
            writer.add_message(channel, log_time=i, data=bytes(12), publish_time=i)
        writer.add_metadata('m', {'k': 'v'})
        writer.finish()
    for path in (ours / 'ours_0.mcap', library):
        with open(path, 'rb') as handle:
            summary, metadata = read_summary(handle)
            handle.seek(0)
            reader = make_reader(handle)
            expected = reader.get_summary()
            assert len(summary.chunk_indexes) > 1
            for name in ('chunk_indexes', 'channels', 'schemas', 'statistics',
                         'metadata_indexes'):
                assert getattr(summary, name) == getattr(expected, name), name
            assert metadata == list(reader.iter_metadata()) and metadata


def test_the_library_errors_derive_from_mcap_error():
    """The reader turns McapError (EndOfFile, InvalidMagic, ...) into one-line ValueErrors."""
    from mcap import exceptions
    for name in ('EndOfFile', 'InvalidMagic', 'RecordLengthLimitExceeded'):
        assert issubclass(getattr(exceptions, name), exceptions.McapError)


def test_the_hand_packed_footer_and_chunk_heads_match_the_library(tmp_path):
    """The summary CRC check and the chunk resync read the library's layout and CRC rule."""
    from gyro_emulator.recording.scan import _intact_chunk_at, summary_crc_problem
    from mcap.writer import Writer
    path = tmp_path / 'library.mcap'
    with open(path, 'wb') as handle:
        writer = Writer(handle)
        writer.start('ros2', 'test')
        schema = writer.register_schema('s', 'ros2msg', b'float64 x')
        channel = writer.register_channel('/t', 'cdr', schema)
        for i in range(100):
            writer.add_message(channel, log_time=i, data=b'\x00\x01\x00\x00' + bytes(8),
                               publish_time=i)
        writer.finish()
    data = path.read_bytes()
    with open(path, 'rb') as handle:
        assert summary_crc_problem(handle, len(data)) is None
    chunk_at = data.index(bytes([6]), 8)
    assert _intact_chunk_at(data, chunk_at, chunk_at, len(data))
    flipped = bytearray(data)
    flipped[-20] ^= 1                          # inside the footer's summary_offset_start
    path.write_bytes(bytes(flipped))
    with open(path, 'rb') as handle:
        assert 'CRC mismatch' in summary_crc_problem(handle, len(flipped))
