"""
The node never stalls and never dies, as real processes (issues 25 and 26).

* A coarse ``/clock`` and a CPU hog: every sample whose time has passed comes
  out (``overrun_policy: fifo``), stamped with its own sample time, in
  bounded bursts; with ``drop`` every lost sample is counted.
* A full disk (``RLIMIT_FSIZE`` with SIGXFSZ ignored: writes past the limit
  fail with EFBIG, as ENOSPC would) stops the recording, not the node.
* ``rate_hz: 1.0`` starts with the shipped ``temperature_rate_hz``.
* The array stops on a terminal's Ctrl-C with status 0.
"""

import os
import resource
import signal
import subprocess
import sys
import time

from conftest import ros_env
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Vector3Stamped
from gyro_emulator.recording import bag
from gyro_emulator.recording.repair import repair_bag
from gyro_emulator.sensor import config as sensor_config
import numpy as np
import pytest
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu
from test_node import diag_values, HANG_S, NodeProcess, Probe, stamp_ns
from test_node_sim import DEEP, listen_matched, reliable_links, wait_matched

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
NS = 1_000_000_000
pytestmark = pytest.mark.ros
#: Busy loop of one CPU hog process, bounded in time (s as argv[1]).
HOG = 'import sys, time\nend = time.monotonic() + float(sys.argv[1])\n' \
      'while time.monotonic() < end:\n    pass\n'


def last_diag(diags):
    return diag_values(diags[-1])


def command_args(*extra):
    """Return node arguments: reliable, deep Imu and truth outputs, no jitter or drift."""
    args = ['-p', 'sensor_config:=consumer', '-p', 'sensor.terms.timestamp_jitter:=false',
            '-p', 'sensor.terms.clock_drift:=false',
            '-p', 'diagnostics_period_s:=0.2', *extra]
    for override in reliable_links(topic_in='/cmd/angular_velocity') + [
            'qos_overrides./gyro_emulator/truth/rate.publisher.reliability:=reliable',
            'qos_overrides./gyro_emulator/truth/rate.publisher.depth:=5000']:
        args += ['-p', override]
    return args


def consecutive(stamps, period_ns):
    """Return the gaps between consecutive stamps in periods (1 everywhere = none lost)."""
    return np.round(np.diff(np.asarray(stamps, dtype=np.int64)) / period_ns).astype(int)


def lost_in(messages, period_ns):
    """Return how many samples are missing between the first and last received."""
    gaps = consecutive([stamp_ns(m.header) for m in messages], period_ns)
    return int(np.sum(gaps - 1))


@pytest.mark.parametrize('step_ms', [10, 20])
def test_a_coarse_clock_gets_every_sample_stamped_with_its_own_time(tmp_path, step_ms):
    """use_sim_time, /clock every 10 or 20 ms at 200 Hz: ~all samples out (was 1/2, 1/4)."""
    env = ros_env()
    node = NodeProcess(env, str(tmp_path / 'node.log'), *command_args(
        '-p', 'use_sim_time:=true', '-p', 'rate_hz:=200.0',
        '-p', 'sensor.terms.timestamp_jitter:=true', '-p', 'sensor.timestamp_jitter_s:=0.1'))
    probe = Probe(env)
    try:
        out, sub = listen_matched(probe, Imu, 'imu/data_raw')
        truth = probe.listen(Vector3Stamped, 'gyro_emulator/truth/rate', DEEP)
        diags = probe.listen(DiagnosticArray, '/diagnostics', 50)
        clock = probe.publisher(Clock, '/clock', 10)
        wait_matched(probe, [sub])
        probe.spin_until(lambda: clock.get_subscription_count() > 0, HANG_S, 'the /clock link')
        msg = Clock()
        start_ns, steps = 1000 * NS, 2000 // step_ms         # 2 s of sim time
        probe.preroll(clock, start_ns, 5_000_000, (out, truth), 400)
        for k in range(steps + 1):
            t_ns = start_ns + k * step_ms * 1_000_000
            msg.clock.sec, msg.clock.nanosec = t_ns // NS, t_ns % NS
            clock.publish(msg)
            probe.executor.spin_once(timeout_sec=0.005)     # paces the simulator
        end_ns = t_ns
        first = lambda: stamp_ns(truth[0].header) if truth else end_ns  # noqa: E731
        want = lambda: (end_ns - first()) // 5_000_000 + 1  # noqa: E731 (with the pre-roll's)
        window = (end_ns - start_ns) // 5_000_000 + 1       # from start_ns on

        def held():
            # the node's /clock subscription is best effort, depth 1 (rclpy's
            # TimeSource): a simulator holding its time repeats its last /clock,
            # or a loaded machine can lose it and the node never reaches it
            clock.publish(msg)
            return (len(_from(truth, start_ns)) >= window
                    and len(_from(out, start_ns - JITTER_CUT_NS)) >= window)

        probe.spin_until(held, HANG_S, 'every sample up to the last /clock')
        # the diagnostics thread reads the sample counters while the executor
        # thread moves them: one message can hold a sample counted due and not
        # yet out, so wait for one that has the last samples out
        probe.spin_until(lambda: diags and float(last_diag(diags)[1]['samples_due']) >=
                         want() and float(last_diag(diags)[1]['emitted_ratio']) == 1.0,
                         HANG_S, 'the diagnostics of the last samples, all out')
    finally:
        probe.close()
        code = node.stop()
    log = node.log()
    assert code == 0 and 'Traceback' not in log
    truth, out = _from(truth, start_ns), _from(out, start_ns - JITTER_CUT_NS)
    sample_ns = [stamp_ns(m.header) for m in truth]
    # Every sample on the 5 ms grid from start_ns to the last /clock, in order.
    assert np.all(consecutive(sample_ns, 5_000_000) == 1)
    assert sample_ns[-1] == end_ns and len(sample_ns) == window
    assert np.all(np.diff(sample_ns) == 5_000_000)
    # Stamp jitter of 0.1 s (the top of its range) at 200 Hz: stamps still increase.
    stamps = [stamp_ns(m.header) for m in out]
    assert len(stamps) == len(sample_ns) and np.all(np.diff(stamps) > 0)
    # Each stamp within the latency (1 ms) + 0.45 periods of its sample time.
    latency_ns = 1_000_000
    assert sensor_config.load_sensor_config('consumer').latency_s == latency_ns / NS
    assert max(abs(s - t - latency_ns) for s, t in zip(stamps, sample_ns)) <= 0.45 * 5_000_000
    values = last_diag(diags)[1]
    assert float(values['emitted_ratio']) == 1.0 and values['samples_dropped'] == '0'
    # A tick gets step_ms / 5 ms samples or more (a late /clock): bursts, bounded.
    assert step_ms // 5 <= int(values['largest_burst']) <= 32
    assert int(values['samples_caught_up']) >= len(sample_ns) // 2
    print(f'/clock every {step_ms} ms: {len(sample_ns)} of {window} samples out, '
          f'caught up {values["samples_caught_up"]}, largest burst {values["largest_burst"]}')


#: Parts the Imu stamps of the samples before start_ns from those at and after it:
#: a stamp is the sample time + 1 ms latency + at most 0.45 periods (2.25 ms) of jitter.
JITTER_CUT_NS = 1_500_000


def _from(messages, t_ns):
    """Return the messages stamped at or after ``t_ns`` (without the pre-roll's)."""
    return [m for m in messages if stamp_ns(m.header) >= t_ns]


def hog(seconds):
    """Two busy processes (one per core), each ending by itself after ``seconds``."""
    return [subprocess.Popen([sys.executable, '-c', HOG, str(seconds)]) for _ in range(2)]


@pytest.mark.parametrize('policy', ['fifo', 'drop'])
def test_under_a_cpu_hog_fifo_loses_nothing_and_drop_counts_what_it_loses(tmp_path, policy):
    """
    A 500 Hz node against two busy processes, one per core, for 4 s.

    The FIFO holds two minutes of samples (HANG_S): its default 1000 (2 s)
    overflows when a machine already loaded (the suite beside a CPU-heavy
    job) starves the node longer than that, and an overflow is a loss by
    design, not what this test is about.
    """
    env = ros_env()
    node = NodeProcess(env, str(tmp_path / 'node.log'), *command_args(
        '-p', 'rate_hz:=500.0', '-p', f'overrun_policy:={policy}',
        '-p', 'max_burst_samples:=16', '-p', 'publish_truth:=false',
        '-p', f'fifo_depth_samples:={int(HANG_S * 500)}'))
    probe = Probe(env)
    hogs = []
    period_ns = 2_000_000
    try:
        out, sub = listen_matched(probe, Imu, 'imu/data_raw')
        diags = probe.listen(DiagnosticArray, '/diagnostics', 200)
        wait_matched(probe, [sub])
        probe.spin_until(lambda: len(out) > 500, HANG_S, 'a steady output')
        hogs = hog(4.0)
        probe.spin_until(lambda: all(h.poll() is not None for h in hogs), HANG_S,
                         'the CPU hogs to end')
        # Then until samples stamped 0.5 s after the hogs ended arrive (the node
        # runs on the wall clock: the backlog has drained by then), and a report.
        after_ns = time.time_ns() + NS // 2
        probe.spin_until(lambda: out and stamp_ns(out[-1].header) > after_ns, HANG_S,
                         'the samples after the hog')
        # A report is made every 0.2 s: the one that counts the last loss comes
        # after it. Wait for a report that counts at least the gaps seen so far
        # (it can count more: a sample dropped after the last one received).
        diags.clear()
        probe.spin_until(lambda: diags and int(last_diag(diags)[1]['samples_dropped'])
                         >= lost_in(out, period_ns), HANG_S,
                         'a report that counts every sample lost so far')
    finally:
        for h in hogs:
            h.kill()
            h.wait()
        probe.close()
        code = node.stop()
    log = node.log()
    assert code == 0 and 'Traceback' not in log
    stamps = [stamp_ns(m.header) for m in out]
    values = last_diag(diags)[1]
    assert np.all(np.diff(stamps) > 0)
    assert int(values['overruns']) > 0, 'the hog made no tick late: nothing was tested'
    lost = lost_in(out, period_ns)
    if policy == 'fifo':
        assert lost == 0 and values['samples_dropped'] == '0'
        assert float(values['emitted_ratio']) == 1.0
        assert int(values['samples_caught_up']) > 0
        assert 1 < int(values['largest_burst']) <= 16
    else:
        assert lost > 0 and int(values['samples_dropped']) >= lost
        assert values['largest_burst'] == '1'
    print(f'{policy}: {len(stamps)} samples received, {lost} lost; overruns '
          f'{values["overruns"]}, caught up {values["samples_caught_up"]}, dropped '
          f'{values["samples_dropped"]}, largest burst {values["largest_burst"]}, '
          f'ratio {values["emitted_ratio"]}')


def _limit_file_size(limit_bytes):
    def apply():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    return apply


def test_a_full_disk_stops_the_recording_not_the_node(tmp_path):
    """record_dir and the recorder with a 200 kB file-size limit (writes fail: EFBIG)."""
    env = ros_env()
    limit = _limit_file_size(200_000)
    node_log = open(tmp_path / 'node.log', 'w')
    node = subprocess.Popen(
        [sys.executable, '-m', 'gyro_emulator.ros.node', '--ros-args', '-p',
         f'record_dir:={tmp_path / "self"}', '-p', 'diagnostics_period_s:=0.2', '-p',
         'rate_hz:=400.0'], env=env, cwd=ROOT, stdout=node_log,
        stderr=subprocess.STDOUT, preexec_fn=limit)
    recorder = subprocess.Popen(
        [sys.executable, '-m', 'gyro_emulator.ros.recorder', '-o', str(tmp_path / 'rec')],
        env=env, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=limit)
    probe = Probe(env)
    try:
        probe.spin_until(lambda: recorder.poll() is not None, 120.0,
                         'the recorder to stop on its write error')
        out = probe.listen(Imu, 'imu/data_raw')
        diags = probe.listen(DiagnosticArray, '/diagnostics', 50)
        probe.spin_until(lambda: any(diag_values(d)[1].get('recording_error')
                                     for d in diags), HANG_S, 'the recording error')
        status, values = last_diag(diags)
        out.clear()
        probe.spin_until(lambda: len(out) > 100, HANG_S, 'the output after the error')
    finally:
        probe.close()
        node.send_signal(signal.SIGINT)
        code = node.wait(HANG_S)
        node_log.close()
        if recorder.poll() is None:
            recorder.kill()
        stderr = recorder.communicate()[1]
    log = (tmp_path / 'node.log').read_text()
    assert code == 0 and 'Traceback' not in log
    assert status.level == DiagnosticStatus.ERROR
    assert 'recording stopped: cannot write' in status.message
    assert 'File too large' in values['recording_error']
    errors = [line for line in log.splitlines() if 'cannot write' in line]
    assert len(errors) == 1 and 'bag repair' in errors[0]
    # The standalone recorder: one line, status 2, no traceback.
    assert recorder.returncode == 2, stderr
    assert 'Traceback' not in stderr
    assert stderr.count('recorder: error: cannot write') == 1
    # Both bags: every chunk before the error is recoverable.
    for path in (tmp_path / 'self', tmp_path / 'rec'):
        repair_bag(str(path))
        imu = bag.BagReader(str(path)).read_arrays('/imu/data_raw')
        assert imu.log_time_ns.size > 100, path


def test_the_lowest_rate_starts_with_the_shipped_temperature_rate(tmp_path):
    """rate_hz 1.0 (the documented minimum) with temperature_rate_hz left at its default."""
    env = ros_env()
    node = NodeProcess(env, str(tmp_path / 'node.log'), '-p', 'rate_hz:=1.0')
    probe = Probe(env)
    try:
        got = probe.listen(Imu, 'imu/data_raw')
        probe.spin_until(lambda: len(got) >= 2, HANG_S, 'two samples at 1 Hz')
    finally:
        probe.close()
        code = node.stop()
    assert code == 0 and 'gyro emulator up: 1 Hz' in node.log()
    # An explicit temperature_rate_hz above rate_hz is still refused, naming both.
    refused = subprocess.run(
        [sys.executable, '-m', 'gyro_emulator.ros.node', '--ros-args', '-p', 'rate_hz:=1.0',
         '-p', 'temperature_rate_hz:=10.0'], env=ros_env(), cwd=ROOT, capture_output=True,
        text=True, timeout=120)
    assert refused.returncode == 2
    assert 'temperature_rate_hz = 10.0 is out of range: allowed (0, rate_hz = 1]' in \
        refused.stderr


def test_the_array_stops_on_a_terminal_ctrl_c_with_status_zero(tmp_path):
    """SIGINT to the array's process group, as a terminal's Ctrl-C sends it."""
    env = ros_env()
    log_path = tmp_path / 'array.log'
    with open(log_path, 'w') as log:
        array = subprocess.Popen([sys.executable, '-m', 'gyro_emulator.ros.gyro_array'],
                                 env=env, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT,
                                 start_new_session=True)
        probe = Probe(env)
        try:
            got = {n: probe.listen(Imu, f'/imu_array/gyro_{n}/imu/data_raw') for n in 'abc'}
            probe.spin_until(lambda: all(len(g) > 10 for g in got.values()), HANG_S,
                             'the three nodes')
            children = open(f'/proc/{array.pid}/task/{array.pid}/children').read().split()
            groups = {os.getpgid(int(pid)) for pid in children}
            own_group = os.getpgid(array.pid)
        finally:
            probe.close()
            os.killpg(array.pid, signal.SIGINT)
            code = array.wait(HANG_S)
    text = log_path.read_text()
    assert code == 0, text
    assert 'failure' not in text and 'Traceback' not in text
    # The nodes are in a group of their own: the terminal's SIGINT reaches the
    # array only, which passes one on to each.
    assert len(children) == 3 and own_group not in groups
    assert text.count('shutting down:') == 3
