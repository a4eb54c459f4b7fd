"""
``cmd/linear_acceleration`` means the applied acceleration (gravity excluded) everywhere.

A seeded ``simulate`` bag of a tilt-and-turn profile (a roll of 90 deg, a
push along x, a yaw of 60 deg) carries the applied acceleration on that
topic and ``custom_data`` ``cmd_linear_acceleration: applied``. Read back
offline (``replay``'s inputs and ``simulate --profile BAG``) and replayed
into the node (real processes, ``use_sim_time``), it gives the specific
force simulate's own Imu holds: gravity counted once. A bag written when the
topic held the specific force (no such ``custom_data``) is read as the
specific force with a one-line note offline, and ``replay`` refuses to
play its acceleration commands into the node.
"""

import os
import subprocess
import sys

from conftest import ros_env
from gyro_emulator.analysis.replay.inputs import emulate, load_inputs
from gyro_emulator.emulation import emulator_bag, simulate
from gyro_emulator.emulation.recorded_profile import recorded_profile
from gyro_emulator.recording import bag, record, topics
from gyro_emulator.units import NS_PER_S, STANDARD_GRAVITY_M_S2
import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CONFIG, SEED, RATE_HZ, DURATION_S = 'consumer', 4, 100.0, 7.0
START_NS = 1000 * NS_PER_S
PROFILE = """name: tilt-and-turn
segments:
  - {duration_s: 1.0, rate_deg_s: [0, 0, 0], temp_c: 25}
  - {duration_s: 2.0, rate_deg_s: [45, 0, 0], temp_c: 25}
  - {duration_s: 1.0, rate_deg_s: [0, 0, 0], temp_c: 25, linear_accel_m_s2: [0.5, 0, 0]}
  - {duration_s: 2.0, rate_deg_s: [0, 0, 30], temp_c: 25}
  - {duration_s: 1.0, rate_deg_s: [0, 0, 0], temp_c: 25}
"""
#: Windows at rest (s): level; rolled 90 deg and pushed along x; rolled and yawed 60 deg.
REST_S = ((0.2, 0.9), (3.2, 3.9), (6.2, 6.9))


@pytest.fixture(scope='module')
def tilt(tmp_path_factory):
    """Return (profile path, bag path, simulate's whole run (time, samples, batch))."""
    folder = tmp_path_factory.mktemp('accel_commands')
    path = str(folder / 'tilt.yaml')
    with open(path, 'w') as handle:
        handle.write(PROFILE)
    out = str(folder / 'tilt_bag')
    simulate.write_record(out, CONFIG, path, DURATION_S, RATE_HZ, seed=SEED,
                          start_time_ns=START_NS)
    return path, out, simulate.run_simulation(CONFIG, path, DURATION_S, RATE_HZ, seed=SEED)


def _rest(time_s):
    return [(time_s >= lo) & (time_s <= hi) for lo, hi in REST_S]


def test_the_bag_holds_the_applied_acceleration_and_says_so(tilt):
    _, out, (time_s, samples, _) = tilt
    assert topics.accel_commands_applied(bag.BagReader(out).custom_data)
    rec = record.load_record(out, {'gyro': None, 'accel': None})
    assert rec.accel is None and rec.recovery == ()
    applied = rec.linear_accel.values
    expected = np.zeros_like(applied)
    expected[(time_s >= 3.0 - 1e-9) & (time_s < 4.0 - 1e-9), 0] = 0.5
    # the 0.5 m/s^2 push, and no gravity, in the commands
    assert np.max(np.abs(applied - expected)) < 1e-12
    np.testing.assert_array_equal(samples.linear_accel_m_s2, applied)
    # simulate's specific force: gravity once, turned with the roll and the yaw
    level, rolled, yawed = (samples.accel_m_s2[w] for w in _rest(time_s))
    np.testing.assert_allclose(level, np.tile([0.0, 0.0, STANDARD_GRAVITY_M_S2],
                                              (len(level), 1)), atol=1e-12)
    for rest in (level, yawed):
        np.testing.assert_allclose(np.linalg.norm(rest, axis=1), STANDARD_GRAVITY_M_S2,
                                   rtol=1e-12)
    assert np.all(np.abs(rolled[:, 1] - STANDARD_GRAVITY_M_S2) < 2e-3)    # gravity on y
    assert np.all(np.abs(rolled[:, 0] - 0.5) < 1e-12)                       # the push on x
    assert np.all(np.abs(yawed[:, 2]) < 0.02) and np.all(np.abs(yawed[:, 0]) > 8.0)


def test_offline_replay_and_the_recorded_profile_give_simulates_specific_force(tilt):
    path, out, (time_s, samples, batch) = tilt
    inputs = load_inputs(out)
    assert inputs.accel_m_s2 is None and not any('specific force' in n for n in inputs.notes)
    # the same attitude route, on nanosecond stamps instead of n T: equal to rounding
    np.testing.assert_allclose(inputs.completed().accel_m_s2, samples.accel_m_s2,
                               rtol=0.0, atol=1e-8)
    _, emulated = emulate(inputs, CONFIG, SEED)
    # the same seed and quantised output: the same accelerometer samples, exactly
    np.testing.assert_array_equal(emulated.accel_m_s2, batch.accel_m_s2)
    np.testing.assert_array_equal(emulated.gyro_rad_s, batch.gyro_rad_s)
    profile = recorded_profile(out)
    assert profile.accel_m_s2 is None and profile.notes == ()
    # On the model's grid at the record's median interval (the record's samples
    # published) the rate is interpolated where the turns start and stop: the
    # attitude moves by a part of one period's turn (g 45 deg/s T = 0.077 m/s^2).
    chunks = list(simulate.iter_simulation(CONFIG, profile, 0.0, 0.0, seed=SEED))
    force = np.concatenate([c.profile.accel_m_s2[c.published] for c in chunks])
    assert force.shape == samples.accel_m_s2.shape
    for window in _rest(time_s):
        np.testing.assert_allclose(force[window], samples.accel_m_s2[window], rtol=0.0,
                                   atol=0.01)
        assert np.max(np.abs(np.linalg.norm(force[window], axis=1) - np.linalg.norm(
            samples.accel_m_s2[window], axis=1))) < 1e-9


def _old_bag(tilt, out):
    """Write the run as the writer did when the topic held the specific force (no marker)."""
    path = tilt[0]
    chunks = list(simulate.iter_simulation(CONFIG, path, DURATION_S, RATE_HZ, seed=SEED))
    with bag.BagWriter(out, custom_data={'generator': 'gyro-emulator simulate',
                                         'rate_hz': repr(RATE_HZ)}) as writer:
        old = emulator_bag.EmulatorBagWriter(writer)
        for chunk in chunks:
            stamp = START_NS + np.round(chunk.time_s * NS_PER_S).astype(np.int64)
            old.write(stamp, chunk.profile.rate_rad_s, chunk.profile.temp_c,
                      chunk.profile.accel_m_s2, chunk.batch)
    return out


def test_an_older_bag_is_read_as_the_specific_force_with_a_note(tilt, tmp_path):
    _, _, (time_s, samples, batch) = tilt
    old = _old_bag(tilt, str(tmp_path / 'old'))
    assert not topics.accel_commands_applied(bag.BagReader(old).custom_data)
    note = topics.old_accel_note('/cmd/linear_acceleration')
    assert '\n' not in note and 'specific force' in note and 'applied' in note
    rec = record.load_record(old, {'gyro': None, 'accel': None})
    assert rec.linear_accel is None and note in rec.recovery
    inputs = load_inputs(old)
    assert note in inputs.notes
    np.testing.assert_array_equal(inputs.accel_m_s2, samples.accel_m_s2)
    _, emulated = emulate(inputs, CONFIG, SEED)
    np.testing.assert_array_equal(emulated.accel_m_s2, batch.accel_m_s2)     # not 2 g
    profile = recorded_profile(old)
    assert profile.notes == (note,)
    for window in _rest(time_s):      # on the Imu's stamps (the output delay): at rest
        np.testing.assert_allclose(profile.accel_m_s2[window], samples.accel_m_s2[window],
                                   rtol=0.0, atol=1e-9)


@pytest.mark.ros
def test_replay_refuses_an_older_bags_acceleration_commands(tilt, tmp_path):
    old = _old_bag(tilt, str(tmp_path / 'old'))
    run = subprocess.run([sys.executable, '-m', 'gyro_emulator.ros.replay', old],
                         env=ros_env(), cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert run.returncode == 2, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('replay: error: /cmd/linear_acceleration')
    assert 'count it twice' in lines[0] and '--topics /cmd/angular_velocity' in lines[0]
    assert 'Traceback' not in run.stderr


def _node_run(tilt, tmp_path):
    """Replay the bag's commands into the node on sim time; return its truth and output."""
    from sensor_msgs.msg import Imu
    from test_node import NodeProcess, replay_into_node, stamp_ns, vector
    out = tilt[1]
    env = ros_env()
    node = NodeProcess(env, str(tmp_path / 'node.log'), '-p', 'use_sim_time:=true', '-p',
                       f'sensor_config:={CONFIG}', '-p', f'rate_hz:={RATE_HZ}', '-p',
                       f'seed:={SEED}', '-p', 'max_stamp_lead_s:=30.0')
    end_ns = START_NS + int((REST_S[-1][1]) * NS_PER_S)
    truth, imu = replay_into_node(
        env, node, '/imu/data_raw',
        [(Imu, f'/{topics.NODE_NAME}/truth/imu'), (Imu, '/imu/data_raw')],
        # --delay: /clock holds the bag's first instant, so the node starts there even
        # when discovery comes late (a loaded CI run heard it only from 0.56 s in)
        [out, '--clock', '100', '--wait-for-subscribers', '60', '--delay', '2', '--reliable',
         '--topics',
         '/cmd/angular_velocity', '/cmd/temperature', '/cmd/linear_acceleration'],
        end_ns, 60.0)
    return tuple(((np.array([stamp_ns(m.header) for m in messages]) - START_NS) / NS_PER_S,
                  np.array([vector(m.linear_acceleration) for m in messages]))
                 for messages in (truth, imu))


@pytest.mark.ros
def test_the_node_fed_the_bag_senses_simulates_specific_force(tilt, tmp_path):
    _, _, (time_s, samples, batch) = tilt
    (t_truth, force), (t_imu, measured) = _node_run(tilt, tmp_path)
    # The node's samples fall between simulate's: its attitude is off by at most
    # one period's turn (45 deg/s and 30 deg/s at 100 Hz: 0.0131 rad, 0.13 m/s^2).
    bound = STANDARD_GRAVITY_M_S2 * np.radians(45.0 + 30.0) / RATE_HZ
    sigma = np.std(batch.accel_m_s2[_rest(time_s)[0]], axis=0)
    for (lo, hi), node_rest, imu_rest, sim_rest in zip(REST_S, _rest(t_truth), _rest(t_imu),
                                                       _rest(time_s)):
        assert node_rest.sum() >= 50 and imu_rest.sum() >= 50, (lo, hi)
        expected = samples.accel_m_s2[sim_rest].mean(axis=0)
        assert np.max(np.abs(force[node_rest] - expected)) < bound, (lo, hi)
        # gravity once: |f| = g at rest, plus the push along x in the middle window
        norm = np.linalg.norm(force[node_rest] - [0.5 if lo == 3.2 else 0.0, 0.0, 0.0],
                              axis=1)
        np.testing.assert_allclose(norm, STANDARD_GRAVITY_M_S2, rtol=1e-9)
        # the noisy output: simulate's Imu mean within the attitude bound and 5 sigma
        spread = 5.0 * sigma * np.sqrt(1.0 / imu_rest.sum() + 1.0 / sim_rest.sum())
        gap = np.abs(measured[imu_rest].mean(axis=0) - batch.accel_m_s2[sim_rest].mean(axis=0))
        worst = np.max(np.abs(force[node_rest] - expected))
        print(f'rest {lo}-{hi} s: node truth - simulate {worst:.3g} m/s^2 (bound {bound:.3g}); '
              f'| |f| - g | {np.max(np.abs(norm - STANDARD_GRAVITY_M_S2)):.2g}; output means '
              f'{np.round(gap, 4)} (bound {np.round(bound + spread, 4)})')
        assert np.all(gap < bound + spread), (lo, hi, gap)


def test_a_scenario_step_with_an_acceleration_is_refused_in_one_line():
    from gyro_emulator.emulation.scenario import parse_scenario
    for key in ('accel_m_s2', 'linear_accel_m_s2'):
        with pytest.raises(ValueError) as caught:
            parse_scenario({'segments': [{'duration_s': 1.0, 'rate_deg_s': 10.0,
                                          'temp_c': 25.0, key: [0.5, 0.0, 0.0]}]}, 'play.yaml')
        text = str(caught.value)
        assert '\n' not in text and text.startswith(f'play.yaml.segments[0]: {key} is not played')
    scenario = parse_scenario({'axis': [1.0, 0.0, 0.0], 'segments': [
        {'duration_s': 1.0, 'rate_deg_s': 90.0, 'temp_c': 25.0}]}, 'play.yaml')
    assert scenario.steps[0].accel_m_s2 is None      # the specific force follows the motion
