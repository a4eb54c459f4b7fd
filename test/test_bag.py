"""The bag layer: rosbag2 MCAP writing, reading, rosbags acceptance, recovery."""

from functools import reduce
import os
import signal
import subprocess
import sys
import time

from conftest import ROOT
from gyro_emulator.recording import bag, cdr
import numpy as np
import pytest
import yaml

IMU = 'sensor_msgs/msg/Imu'
TEMPERATURE = 'sensor_msgs/msg/Temperature'
T0_NS = 1_700_000_000_123_456_789


def _imu_batch(count, seed, rate_hz=200.0):
    rng = np.random.default_rng(seed)
    times = T0_NS + np.round(np.arange(count) * 1e9 / rate_hz).astype(np.int64)
    values = rng.normal(size=(count, len(cdr.LAYOUTS[IMU].fields)))
    return times, values


def _write_bag(path, count=3000, seed=1, **kwargs):
    """Write Imu at 200 Hz and Temperature at 10 Hz; return the inputs."""
    times, values = _imu_batch(count, seed)
    temp_times = times[::20]
    temps = np.column_stack([20.0 + np.arange(len(temp_times)) * 0.01,
                             np.full(len(temp_times), 0.04)])
    with bag.BagWriter(path, custom_data={'seed': str(seed)}, **kwargs) as writer:
        writer.add_topic('/imu/data_raw', IMU, qos_profiles=[bag.qos_profile('best_effort')])
        writer.add_topic('/imu/temperature', TEMPERATURE)
        writer.write_batches([
            ('/imu/data_raw', cdr.encode(IMU, times, values, 'imu_link'), times),
            ('/imu/temperature', cdr.encode(TEMPERATURE, temp_times, temps, 'imu_link'),
             temp_times)])
    return times, values, temp_times, temps


@pytest.fixture(scope='module')
def written(tmp_path_factory):
    path = str(tmp_path_factory.mktemp('bags') / 'run')
    return path, _write_bag(path)


def test_message_definition_concatenates_dependencies_once():
    text = bag.message_definition(IMU)
    with open(os.path.join(sys.prefix, 'share', 'sensor_msgs', 'msg', 'Imu.msg'),
              encoding='utf-8') as handle:
        assert text.startswith(handle.read())
    for dep in ('std_msgs/Header', 'builtin_interfaces/Time', 'geometry_msgs/Quaternion',
                'geometry_msgs/Vector3'):
        assert text.count('=' * 80 + '\nMSG: ' + dep + '\n') == 1, dep
    assert 'MSG: sensor_msgs' not in text
    with pytest.raises(ValueError, match='no .msg definition'):
        bag.message_definition('sensor_msgs/msg/NoSuchType')
    with pytest.raises(ValueError, match='not understood'):
        bag.message_definition('Imu')


def test_type_hash_is_rihs01():
    assert bag.type_hash(IMU).startswith('RIHS01_')
    assert len(bag.type_hash(IMU)) == len('RIHS01_') + 64


def test_round_trip_values_and_times(written):
    path, (times, values, temp_times, temps) = written
    reader = bag.BagReader(path)
    assert reader.complete and reader.problems == []
    assert reader.message_count == len(times) + len(temp_times)
    assert reader.topics['/imu/data_raw'].message_count == len(times)
    assert reader.start_time_ns == T0_NS and reader.end_time_ns == times[-1]
    imu = reader.read_arrays('/imu/data_raw')
    np.testing.assert_array_equal(imu.log_time_ns, times)
    np.testing.assert_array_equal(imu.stamp_ns, times)
    np.testing.assert_array_equal(imu.decoded.values, values)
    np.testing.assert_array_equal(imu.field('angular_velocity'), values[:, 13:16])
    assert set(imu.decoded.frame_id) == {'imu_link'}
    temp = reader.read_arrays('/imu/temperature')
    np.testing.assert_array_equal(temp.field('temperature'), temps[:, 0])
    log_times = [m.log_time_ns for m in reader.messages()]
    assert log_times == sorted(log_times)
    assert reader.custom_data == {'seed': '1'}


def test_topic_and_time_filters(written):
    path, (times, _, temp_times, _) = written
    reader = bag.BagReader(path)
    start, end = int(times[100]), int(times[900])
    got = list(reader.messages('/imu/temperature', start_ns=start, end_ns=end))
    expected = temp_times[(temp_times >= start) & (temp_times < end)]
    assert [m.log_time_ns for m in got] == expected.tolist()
    assert {m.topic for m in got} == {'/imu/temperature'}
    assert got[0].type_name == TEMPERATURE
    sub = reader.read_arrays('/imu/data_raw', start_ns=start, end_ns=end)
    np.testing.assert_array_equal(sub.log_time_ns, times[100:900])
    with pytest.raises(ValueError, match='not in bag'):
        list(reader.messages('/nope'))


def test_decoded_messages_use_the_stored_schema(written):
    path, (times, values, _, _) = written
    reader = bag.BagReader(path)
    decoded = list(reader.decoded_messages('/imu/data_raw', end_ns=int(times[5])))
    assert len(decoded) == 5
    for i, (item, msg) in enumerate(decoded):
        assert msg.angular_velocity.y == values[i, 14]
        assert msg.header.frame_id == 'imu_link'
        assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == times[i]


def test_rosbags_accepts_the_bag(written):
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2 import Reader
    from pathlib import Path
    path, (times, values, temp_times, temps) = written
    with Reader(path) as reader:
        assert reader.message_count == len(times) + len(temp_times)
        assert reader.duration == times[-1] - times[0] + 1
        by_topic = {c.topic: c for c in reader.connections}
        assert by_topic['/imu/data_raw'].msgtype == IMU
        assert by_topic['/imu/data_raw'].msgcount == len(times)
        qos = by_topic['/imu/data_raw'].ext.offered_qos_profiles
        assert qos[0].reliability.name == 'BEST_EFFORT'
        assert by_topic['/imu/data_raw'].digest == bag.type_hash(IMU)
    # AnyReader decodes with the message definitions stored in the bag.
    with AnyReader([Path(path)]) as reader:
        gyro, temp = [], []
        for connection, stamp, raw in reader.messages():
            msg = reader.deserialize(raw, connection.msgtype)
            if connection.topic == '/imu/data_raw':
                gyro.append((stamp, msg.angular_velocity.x, msg.linear_acceleration.z))
            else:
                temp.append(msg.temperature)
    np.testing.assert_array_equal([g[0] for g in gyro], times)
    np.testing.assert_array_equal([g[1] for g in gyro], values[:, 13])
    np.testing.assert_array_equal([g[2] for g in gyro], values[:, 27])
    np.testing.assert_array_equal(temp, temps[:, 0])


def _rosbags_field(msg, name):
    """Return field ``a.b.c`` or ``a[i]`` of a rosbags message as a float."""
    dotted, _, index = name.partition('[')
    value = reduce(getattr, dotted.split('.'), msg)
    return float(value[int(index.rstrip(']'))] if index else value)


@pytest.mark.parametrize('type_name', sorted(cdr.LAYOUTS))
def test_every_cdr_layout_round_trips_and_agrees_with_rosbags(type_name):
    """Ours -> ours, ours -> rosbags and rosbags -> ours give back every field exactly."""
    from rosbags.typesys import get_typestore, Stores
    typestore = get_typestore(Stores.ROS2_JAZZY)
    layout = cdr.LAYOUTS[type_name]
    stamps_ns = T0_NS + np.array([0, 999_999_999, 86_400 * 10**9 + 1])
    values = np.random.default_rng(11).uniform(-1e4, 1e4, (len(stamps_ns), len(layout.fields)))
    values[0] = np.arange(len(layout.fields)) + 0.5
    values[1, 0], values[2, -1] = -0.0, 1e-300
    payloads = cdr.encode(type_name, stamps_ns, values, 'gyro_frame')
    ours = cdr.decode(type_name, payloads)
    assert np.array_equal(ours.values, values)
    assert np.array_equal(np.signbit(ours.values), np.signbit(values))
    for payload, stamp_ns, row in zip(payloads, stamps_ns, values):
        msg = typestore.deserialize_cdr(bytes(payload), type_name)
        assert [_rosbags_field(msg, name) for name in layout.fields] == list(row)
        if layout.has_header:
            assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == stamp_ns
            assert msg.header.frame_id == 'gyro_frame'
        back = cdr.decode(type_name, [bytes(typestore.serialize_cdr(msg, type_name))])
        assert np.array_equal(back.values[0], row)
        assert back.stamp_ns[0] == (stamp_ns if layout.has_header else 0)


def test_metadata_yaml_is_rosbag2_version_9(written):
    path, (times, _, temp_times, _) = written
    with open(os.path.join(path, 'metadata.yaml'), encoding='utf-8') as handle:
        meta = yaml.safe_load(handle)['rosbag2_bagfile_information']
    assert meta['version'] == 9
    assert meta['storage_identifier'] == 'mcap'
    assert meta['relative_file_paths'] == ['run_0.mcap']
    assert meta['message_count'] == len(times) + len(temp_times)
    assert meta['starting_time']['nanoseconds_since_epoch'] == T0_NS
    assert meta['duration']['nanoseconds'] == times[-1] - T0_NS
    counts = {t['topic_metadata']['name']: t['message_count']
              for t in meta['topics_with_message_count']}
    assert counts == {'/imu/data_raw': len(times), '/imu/temperature': len(temp_times)}
    assert meta['custom_data'] == {'seed': '1'}


def test_mcap_header_schemas_and_channels(written):
    from mcap.reader import make_reader
    path, _ = written
    with open(os.path.join(path, 'run_0.mcap'), 'rb') as handle:
        reader = make_reader(handle)
        assert reader.get_header().profile == 'ros2'
        summary = reader.get_summary()
    assert sorted(s.name for s in summary.schemas.values()) == [IMU, TEMPERATURE]
    assert {s.encoding for s in summary.schemas.values()} == {'ros2msg'}
    assert {c.message_encoding for c in summary.channels.values()} == {'cdr'}
    assert len(summary.chunk_indexes) > 5        # small chunks, not one big one


def test_writer_registers_once_and_finishes_twice(tmp_path):
    path = str(tmp_path / 'b')
    writer = bag.BagWriter(path)
    first = writer.add_topic('/a', IMU)
    assert writer.add_topic('/a', IMU) == first
    second = writer.add_topic('/b', IMU)
    with pytest.raises(ValueError, match='already recorded as'):
        writer.add_topic('/a', TEMPERATURE)
    times, values = _imu_batch(3, seed=2)
    for t, payload in zip(times, cdr.encode(IMU, times, values)):
        writer.write(second, payload, int(t))
    with pytest.raises(ValueError, match='add_topic first'):
        writer.write('/c', b'', 0)
    with pytest.raises(ValueError, match='>= 0'):
        writer.write('/a', b'', -1)
    writer.finish()
    writer.finish()
    reader = bag.BagReader(path)
    assert reader.message_count == 3 and reader.topics['/a'].message_count == 0
    from mcap.reader import make_reader
    with open(os.path.join(path, 'b_0.mcap'), 'rb') as handle:
        assert len(make_reader(handle).get_summary().schemas) == 1
    with pytest.raises(FileExistsError, match='not empty'):
        bag.BagWriter(path)


@pytest.mark.parametrize('compression', ['none', 'lz4'])
def test_other_compressions_read_back(tmp_path, compression):
    path = str(tmp_path / compression)
    times, values, _, _ = _write_bag(path, count=400, seed=3, compression=compression)
    np.testing.assert_array_equal(
        bag.BagReader(path).read_arrays('/imu/data_raw').decoded.values, values)


def test_empty_bag_is_valid(tmp_path):
    from rosbags.rosbag2 import Reader
    path = str(tmp_path / 'empty')
    with bag.BagWriter(path) as writer:
        writer.add_topic('/imu/data_raw', IMU)
    assert bag.BagReader(path).message_count == 0
    with Reader(path) as reader:
        assert reader.message_count == 0


def _mcap(path):
    return os.path.join(path, os.path.basename(path) + '_0.mcap')


def _truncated_copy(source_dir, target_dir, keep_bytes):
    os.makedirs(target_dir)
    with open(_mcap(source_dir), 'rb') as handle:
        data = handle.read()
    name = os.path.basename(target_dir) + '_0.mcap'
    with open(os.path.join(target_dir, name), 'wb') as handle:
        handle.write(data[:keep_bytes])
    return len(data)


@pytest.mark.parametrize('fraction', [0.0, 0.003, 0.37, 0.81, 0.999, 1.0])
def test_truncated_file_is_recovered_by_repair(written, tmp_path, fraction):
    from rosbags.rosbag2 import Reader
    path, (times, values, temp_times, _) = written
    size = os.path.getsize(_mcap(path))
    keep = max(8, int(size * fraction)) if fraction < 1.0 else size - 1
    target = str(tmp_path / 'cut')
    _truncated_copy(path, target, keep)
    with pytest.raises(ValueError, match='bag repair'):
        bag.BagReader(target)
    tolerant = bag.BagReader(target, tolerant=True)
    assert len(tolerant.problems) == 1 and 'recovered' in tolerant.problems[0]
    report = bag.repair_bag(target)
    assert report.rewritten and os.path.exists(_mcap(target) + '.orig')
    assert report.message_count == tolerant.message_count
    repaired = bag.BagReader(target)
    assert repaired.complete and repaired.message_count == tolerant.message_count
    if '/imu/data_raw' in repaired.topics:
        imu = repaired.read_arrays('/imu/data_raw')
        count = len(imu.log_time_ns)
        np.testing.assert_array_equal(imu.decoded.values, values[:count])
        np.testing.assert_array_equal(imu.log_time_ns, times[:count])
    if fraction >= 0.999:      # only the summary/footer is lost: every message is back
        assert repaired.message_count == len(times) + len(temp_times)
    with Reader(target) as reader:
        assert reader.message_count == repaired.message_count
    if fraction > 0.01:        # the custom data record follows the header
        assert repaired.custom_data.get('seed') == '1'
    # Repairing a repaired bag changes nothing but metadata.yaml.
    assert bag.repair_bag(target).rewritten == []


def test_corrupt_chunk_is_skipped_and_reported(written, tmp_path):
    from mcap.reader import make_reader
    path, (times, values, _, _) = written
    with open(_mcap(path), 'rb') as handle:
        chunks = make_reader(handle).get_summary().chunk_indexes
    victim = sorted(chunks, key=lambda c: c.chunk_start_offset)[2]
    target = str(tmp_path / 'bad')
    size = _truncated_copy(path, target, None)
    mcap_path = os.path.join(target, 'bad_0.mcap')
    with open(mcap_path, 'r+b') as handle:
        handle.seek(victim.chunk_start_offset + victim.chunk_length - 40)
        handle.write(b'\xff' * 16)
        handle.truncate(size - 200)          # and lose the footer
    report = bag.repair_bag(target)
    text = report.describe()
    assert 'corrupt chunk' in text and 'skipped 1 corrupt chunks' in text
    imu = bag.BagReader(target).read_arrays('/imu/data_raw')
    lost = (imu.log_time_ns.size < times.size)
    assert lost
    kept = np.isin(times, imu.log_time_ns)
    np.testing.assert_array_equal(imu.decoded.values, values[kept])
    assert not np.any(kept[(times >= victim.message_start_time)
                           & (times <= victim.message_end_time)])


def _cli(*args):
    return subprocess.run([sys.executable, '-m', 'gyro_emulator.cli', *args], cwd=ROOT,
                          capture_output=True, text=True,
                          env={**os.environ, 'PYTHONPATH': ROOT})


def test_cli_repair_and_info(written, tmp_path):
    path, (times, _, temp_times, _) = written
    target = str(tmp_path / 'half')
    _truncated_copy(path, target, os.path.getsize(_mcap(path)) // 2)
    info = _cli('bag', 'info', target)
    assert info.returncode == 0 and 'bag repair' in info.stdout
    out = _cli('bag', 'repair', target)
    assert out.returncode == 0, out.stderr
    assert 'recovered' in out.stdout and 'metadata.yaml' in out.stdout
    info = _cli('bag', 'info', target)
    assert info.returncode == 0 and 'Incomplete' not in info.stdout
    assert '/imu/data_raw' in info.stdout


@pytest.mark.parametrize('content', [b'', b'not an mcap file at all', b'\x89MCA'])
def test_cli_bad_input_is_a_clean_message(tmp_path, content):
    target = tmp_path / 'junk'
    target.mkdir()
    (target / 'junk_0.mcap').write_bytes(content)
    out = _cli('bag', 'repair', str(target))
    assert 'Traceback' not in out.stderr
    if content.startswith(b'\x89MCA') or not content:
        assert out.returncode == 0 and 'recovered 0 messages' in out.stdout
    else:
        assert out.returncode == 2 and 'not an MCAP file' in out.stderr
    missing = _cli('bag', 'info', str(tmp_path / 'missing'))
    assert missing.returncode == 2 and 'no bag at' in missing.stderr
    assert 'Traceback' not in missing.stderr


WRITER_SCRIPT = r"""
from gyro_emulator.recording import bag, cdr
import numpy as np
import sys, time
writer = bag.BagWriter(sys.argv[1], flush_interval_s=0.5)
writer.add_topic('/imu/data_raw', 'sensor_msgs/msg/Imu')
i = 0
print('ready', flush=True)
while True:
    now = time.time_ns()
    values = np.zeros((1, 37))
    values[0, 13] = i
    writer.write('/imu/data_raw', cdr.encode('sensor_msgs/msg/Imu', [now], values)[0], now)
    i += 1
    time.sleep(0.002)
"""


def test_sigkill_of_a_writing_process_loses_at_most_one_second(tmp_path):
    """A real writer process killed with SIGKILL: repair recovers all but <= 1 s."""
    path = str(tmp_path / 'killed')
    proc = subprocess.Popen([sys.executable, '-c', WRITER_SCRIPT, path], cwd=ROOT,
                            env={**os.environ, 'PYTHONPATH': ROOT}, stdout=subprocess.PIPE,
                            text=True)
    try:
        assert proc.stdout.readline().strip() == 'ready'
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if os.path.exists(_mcap(path)) and \
                    bag.BagReader(path, tolerant=True).message_count >= 500:
                break
            time.sleep(0.2)
        killed_at_ns = time.time_ns()
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    report = bag.repair_bag(path)
    imu = bag.BagReader(path).read_arrays('/imu/data_raw')
    assert report.message_count == imu.log_time_ns.size >= 500
    counter = imu.field('angular_velocity.x')
    np.testing.assert_array_equal(counter, np.arange(counter.size))   # no gaps
    assert imu.log_time_ns[-1] >= killed_at_ns - 1_000_000_000
