"""The recorder and the node's record_dir, as real ROS processes, under signals."""

import os
import signal
import subprocess
import sys
import time

from conftest import ROOT, ros_env
from gyro_emulator.recording import bag
import numpy as np
import pytest

pytestmark = [pytest.mark.ros, pytest.mark.slow]

#: Publishes what the emulator would: Imu (reliable, counter in angular_velocity.x,
#: wall-clock stamp), Temperature (best effort) and one truth topic.
PUBLISHER = r"""
import time
from gyro_emulator.ros.spinning import close, spin_once
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data, QoSProfile
from geometry_msgs.msg import Vector3Stamped
from sensor_msgs.msg import Imu, Temperature
rclpy.init()
node = Node('gyro_emulator')
imu_pub = node.create_publisher(Imu, 'imu/data_raw', QoSProfile(depth=1000))
temp_pub = node.create_publisher(Temperature, 'imu/temperature', qos_profile_sensor_data)
truth_pub = node.create_publisher(Vector3Stamped, '~/truth/rate', QoSProfile(depth=1000))
ignored = node.create_publisher(Vector3Stamped, 'not_recorded', 10)
count = 0
def tick():
    global count
    imu = Imu()
    imu.header.stamp.sec, imu.header.stamp.nanosec = divmod(time.time_ns(), 10**9)
    imu.header.frame_id = 'imu_link'
    imu.angular_velocity.x = float(count)
    imu_pub.publish(imu)
    truth = Vector3Stamped(header=imu.header)
    truth.vector.x = float(count)
    truth_pub.publish(truth)
    ignored.publish(truth)
    if count % 10 == 0:
        temp_pub.publish(Temperature(header=imu.header, temperature=25.0))
    count += 1
node.create_timer(0.005, tick)
executor = SingleThreadedExecutor()
executor.add_node(node)
while spin_once(executor, 0.25):
    pass
close(node)
"""


def _mcap(path):
    return os.path.join(path, os.path.basename(path) + '_0.mcap')


def _wait_for_messages(path, topic, count, procs, timeout_s=90.0):
    """Poll the (unfinished) bag until ``topic`` has ``count`` messages."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for proc in procs:
            assert proc.poll() is None, f'{proc.args} exited early: {proc.returncode}'
        if os.path.exists(_mcap(path)):
            reader = bag.BagReader(path, tolerant=True)
            if topic in reader.topics and reader.topics[topic].message_count >= count:
                return
        time.sleep(0.25)
    raise AssertionError(f'{topic} did not reach {count} messages in {path}')


def _stop(proc, sig=signal.SIGINT, timeout_s=30.0):
    if proc.poll() is None:
        proc.send_signal(sig)
    try:
        return proc.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        raise


def _counter_is_gapless(imu):
    counter = imu.field('angular_velocity.x')
    np.testing.assert_array_equal(np.diff(counter), np.ones(counter.size - 1))
    return counter


def _check_with_rosbags(path, reader):
    from pathlib import Path

    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2 import Reader
    with Reader(path) as rb:
        counts = {c.topic: c.msgcount for c in rb.connections}
        assert rb.message_count == reader.message_count
    assert counts == {name: t.message_count for name, t in reader.topics.items()}
    with AnyReader([Path(path)]) as any_reader:
        connections = [c for c in any_reader.connections if c.topic == '/imu/data_raw']
        values = [any_reader.deserialize(raw, c.msgtype).angular_velocity.x
                  for c, _, raw in any_reader.messages(connections=connections)]
    np.testing.assert_array_equal(values, reader.read_arrays('/imu/data_raw')
                                  .field('angular_velocity.x'))


@pytest.mark.parametrize('args,message', [
    (['-e', '('], "--regex = '(' is not a regular expression"),
    (['--topics', 'bad name!'], "--topics = 'bad name!' is not a ROS topic name: topic name "
     'must not contain characters other than'),
    (['--topics', '/a//b'], "--topics = '/a//b' is not a ROS topic name: topic name must "
     "not contain repeated '/'"),
    (['-x', 'bad name!'], "--exclude = 'bad name!' is not a ROS topic name"),
    # the API's words (BagWriter.flush_interval_s) and an empty bag directory left behind
    (['--flush-interval', '0'], '--flush-interval = 0.0 is out of range: allowed (0, 3600] s'),
    (['--flush-interval', 'inf'], '--flush-interval = inf is out of range: allowed (0, 3600] s'),
    (['--duration', 'inf'], '--duration = inf is out of range: allowed (0, inf) s'),
], ids=['regex', 'topic', 'topic_slashes', 'exclude', 'flush_0', 'flush_inf', 'duration_inf'])
def test_a_bad_topic_or_pattern_is_one_line_and_leaves_no_bag(tmp_path, args, message):
    path = tmp_path / 'rec'
    out = subprocess.run([sys.executable, '-m', 'gyro_emulator.ros.recorder', '-o', str(path),
                          *args], env=ros_env(), cwd=ROOT, capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == 2, out.stderr
    assert out.stderr.startswith('recorder: error: '), out.stderr
    assert message in out.stderr and 'Traceback' not in out.stderr, out.stderr
    assert out.stderr.strip().count('\n') == 0, out.stderr
    assert not path.exists()


def test_an_existing_output_is_refused_with_the_option_to_use(tmp_path):
    # BagWriter's "pass overwrite" is the API's word: the recorder says --overwrite
    full = tmp_path / 'full'
    full.mkdir()
    (full / 'notes.txt').write_text('mine')
    for path, message in ((full, f'recorder: error: --output {full} exists: pass --overwrite '
                                 'to replace it'),
                          (full / 'notes.txt', f'recorder: error: --output {full}/notes.txt is '
                                               'a file: give a directory name')):
        out = subprocess.run([sys.executable, '-m', 'gyro_emulator.ros.recorder', '-o',
                              str(path)], env=ros_env(), cwd=ROOT, capture_output=True,
                             text=True, timeout=60)
        assert out.returncode == 2 and out.stderr.strip() == message, out.stderr
    assert os.listdir(full) == ['notes.txt']
    with pytest.raises(FileExistsError, match=r'pass overwrite=True\)$'):
        bag.BagWriter(str(full))


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_signal_leaves_a_complete_bag(tmp_path, sig):
    env = ros_env()
    path = str(tmp_path / 'rec')
    publisher = subprocess.Popen([sys.executable, '-c', PUBLISHER], env=env, cwd=ROOT)
    recorder = subprocess.Popen(
        [sys.executable, '-m', 'gyro_emulator.ros.recorder', '-o', path], env=env, cwd=ROOT,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _wait_for_messages(path, '/imu/data_raw', 300, [publisher, recorder])
        assert _stop(recorder, sig) == 0
    finally:
        _stop(publisher)
        if recorder.poll() is None:
            _stop(recorder, signal.SIGKILL)
    out = recorder.stdout.read()
    assert 'wrote' in out and path in out
    reader = bag.BagReader(path)             # strict: summary, footer and metadata present
    assert reader.complete and reader.metadata['version'] == 9
    assert set(reader.topics) == {'/imu/data_raw', '/imu/temperature',
                                  '/gyro_emulator/truth/rate'}
    assert reader.topics['/imu/data_raw'].type_name == 'sensor_msgs/msg/Imu'
    assert reader.topics['/imu/data_raw'].qos_profiles[0]['reliability'] == 'reliable'
    assert reader.topics['/imu/temperature'].qos_profiles[0]['reliability'] == 'best_effort'
    imu = reader.read_arrays('/imu/data_raw')
    assert imu.log_time_ns.size >= 300
    _counter_is_gapless(imu)
    assert np.all(np.diff(imu.log_time_ns) >= 0)
    _check_with_rosbags(path, reader)


def test_sigkill_then_repair_loses_at_most_the_last_second(tmp_path):
    env = ros_env()
    path = str(tmp_path / 'killed')
    publisher = subprocess.Popen([sys.executable, '-c', PUBLISHER], env=env, cwd=ROOT)
    recorder = subprocess.Popen(
        [sys.executable, '-m', 'gyro_emulator.ros.recorder', '-o', path, '--topics',
         'imu/data_raw', '--flush-interval', '0.5'], env=env, cwd=ROOT,
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        _wait_for_messages(path, '/imu/data_raw', 600, [publisher, recorder])
        killed_at_ns = time.time_ns()
        _stop(recorder, signal.SIGKILL)
    finally:
        _stop(publisher)
        if recorder.poll() is None:
            _stop(recorder, signal.SIGKILL)
    assert not os.path.exists(os.path.join(path, 'metadata.yaml'))
    with pytest.raises(ValueError, match='bag repair'):
        bag.BagReader(path)
    repair = subprocess.run([sys.executable, '-m', 'gyro_emulator.cli', 'bag', 'repair', path],
                            env=env, cwd=ROOT, capture_output=True, text=True)
    assert repair.returncode == 0, repair.stderr
    assert 'recovered' in repair.stdout and 'Traceback' not in repair.stderr
    reader = bag.BagReader(path)
    imu = reader.read_arrays('/imu/data_raw')
    assert imu.log_time_ns.size >= 600
    _counter_is_gapless(imu)
    # Everything received up to one second before the kill is in the bag.
    assert imu.stamp_ns[-1] >= killed_at_ns - 1_000_000_000
    _check_with_rosbags(path, reader)


def test_node_record_dir_records_inputs_outputs_and_truth(tmp_path):
    env = ros_env()
    path = str(tmp_path / 'self')
    node = subprocess.Popen(
        [sys.executable, '-m', 'gyro_emulator.ros.node', '--ros-args', '-p',
         f'record_dir:={path}', '-p', 'seed:=5'], env=env, cwd=ROOT,
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        _wait_for_messages(path, '/imu/data_raw', 200, [node])
        status = _stop(node, signal.SIGTERM)
    finally:
        if node.poll() is None:
            _stop(node, signal.SIGKILL)
    log = node.stdout.read()
    assert status == 0, log
    samples = int(log.split('shutting down: ')[1].split(' samples')[0])
    reader = bag.BagReader(path)
    assert reader.custom_data['seed'] == '5'
    # the node's name: with seed -1 replay derives the node's seed from it
    assert reader.custom_data['node'] == '/gyro_emulator'
    for topic in ('/cmd/angular_velocity', '/cmd/temperature', '/cmd/linear_acceleration',
                  '/diagnostics', '/imu/temperature'):
        assert topic in reader.topics
    imu = reader.read_arrays('/imu/data_raw')
    truth = reader.read_arrays('/gyro_emulator/truth/rate')
    # Every published sample is in the bag, the last ones before the stop too: the
    # node writes what it publishes as it publishes it (a subscription to its own
    # topics lost those in flight at shutdown, 5 of 1411 once). The one sample the
    # driver may count but not publish: the signal handler shut the context down
    # under the callback that was publishing it (imu/data_raw first, then truth).
    assert samples - 1 <= imu.log_time_ns.size <= samples
    assert imu.log_time_ns.size - 1 <= truth.log_time_ns.size <= imu.log_time_ns.size
    assert np.all(np.diff(imu.stamp_ns) > 0)
    # each output topic is stored with its publisher's QoS (imu/data_raw: sensor data)
    assert reader.topics['/imu/data_raw'].qos_profiles[0]['reliability'] == 'best_effort'
    assert reader.topics['/gyro_emulator/truth/fault'].qos_profiles[0]['durability'] == \
        'transient_local'
    _check_with_rosbags(path, reader)
