"""Offline replay: simulate --out bags, driving the model from a bag, the report."""

import json
import os
import subprocess
import sys
import time

from conftest import ROOT
from gyro_emulator.analysis.replay.inputs import emulate, hold, load_inputs
from gyro_emulator.analysis.replay.report import compare
from gyro_emulator.emulation import emulator_bag
from gyro_emulator.recording import bag, cdr
from gyro_emulator.sensor.config import load_sensor_config
import numpy as np
import pytest

IMU = 'sensor_msgs/msg/Imu'
TEMPERATURE = 'sensor_msgs/msg/Temperature'
VECTOR = 'geometry_msgs/msg/Vector3Stamped'


def _cli(*args):
    return subprocess.run([sys.executable, '-m', 'gyro_emulator.cli', *args], cwd=ROOT,
                          capture_output=True, text=True,
                          env={**os.environ, 'PYTHONPATH': ROOT, 'MPLBACKEND': 'Agg'})


@pytest.fixture(scope='module')
def simulated(tmp_path_factory):
    """Write a 20 s rate-table record at 100 Hz with ``simulate --out``."""
    path = str(tmp_path_factory.mktemp('sim') / 'steps')
    out = _cli('simulate', '--profile', 'steps', '--duration-s', '20', '--rate-hz', '100',
               '--seed', '3', '--out', path)
    assert out.returncode == 0, out.stderr
    return path


def test_simulate_out_writes_the_emulator_layout(simulated):
    from gyro_emulator.emulation import simulate
    from rosbags.rosbag2 import Reader
    reader = bag.BagReader(simulated)
    assert reader.custom_data['seed'] == '3' and reader.custom_data['rate_hz'] == '100.0'
    for topic in (emulator_bag.RATE_TOPIC, emulator_bag.TEMPERATURE_COMMAND_TOPIC,
                  emulator_bag.IMU_TOPIC, emulator_bag.DIE_TEMPERATURE_TOPIC,
                  emulator_bag.TRUTH_NAMESPACE + '/rate'):
        assert reader.topics[topic].message_count == 2000, topic
    # The bag holds exactly what run_simulation returns for the same arguments.
    time_s, profile, batch = simulate.run_simulation('paper', 'steps', 20.0, 100.0, seed=3)
    imu = reader.read_arrays(emulator_bag.IMU_TOPIC)
    np.testing.assert_array_equal(imu.field('angular_velocity'), batch.gyro_rad_s)
    # Issue 15: stamped from the start time (default: now), not from 1970.
    start = int(reader.custom_data['start_time_ns'])
    assert abs(start - time.time_ns()) < 600 * 10**9
    np.testing.assert_array_equal(imu.log_time_ns - start,
                                  np.round(time_s * 1e9).astype(np.int64))
    np.testing.assert_array_equal(
        imu.stamp_ns, imu.log_time_ns + np.round(batch.output_delay_s * 1e9).astype(np.int64))
    assert imu.field('orientation_covariance[0]')[0] == -1.0
    assert imu.field('angular_velocity_covariance[0]')[0] > 0.0
    rate = reader.read_arrays(emulator_bag.RATE_TOPIC)
    np.testing.assert_array_equal(rate.field('vector'), profile.rate_rad_s)
    with Reader(simulated) as rosbags_reader:
        assert rosbags_reader.message_count == reader.message_count


def test_replay_with_the_recording_seed_reproduces_it_exactly(simulated, tmp_path):
    out = _cli('replay', simulated, '--out', str(tmp_path / 'same'))
    assert out.returncode == 0, out.stderr
    assert 'identical to the measured one' in out.stdout
    with open(tmp_path / 'same' / 'report.json', encoding='utf-8') as handle:
        stats = json.load(handle)['stats']
    assert stats['matched'] == stats['samples'] == 2000
    assert all(s['max_abs'] == 0.0 for s in stats['residual_rad_s'].values())
    for name in ('rates.png', 'residual.png', 'allan.png', 'report.md'):
        assert os.path.getsize(tmp_path / 'same' / name) > 0


def test_same_bag_and_seed_give_identical_decoded_output(simulated, tmp_path):
    outputs = []
    for run in ('a', 'b'):
        out = _cli('replay', simulated, '--out', str(tmp_path / run), '--seed', '11',
                   '--no-plots')
        assert out.returncode == 0, out.stderr
        reader = bag.BagReader(str(tmp_path / run / 'emulated'))
        outputs.append({t: reader.read_arrays(t).decoded.values for t in
                        (emulator_bag.IMU_TOPIC, emulator_bag.TRUTH_NAMESPACE + '/bias',
                         emulator_bag.RESIDUAL_TOPIC)})
    for topic, values in outputs[0].items():
        np.testing.assert_array_equal(values, outputs[1][topic], err_msg=topic)
    # Another seed is another noise realisation: the residual is the difference
    # of two independent white noises, sqrt(2) sigma on a static axis (x).
    with open(tmp_path / 'a' / 'report.json', encoding='utf-8') as handle:
        stats = json.load(handle)['stats']
    sigma = emulator_bag.white_noise_sigma(load_sensor_config('paper'), 100.0)[0]
    ratio = stats['residual_rad_s']['x']['std'] / (np.sqrt(2.0) * sigma)
    assert 0.85 < ratio < 1.3


def test_hold_is_a_zero_order_hold_at_the_stamps():
    stamps = np.array([0, 100, 200], dtype=np.int64)
    values = np.array([[1.0], [2.0], [3.0]])
    query = np.array([-50, 0, 99, 100, 150, 199, 500], dtype=np.int64)
    np.testing.assert_array_equal(hold(stamps, values, query, 0, before=0.0)[:, 0],
                                  [0, 1, 1, 2, 2, 2, 3])
    # within the tolerance a command counts for the sample just before its stamp
    np.testing.assert_array_equal(hold(stamps, values, query, 1)[:, 0],
                                  [1, 1, 2, 2, 2, 3, 3])


def _robot_bag(path, rate_hz=100.0, seconds=30.0, seed=0, spoil=None):
    """Write a "real robot" bag: Imu under a namespace, temperature at 1 Hz (``spoil`` edits)."""
    rng = np.random.default_rng(seed)
    n = int(seconds * rate_hz)
    t0 = 1_700_000_000_000_000_000
    # a robot's IMU stamps jitter around the nominal period
    stamps = t0 + np.round((np.arange(n) + rng.uniform(-0.1, 0.1, n)) * 1e9 / rate_hz) \
        .astype(np.int64)
    t = np.arange(n) / rate_hz
    rate = np.column_stack([0.2 * np.sin(t), np.zeros(n), 0.5 * np.sin(0.3 * t)])
    values = np.zeros((n, 37))
    values[:, 13:16] = rate
    values[:, 25:28] = [0.0, 0.0, 9.81]
    temp_stamps = stamps[::int(rate_hz)]
    temps = np.column_stack([30.0 + np.arange(len(temp_stamps)) * 0.1,
                             np.zeros(len(temp_stamps))])
    if spoil is not None:
        spoil(values, temps)
    with bag.BagWriter(path) as writer:
        writer.add_topic('/robot/imu', IMU)
        writer.add_topic('/robot/imu_temp', TEMPERATURE)
        writer.write_batches([('/robot/imu', cdr.encode(IMU, stamps, values, 'base'), stamps),
                              ('/robot/imu_temp', cdr.encode(TEMPERATURE, temp_stamps, temps),
                               temp_stamps)])
    return stamps, rate, temp_stamps, temps[:, 0]


def test_imu_source_takes_the_robot_rate_as_truth(tmp_path):
    path = str(tmp_path / 'robot')
    stamps, rate, temp_stamps, temps = _robot_bag(path)
    reader = bag.BagReader(path)
    inputs = load_inputs(reader, rate_topic='/robot/imu',
                         temperature_topic='/robot/imu_temp')
    assert inputs.source == 'imu' and inputs.rate_hz == 100.0
    np.testing.assert_array_equal(inputs.stamp_ns, stamps)
    np.testing.assert_array_equal(inputs.rate_rad_s, rate)
    np.testing.assert_array_equal(inputs.accel_m_s2[:, 2], np.full(len(stamps), 9.81))
    # the temperature in force at a sample is the latest one stamped at or before it
    assert inputs.temp_c[99] == temps[0] and inputs.temp_c[100] == temps[1]
    assert inputs.temp_c[350] == temps[3] and inputs.temp_c[-1] == temps[-1]
    out = _cli('replay', path, '--out', str(tmp_path / 'out'), '--source', 'imu',
               '--rate-topic', '/robot/imu', '--temperature-topic', '/robot/imu_temp')
    assert out.returncode == 0, out.stderr
    with open(tmp_path / 'out' / 'report.json', encoding='utf-8') as handle:
        report = json.load(handle)
    assert report['stats']['matched'] == len(stamps)
    assert set(report['adev']) == {'measured', 'emulated'}
    emulated = bag.BagReader(str(tmp_path / 'out' / 'emulated'))
    truth = emulated.read_arrays(emulator_bag.TRUTH_NAMESPACE + '/rate').field('vector')
    np.testing.assert_array_equal(truth, rate)


def test_command_source_holds_sparse_commands_on_the_sample_grid(tmp_path):
    path = str(tmp_path / 'sparse')
    cmd_stamps = np.arange(0, 2_000_000_000, 100_000_000, dtype=np.int64)    # 10 Hz
    cmd = np.column_stack([np.arange(len(cmd_stamps)) * 0.01,
                           np.zeros((len(cmd_stamps), 2))])
    with bag.BagWriter(path) as writer:
        writer.add_topic(emulator_bag.RATE_TOPIC, VECTOR)
        writer.write_batches([(emulator_bag.RATE_TOPIC, cdr.encode(VECTOR, cmd_stamps, cmd),
                               cmd_stamps)])
    inputs = load_inputs(bag.BagReader(path), rate_hz=50.0, temp_c=40.0)
    assert inputs.source == 'command' and len(inputs.stamp_ns) == 96
    np.testing.assert_array_equal(inputs.stamp_ns, np.arange(96) * 20_000_000)
    np.testing.assert_array_equal(inputs.rate_rad_s[:, 0], cmd[inputs.stamp_ns // 100_000_000, 0])
    assert np.all(inputs.temp_c == 40.0) and inputs.measured_rad_s is None
    _, batch = emulate(inputs, 'paper', seed=1)
    assert compare(inputs, batch).matched == 0


@pytest.mark.parametrize('args,message', [
    (['--rate-topic', '/nope'], "no topic '/nope'"),
    (['--rate-topic', '/robot/imu_temp'], 'has type sensor_msgs/msg/Temperature'),
    (['--source', 'command'], 'no rate commands'),
    (['--rate-hz', '-5'], 'out of range'),
])
def test_replay_bad_options_are_clean_messages(tmp_path, args, message):
    path = str(tmp_path / 'robot')
    _robot_bag(path, seconds=1.0)
    out = _cli('replay', path, '--out', str(tmp_path / 'out'), *args)
    assert out.returncode == 2 and message in out.stderr, out.stderr
    assert 'Traceback' not in out.stderr


@pytest.mark.parametrize('args,message', [
    # named as the model's fields (GyroModel: ambient_temp_c, replay.rate_hz,
    # replay.seed), after the bag was read; an unused --temp-c nan passed
    (['--rate-hz', 'inf'], '--rate-hz inf is out of range: allowed (0, 1e6] Hz'),
    (['--temp-c', 'nan'], '--temp-c nan is out of range: allowed [-60, 200] C'),
    (['--temp-c', '1e9'], '--temp-c 1000000000.0 is out of range: allowed [-60, 200] C'),
    (['--seed', '-1'], '--seed -1 is out of range: allowed >= 0'),
])
def test_replay_options_are_refused_in_their_own_words_before_the_work(tmp_path, args,
                                                                       message):
    path = str(tmp_path / 'robot')
    _robot_bag(path, seconds=1.0)
    out = _cli('replay', path, '--out', str(tmp_path / 'out'), *args)
    assert out.returncode == 2 and out.stderr.startswith(f'gyro-emulator replay: error: '
                                                         f'{message}'), out.stderr
    assert out.stderr.count('\n') == 1 and not os.path.exists(tmp_path / 'out')


@pytest.mark.parametrize('topic, column, value, message', [
    ('/robot/imu', 14, np.nan, r'/robot/imu angular_velocity is not finite at message 7 '
                               r'\(1 of 100 messages\)'),
    ('/robot/imu', 13, np.inf, r'/robot/imu angular_velocity is not finite at message 7'),
    ('/robot/imu', 26, np.nan, r'/robot/imu linear_acceleration is not finite at message 7'),
    ('/robot/imu', 15, 5e3, r'/robot/imu angular_velocity = 5000.0 at sample 7 .* is beyond '
                            r'\[-1000, 1000\] rad/s'),
    ('/robot/imu_temp', 0, np.nan, r'/robot/imu_temp temperature is not finite at message 0'),
    ('/robot/imu_temp', 0, 900.0, r'/robot/imu_temp temperature = 900.0 at sample 0 .* is '
                                  r'beyond \[-60, 200\] C'),
])
def test_a_drive_no_part_could_have_is_refused_naming_the_topic_and_message(
        tmp_path, topic, column, value, message):
    # the rule simulate --profile and diagnose apply: it reached the model as
    # "propagate: rate_rad_s ... not finite" (or not at all: 5000 rad/s was replayed)
    def spoil(imu, temps):
        (imu[7] if topic == '/robot/imu' else temps[0])[column] = value

    path = str(tmp_path / 'robot')
    _robot_bag(path, seconds=1.0, spoil=spoil)
    with pytest.raises(ValueError, match=message) as info:
        load_inputs(bag.BagReader(path), rate_topic='/robot/imu',
                    temperature_topic='/robot/imu_temp')
    assert '\n' not in str(info.value)
    out = _cli('replay', path, '--out', str(tmp_path / 'out'), '--rate-topic', '/robot/imu',
               '--temperature-topic', '/robot/imu_temp')
    assert out.returncode == 2 and 'Traceback' not in out.stderr, out.stderr
    assert len(out.stderr.strip().splitlines()) == 1 and not os.path.exists(tmp_path / 'out')
