"""Bags another library wrote (rosbags' rosbag2 Writer): read as written, or refused."""

import os

from gyro_emulator import cli
from gyro_emulator.recording import bag, cdr, files
import numpy as np
import pytest

IMU = 'sensor_msgs/msg/Imu'
TOPIC = '/imu/data'
T0_NS = 1_700_000_000_000_000_000
COUNT = 400


def _imu_messages(typestore, stamps_ns=None):
    """Return (log time, Imu) of COUNT rosbags messages at 200 Hz with seeded rates."""
    types = typestore.types
    rates = np.random.default_rng(11).normal(scale=0.01, size=(COUNT, 3))
    vector, quaternion = types['geometry_msgs/msg/Vector3'], types['geometry_msgs/msg/Quaternion']
    messages = []
    for i, rate in enumerate(rates):
        log_ns = T0_NS + i * 5_000_000
        stamp_ns = log_ns if stamps_ns is None else int(stamps_ns[i])
        header = types['std_msgs/msg/Header'](
            stamp=types['builtin_interfaces/msg/Time'](sec=stamp_ns // 10**9,
                                                       nanosec=stamp_ns % 10**9),
            frame_id='imu_link')
        messages.append((log_ns, types[IMU](
            header=header, orientation=quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=np.array([-1.0] + [0.0] * 8),
            angular_velocity=vector(x=rate[0], y=rate[1], z=rate[2]),
            angular_velocity_covariance=np.zeros(9),
            linear_acceleration=vector(x=0.0, y=0.0, z=9.81),
            linear_acceleration_covariance=np.zeros(9))))
    return messages


def _write(path, connections=1, little_endian=True, compression_mode=None, storage='mcap',
           stamps_ns=None):
    """Write COUNT Imu messages with rosbags, spread over ``connections`` connections."""
    from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness,
                                    QosReliability, QosTime)
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
    from rosbags.typesys import get_typestore, Stores

    typestore = get_typestore(Stores.ROS2_JAZZY)
    zero = QosTime(sec=0, nsec=0)
    writer = Writer(path, version=9, storage_plugin=getattr(StoragePlugin, storage.upper()))
    if compression_mode:
        writer.set_compression(getattr(CompressionMode, compression_mode.upper()),
                               CompressionFormat.ZSTD)
    with writer:
        conns = [writer.add_connection(TOPIC, IMU, typestore=typestore, offered_qos_profiles=[
            Qos(QosHistory.KEEP_LAST, depth + 1, QosReliability.RELIABLE,
                QosDurability.VOLATILE, zero, zero, QosLiveliness.AUTOMATIC, zero, False)])
            for depth in range(connections)]
        for i, (stamp_ns, message) in enumerate(_imu_messages(typestore, stamps_ns)):
            data = typestore.serialize_cdr(message, IMU, little_endian=little_endian)
            writer.write(conns[i % connections], stamp_ns, bytes(data))
    return str(path)


def _cli(argv, capsys):
    """Run the command line; return (status, stdout, stderr)."""
    status = cli.main(argv)
    out, err = capsys.readouterr()
    return status, out, err


def test_a_topic_on_two_connections_counts_both(tmp_path, capsys):
    path = _write(tmp_path / 'two', connections=2)
    reader = bag.BagReader(path)
    assert reader.topics[TOPIC].message_count == COUNT == reader.message_count
    arrays = reader.read_arrays(TOPIC)
    assert len(arrays.log_time_ns) == COUNT
    assert reader.problems == []            # no "read 400 of the 200 messages the bag counts"
    status, out, _ = _cli(['bag', 'info', path], capsys)
    assert status == 0
    assert f'{COUNT} msgs' in out and 'Notice' not in out and 'repair' not in out
    assert 'the bag is sound' in bag.repair_bag(path).describe()
    # repair keeps rosbags' entry per connection, which counts the topic's messages whole
    meta = files.load_metadata(os.path.join(path, 'metadata.yaml'))
    assert [t['message_count'] for t in meta['topics_with_message_count']] == [COUNT // 2] * 2


def test_big_endian_cdr_reads_as_little_endian(tmp_path):
    little = bag.BagReader(_write(tmp_path / 'le')).read_arrays(TOPIC)
    big = bag.BagReader(_write(tmp_path / 'be', little_endian=False)).read_arrays(TOPIC)
    np.testing.assert_array_equal(big.log_time_ns, little.log_time_ns)
    np.testing.assert_array_equal(big.stamp_ns, little.stamp_ns)
    np.testing.assert_array_equal(big.decoded.values, little.decoded.values)
    assert list(big.decoded.frame_id) == ['imu_link'] * COUNT


def test_a_payload_that_is_not_cdr_is_named(tmp_path):
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import get_typestore, Stores

    path = tmp_path / 'junk'
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection(TOPIC, IMU, typestore=get_typestore(Stores.ROS2_JAZZY))
        for i in range(3):                  # big-endian header, then too few bytes
            writer.write(conn, T0_NS + i, b'\x00\x00\x00\x00\x01\x02')
    with pytest.raises(ValueError, match=rf'^{TOPIC}: message 0 is not CDR of {IMU} \('):
        bag.BagReader(str(path)).read_arrays(TOPIC)


@pytest.mark.parametrize('mode', ['message', 'file'])
def test_compressed_rosbag2_files_are_refused_and_left_alone(tmp_path, capsys, mode):
    path = _write(tmp_path / mode, compression_mode=mode)
    meta_path = os.path.join(path, 'metadata.yaml')
    before = {name: open(os.path.join(path, name), 'rb').read() for name in os.listdir(path)}
    with pytest.raises(ValueError, match=f"compression_mode is '{mode}'"):
        bag.BagReader(path)
    for action in ('info', 'repair'):
        status, out, err = _cli(['bag', action, path], capsys)
        assert status != 0 and out == ''
        assert len(err.strip().splitlines()) == 1
        assert f"compression_mode is '{mode}'" in err and 'rosbags-convert' in err
    # repair left the bag as it was: its metadata still says the messages are compressed
    assert {name: open(os.path.join(path, name), 'rb').read()
            for name in os.listdir(path)} == before
    assert files.load_metadata(meta_path)['compression_mode'] == mode


def _contents(path):
    """Return {name: (bytes, mtime ns)} of the files in ``path``."""
    return {name: (open(os.path.join(path, name), 'rb').read(),
                   os.stat(os.path.join(path, name)).st_mtime_ns) for name in os.listdir(path)}


def test_repairing_a_sound_bag_changes_no_byte(tmp_path, capsys):
    # a rosbags bag lists a topic once per connection, with each one's QoS and
    # the type hash, and ros_distro: rosbags; repair rewrote it as one entry
    # without them, version 9 and jazzy, though nothing was wrong
    path = _write(tmp_path / 'sound', connections=2)
    before = _contents(path)
    status, out, err = _cli(['bag', 'repair', path], capsys)
    assert status == 0 and err == ''
    assert 'the bag is sound' in out and 'kept byte for byte' in out and 'rewrote' not in out
    assert _contents(path) == before
    copy = str(tmp_path / 'copy')
    status, out, err = _cli(['bag', 'repair', path, '--out', copy], capsys)
    assert status == 0 and 'the bag is sound' in out
    assert {n: b for n, (b, _) in _contents(copy).items()} == \
        {n: b for n, (b, _) in before.items()}


@pytest.mark.parametrize('field,value,said', [
    ('message_count', 399, 'metadata.yaml counts 399 messages, the files hold 400'),
    ('starting_time', {'nanoseconds_since_epoch': T0_NS - 7},
     f'metadata.yaml gives starting_time {T0_NS - 7} ns, the files {T0_NS} ns'),
    ('duration', {'nanoseconds': 5}, 'metadata.yaml gives duration 5 ns, the files 1995000000 ns'),
])
def test_a_metadata_yaml_that_disagrees_is_said_and_rewritten(tmp_path, capsys, field,
                                                              value, said):
    import yaml
    path = _write(tmp_path / 'off', connections=1)
    meta_path = os.path.join(path, 'metadata.yaml')
    with open(meta_path, encoding='utf-8') as handle:
        doc = yaml.safe_load(handle)
    doc['rosbag2_bagfile_information'][field] = value
    with open(meta_path, 'w', encoding='utf-8') as handle:
        yaml.safe_dump(doc, handle)
    status, out, _ = _cli(['bag', 'info', path], capsys)
    assert status == 0 and f'Notice:           {said}' in out
    assert 'run: gyro-emulator bag repair' in out
    mcap_before = _contents(path)['off.mcap']
    status, out, _ = _cli(['bag', 'repair', path], capsys)
    line = next(n for n in out.splitlines() if said in n)
    assert status == 0 and line.endswith(': rewrote metadata.yaml')
    assert _contents(path)['off.mcap'] == mcap_before
    status, out, _ = _cli(['bag', 'info', path], capsys)
    assert 'Notice' not in out and 'repair' not in out
    status, out, _ = _cli(['bag', 'repair', path], capsys)
    assert 'the bag is sound' in out


def test_a_sqlite3_bag_is_refused_naming_its_storage(tmp_path, capsys):
    path = _write(tmp_path / 'sq', storage='sqlite3')
    status, out, err = _cli(['replay', path, '--out', str(tmp_path / 'out')], capsys)
    assert status != 0 and out == '' and len(err.strip().splitlines()) == 1
    assert "storage_identifier is 'sqlite3': expected \"mcap\"" in err
    assert not os.path.exists(tmp_path / 'out')
    os.remove(os.path.join(path, 'metadata.yaml'))
    status, out, err = _cli(['bag', 'info', path], capsys)
    assert status != 0 and 'sq.db3, a rosbag2 sqlite3' in err and 'rosbags-convert' in err


def test_fixed_layouts_read_from_decoded_messages():
    stamps = T0_NS + np.arange(3, dtype=np.int64)
    values = np.random.default_rng(2).normal(size=(3, len(cdr.LAYOUTS[IMU].fields)))
    payloads = cdr.encode(IMU, stamps, values, 'f')
    from mcap.records import Schema
    from mcap_ros2.decoder import DecoderFactory

    schema = Schema(id=1, name=IMU, encoding='ros2msg',
                    data=bag.message_definition(IMU).encode('utf-8'))
    decoder = DecoderFactory().decoder_for('cdr', schema)
    decoded = cdr.from_messages(IMU, [decoder(p) for p in payloads])
    np.testing.assert_array_equal(decoded.values, values)
    np.testing.assert_array_equal(decoded.stamp_ns, stamps)


def test_what_the_stamp_rule_did_is_said(tmp_path, capsys):
    from gyro_emulator.analysis.replay.inputs import load_inputs

    stamps = T0_NS + np.arange(COUNT, dtype=np.int64) * 5_000_000
    stamps[[100, 101]] = stamps[[101, 100]]         # two messages out of stamp order
    inputs = load_inputs(_write(tmp_path / 'swapped', stamps_ns=stamps))
    assert f'{TOPIC}: its header stamps step back 1 time(s) in bag order (at most 0.005 s): ' \
        'read in time order' in inputs.notes
    np.testing.assert_array_equal(inputs.stamp_ns, np.sort(stamps))
    path = _write(tmp_path / 'zero', stamps_ns=np.zeros(COUNT))
    inputs = load_inputs(path)
    assert f'{TOPIC}: every header stamp is zero: its log (receive) times are used' in inputs.notes
    status, _, err = _cli(['allan', path, '--json', str(tmp_path / 'a.json')], capsys)
    assert status == 0 and 'every header stamp is zero' in err
    # in order, stamped: nothing to say
    assert not any('stamp' in n and 'step back' in n
                   for n in load_inputs(_write(tmp_path / 'plain')).notes)


def test_repairing_one_file_of_a_bag_repairs_the_bag(tmp_path, capsys):
    """In place, ``bag repair DIR/x.mcap`` never rewrites DIR's metadata.yaml from x alone."""
    from gyro_emulator.recording.reader import index_file
    from rosbags.rosbag2 import Reader

    joined = tmp_path / 'joined'
    joined.mkdir()
    for part in ('a', 'b'):         # a bag of two files (rosbag2 splits by size or time)
        written = _write(tmp_path / part)
        os.rename(os.path.join(written, f'{part}.mcap'), joined / f'{part}.mcap')
    infos = [index_file(str(joined / f'{part}.mcap'), False) for part in ('a', 'b')]
    (joined / 'metadata.yaml').write_text(bag.metadata_yaml(str(joined), infos))
    status, out, err = _cli(['bag', 'repair', str(joined / 'a.mcap')], capsys)
    assert status == 0, err
    meta = files.load_metadata(str(joined / 'metadata.yaml'))
    assert meta['relative_file_paths'] == ['a.mcap', 'b.mcap']
    with Reader(joined) as reader:                      # what rosbags and ros2 bag see
        assert reader.message_count == 2 * COUNT
    # a file the bag beside it does not list: refused, that metadata.yaml left alone
    stray = joined / 'stray.mcap'
    stray.write_bytes((joined / 'a.mcap').read_bytes())
    before = (joined / 'metadata.yaml').read_bytes()
    status, out, err = _cli(['bag', 'repair', str(stray)], capsys)
    assert status != 0 and len(err.strip().splitlines()) == 1
    assert 'is not a file of the bag' in err and 'with --out DIR' in err
    assert (joined / 'metadata.yaml').read_bytes() == before
    # a compressed bag's file: refused as the bag is
    path = _write(tmp_path / 'zipped', compression_mode='message')
    status, out, err = _cli(['bag', 'repair', os.path.join(path, 'zipped.mcap')], capsys)
    assert status != 0 and "compression_mode is 'message'" in err


def test_bag_info_of_one_file_does_not_call_the_metadata_missing(tmp_path, capsys):
    path = _write(tmp_path / 'whole')
    status, out, _ = _cli(['bag', 'info', os.path.join(path, 'whole.mcap')], capsys)
    assert status == 0 and 'metadata.yaml is missing' not in out
    assert 'one file read alone: the metadata.yaml beside it was not read' in out
    os.remove(os.path.join(path, 'metadata.yaml'))
    status, out, _ = _cli(['bag', 'info', path], capsys)
    assert status == 0 and 'metadata.yaml is missing (gyro-emulator bag repair writes it)' in out


def test_replay_refuses_times_before_zero_before_any_work(tmp_path, capsys):
    from gyro_emulator.analysis.replay.inputs import load_inputs

    stamps = -5 * 10**9 + np.arange(COUNT, dtype=np.int64) * 5_000_000
    path = _write(tmp_path / 'early', stamps_ns=stamps)
    with pytest.raises(ValueError, match=rf'{TOPIC} times start at -5 s: allowed >= 0 .*'
                                         'try --use-log-time$'):
        load_inputs(path)
    assert len(load_inputs(path, use_log_time=True).stamp_ns) == COUNT
    status, out, err = _cli(['replay', path, '--out', str(tmp_path / 'out')], capsys)
    assert status != 0 and len(err.strip().splitlines()) == 1 and 'times start at -5 s' in err
    assert not os.path.exists(tmp_path / 'out')
