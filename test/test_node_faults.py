"""
Fault injection on the running node: a scenario's fault schedule, runtime parameters.

The scenario player (a real process) plays a resting profile with a fault
schedule of every type; the node applies each through its ``fault.*``
parameters. Each fault's window is taken from ``~/truth/fault`` (the
sample instants where it became active and ended) and its signature is
checked in ``imu/data_raw`` (the paper preset: no latency, so the Imu stamp is
the sample instant; white noise 1.1e-3 rad/s per sample at 200 Hz). The
node publishes with ``qos_reliability:=reliable`` and the probe listens
reliably with a deep queue: a one-sample signature (the spike) must not be
lost to best-effort delivery on a loaded machine.
"""

import os
import struct
import subprocess
import sys

from conftest import ros_env
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu
from test_node import HANG_S, NodeProcess, Probe, stamp_ns
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
pytestmark = pytest.mark.ros
SIGMA = 1.13e-3
RANGE = 5.235987755982989
LATCHED = QoSProfile(depth=50, durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Reliable, deep: every sample the node publishes reaches the probe.
EVERY = QoSProfile(depth=2000, reliability=ReliabilityPolicy.RELIABLE)
#: (type, axis, magnitude) in schedule order, 0.4 s each, 0.35 s apart.
SCHEDULE = [('stuck', 'x', 0.0), ('bias_step', 'z', 0.05), ('drift', 'y', 0.2),
            ('spike', 'x', 1.0), ('dropout', 'all', 0.0), ('saturate', 'z', 1.0),
            ('noise_burst', 'x', 0.05)]


def windows(fault_msgs):
    """Return {type: (active since ns, ended since ns)} from ~/truth/fault."""
    found = {}
    for msg in fault_msgs:
        values = {kv.key: kv.value for kv in msg.status[0].values}
        found.setdefault(values['type'], {})[values['state']] = int(values['since_ns'])
    return {kind: (states['active'], states['ended']) for kind, states in found.items()
            if 'active' in states and 'ended' in states}


def bits(value):
    return struct.pack('<d', value)


@pytest.fixture(scope='module')
def played(tmp_path_factory):
    tmp = tmp_path_factory.mktemp('faults')
    profile = tmp / 'faults.yaml'
    profile.write_text(yaml.safe_dump({
        'name': 'faults', 'publish_rate_hz': 50.0,
        'segments': [{'duration_s': 6.0, 'rate_rad_s': 0.0, 'temp_c': 25.0}],
        'faults': [{'type': kind, 'axis': axis, 'magnitude': magnitude,
                    'start_s': 0.6 + 0.75 * k, 'duration_s': 0.4}
                   for k, (kind, axis, magnitude) in enumerate(SCHEDULE)]}))
    env = ros_env()
    node = NodeProcess(env, str(tmp / 'node.log'), '-p', 'diagnostics_period_s:=0.1',
                       '-p', 'qos_reliability:=reliable')
    probe = Probe(env)
    got = {'imu': probe.listen(Imu, 'imu/data_raw', EVERY),
           'truth': probe.listen(Vector3Stamped, 'gyro_emulator/truth/rate', EVERY),
           'fault': probe.listen(DiagnosticArray, 'gyro_emulator/truth/fault', LATCHED),
           'diag': probe.listen(DiagnosticArray, '/diagnostics', 100)}
    scenario = None
    try:
        probe.spin_until(lambda: len(got['imu']) > 20 and got['fault'], HANG_S, 'the node')
        scenario = subprocess.Popen([sys.executable, '-m', 'gyro_emulator.ros.scenario',
                                     str(profile)], env=env, cwd=ROOT, text=True,
                                    stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        probe.spin_until(lambda: scenario.poll() is not None, HANG_S, 'the scenario')

        def heard_out():
            """Every fault's end on ~/truth/fault, and Imu samples after the last one."""
            found = windows(got['fault'])
            return len(found) == len(SCHEDULE) and got['imu'] and stamp_ns(
                got['imu'][-1].header) > max(end for _, end in found.values())
        # a loaded machine can leave the node behind the scenario's end
        probe.spin_until(heard_out, HANG_S, 'every fault window and the samples after it')
        yield got, scenario.stdout.read(), node, probe
    finally:
        # also after a failed start: no process is left answering on this ROS domain
        if scenario is not None and scenario.poll() is None:
            scenario.kill()
            scenario.wait()
        probe.close()
        node.stop()


def series(got, start_ns, end_ns, axis):
    rows = [(stamp_ns(m.header), getattr(m.angular_velocity, axis)) for m in got['imu']]
    return np.array([v for t, v in rows if start_ns <= t < end_ns])


def test_the_schedule_reached_the_node_and_each_fault_was_reported(played):
    got, output, node, _ = played
    assert output.count('fault injected:') == len(SCHEDULE), output
    assert 'refused' not in output
    found = windows(got['fault'])
    assert set(found) == {kind for kind, _, _ in SCHEDULE}
    truth_ns = np.sort([stamp_ns(m.header) for m in got['truth']])
    for kind, (start, end) in found.items():
        # 0.4 s on the node clock, to the sample (5 ms) it was checked at; a
        # machine stall the node caught up from shows as a longer gap between
        # its truth stamps and can shorten or lengthen the window by as much
        near = truth_ns[(truth_ns >= start - 100_000_000) & (truth_ns <= end + 100_000_000)]
        stall_s = max(0.0, float(np.max(np.diff(near), initial=0)) * 1e-9 - 0.005)
        assert (end - start) * 1e-9 == pytest.approx(0.4, abs=0.011 + stall_s), kind
    levels = {}
    for array in got['diag']:
        status = array.status[0]
        if 'fault injected: ' in status.message:
            kind = status.message.split('fault injected: ')[1].split()[0]
            levels[kind] = max(levels.get(kind, 0), status.level[0])
    assert levels == {'stuck': 2, 'dropout': 2, 'saturate': 2, 'bias_step': 1, 'drift': 1,
                      'spike': 1, 'noise_burst': 1}
    assert 'Traceback' not in node.log() and 'fault set: stuck' in node.log()


def test_each_type_shows_its_signature_in_imu_data_raw(played):
    got, _, _, _ = played
    found = windows(got['fault'])
    start, end = found['stuck']
    x = series(got, start, end, 'x')
    assert len(x) > 60 and len({bits(v) for v in x}) == 1
    # ... and it is the value of the sample before the fault (if that Imu arrived).
    previous = max(t for t in (stamp_ns(m.header) for m in got['truth']) if t < start)
    before = series(got, previous, start, 'x')
    if len(before):
        assert bits(x[0]) == bits(before[-1])
    start, end = found['bias_step']
    shift = series(got, start, end, 'z').mean() - series(got, start - 3 * 10**8, start,
                                                         'z').mean()
    assert shift == pytest.approx(0.05, abs=6 * SIGMA / np.sqrt(60))
    start, end = found['drift']
    y = series(got, start, end, 'y')
    t = np.array([stamp_ns(m.header) for m in got['imu'] if start <= stamp_ns(m.header) < end])
    assert np.polyfit((t - start) * 1e-9, y, 1)[0] == pytest.approx(0.2, abs=0.02)
    start, end = found['spike']
    x = series(got, start, end, 'x')
    outliers = np.flatnonzero(np.abs(x - np.median(x)) > 0.5)
    assert list(outliers) == [0] and x[0] - np.median(x) == pytest.approx(1.0, abs=0.01)
    start, end = found['dropout']
    assert len(series(got, start, end, 'x')) == 0
    truth = [t for t in (stamp_ns(m.header) for m in got['truth']) if start <= t < end]
    assert len(truth) > 50                      # the sensor kept sampling
    start, end = found['saturate']
    z = series(got, start, end, 'z')
    assert len(z) > 60 and np.all(z == RANGE)
    start, end = found['noise_burst']
    x = series(got, start, end, 'x')
    # Sample sd of n = 80 normals: within 0.6-1.5 of 0.05 (chi-square, p < 1e-4 outside).
    assert 0.6 < np.std(x) / np.hypot(0.05, SIGMA) < 1.5


def test_faults_set_at_run_time_and_refused_values(played):
    got, _, node, probe = played
    client = AsyncParameterClient(probe.node, 'gyro_emulator')
    refused = probe.call(client.set_parameters([Parameter('fault.type', value='melt')]))
    assert not refused.results[0].successful
    assert 'choose one of none, stuck' in refused.results[0].reason
    refused = probe.call(client.set_parameters([Parameter('fault.magnitude', value=5e3)]))
    assert not refused.results[0].successful and 'fault.magnitude' in refused.results[0].reason
    got['fault'].clear()
    done = probe.call(client.set_parameters([Parameter('fault.type', value='dropout')]))
    assert done.results[0].successful
    probe.spin_until(lambda: any(
        {kv.key: kv.value for kv in m.status[0].values}['state'] == 'active'
        for m in got['fault']), HANG_S, 'the dropout to act')
    since_ns = max(int({kv.key: kv.value for kv in m.status[0].values}['since_ns'])
                   for m in got['fault'])
    # 0.3 s of node time in the dropout, and 0.1 s more (any Imu of those samples
    # was published long before): the truth says the node sampled on.
    probe.spin_until(lambda: any(stamp_ns(m.header) >= since_ns + 400_000_000
                                 for m in got['truth']), HANG_S, '0.4 s of dropout')
    # a dropout stops publishing (a loaded machine can deliver older Imu late)
    assert not [m for m in got['imu'] if since_ns <= stamp_ns(m.header) < since_ns + 3 * 10**8]
    assert series(got, since_ns - 10**8, since_ns, 'x').size > 0     # ... not before it
    done = probe.call(client.set_parameters([Parameter('fault.type', value='none')]))
    assert done.results[0].successful
    probe.spin_until(lambda: len(got['imu']) > 5, HANG_S, 'the output back')
    assert node.proc.poll() is None
