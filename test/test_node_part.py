"""
The node runs the part ``diagnose --write-config`` made of a real log (issue 24).

The LSM6DSM chamber log (static, cooling 23.9 -> 15.6 C over 2 h, in bursts
of 5 s every 5 min) goes through ``diagnose --write-config part.yaml``; its
temperatures are played into the node started with ``-p
sensor_config:=part.yaml`` and ``use_sim_time`` (one sample per record
second): the test steps ``/clock`` four record seconds at a time, the
temperature commands stamped two steps ahead, and takes the next step once
the node's samples of this one arrived. So the play goes as fast as the
machine allows and never loses a sample to a loaded machine, which a play
paced by the wall clock (``replay --clock --rate``, tested in
test_replay_ros.py and test_accel_commands.py) does: a stall of either
process coalesces ``/clock`` past the node's 10 s jump rule. The node's mean
output per 1 K temperature bin must follow the measured one, up to the
user's bias calibration b0 (the emulator is the calibrated part: one
constant), within the measured noise.

Two terms the record does not measure ride on its empty axes, to check the
record time of the extended terms on the node's clock: a bias step on x at
record time 4000 s and a warm-up plus drift on y (``start_time_s``,
``time_origin_s``), with ``record_start_clock_s`` the bag's start
(docs/node.md).
"""

import os
import subprocess
import sys

from conftest import ros_env
from gyro_emulator.sensor import config as sensor_config
import numpy as np
import pytest
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, Temperature
from test_node import HANG_S, NodeProcess, Probe, set_stamp, stamp_ns, vector
from test_node_sim import DEEP
import yaml

pytestmark = pytest.mark.ros

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LOG = os.path.join(os.path.dirname(ROOT), 'shared', 'data', 'real', 'lsm6dsm_thermal_chamber',
                   'lsm6dsm_tvc_x.csv')
NS = 1_000_000_000
#: Clock time of the record's time 0, ns (the node's clock then reads record time + 1000 s).
BASE_NS = 1000 * NS
#: One /clock step, ns: four record seconds (below the node's 10 s jump rule).
STEP_NS = 4 * NS
#: How far the temperature commands go ahead of the clock, ns (below max_stamp_lead_s).
LEAD_NS = 2 * STEP_NS
#: Clock ticks, a record second apart, before the record (``Probe.preroll``): the
#: node's first samples can be lost to a reliable writer's late match.
PREROLL_TICKS = 120
#: Marker terms on the axes the record does not measure (x, y).
STEP_S, STEP_RAD_S = 4000.0, 0.02
TAU_S, WARM_RAD_S, DRIFT_RAD_S_H, ORIGIN_S = 1500.0, 0.03, 0.01, 3662.3


def _cli(*args):
    env = dict(os.environ, MPLBACKEND='Agg',
               PYTHONPATH=ROOT + os.pathsep + os.environ.get('PYTHONPATH', ''))
    return subprocess.run([sys.executable, '-m', 'gyro_emulator.cli', *args], cwd=ROOT,
                          capture_output=True, text=True, env=env, timeout=300)


@pytest.fixture(scope='module')
def record():
    if not os.path.exists(LOG):
        pytest.skip('the real LSM6DSM chamber log (../shared/data/real) is not present')
    data = np.genfromtxt(LOG, delimiter=',', names=True)
    return data['time_s'], data['temp_c'], data['gyro_rad_s']


@pytest.fixture(scope='module')
def part_yaml(record, tmp_path_factory):
    """Run diagnose --write-config on the log; add the marker terms on x and y."""
    folder = tmp_path_factory.mktemp('part')
    path = folder / 'part.yaml'
    proc = _cli('diagnose', LOG, '--write-config', str(path))
    assert proc.returncode == 0, proc.stderr
    doc = yaml.safe_load(path.read_text())
    assert doc['bias_temp_coeff_rad_s_k'][2] > 5e-4       # what diagnose found: z, 1e-3/K
    assert not doc.get('extended')
    doc['extended'] = {
        'start_time_s': 0.0,
        'bias_step': {'step_time_s': STEP_S, 'bias_step_rad_s': [STEP_RAD_S, 0.0, 0.0]},
        'bias_time': {'warmup_time_constant_s': TAU_S, 'warmup_rad_s': [0.0, WARM_RAD_S, 0.0],
                      'bias_drift_rad_s_per_h': [0.0, DRIFT_RAD_S_H, 0.0],
                      'time_origin_s': ORIGIN_S}}
    marked = folder / 'part_marked.yaml'
    marked.write_text(yaml.safe_dump(doc))
    return str(marked)


def _bins(temp_c, values, edges):
    """Return, per bin of ``edges`` (index, count, mean)."""
    k = np.digitize(temp_c, edges)
    return {int(i): (int(np.sum(k == i)), float(values[k == i].mean())) for i in np.unique(k)}


def _play(tmp_path, part_yaml, t_s, temp_c):
    """Play the profile into the node, /clock step by step; return the Imu stamps and rates."""
    env = ros_env()
    node = NodeProcess(env, str(tmp_path / 'node.log'), '-r', '__ns:=/part', '-p',
                       'use_sim_time:=true', '-p', f'sensor_config:={part_yaml}', '-p',
                       'rate_hz:=1.0', '-p', f'initial_temperature_c:={temp_c[0]}', '-p',
                       'publish_truth:=false', '-p', 'max_stamp_lead_s:=30.0', '-p',
                       'seed:=5', '-p', f'record_start_clock_s:={BASE_NS / NS}',
                       '-p', 'qos_reliability:=reliable')
    probe = Probe(env)
    try:
        imu = probe.listen(Imu, '/part/imu/data_raw', DEEP)
        clock = probe.publisher(Clock, '/clock', 10)
        temp = probe.publisher(Temperature, '/part/cmd/temperature', 1000)
        probe.spin_until(lambda: clock.get_subscription_count() > 0 and
                         temp.get_subscription_count() > 0 and imu_publishers(probe) > 0,
                         HANG_S, 'the node on the graph')
        probe.preroll(clock, BASE_NS, NS, (imu,), PREROLL_TICKS)
        command_ns = BASE_NS + np.round(t_s * NS).astype(np.int64)
        sent = 0
        for clock_ns in range(BASE_NS, int(command_ns[-1]) + STEP_NS, STEP_NS):
            _step(probe, clock, imu, clock_ns)
            # after the clock: a command stamped too far ahead of it is refused
            ahead = int(np.searchsorted(command_ns, clock_ns + LEAD_NS, side='right'))
            for k in range(sent, ahead):
                msg = Temperature(temperature=float(temp_c[k]))
                set_stamp(msg.header, int(command_ns[k]))
                temp.publish(msg)
            sent = ahead
        assert node.proc.poll() is None, node.log()
    finally:
        probe.close()
        assert node.stop() == 0
    played = [m for m in imu if stamp_ns(m.header) >= BASE_NS]     # without the pre-roll's
    stamps = np.array([stamp_ns(m.header) for m in played], dtype=np.int64)
    return stamps, np.array([vector(m.angular_velocity) for m in played])


def imu_publishers(probe):
    return probe.node.count_publishers('/part/imu/data_raw')


def _step(probe, clock, imu, clock_ns):
    """
    Set the node's clock to ``clock_ns`` and wait for its samples of this step.

    A sample stamped less than 3.5 s before ``clock_ns`` came due in this step
    (the step before ended 4 s earlier; the part's delay is far below 0.5 s).
    The node's /clock subscription is best effort, depth 1 (rclpy's
    TimeSource): the same time goes out again until the samples come (no
    extra tick).
    """
    msg = Clock()
    msg.clock.sec, msg.clock.nanosec = divmod(clock_ns, NS)

    def stepped():
        clock.publish(msg)
        return imu and stamp_ns(imu[-1].header) > clock_ns - 3_500_000_000
    probe.spin_until(stepped, HANG_S, f'the samples up to clock {clock_ns / NS:g} s')


def test_the_node_runs_the_part_diagnose_wrote_and_follows_the_measured_bias(
        tmp_path, record, part_yaml):
    t_s, temp_c, gyro = record
    stamps, rates = _play(tmp_path, part_yaml, t_s, temp_c)
    assert len(stamps) > 0.8 * t_s[-1]              # most of the 7325 samples arrived
    rec_s = (stamps - BASE_NS) / NS                 # bag time - bag start: record time
    # The temperature in force at each output: the last command before it.
    node_temp = temp_c[np.clip(np.searchsorted(t_s, rec_s, side='right') - 1, 0, None)]
    noise = np.std(np.diff(rates, axis=0), axis=0) / np.sqrt(2.0)   # per sample and axis

    # Measured: one mean per 5 s burst (its noise is correlated within a burst).
    bursts = np.split(np.arange(t_s.size), np.flatnonzero(np.diff(t_s) > 1.0) + 1)
    burst_temp = np.array([temp_c[b].mean() for b in bursts])
    burst_mean = np.array([gyro[b].mean() for b in bursts])
    edges = np.arange(np.floor(temp_c.min()), np.ceil(temp_c.max()) + 1.0)
    measured = _bins(burst_temp, burst_mean, edges)
    emulated = _bins(node_temp, rates[:, 2], edges)
    # The burst means' scatter within the bins, pooled: the record's noise on a burst mean.
    within = burst_mean - np.array([measured[int(i)][1] for i in np.digitize(burst_temp, edges)])
    sigma = np.sqrt(np.sum(within ** 2) / (len(bursts) - len(measured)))
    shared = [i for i in measured if measured[i][0] >= 2 and i in emulated]
    assert len(shared) >= 5
    diff = np.array([measured[i][1] - emulated[i][1] for i in shared])
    se = np.sqrt([sigma ** 2 / measured[i][0] + noise[2] ** 2 / emulated[i][0]
                  for i in shared])
    b0 = np.sum(diff / se ** 2) / np.sum(1.0 / se ** 2)    # the user's bias calibration
    # 4 standard errors per bin (about 1e-3 false alarms over the bins); the
    # fitted 1e-3 rad/s/K moves the bins by about 3 standard errors per kelvin.
    assert np.all(np.abs(diff - b0) <= 4.0 * se), (diff - b0) / se
    assert np.ptp([emulated[i][1] for i in shared]) > 10 * se.max()

    # Record time on the node's clock: record_start_clock_s is the record's start
    # on the clock, so a sample's record time is its clock time - that start.
    # Every sample before the step must be low and every one after high.
    before, after = rec_s < STEP_S, rec_s >= STEP_S
    assert STEP_S - rec_s[before].max() < 15.0 and rec_s[after].min() - STEP_S < 15.0
    assert np.all(rates[before, 0] < STEP_RAD_S / 2) and np.all(rates[after, 0] > STEP_RAD_S / 2)
    expected_y = (WARM_RAD_S * np.exp(-rec_s / TAU_S)
                  + DRIFT_RAD_S_H * (rec_s - ORIGIN_S) / 3600.0)
    residual = rates[:, 1] - expected_y
    residual -= np.median(residual)                 # the turn-on bias of y
    assert np.max(np.abs(residual)) <= 6.0 * noise[1], np.max(np.abs(residual)) / noise[1]


def test_the_record_time_follows_the_node_clock_across_a_jump(tmp_path):
    """
    A bias step at record time 25 s; the /clock jumps 30 s ahead, then back.

    The node restarts its filters at a jump; the extended terms' record time
    follows its clock: the step is on after the jump ahead and off again
    after the jump back to before it.
    """
    path = tmp_path / 'part.yaml'
    path.write_text(yaml.safe_dump({
        'terms': dict.fromkeys(sensor_config.ErrorTerms.names(), False),
        'extended': {'bias_step': {'step_time_s': 25.0, 'bias_step_rad_s': 0.5}}}))
    env = ros_env()
    node = NodeProcess(env, str(tmp_path / 'node.log'), '-r', '__ns:=/jump', '-p',
                       'use_sim_time:=true', '-p', f'sensor_config:={path}', '-p', 'rate_hz:=10.0')
    probe = Probe(env)
    try:
        clock = probe.publisher(Clock, '/clock', 10)
        imu = probe.listen(Imu, '/jump/imu/data_raw')
        probe.spin_until(lambda: clock.get_subscription_count() > 0 and
                         probe.node.count_publishers('/jump/imu/data_raw') > 0, HANG_S,
                         'the node on the graph')
        # record time 0 is the node's first sample: in the pre-roll, at most 4 s before 100 s
        probe.preroll(clock, 100 * NS, NS // 10, (imu,), 40)

        def outputs(t0_s, count):
            """Step the clock by 0.1 s from t0_s; return the span (ns) of those steps."""
            for k in range(count):
                msg = Clock()
                msg.clock.sec, msg.clock.nanosec = divmod(int(round((t0_s + 0.1 * k) * NS)), NS)
                seen = len(imu)
                for _ in range(10):                 # until this tick's output (or 0.5 s)
                    clock.publish(msg)
                    probe.executor.spin_once(timeout_sec=0.05)
                    if len(imu) > seen:
                        break
            return int(round(t0_s * NS)), int(round((t0_s + 0.1 * count) * NS))

        steps = [outputs(100.0, 5),                 # record time below 4.4 s: off
                 outputs(130.0, 5),                 # 30-34.4 s: on
                 outputs(100.5, 10)]                # back below 5.4 s: off
    finally:
        probe.close()
        assert node.stop() == 0
    # Counted now: an output a loaded machine delivered after its step's 0.5 s counts.
    before, ahead, back = ([m.angular_velocity.x for m in imu if start <= stamp_ns(m.header) < end]
                           for start, end in steps)
    assert len(before) >= 3 and len(ahead) >= 3 and len(back) >= 3, (before, ahead, back)
    assert set(before) == {0.0} and set(ahead) == {0.5} and set(back) == {0.0}
    assert 'jumped ahead' in node.log() and 'jumped back' in node.log()
