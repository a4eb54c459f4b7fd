"""
The IMU a navigation stack reads: attitude filters (the ``ahrs`` package) on the node's output.

Real node processes on sim time: a probe drives ``/clock`` step by step and
the rate commands of a scenario, and records ``imu/data_raw`` and
``~/truth/*`` from T0 on (reliable; clock steps before T0 first prove that
every writer has matched the probe's readers, :meth:`SimRun.preroll`).
The bounds are derived in :mod:`attitude_reference`; an offline test
checks that the heading bound is calibrated (its false-alarm rate over
many seeds), so the one seeded node run is not a lucky seed.
"""

import math

from ahrs.common.orientation import acc2q
import attitude_reference as ref
from conftest import ros_env
from geometry_msgs.msg import Vector3Stamped
from gyro_emulator.physics import kinematics
from gyro_emulator.sensor.config import config_yaml, load_sensor_config
from gyro_emulator.sensor.imu import ImuModel
from gyro_emulator.units import STANDARD_GRAVITY_M_S2 as G
import numpy as np
import pytest
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu
from test_node import NodeProcess, Probe, set_stamp, stamp_ns, vector

NS = 1_000_000_000
T0_NS = 100 * NS
DEEP = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=20000,
                  reliability=ReliabilityPolicy.RELIABLE)
#: Samples per /clock step.
STEP_SAMPLES = 5
#: At most this many /clock steps before T0 for every node's writers to match.
PREROLL_STEPS = 400


# --- the bounds are calibrated (offline, many seeds) -----------------------------------

def test_the_heading_bound_is_calibrated_and_the_tilt_bound_holds_over_seeds():
    """30 seeds of the scenario through both filters: the 2-sigma heading bound's false alarms."""
    config = ref.noise_only_config()
    rates = ref.scenario_rates()
    truth = ref.truth_attitudes(rates)
    force = kinematics.specific_force(truth)
    tilt = ref.tilt_sigma_deg(config)[0]
    heading = ref.heading_sigma_deg(config, len(rates) / ref.RATE_HZ)
    finals = {'Madgwick': [], 'Mahony': []}
    for seed in range(30):
        model = ImuModel(config, ref.RATE_HZ, np.random.default_rng(seed))
        batch = model.run(rates, 25.0, force)
        gyro = batch.gyro_rad_s - batch.bias_rad_s[0]          # the turn-on bias known
        for name, estimate in ref.run_filters(gyro, batch.accel_m_s2).items():
            error = ref.errors_deg(estimate, truth)
            assert np.all(np.sqrt(np.mean(error[:, :2] ** 2, axis=0)) <= tilt), (seed, name)
            assert np.all(np.abs(error[:, :2]) <= 5 * tilt), (seed, name)
            finals[name].append(error[-1, 2])
    for name, values in finals.items():
        values = np.array(values)
        print(f'{name}: heading drift sd / predicted sigma {values.std() / heading:.3f}, '
              f'{np.sum(np.abs(values) > 2 * heading)} of 30 beyond 2 sigma')
        # 30 draws: the sample sd is within 3 of its own sd (1/sqrt(58) = 0.13) of sigma ...
        assert 0.61 <= values.std() / heading <= 1.39, name
        # ... and beyond 2 sigma at most 5 of 30 (binomial, p = 0.046: P(>= 6) = 0.5 %).
        assert np.sum(np.abs(values) > 2 * heading) <= 5, name


# --- the node on sim time ------------------------------------------------------------

class SimRun:
    """Nodes driven on sim time by a probe: /clock steps, rate commands, recorded outputs."""

    def __init__(self, env, namespaces):
        self.probe = Probe(env)
        node = self.probe.node
        self.clock_pub = node.create_publisher(Clock, '/clock', 10)
        self.rate_pubs = {ns: node.create_publisher(Vector3Stamped, f'/{ns}/cmd/angular_velocity',
                                                    DEEP) for ns in namespaces}
        self.imu = {ns: [] for ns in namespaces}
        self.truth = {ns: [] for ns in namespaces}
        self.bias = {ns: [] for ns in namespaces}
        self.subs = []
        for ns in namespaces:
            for topic, kind, store in (('imu/data_raw', Imu, self.imu),
                                       ('gyro_emulator/truth/imu', Imu, self.truth),
                                       ('gyro_emulator/truth/bias', Vector3Stamped, self.bias)):
                self.subs.append(node.create_subscription(kind, f'/{ns}/{topic}',
                                                          store[ns].append, DEEP))

    def wait_matched(self):
        self.probe.spin_until(lambda: all(s.get_publisher_count() > 0 for s in self.subs) and
                              self.clock_pub.get_subscription_count() >= len(self.imu) and
                              all(p.get_subscription_count() for p in self.rate_pubs.values()),
                              60.0, 'the nodes to match')

    def command(self, t_ns, rate_rad_s):
        for pub in self.rate_pubs.values():
            msg = Vector3Stamped()
            msg.vector.x, msg.vector.y, msg.vector.z = (float(v) for v in rate_rad_s)
            set_stamp(msg.header, t_ns)
            pub.publish(msg)

    def tick(self, t_ns):
        msg = Clock()
        msg.clock.sec, msg.clock.nanosec = t_ns // NS, t_ns % NS
        self.clock_pub.publish(msg)

    def preroll(self, period_ns):
        """
        Step the clock before T0 until every node's output, truth and bias have arrived.

        A reliable writer drops what it publishes before it has matched a
        reader, and the probe sees a match from its own side only: once, under
        load, a node's first truth was lost and the clock at T0 waited for it
        in vain. Whole periods before T0, so T0 stays on each node's grid;
        :meth:`drop_before` removes these samples afterwards.
        """
        topics = (self.imu, self.truth, self.bias)
        for m in range(PREROLL_STEPS, 0, -1):
            self.tick(T0_NS - m * period_ns)
            try:
                self.probe.spin_until(lambda: all(store[ns] for store in topics
                                                  for ns in self.imu), 0.05, 'every topic')
                return
            except AssertionError:
                continue
        raise AssertionError('no node delivered all its topics before T0: ' + ', '.join(
            f'{ns}: {[len(store[ns]) for store in topics]}' for ns in self.imu))

    def drop_before(self, t_ns):
        """Forget every message stamped before ``t_ns`` (the pre-roll's)."""
        for store in (self.imu, self.truth, self.bias):
            for ns, got in store.items():
                store[ns] = [m for m in got if stamp_ns(m.header) >= t_ns]

    def clock(self, t_ns, period_ns):
        """
        Step the clock to t_ns; wait until every node's sample at t_ns arrived.

        A part with a clock drift samples off the nominal grid: its last sample
        instant (``~/truth/imu``, no latency) within one period before t_ns counts.
        """
        for _ in range(20):
            self.tick(t_ns)                 # again if lost: same time, no extra sample
            try:
                self.probe.spin_until(lambda: all(
                    got and stamp_ns(got[-1].header) > t_ns - period_ns
                    and len(self.imu[ns]) >= len(got)
                    for ns, got in self.truth.items()), 1.0, f'the samples at {t_ns}')
                return
            except AssertionError:
                continue
        raise AssertionError(f'no sample at {t_ns} ns: ' + ', '.join(
            f'{ns}: {len(got)} samples to {stamp_ns(got[-1].header) if got else None}, '
            f'{len(self.truth[ns])} truths' for ns, got in self.imu.items()))

    def play(self, rates, rate_hz):
        """
        Command ``rates`` (N, 3) sample by sample from T0 (a command where it changes).

        After the pre-roll (:meth:`preroll`); what was recorded before T0
        (half a period's margin for a part whose clock drifts) is dropped.
        """
        period_ns = int(round(NS / rate_hz))
        self.preroll(period_ns)
        last = None
        for k in range(len(rates)):
            if last is None or not np.array_equal(rates[k], last):
                self.command(T0_NS + k * period_ns, rates[k])
                last = rates[k]
            if k % STEP_SAMPLES == 0 or k == len(rates) - 1:
                self.clock(T0_NS + k * period_ns, period_ns)
        self.drop_before(T0_NS - period_ns // 2)

    def close(self):
        self.probe.close()


def node_args(ns, rate_hz, sensor_config, seed):
    deep = []
    for topic in ('imu/data_raw', 'gyro_emulator/truth/imu', 'gyro_emulator/truth/bias'):
        deep += ['-p', f'qos_overrides./{ns}/{topic}.publisher.depth:=20000']
    sensor = [] if sensor_config is None else ['-p', f'sensor_config:={sensor_config}']
    return ['-r', f'__ns:=/{ns}', '-p', 'use_sim_time:=true', '-p', f'rate_hz:={rate_hz}',
            *sensor, '-p', f'seed:={seed}',
            '-p', 'command_timeout_s:=0.0', '-p', 'qos_reliability:=reliable', *deep]


def run_nodes(tmp_path, setups, rates, rate_hz):
    """Run one node per (namespace, sensor_config, seed) over ``rates``; return the SimRun."""
    env = ros_env()
    nodes = {ns: NodeProcess(env, str(tmp_path / f'{ns}.log'),
                             *node_args(ns, rate_hz, sensor, seed))
             for ns, sensor, seed in setups}
    run = SimRun(env, list(nodes))
    try:
        run.wait_matched()
        run.play(rates, rate_hz)
    finally:
        run.close()
        codes = {ns: node.stop() for ns, node in nodes.items()}
    for ns, node in nodes.items():
        assert codes[ns] == 0 and 'Traceback' not in node.log(), node.log()
    return run


def arrays(imu):
    """Return stamps (N,), angular velocity (N, 3), linear acceleration (N, 3)."""
    return (np.array([stamp_ns(m.header) for m in imu]),
            np.array([vector(m.angular_velocity) for m in imu]),
            np.array([vector(m.linear_acceleration) for m in imu]))


def orientations(truth):
    return np.array([(m.orientation.w, m.orientation.x, m.orientation.y, m.orientation.z)
                     for m in truth])


@pytest.mark.ros
def test_madgwick_and_mahony_follow_the_node_over_a_tilt_and_turn(tmp_path):
    config = ref.noise_only_config()
    sensor = tmp_path / 'noise_only.yaml'
    sensor.write_text(config_yaml(config))
    rates = ref.scenario_rates()
    run = run_nodes(tmp_path, [('part', str(sensor), 11)], rates, ref.RATE_HZ)
    imu, truth, bias = run.imu['part'], run.truth['part'], run.bias['part']
    stamps, gyro, accel = arrays(imu)
    # Every sample from the first, in order, each with its truth (same instant: no latency).
    period_ns = int(round(NS / ref.RATE_HZ))
    assert list(stamps) == [T0_NS + k * period_ns for k in range(len(rates))]
    assert [stamp_ns(m.header) for m in truth] == list(stamps)
    # The node's attitude is the scenario's, integrated from the commanded rates.
    q_true = orientations(truth)
    assert np.allclose(q_true, ref.truth_attitudes(rates), atol=1e-9)
    assert np.all(np.isfinite(accel)) and np.all(np.isfinite(gyro))
    # The turn-on bias known (the first sample's truth): removed, as a driver calibration does.
    gyro = gyro - np.array(vector(bias[0].vector))
    tilt = ref.tilt_sigma_deg(config)[0]
    heading = ref.heading_sigma_deg(config, len(rates) / ref.RATE_HZ)
    figures = {}
    # Never a zero accelerometer vector (imu_tools' start-up check would call it free fall).
    assert np.all(np.abs(np.linalg.norm(accel, axis=1) - G) < 0.05 * G)
    for name, estimate in ref.run_filters(gyro, accel).items():
        # Both initialise from the first message: a finite unit attitude, level within noise,
        # and exactly the one ahrs makes of message 1's accelerometer (acc2q).
        assert np.all(np.isfinite(estimate)) and abs(np.linalg.norm(estimate[0]) - 1) < 1e-9
        np.testing.assert_array_equal(estimate[0], acc2q(accel[0]))
        error = ref.errors_deg(estimate, q_true)
        assert np.all(np.abs(error[0, :2]) <= 5 * tilt), (name, error[0])
        rms = np.sqrt(np.mean(error[:, :2] ** 2, axis=0))
        peak = np.abs(error[:, :2]).max(axis=0)
        figures[name] = (rms, peak, error[-1, 2])
        assert np.all(rms <= tilt) and np.all(peak <= 5 * tilt), (name, rms, peak, tilt)
        assert abs(error[-1, 2]) <= 2 * heading, (name, error[-1, 2], heading)
    print(f'tilt sigma {tilt:.4f} deg, heading sigma {heading:.4f} deg;',
          {n: (np.round(r, 4).tolist(), np.round(p, 4).tolist(), round(h, 4))
           for n, (r, p, h) in figures.items()})


@pytest.mark.ros
def test_covariances_match_a_static_run_and_gravity_turns_from_z_to_y(tmp_path):
    """A default node and a consumer node: 40 s at rest, then 90 deg about x in 1 s."""
    rate_hz = 200.0
    rest, turn, after = 8000, 200, 400
    rates = np.zeros((rest + turn + after, 3))
    rates[rest:rest + turn, 0] = 0.5 * math.pi
    # 'paper': a default node (no sensor_config: the paper preset)
    run = run_nodes(tmp_path, [('paper', None, 3), ('consumer', 'consumer', 4)], rates,
                    rate_hz)
    for ns in ('paper', 'consumer'):
        _, gyro, accel = arrays(run.imu[ns])
        assert len(gyro) >= len(rates) - 1    # a clock drift (1000 ppm: consumer): +- a few
        # From the node's sample at T0 (every writer matched in the pre-roll) the
        # accelerometer is present and never a zero vector.
        assert stamp_ns(run.truth[ns][0].header) <= T0_NS + int(NS / rate_hz), ns
        assert all(m.linear_acceleration_covariance[0] > 0.0 for m in run.imu[ns]), ns
        assert np.all(np.linalg.norm(accel, axis=1) > 0.5 * G), ns
        model = ImuModel(load_sensor_config(ns), rate_hz, np.random.default_rng(0))
        for field, values, sigma in (('angular_velocity_covariance', gyro,
                                      model.white_noise_sigma_rad_s),
                                     ('linear_acceleration_covariance', accel,
                                      model.accel_white_noise_sigma_m_s2)):
            published = np.array([np.diag(np.reshape(getattr(m, field), (3, 3)))
                                  for m in run.imu[ns]])
            # sigma of N at the die temperature (it moves little at rest), at the part's rate
            published = published[100:rest].mean(axis=0)
            assert np.allclose(published, sigma ** 2, rtol=0.01)
            # 8000 samples: the sample variance's relative sd is sqrt(2 / 8000) = 1.6 %
            # (white noise; the filters' correlation and the slow terms add < 1 %): 10 %
            # is over 6 sd (4 sd if correlation halves the independent samples).
            ratio = np.var(values[100:rest], axis=0, ddof=1) / published
            print(f'{ns} {field}: measured / published variance {np.round(ratio, 4)}')
            assert np.all(np.abs(ratio - 1.0) <= 0.10), (ns, field, ratio)
        # Gravity turned with the part: z before, y after (the truth exactly).
        force = np.array([vector(m.linear_acceleration) for m in run.truth[ns]])
        assert np.allclose(force[:rest], (0.0, 0.0, G), atol=1e-12)
        # On the nominal grid (paper) exactly; a part with a clock drift (consumer, 1000 ppm)
        # takes each command at its next sample: the turn is off by at most one period's
        # angle, (pi / 2) 5 ms = 0.45 deg, g sin(0.45 deg) = 0.077 m/s^2.
        bound = 1e-9 if ns == 'paper' else G * math.sin(0.5 * math.pi / rate_hz)
        assert np.all(np.abs(force[rest + turn + 10:] - (0.0, G, 0.0)) <= bound), ns
    # The default node's accelerometer reads it within 1 % of g after the turn.
    _, _, accel = arrays(run.imu['paper'])
    before, later = accel[100:rest].mean(axis=0), accel[rest + turn + 10:].mean(axis=0)
    print(f'paper accelerometer before {before}, after the turn {later} m/s^2')
    assert np.all(np.abs(before - (0.0, 0.0, G)) <= 0.01 * G)
    assert np.all(np.abs(later - (0.0, G, 0.0)) <= 0.01 * G)
