"""
Behind a simulator (``input_source: imu``) and redundant IMUs, as real processes.

A stand-in simulator process (``test/sim_imu_publisher.py``) publishes
``/clock`` and an ideal ``sensor_msgs/Imu`` on sim time, faster and slower
than real time, paused, and jumping back. The links are made reliable with
``qos_overrides`` so that "one output per input" can be counted exactly.
"""

import json
import os
import signal
import subprocess
import sys

from conftest import ros_env
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
from gyro_emulator.sensor import config as sensor_config
from gyro_emulator.sensor import model as sensor_model
from gyro_emulator.sensor.imu import ImuModel
import numpy as np
import pytest
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu
from test_node import diag_values, HANG_S, NodeProcess, Probe, stamp_ns
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PUBLISHER = os.path.join(ROOT, 'test', 'sim_imu_publisher.py')
pytestmark = pytest.mark.ros
DEEP = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5000,
                  reliability=ReliabilityPolicy.RELIABLE)


def reliable_links(topic_in='/imu/ideal', topic_out='/imu/data_raw'):
    """Parameters that make the node's Imu input and output reliable and deep."""
    return [f'qos_overrides.{topic_in}.subscription.reliability:=reliable',
            f'qos_overrides.{topic_in}.subscription.depth:=5000',
            f'qos_overrides.{topic_out}.publisher.reliability:=reliable',
            f'qos_overrides.{topic_out}.publisher.depth:=5000']


def listen_matched(probe, msg_type, topic):
    """Subscribe reliably; return (received list, subscription) to wait for its match."""
    got = []
    return got, probe.node.create_subscription(msg_type, topic, got.append, DEEP)


def wait_matched(probe, subscriptions):
    """Wait until every subscription matched its publisher (reliable volatile: no loss)."""
    probe.spin_until(lambda: all(s.get_publisher_count() > 0 for s in subscriptions), HANG_S,
                     'the node outputs to match')


def run_simulator(env, out, *args):
    return subprocess.Popen([sys.executable, PUBLISHER, str(out), *args], env=env, cwd=ROOT)


def wait_for(proc, probe, timeout_s=120.0):
    probe.spin_until(lambda: proc.poll() is not None, timeout_s, 'the simulator to finish')
    assert proc.returncode == 0


def test_behind_a_simulator_one_output_per_input_on_sim_time(tmp_path):
    env = ros_env()
    args = ['-p', 'input_source:=imu', '-p', 'use_sim_time:=true',
            '-p', 'qos_reliability:=reliable', '-p', 'sensor_config:=consumer',
            '-p', 'sensor.terms.timestamp_jitter:=false',
            '-p', 'diagnostics_period_s:=0.2', '-p', 'temperature_rate_hz:=5.0']
    for override in reliable_links():
        args += ['-p', override]
    node = NodeProcess(env, str(tmp_path / 'node.log'), *args)
    probe = Probe(env)
    try:
        out, sub = listen_matched(probe, Imu, 'imu/data_raw')
        truth = probe.listen(Vector3Stamped, 'gyro_emulator/truth/scale_factor', DEEP)
        bias = probe.listen(Vector3Stamped, 'gyro_emulator/truth/bias', DEEP)
        truth_imu = probe.listen(Imu, 'gyro_emulator/truth/imu', DEEP)
        diags = probe.listen(DiagnosticArray, '/diagnostics', 50)
        wait_matched(probe, [sub])
        sim = run_simulator(env, tmp_path / 'sent.json', '--subscribers', '1')
        wait_for(sim, probe)
        sent = json.loads((tmp_path / 'sent.json').read_text())
        probe.spin_until(lambda: len(out) >= len(sent['stamps_ns']), HANG_S, 'every output')
        probe.spin_until(lambda: any(diag_values(d)[1].get('input_restarts') == '1'
                                     for d in diags), HANG_S, 'diagnostics after the jump')
    finally:
        probe.close()
        code = node.stop()
    log = node.log()
    assert code == 0 and 'Traceback' not in log
    stamps = sent['stamps_ns']
    phases = sent['phases']
    # One imu/data_raw per imu/ideal, in order, stamped input + latency (1 ms).
    assert len(out) == len(stamps)
    config = sensor_config.load_sensor_config('consumer')
    latency_ns = round(config.latency_s * 1e9)
    assert [stamp_ns(m.header) for m in out] == [s + latency_ns for s in stamps]
    # The simulator's specific force is the accelerometer's true input (and feeds
    # g-sensitivity): exact on ~/truth/imu; imu/data_raw carries the accelerometer's
    # noisy output with its covariance at the input rate; orientation absent.
    sent_force = {(s, 1e-4 * k, 9.80665) for k, s in enumerate(stamps)}
    assert len(truth_imu) >= 0.9 * len(stamps)
    assert all((stamp_ns(m.header), m.linear_acceleration.x, m.linear_acceleration.z)
               in sent_force for m in truth_imu)
    assert all(m.orientation_covariance[0] == -1.0 for m in out)
    accel_sigma = ImuModel(config, 250.0, np.random.default_rng(0)).accel_white_noise_sigma_m_s2
    assert all(m.linear_acceleration_covariance[0] == pytest.approx(accel_sigma[0] ** 2,
                                                                    rel=0.01)
               for m in out[phases['slow']:phases['pause']])
    error = np.array([[m.linear_acceleration.x - 1e-4 * k, m.linear_acceleration.z - 9.80665]
                      for k, m in enumerate(out)])
    turn_on = np.array(config.accelerometer.turn_on_bias_sigma_m_s2)[[0, 2]]
    assert np.all(np.std(error, axis=0) > 0) and np.all(np.abs(error.mean(axis=0)) < 6 * turn_on)
    # dt from the stamps: the model runs at 250 Hz, not at rate_hz (200 Hz), and
    # the covariance is its white-noise sigma^2 there.
    assert 'input rate 250 Hz from the imu/ideal stamps' in log
    sigma = sensor_model.GyroModel(config, 250.0, np.random.default_rng(0)) \
        .white_noise_sigma_rad_s[2]
    cov = out[phases['slow']].angular_velocity_covariance[8]
    assert cov == pytest.approx(sigma ** 2, rel=0.01)
    # The full error model acts: z reads the true 0.5 rad/s times the scale factor
    # plus the bias (turn-on, g-sensitivity to the 1 g passed through, ...), within
    # the quadratic nonlinearity (6.9e-4 s/rad: 2e-4 rad/s) and the noise.
    window = slice(50, phases['pause'])
    z = np.array([m.angular_velocity.z for m in out[window]])
    want = np.array([0.5 * t.vector.z + b.vector.z for t, b in zip(truth[window],
                                                                   bias[window])])
    assert abs(np.mean(z - want)) < 1e-3 and np.std(z - want) > 0
    assert abs(np.mean(want) - 0.5) > 0.01    # the bias and scale factor are there
    # The jump back restarted the filters, said so, and the outputs continued.
    assert 'input clock jumped back' in log and 'filters restarted' in log
    # Temperature from cmd/temperature (stamped on sim time) once sent.
    last = diag_values(diags[-1])[1]
    assert last['temperature_source'] == 'command' and float(last['ambient_temp_c']) == 40.0
    assert float(last['input_rate_hz']) == pytest.approx(250.0)
    assert float(last['sample_period_s']) == pytest.approx(0.004, rel=1e-9)


def array_spec(path, names, seeds):
    """Write an array spec: imu input on sim time, reliable Imu links, the given seeds."""
    def reliable(name):
        link = {'reliability': 'reliable', 'depth': 5000}
        return {'qos_overrides': {'/sim/imu/ideal': {'subscription': link},
                                  f'/{name}/imu/data_raw': {'publisher': link}}}
    instances = []
    for name, seed in zip(names, seeds):
        parameters = reliable(name)
        if seed is not None:
            parameters['seed'] = seed
        instances.append({'name': name, 'parameters': parameters})
    path.write_text(yaml.safe_dump({
        'parameters': {'input_source': 'imu', 'use_sim_time': True,
                       'sensor_config': 'consumer',
                       'sensor': {'terms': {'timestamp_jitter': False}}},
        'instances': instances}))
    return path


def test_redundant_imus_are_independent_unless_seeded_alike(tmp_path):
    """Four nodes from the array entry point on one simulated Imu."""
    env = ros_env()
    names = ('free_a', 'free_b', 'seeded_a', 'seeded_b')
    log = open(tmp_path / 'array.log', 'w')
    array = subprocess.Popen(
        [sys.executable, '-m', 'gyro_emulator.ros.gyro_array',
         str(array_spec(tmp_path / 'a.yaml', names, (None, None, 42, 42))),
         '--ros-args', '-r', 'imu/ideal:=/sim/imu/ideal'],
        env=env, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT)
    probe = Probe(env)
    try:
        listening = {n: listen_matched(probe, Imu, f'/{n}/imu/data_raw') for n in names}
        outs = {n: got for n, (got, _) in listening.items()}
        wait_matched(probe, [sub for _, sub in listening.values()])
        sim = run_simulator(env, tmp_path / 'sent.json', '--subscribers', '4', '--topic',
                            '/sim/imu/ideal', '--fast', '400', '--slow', '0', '--after', '0')
        wait_for(sim, probe)
        count = len(json.loads((tmp_path / 'sent.json').read_text())['stamps_ns'])
        probe.spin_until(lambda: all(len(o) >= count for o in outs.values()), HANG_S,
                         'the outputs of all four')
    finally:
        probe.close()
        array.send_signal(signal.SIGINT)
        code = array.wait(HANG_S)
        log.close()
    text = (tmp_path / 'array.log').read_text()
    assert code == 0 and 'Traceback' not in text
    z = {}
    for name, got in outs.items():
        z[name] = {stamp_ns(m.header): m.angular_velocity.z for m in got}
    common = sorted(set.intersection(*(set(v) for v in z.values())))
    assert len(common) == count
    series = {n: np.array([z[n][t] for t in common]) for n in names}
    # Equal seeds: identical, bit for bit.
    assert series['seeded_a'].tobytes() == series['seeded_b'].tobytes()
    # Seeds from the names: different parts and noise, uncorrelated (|r| < 0.3 is
    # over 4 sd of r for independent noise through the 42 Hz filter at 250 Hz).
    a, b = (np.diff(series[n]) for n in ('free_a', 'free_b'))
    assert not np.array_equal(a, b)
    assert abs(np.corrcoef(a, b)[0, 1]) < 0.3
    assert text.count('(from the node name)') == 2
