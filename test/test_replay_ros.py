"""``replay`` republishes a bag with its timing, /clock, rate scaling and looping."""

import ctypes
import os
import signal
import subprocess
import sys
import time

from conftest import ROOT, ros_env
from gyro_emulator.recording import bag, cdr
import numpy as np
import pytest

pytestmark = [pytest.mark.ros, pytest.mark.slow]

IMU = 'sensor_msgs/msg/Imu'
T0_NS = 1_700_000_000_000_000_000


def _make_bag(path, count, period_ns):
    stamps = T0_NS + np.arange(count, dtype=np.int64) * period_ns
    values = np.zeros((count, 37))
    values[:, 13] = np.arange(count)
    with bag.BagWriter(path) as writer:
        writer.add_topic('/imu/data_raw', IMU, qos_profiles=[bag.qos_profile('reliable')])
        writer.write_batches([('/imu/data_raw', cdr.encode(IMU, stamps, values, 'imu'),
                               stamps)])
    return stamps


def _start(args, env, **kwargs):
    return subprocess.Popen([sys.executable, '-m', *args], env=env, cwd=ROOT, **kwargs)


def _stop(proc, sig=signal.SIGINT):
    if proc.poll() is None:
        proc.send_signal(sig)
    try:
        return proc.wait(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        raise


def _recorded_count(path, topic):
    mcap = os.path.join(path, os.path.basename(path) + '_0.mcap')
    if not os.path.exists(mcap):
        return 0
    reader = bag.BagReader(path, tolerant=True)
    return reader.topics[topic].message_count if topic in reader.topics else 0


def _wait(predicate, procs, timeout_s=90.0):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return
        for proc in procs:
            assert proc.poll() is None or proc.returncode == 0, proc.args
        time.sleep(0.2)
    raise AssertionError('timed out')


def test_replay_keeps_timing_scaled_by_rate_and_publishes_clock(tmp_path):
    env = ros_env()
    source, target = str(tmp_path / 'source'), str(tmp_path / 'target')
    stamps = _make_bag(source, 200, 10_000_000)          # 100 Hz for 2 s
    recorder = _start(['gyro_emulator.ros.recorder', '-o', target, '--topics',
                       '/imu/data_raw', '/clock'], env, stdout=subprocess.DEVNULL,
                      stderr=subprocess.DEVNULL)
    replay = _start(['gyro_emulator.ros.replay', source, '--rate', '2', '--clock', '50',
                     '--wait-for-subscribers', '60', '--delay', '1'], env,
                    stdout=subprocess.PIPE, text=True)
    try:
        assert replay.wait(timeout=120) == 0
        assert 'published 200 messages' in replay.stdout.read()
        _wait(lambda: _recorded_count(target, '/imu/data_raw') >= 200, [recorder])
    finally:
        _stop(replay)
        assert _stop(recorder) == 0
    reader = bag.BagReader(target)
    imu = reader.read_arrays('/imu/data_raw')
    # Reliable QoS: every message, in order, payload untouched.
    np.testing.assert_array_equal(imu.field('angular_velocity.x'), np.arange(200))
    np.testing.assert_array_equal(imu.stamp_ns, stamps)
    # Timing: message i is published (stamp_i - stamp_0) / 2 after the first. The
    # recorder's receive times lag the publishes by a delivery delay that is never
    # negative and, on a loaded machine, comes in bursts (a median gap of 0.07 ms
    # once), so the pace is read from the least lag of each quarter of the bag: the
    # lower envelope of receive time minus schedule. At the right rate it is flat;
    # a rate of 1.8 or 2.2 instead of 2 moves it by 70-80 ms over the 0.75 s
    # between the first quarter and the last.
    lag_ms = ((imu.log_time_ns - imu.log_time_ns[0]) - (imu.stamp_ns - imu.stamp_ns[0]) / 2) / 1e6
    quarter = lag_ms.size // 4
    assert abs(np.min(lag_ms[-quarter:]) - np.min(lag_ms[:quarter])) < 40.0
    clock_log_ns, clock_values = (np.array(column) for column in zip(*(
        (item.log_time_ns, msg.clock.sec * 10**9 + msg.clock.nanosec)
        for item, msg in reader.decoded_messages('/clock'))))
    assert len(clock_values) >= 10
    assert np.all(np.diff(clock_values) >= 0)
    assert T0_NS <= clock_values[0] and clock_values[-1] <= stamps[-1] + 500_000_000
    # During the 1 s --delay /clock holds the bag's first instant (50 Hz: about
    # 50 messages; without the hold, none), so a node that matched late starts there.
    held = clock_values == T0_NS
    assert held[0] and held.sum() >= 10, held.sum()
    held_s = (clock_log_ns[held][-1] - clock_log_ns[held][0]) / 1e9
    assert held_s >= 0.5, held_s


def test_replay_loops_until_interrupted(tmp_path):
    env = ros_env()
    source, target = str(tmp_path / 'source'), str(tmp_path / 'target')
    _make_bag(source, 50, 10_000_000)
    recorder = _start(['gyro_emulator.ros.recorder', '-o', target, '--topics',
                       '/imu/data_raw'], env, stdout=subprocess.DEVNULL,
                      stderr=subprocess.DEVNULL)
    # 100 messages/s: a loop every half second, and a pace a Python recorder keeps
    # up with on a loaded 2-core machine (at 500/s its keep-last 100 history
    # could overflow, and reliable delivery then loses the oldest messages).
    replay = _start(['gyro_emulator.ros.replay', source, '--rate', '1', '--loop',
                     '--wait-for-subscribers', '60'], env, stdout=subprocess.PIPE, text=True)
    try:
        _wait(lambda: _recorded_count(target, '/imu/data_raw') >= 160, [recorder, replay])
        assert _stop(replay) == 0
        published = int(replay.stdout.read().split('published ')[1].split()[0])
        _wait(lambda: _recorded_count(target, '/imu/data_raw') >= published, [recorder])
    finally:
        _stop(replay)
        assert _stop(recorder) == 0
    counter = bag.BagReader(target).read_arrays('/imu/data_raw').field('angular_velocity.x')
    assert counter.size == published >= 160
    np.testing.assert_array_equal(counter, np.arange(counter.size) % 50)


def test_replay_bad_input_is_a_clean_message(tmp_path):
    source = str(tmp_path / 'source')
    _make_bag(source, 5, 10_000_000)
    for args, text in ((['missing_bag'], 'no bag at'),
                       ([str(tmp_path), '--rate', '0'], 'out of range'),
                       ([source, '--remap', '/imu/data_raw:=bad name!'],
                        "--remap /imu/data_raw:=bad name!: 'bad name!' is not a ROS topic "
                        'name: topic name must not contain characters other than'),
                       ([source, '--remap', '/imu/data_raw:=/a//b'],
                        "'/a//b' is not a ROS topic name: topic name must not contain "
                        "repeated '/'"),
                       ([source, '--remap', 'imu/data_raw:=/x'],
                        'topic imu/data_raw is not in bag')):
        out = subprocess.run([sys.executable, '-m', 'gyro_emulator.ros.replay', *args],
                             env=ros_env(), cwd=str(tmp_path), capture_output=True, text=True)
        assert out.returncode == 2 and text in out.stderr
        assert 'Traceback' not in out.stderr


def test_replay_remap_publishes_a_topic_under_its_new_name(tmp_path):
    """``--remap FROM:=TO`` (docs/recording.md): rclpy must not take it as a ROS remap rule."""
    env = ros_env()
    source, target = str(tmp_path / 'source'), str(tmp_path / 'target')
    _make_bag(source, 50, 10_000_000)
    recorder = _start(['gyro_emulator.ros.recorder', '-o', target, '--topics',
                       '/imu/remapped', '/imu/data_raw'], env, stdout=subprocess.DEVNULL,
                      stderr=subprocess.DEVNULL)
    replay = _start(['gyro_emulator.ros.replay', source, '--remap', '/imu/data_raw:=/imu/remapped',
                     '--rate', '5', '--wait-for-subscribers', '60'], env,
                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        out, err = replay.communicate(timeout=120)
        assert replay.returncode == 0, err
        assert 'published 50 messages' in out and 'deprecated' not in err, (out, err)
        _wait(lambda: _recorded_count(target, '/imu/remapped') >= 50, [recorder])
    finally:
        _stop(replay)
        assert _stop(recorder) == 0
    reader = bag.BagReader(target)
    assert '/imu/data_raw' not in reader.topics
    counter = reader.read_arrays('/imu/remapped').field('angular_velocity.x')
    np.testing.assert_array_equal(counter, np.arange(50))


def test_replay_skips_a_topic_whose_type_is_not_installed(tmp_path):
    """A robot bag with a custom type plays its other topics, as ``ros2 bag play`` does."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import get_typestore, Stores

    source = tmp_path / 'robot'
    stamps = T0_NS + np.arange(20, dtype=np.int64) * 10_000_000
    with Writer(source, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        imu = writer.add_connection('/imu/data_raw', IMU,
                                    typestore=get_typestore(Stores.ROS2_JAZZY))
        custom = writer.add_connection('/custom', 'my_pkg/msg/Thing', msgdef='float64 x\n',
                                       rihs01='RIHS01_' + '0' * 64)
        for stamp, payload in zip(stamps, cdr.encode(IMU, stamps, np.zeros((20, 37)), 'imu')):
            writer.write(imu, int(stamp), payload)
            writer.write(custom, int(stamp), b'\x00\x01\x00\x00' + bytes(8))
    run = [sys.executable, '-m', 'gyro_emulator.ros.replay', str(source), '--rate', '10']
    out = subprocess.run(run, env=ros_env(), cwd=str(tmp_path), capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert 'published 20 messages' in out.stdout and 'replaying 20 messages' in out.stderr
    assert "skipping topic /custom: no .msg definition for 'my_pkg/msg/Thing'" in out.stderr
    out = subprocess.run(run + ['--topics', '/custom'], env=ros_env(), cwd=str(tmp_path),
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and 'Traceback' not in out.stderr
    assert out.stderr.strip().splitlines() == [
        "replay: error: --topics /custom: no .msg definition for 'my_pkg/msg/Thing' under "
        f"share/ of {out.stderr.split('share/ of ')[1].strip()}"]


def test_replay_refuses_a_remap_that_gives_a_topic_two_types(tmp_path):
    source = str(tmp_path / 'two')
    stamps = T0_NS + np.arange(5, dtype=np.int64) * 10_000_000
    with bag.BagWriter(source) as writer:
        writer.add_topic('/imu/data_raw', IMU)
        writer.add_topic('/temp', 'sensor_msgs/msg/Temperature')
        writer.write_batches([
            ('/imu/data_raw', cdr.encode(IMU, stamps, np.zeros((5, 37)), 'imu'), stamps),
            ('/temp', cdr.encode('sensor_msgs/msg/Temperature', stamps, np.zeros((5, 2)), 't'),
             stamps)])
    out = subprocess.run([sys.executable, '-m', 'gyro_emulator.ros.replay', source,
                          '--remap', '/temp:=/imu/data_raw'], env=ros_env(), cwd=str(tmp_path),
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and 'Traceback' not in out.stderr, out.stderr
    assert out.stderr.strip().splitlines() == [
        'replay: error: --remap /temp:=/imu/data_raw: /imu/data_raw would carry /imu/data_raw '
        '(sensor_msgs/msg/Imu) and /temp (sensor_msgs/msg/Temperature): a topic has one type; '
        'remap one elsewhere or leave it out of --topics']


def _replay_run(args, cwd, timeout=120):
    return subprocess.run([sys.executable, '-m', 'gyro_emulator.ros.replay', *args],
                          env=ros_env(), cwd=str(cwd), capture_output=True, text=True,
                          timeout=timeout)


def _two_topic_bag(path):
    """Write /a (10 messages over 0.09 s), /b (100 over 0.99 s) and /empty (none)."""
    with bag.BagWriter(path) as writer:
        for name, count in (('/a', 10), ('/b', 100), ('/empty', 0)):
            writer.add_topic(name, IMU)
            stamps = T0_NS + np.arange(count, dtype=np.int64) * 10_000_000
            if count:
                writer.write_batches([(name, cdr.encode(IMU, stamps, np.zeros((count, 37)),
                                                        'imu'), stamps)])
    return path


#: Runs ``replay``'s main on each argument list in one process (these are refused
#: before ROS starts): prints {repr(args): [exit status, stderr]} as JSON.
REFUSALS = r"""
import contextlib, io, json, sys
from gyro_emulator.ros import replay
out = {}
for args in json.loads(sys.argv[1]):
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        status = replay.main(args)
    out[repr(args)] = [status, err.getvalue()]
print(json.dumps(out))
"""


def test_replay_refuses_what_it_would_silently_do_wrong(tmp_path):
    import json
    source = _two_topic_bag(str(tmp_path / 'two'))
    cases = (
            # a repeated --remap took the last rule without a word
            (['--remap', '/a:=/x', '/a:=/y'], '--remap /a:=/x and --remap /a:=/y: two names '
                                              'for /a; give one rule per topic'),
            # a rule for a topic left out of --topics was ignored without a word
            (['--topics', '/a', '--remap', '/b:=/x'], '--remap /b:=/x: /b is not replayed '
                                                      '(--topics /a); add it to --topics or '
                                                      'drop the rule'),
            # an offset past the end published 0 messages with exit 0
            (['--start-offset', '5'], f'--start-offset = 5.0 is past the end of bag {source}: '
                                      'its messages span 0.99 s; allowed [0, 0.99] s'),
            (['--start-offset', '1e300'], '--start-offset = 1e+300 is past the end of bag'),
            (['--topics', '/a', '--start-offset', '0.5'],
             '--start-offset = 0.5 leaves no message of /a to replay: the last comes before it '
             f'(bag {source} spans 0.99 s)'),
            (['--topics', '/empty'], f'nothing to replay: bag {source} has no message on /empty'),
            # inf waited forever, or was a traceback (OverflowError)
            (['--wait-for-subscribers', 'inf'],
             '--wait-for-subscribers = inf is out of range: allowed [0, inf) s'),
            (['--delay', 'inf'], '--delay = inf is out of range: allowed [0, inf) s'),
            (['--start-offset', 'inf'],
             '--start-offset = inf is out of range: allowed [0, inf) s'),
            (['--delay', 'nan'], '--delay = nan is out of range: allowed [0, inf) s'),
            # a loop over one instant published about 12 000 messages a second
            (['--loop', '--start-offset', '0.99'], f'--loop: the messages to replay of bag '
                                                   f'{source} are all at one instant: a loop '
                                                   'would publish them as fast as it can; '
                                                   'replay them once, without --loop'),
            (['--loop', '--topics', '/a', '--start-offset', '0.09'], '--loop: the messages'))
    run = subprocess.run([sys.executable, '-c', REFUSALS, json.dumps(
        [[source, *args] for args, _ in cases])], env=ros_env(), cwd=ROOT,
        capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    refusals = json.loads(run.stdout)
    for args, line in cases:
        status, err = refusals[repr([source, *args])]
        assert status == 2, (args, err)
        assert err.startswith(f'replay: error: {line}') and err.strip().count('\n') == 0, \
            (args, err)
    # the same rule twice is one rule; an offset inside the bag says what it replays
    out = _replay_run([source, '--remap', '/b:=/x', '/b:=/x', '--topics', '/b', '/a', '/b',
                       '--start-offset', '0.5', '--rate', '10'], tmp_path)
    assert out.returncode == 0, out.stderr
    assert 'replay: published 50 messages' in out.stdout
    assert f'replaying {source} from 0.5 s on (the last 0.490 s of its 0.990 s; 110 messages ' \
        'in all) at rate 10.0' in out.stderr, out.stderr


def test_a_bag_topic_that_is_not_a_ros_name_is_named_as_the_bags(tmp_path):
    # the error blamed "--remap /1imu:=/1imu", an option the user never gave
    source = str(tmp_path / 'other')
    stamps = T0_NS + np.arange(5, dtype=np.int64) * 10_000_000
    with bag.BagWriter(source) as writer:
        writer.add_topic('/1imu', IMU)
        writer.write_batches([('/1imu', cdr.encode(IMU, stamps, np.zeros((5, 37)), 'imu'),
                               stamps)])
    out = _replay_run([source], tmp_path)
    assert out.returncode == 2 and out.stderr.strip().splitlines() == [
        f"replay: error: topic '/1imu' of bag {source} is not a ROS topic name: topic name "
        'token must not start with a number; publish it as another with --remap '
        '/1imu:=NEW_NAME, or choose the topics with --topics'], out.stderr
    out = _replay_run([source, '--remap', '/1imu:=/imu1', '--rate', '10'], tmp_path)
    assert out.returncode == 0 and 'replay: published 5 messages' in out.stdout, out.stderr


def _signal_another_thread(pid, signum):
    """
    Send ``signum`` to a thread of ``pid`` other than its main one (tgkill).

    The kernel delivers a process's signal to any thread that does not block
    it; this makes the case that is rare on an idle machine happen every time.
    """
    for tid in sorted(int(t) for t in os.listdir(f'/proc/{pid}/task') if int(t) != pid):
        with open(f'/proc/{pid}/task/{tid}/status') as handle:
            blocked = next(int(line.split()[1], 16) for line in handle
                           if line.startswith('SigBlk:'))
        if not blocked & (1 << (signum - 1)):
            assert ctypes.CDLL(None, use_errno=True).tgkill(pid, tid, signum) == 0
            return
    raise AssertionError(f'every thread of {pid} but the main one blocks {signum}')


@pytest.mark.parametrize('to_thread', [False, True], ids=['process', 'another-thread'])
def test_replay_delay_ends_on_sigint(tmp_path, to_thread):
    source = _two_topic_bag(str(tmp_path / 'two'))
    replay = _start(['gyro_emulator.ros.replay', source, '--wait-for-subscribers', '0.01',
                     '--delay', '600'], ros_env(), stdout=subprocess.PIPE,
                    stderr=subprocess.PIPE, text=True)
    try:
        for line in replay.stderr:      # the wait for subscribers ends: the delay begins
            if 'no subscriber on' in line:
                break
        if to_thread:
            _signal_another_thread(replay.pid, signal.SIGINT)
        else:
            replay.send_signal(signal.SIGINT)
        # the delay slept on through SIGINT (one Event.wait: not woken by a
        # signal that another thread took)
        out, _ = replay.communicate(timeout=60)
    finally:
        if replay.poll() is None:
            replay.kill()
            replay.wait()
    assert replay.returncode == 0 and 'replay: published 0 messages' in out
