"""
The node as a real process where its time line breaks or its part is calibrated.

* ``/clock`` jumping +-1e9 s (a bag replayed with epoch stamps after a
  simulator, then a simulator again): the node keeps publishing, counts the
  jumps and says them on ``/diagnostics``.
* ``startup_bias_calibration``: the turn-on bias leaves ``imu/data_raw``,
  stays on the truth topic, and ``/diagnostics`` says the estimate.

Every wait polls with a timeout; nothing sleeps for synchronisation.
"""

from conftest import ros_env
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Vector3Stamped
import numpy as np
import pytest
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu
from test_node import diag_values, HANG_S, NodeProcess, Probe, stamp_ns, vector

NS = 1_000_000_000
pytestmark = pytest.mark.ros


def test_clock_jumps_of_plus_minus_1e9_s_keep_the_node_publishing(tmp_path):
    """/clock: 10 s, then 1.7e9 s (epoch), back 1e9 s, ahead 1e9 s, back to 10 s."""
    env = ros_env()
    node = NodeProcess(env, str(tmp_path / 'node.log'), '-r', '__ns:=/jumps', '-p',
                       'use_sim_time:=true', '-p', 'rate_hz:=10.0', '-p',
                       'diagnostics_period_s:=0.2')
    probe = Probe(env)
    try:
        clock = probe.publisher(Clock, '/clock', 10)
        imu = probe.listen(Imu, '/jumps/imu/data_raw')
        diags = probe.listen(DiagnosticArray, '/diagnostics', 50)
        probe.spin_until(lambda: clock.get_subscription_count() > 0 and
                         probe.node.count_publishers('/jumps/imu/data_raw') > 0, HANG_S,
                         'the node on the graph')
        probe.preroll(clock, 10 * NS, NS // 10, (imu,), 40)

        def outputs(t0_s, count):
            """Step the clock by 0.1 s from t0_s; return the span (ns) of those steps."""
            start_ns = int(round(t0_s * NS))
            for k in range(count):
                msg = Clock()
                msg.clock.sec, msg.clock.nanosec = divmod(start_ns + k * NS // 10, NS)
                seen = len(imu)
                for _ in range(20):                 # until this tick's output (or 1 s)
                    clock.publish(msg)
                    probe.executor.spin_once(timeout_sec=0.05)
                    if len(imu) > seen:
                        break
            return start_ns, start_ns + count * NS // 10

        steps = [outputs(t0, 5) for t0 in (10.0, 1.7e9, 0.7e9, 1.7e9 + 10.0, 10.0 + 30.0)]
        assert node.proc.poll() is None, node.log()
        probe.spin_until(lambda: any(diag_values(d)[1].get('clock_jumps') == '4'
                                     for d in diags), HANG_S, 'diagnostics after four jumps')
        # Counted now: an output a loaded machine delivered after its step's second counts.
        spans = [[stamp_ns(m.header) for m in imu if start_ns <= stamp_ns(m.header) < end_ns]
                 for start_ns, end_ns in steps]
    finally:
        probe.close()
        code = node.stop()
    log = node.log()
    assert code == 0 and 'Traceback' not in log and 'Error' not in log, log
    assert all(len(span) >= 3 for span in spans), [len(s) for s in spans]
    said = ' '.join(diag_values(d)[0].message for d in diags)
    assert 'the clock jumped ahead 16999999' in said and 'clock jumped back' in said
    assert 'model errors' not in said and diag_values(diags[-1])[1]['model_errors'] == '0'
    assert log.count('command stamps forgotten, filters restarted') == 4


def test_startup_bias_calibration_removes_the_turn_on_bias_and_says_it(tmp_path):
    """The consumer preset's turn-on bias (tenths of a rad/s) is gone after 1 s at rest."""
    env = ros_env()
    node = NodeProcess(env, str(tmp_path / 'node.log'), '-r', '__ns:=/cal', '-p',
                       'sensor_config:=consumer', '-p', 'startup_bias_calibration:=1.0', '-p',
                       'diagnostics_period_s:=0.2', '-p', 'rate_hz:=200.0')
    probe = Probe(env)
    try:
        imu = probe.listen(Imu, '/cal/imu/data_raw')
        bias = probe.listen(Vector3Stamped, '/cal/gyro_emulator/truth/bias')
        diags = probe.listen(DiagnosticArray, '/diagnostics', 50)

        def calibrated():
            return [values for _, values in map(diag_values, diags)
                    if values.get('bias_calibration') == 'applied']
        probe.spin_until(lambda: calibrated() and len(imu) > 600, HANG_S,
                         'the calibration and 2 s of output after it')
    finally:
        probe.close()
        code = node.stop()
    log = node.log()
    assert code == 0 and 'Traceback' not in log, log
    assert 'startup bias calibration over 1 s (200 samples)' in log
    values = calibrated()[-1]
    estimate = np.array([float(values[f'bias_calibration.{a}_rad_s']) for a in 'xyz'])
    assert values['bias_calibration.moved'] == ''
    # Samples stamped after the window (its 200 samples from the first one on).
    first_ns = min(stamp_ns(m.header) for m in imu)
    after = [vector(m.angular_velocity) for m in imu
             if stamp_ns(m.header) > first_ns + 1.1 * NS]
    truth = np.array([vector(m.vector) for m in bias])
    assert np.abs(truth.mean(axis=0)).max() > 0.01      # the part has its turn-on bias ...
    assert np.abs(estimate).max() > 0.01                # ... the calibration found it ...
    # ... and it is gone from the output: within 1e-3 rad/s, ten standard errors
    # of the 200-sample window mean (1e-4 rad/s).
    assert np.abs(np.mean(after, axis=0)).max() < 1e-3, np.mean(after, axis=0)


def test_sim_time_without_a_clock_is_a_warning_until_the_first_sample(tmp_path):
    """A missing /clock bridge: /diagnostics warns (no sample yet) instead of OK with 0 samples."""
    env = ros_env()
    node = NodeProcess(env, str(tmp_path / 'node.log'), '-r', '__ns:=/noclock', '-p',
                       'use_sim_time:=true', '-p', 'diagnostics_period_s:=0.2')
    probe = Probe(env)
    try:
        clock = probe.publisher(Clock, '/clock', 10)
        imu = probe.listen(Imu, '/noclock/imu/data_raw')
        diags = probe.listen(DiagnosticArray, '/diagnostics', 50)

        def said(predicate):
            return [status for status, values in map(diag_values, diags)
                    if predicate(status, values)]
        probe.spin_until(lambda: said(lambda s, v: v.get('samples') == '0'), HANG_S,
                         'a status before any /clock')
        msg = Clock()
        msg.clock.sec = 10
        probe.spin_until(lambda: clock.get_subscription_count() > 0, HANG_S, 'the node on /clock')
        for k in range(400):                    # 10 ms steps until a status counts samples
            msg.clock.sec, msg.clock.nanosec = divmod(10 * NS + k * NS // 100, NS)
            clock.publish(msg)
            probe.spin_for(0.01)
            if imu and said(lambda s, v: v.get('samples', '0') != '0'):
                break
    finally:
        probe.close()
        code = node.stop()
    log = node.log()
    assert code == 0 and 'Traceback' not in log, log
    before = said(lambda s, v: v.get('samples') == '0')
    assert before and all(s.level == DiagnosticStatus.WARN and
                          s.message == 'no sample yet: waiting for /clock' for s in before)
    after = said(lambda s, v: v.get('samples', '0') != '0')
    assert after and all('no sample yet' not in s.message for s in after), after


def test_an_ideal_imu_without_acceleration_is_passed_on_as_absent(tmp_path):
    """REP 145 on the input: covariance[0] = -1 (values NaN, to be ignored) is not refused."""
    env = ros_env()
    node = NodeProcess(env, str(tmp_path / 'node.log'), '-r', '__ns:=/noaccel', '-p',
                       'input_source:=imu')
    probe = Probe(env)
    try:
        ideal = probe.publisher(Imu, '/noaccel/imu/ideal')
        imu = probe.listen(Imu, '/noaccel/imu/data_raw')
        truth = probe.listen(Imu, '/noaccel/gyro_emulator/truth/imu')
        probe.spin_until(lambda: ideal.get_subscription_count() > 0 and
                         probe.node.count_publishers('/noaccel/imu/data_raw') > 0, HANG_S,
                         'the node on the graph')
        for k in range(20):
            msg = Imu()
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(1000 * NS + k * 5_000_000, NS)
            msg.angular_velocity.z = 0.1
            msg.linear_acceleration.x = msg.linear_acceleration.y = float('nan')
            msg.linear_acceleration.z = float('nan')
            msg.linear_acceleration_covariance[0] = -1.0
            seen = len(imu)
            for _ in range(20):                     # until its output comes (or 1 s)
                if k == 0 or len(imu) > seen:
                    break
                probe.spin_for(0.05)
            ideal.publish(msg)
        probe.spin_until(lambda: len(imu) >= 15 and len(truth) >= 15, HANG_S, 'the outputs')
    finally:
        probe.close()
        code = node.stop()
    log = node.log()
    assert code == 0 and 'Traceback' not in log and 'input rejected' not in log, log
    assert ' 0 inputs rejected' in log, log
    for m in imu:
        assert m.linear_acceleration_covariance[0] == -1.0
        assert np.all(np.isfinite(vector(m.angular_velocity) + vector(m.linear_acceleration)))
    # a level part turning about z: the model sensed gravity on z
    np.testing.assert_allclose([vector(m.linear_acceleration) for m in truth],
                               [(0.0, 0.0, 9.80665)] * len(truth), atol=1e-12)
