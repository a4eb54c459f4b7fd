"""Offline simulation, profiles, CSV I/O and the simulate / allan commands."""

import gzip
import io
import json
import math
import os
import time

from gyro_emulator import cli, units
from gyro_emulator.cli.simulate import Progress
from gyro_emulator.emulation import profiles, simulate
from gyro_emulator.emulation.run_profile import samples_with_force
from gyro_emulator.recording import csvio, timing
from gyro_emulator.sensor.config import load_sensor_config
from gyro_emulator.sensor.model import SensorBatch
import numpy as np
import pytest

REAL = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(
    os.path.abspath(__file__)))), 'shared', 'data', 'real')


def test_simulate_cli_writes_the_csv_columns(tmp_path, capsys):
    out = tmp_path / 'static.csv'
    rc = cli.main(['simulate', '--profile', 'static', '--duration-s', '5',
                   '--rate-hz', '100', '--out', str(out), '--seed', '3'])
    assert rc == 0
    columns = csvio.read_csv(out)
    assert tuple(columns) == simulate.CSV_COLUMNS
    assert len(columns['time_s']) == 500
    np.testing.assert_allclose(columns['time_s'], np.arange(500) / 100.0, atol=1e-9)
    assert not np.any(columns['rate_z_rad_s'])
    assert np.all(columns['temp_c'] == 25.0)
    assert np.std(columns['gyro_x_rad_s']) > 0.0         # the paper preset's noise
    assert 'wrote' in capsys.readouterr().out


def test_steps_and_temperature_ramp_profiles():
    steps = profiles.make_profile('steps', 50.0)
    samples = steps.samples(np.array([5.0, 15.0, 25.0, 35.0, 45.0]))
    np.testing.assert_allclose(samples.rate_rad_s[:, 2],
                               units.rpm_to_rad_s([0, 10, 20, 40, 0]))
    ramp = profiles.make_profile('temp-ramp', 60.0)
    samples = ramp.samples(np.array([0.0, 30.0, 60.0, 90.0]))
    np.testing.assert_allclose(samples.temp_c, [25.0, 55.0, 85.0, 85.0])   # holds after
    np.testing.assert_allclose(samples.rate_rad_s[:, 2], math.radians(60.0))
    samples = samples_with_force(ramp, np.array([0.0, 30.0, 60.0, 90.0]))
    np.testing.assert_allclose(samples.accel_m_s2[0], [0.0, 0.0, 9.80665])


def test_yaml_profile(tmp_path):
    path = tmp_path / 'profile.yaml'
    path.write_text(
        'name: ramp-up\n'
        'segments:\n'
        '  - {duration_s: 2, rate_deg_s: [0, 0, 0], temp_c: 20}\n'
        '  - duration_s: 4\n'
        '    rate_deg_s: [[0, 0, 0], [0, 0, 90]]\n'
        '    temp_c: [20, 40]\n'
        '    accel_m_s2: [0, 9.80665, 0]\n'
        '  - {duration_s: 1, rate_rpm: [10, 0, 0]}\n')
    prof = profiles.make_profile(str(path), 100.0)
    assert prof.duration_s == pytest.approx(7.0)
    s = prof.samples(np.array([1.0, 4.0, 6.5, 50.0]))
    np.testing.assert_allclose(s.rate_rad_s[:, 2], [0.0, math.radians(45.0), 0.0, 0.0])
    np.testing.assert_allclose(s.rate_rad_s[2:, 0], units.rpm_to_rad_s(10.0))
    np.testing.assert_allclose(s.temp_c, [20.0, 30.0, 40.0, 40.0])   # last temp carries
    np.testing.assert_allclose(s.accel_m_s2[1], [0.0, 9.80665, 0.0])


@pytest.mark.parametrize('text,match', [
    ('segments: []\n', 'non-empty list'),
    ('segments:\n  - {rate_deg_s: [0, 0, 0]}\n', 'segment 1: duration_s is required'),
    ('segments:\n  - {duration_s: 1, speed: 3}\n', 'segment 1: unknown key'),
    ('segments:\n  - {duration_s: 1, temp_c: 500}\n', 'temp_start_c = 500.0 is out of range'),
    ('segments:\n  - {duration_s: -1}\n', 'duration_s = -1.0 is out of range'),
    ('segments:\n  - {duration_s: 1, rate_deg_s: [1, 2]}\n', 'rate_deg_s'),
    ('loop: true\nsegments: []\n', 'unknown key'),
])
def test_bad_yaml_profiles(tmp_path, text, match):
    path = tmp_path / 'bad.yaml'
    path.write_text(text)
    with pytest.raises(ValueError, match=match):
        profiles.make_profile(str(path), 10.0)


def test_run_simulation_is_reproducible_and_chunk_invariant():
    config = load_sensor_config('consumer')
    t, prof, batch = simulate.run_simulation(config, 'steps', 30.0, 200.0, seed=4)
    assert len(t) == 6000 and prof.rate_rad_s.shape == (6000, 3)
    chunks = list(simulate.iter_simulation(config, 'steps', 30.0, 200.0, seed=4,
                                           chunk_samples=777))
    joined = SensorBatch.concatenate([c.batch for c in chunks])
    assert np.array_equal(joined.gyro_rad_s, batch.gyro_rad_s)
    assert np.array_equal(np.concatenate([c.time_s for c in chunks]), t)
    _, _, other = simulate.run_simulation(config, 'steps', 30.0, 200.0, seed=5)
    assert not np.array_equal(other.gyro_rad_s, batch.gyro_rad_s)


def test_temperature_ramp_shows_the_physics_scale_factor(tmp_path):
    """Ideal sensor but the physics SF(T): the ramp reproduces the paper's Fig 6 rise."""
    cfg = tmp_path / 'sf.yaml'
    terms = ', '.join(f'{n}: false' for n in load_sensor_config().terms.names()
                      if n != 'scale_factor_temperature')
    cfg.write_text(f'device: paper\nterms: {{{terms}}}\n')
    _, prof, batch = simulate.run_simulation(str(cfg), 'temp-ramp', 60.0, 10.0)
    apparent = np.degrees(batch.gyro_rad_s[-1, 2])
    assert 61.8 <= apparent <= 62.0                      # paper: 61.8..62.0 deg/s at 85 C
    assert prof.temp_c[-1] == pytest.approx(85.0, abs=0.2)


def test_progress_lines_every_ten_percent():
    stream = io.StringIO()
    progress = Progress(stream)
    total = 1_000_000
    for done in range(65536, total, 65536):
        progress(done, total)
    progress(total, total)
    lines = stream.getvalue().splitlines()
    assert 9 <= len(lines) <= 11 and lines[-1].startswith('simulate: 100.0 %')
    quiet = io.StringIO()
    Progress(quiet)(10, 100)
    assert quiet.getvalue() == ''


def test_simulate_cli_errors_are_clean(tmp_path, capsys):
    assert cli.main(['simulate', '--config', 'nope', '--out', str(tmp_path / 'a.csv')]) == 2
    assert 'neither a preset' in capsys.readouterr().err
    assert cli.main(['simulate', '--profile', 'wobble', '--out',
                     str(tmp_path / 'a.csv')]) == 2
    assert 'built-in profile' in capsys.readouterr().err
    assert cli.main(['simulate', '--duration-s', '-1', '--out',
                     str(tmp_path / 'a.csv')]) == 2
    assert '--duration-s -1.0 is out of range' in capsys.readouterr().err


def test_allan_cli_on_our_own_output(tmp_path):
    sim = tmp_path / 'paper.csv.gz'
    assert cli.main(['simulate', '--duration-s', '300', '--rate-hz', '200',
                     '--out', str(sim)]) == 0
    out_json, out_png = tmp_path / 'a.json', tmp_path / 'a.png'
    assert cli.main(['allan', str(sim), '--axis', 'y', '--json', str(out_json),
                     '--plot', str(out_png)]) == 0
    info = json.loads(out_json.read_text())
    for key in ('arw_deg_sqrt_h', 'bias_instability_deg_h', 'rrw_deg_h_sqrt_h', 'taus_s',
                'adev_rad_s'):
        assert key in info
    assert len(info['taus_s']) == len(info['adev_rad_s'])
    # the paper preset's ARW is the Brownian 0.276 deg/sqrt(h)
    assert info['arw_deg_sqrt_h'] == pytest.approx(0.2758, rel=0.05)
    assert out_png.stat().st_size > 10_000


def test_allan_cli_reads_a_bag_like_the_csv_of_the_same_run(tmp_path):
    """The same seeded run as CSV and as a bag directory gives the same ADEV."""
    # paper preset: no latency, jitter or clock drift, so the bag's Imu stamps
    # are the CSV's sample instants
    common = ['simulate', '--config', 'paper', '--duration-s', '120', '--rate-hz', '100',
              '--seed', '11']
    assert cli.main(common + ['--out', str(tmp_path / 'run.csv')]) == 0
    assert cli.main(common + ['--out', str(tmp_path / 'run_bag')]) == 0
    docs = []
    for source in ('run.csv', 'run_bag'):
        out = tmp_path / (source + '.json')
        assert cli.main(['allan', str(tmp_path / source), '--axis', 'x',
                         '--json', str(out)]) == 0
        docs.append(json.loads(out.read_text()))
    csv_doc, bag_doc = docs
    np.testing.assert_allclose(bag_doc['taus_s'], csv_doc['taus_s'], rtol=1e-6)
    np.testing.assert_allclose(bag_doc['adev_rad_s'], csv_doc['adev_rad_s'], rtol=1e-6)
    assert bag_doc['arw_deg_sqrt_h'] == pytest.approx(csv_doc['arw_deg_sqrt_h'], rel=1e-6)


@pytest.mark.skipif(not os.path.isdir(REAL), reason='shared real data not present')
def test_allan_cli_on_measured_mpu6050(tmp_path):
    path = os.path.join(REAL, 'mpu6050_static', 'mpu6050_static_100hz.csv')
    out_json = tmp_path / 'mpu.json'
    assert cli.main(['allan', path, '--axis', 'z', '--json', str(out_json)]) == 0
    info = json.loads(out_json.read_text())
    assert info['sample_rate_hz'] == pytest.approx(100.0)
    # datasheet rate noise density 0.005 deg/s/sqrt(Hz) = 0.3 deg/sqrt(h): same order
    assert 0.1 < info['arw_deg_sqrt_h'] < 1.0


def _write(path, text):
    if str(path).endswith('.gz'):
        with gzip.open(path, 'wt') as handle:
            handle.write(text)
    else:
        path.write_text(text)
    return str(path)


@pytest.mark.parametrize('text,match', [
    ('time_s,accel_x_m_s2\n0,1\n', r'no gyro columns: need gyro_rad_s or one or more of '
     r'gyro_x_rad_s'),
    ('time_s,gyro_rad_s\n0,1\n0.01,abc\n', r"row 3, column gyro_rad_s: 'abc' is not a number"),
    ('time_s,gyro_rad_s\n0,1\n0.02,2\n0.01,3\n',
     r'time_s does not increase at data row 3: 0.01 after 0.02'),
    ('time_s,gyro_rad_s\n0,1\n0.01,nan\n', r'column gyro_rad_s: nan is not finite'),
    ('time_s,gyro_rad_s\n0,1,2\n', r'row 2 has 3 values, the header has 2'),
    ('', 'the file is empty'),
    ('gyro_rad_s\n1\n', 'missing required column.*time_s'),
])
def test_csv_errors_name_row_column_and_value(tmp_path, text, match):
    path = _write(tmp_path / 'bad.csv', text)
    with pytest.raises(ValueError, match=match):
        csvio.read_gyro_csv(path)


def test_csv_round_trip_gz_and_repeated_times(tmp_path):
    path = tmp_path / 'x.csv.gz'
    values = np.random.default_rng(0).standard_normal(1000) * 1e-3
    csvio.write_csv(path, {'time_s': np.arange(1000) / 50.0, 'gyro_rad_s': values})
    t, rate, column = csvio.read_gyro_csv(path)
    assert column == 'gyro_rad_s'
    np.testing.assert_allclose(rate, values, rtol=1e-9)
    rep = _write(tmp_path / 'rep.csv', 'time_s,gyro_rad_s\n0,1\n0.02,2\n0.02,3\n0.04,4\n')
    with pytest.raises(ValueError, match='repeated timestamp'):
        csvio.read_gyro_csv(rep)
    t, _, _ = csvio.read_gyro_csv(rep, time_order='nondecreasing')
    assert len(t) == 4


def test_segments_at_gaps():
    t = np.concatenate([np.arange(100) * 0.02, 100.0 + np.arange(50) * 0.02])
    found = timing.timing_of(t)
    rate, bounds = found.rate_hz, found.bounds
    assert rate == pytest.approx(50.0)
    assert bounds == ((0, 100), (100, 150))


def test_simulate_refuses_an_existing_output_unless_overwrite(tmp_path, capsys):
    out = tmp_path / 'a.csv'
    common = ['simulate', '--duration-s', '1', '--rate-hz', '50', '--out', str(out)]
    assert cli.main(common) == 0
    first = out.read_bytes()
    assert cli.main(common + ['--seed', '5']) == 2
    assert 'exists: pass --overwrite' in capsys.readouterr().err
    assert out.read_bytes() == first
    assert cli.main(common + ['--seed', '5', '--overwrite']) == 0
    assert out.read_bytes() != first


def test_simulate_stages_a_csv_gz_and_a_bag_under_their_own_names(tmp_path):
    """The output is staged beside itself (atomic.staged); the writers see the final name."""
    from gyro_emulator.recording import bag
    gz = tmp_path / 'run.csv.gz'
    assert simulate.write_record(str(gz), 'paper', 'static', 0.5, 100.0) == 50
    raw = gz.read_bytes()
    assert raw[:2] == b'\x1f\x8b' and raw[3] & 0x08        # gzip, with a file name ...
    assert raw[10:raw.index(b'\0', 10)] == b'run.csv'      # ... the final one
    assert len(csvio.read_csv(gz)['time_s']) == 50
    out = tmp_path / 'run_bag'
    simulate.write_record(str(out), 'paper', 'static', 0.5, 100.0, start_time_ns=0)
    assert sorted(os.listdir(out)) == ['metadata.yaml', 'run_bag_0.mcap']
    simulate.write_record(str(out), 'paper', 'static', 1.0, 100.0, start_time_ns=0,
                          overwrite=True)
    assert bag.BagReader(str(out)).topics['/imu/data_raw'].message_count == 100
    assert sorted(os.listdir(out)) == ['metadata.yaml', 'run_bag_0.mcap']
    assert sorted(os.listdir(tmp_path)) == ['run.csv.gz', 'run_bag']


@pytest.mark.parametrize('name', ['broken.csv', 'broken_bag'])
def test_a_failed_simulate_leaves_nothing_behind(tmp_path, capsys, name):
    """A die temperature that leaves the model range late in the run stops it."""
    sensor = tmp_path / 'hot.yaml'
    sensor.write_text('device: paper\nself_heating_c: 40.0\nthermal_time_constant_s: 1.0\n')
    profile = tmp_path / 'ramp.yaml'
    profile.write_text('segments:\n  - {duration_s: 20, temp_c: [25, 190]}\n')
    out = tmp_path / name
    rc = cli.main(['simulate', '--config', str(sensor), '--profile', str(profile),
                   '--duration-s', '20', '--rate-hz', '200', '--out', str(out)])
    assert rc == 2
    assert 'out of range' in capsys.readouterr().err
    assert sorted(os.listdir(tmp_path)) == ['hot.yaml', 'ramp.yaml']


def test_a_simulated_bag_starts_at_the_start_time_asked_for(tmp_path):
    """Issue 15: a bag stamped from a settable start time (default now), not from 1970."""
    from gyro_emulator.recording import bag
    t0 = simulate.parse_start_time('2026-03-01T12:00:00')
    assert t0 == simulate.parse_start_time('2026-03-01T12:00:00Z') == 1772366400 * 10**9
    assert simulate.parse_start_time('0') == 0 and simulate.parse_start_time('1.5') == 1.5e9
    assert abs(simulate.parse_start_time('now') - time.time_ns()) < 10**9
    out = str(tmp_path / 'b')
    simulate.write_record(out, 'paper', 'static', 0.1, 100.0, start_time_ns=t0)
    reader = bag.BagReader(out)
    assert reader.start_time_ns == t0 and reader.custom_data['start_time_ns'] == str(t0)
    for bad in ('yesterday', '-1', '1e12'):
        with pytest.raises(ValueError, match=f"start_time = '{bad}' is"):
            simulate.parse_start_time(bad)


@pytest.mark.parametrize('command', [name for name, _ in cli.COMMANDS])
def test_help_shows_no_rst_markup(command, capsys):
    """Issue 15: ``--help`` shows ``name``, not RST backticks or roles."""
    with pytest.raises(SystemExit) as done:
        cli.main([command, '--help'])
    assert done.value.code == 0
    text = capsys.readouterr().out
    assert 'usage: gyro-emulator ' + command in text
    assert '``' not in text and not any(role in text for role in (':func:', ':mod:',
                                                                  ':class:', ':data:'))


def test_help_of_the_installed_command_shows_no_rst_markup():
    """The same through a real process of the command line."""
    import subprocess
    import sys
    proc = subprocess.run([sys.executable, '-m', 'gyro_emulator.cli', 'simulate', '--help'],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and '--start-time' in proc.stdout
    assert '``' not in proc.stdout and 'gyro_emulator.analysis.replay' in proc.stdout


def test_plain_text_keeps_the_words_of_rst_markup():
    assert cli.plain_text('see ``--out`` and :func:`gyro_emulator.sensor.streams.spawn`, '
                          ':class:`~a.b.GyroModel` or :mod:`the replay <x.y>`') == \
        'see --out and gyro_emulator.sensor.streams.spawn, GyroModel or the replay'


def test_simulate_applies_a_fault_schedule_as_the_node_does(tmp_path):
    """Issue 15: the one fault model (sensor.faults) also drives simulate."""
    from gyro_emulator.recording import bag
    from gyro_emulator.sensor import faults
    schedule_file = tmp_path / 'faults.yaml'
    schedule_file.write_text(
        'faults:\n'
        '  - {type: bias_step, axis: z, magnitude: 0.02, start_s: 1.0, duration_s: 0.5}\n'
        '  - {type: dropout, start_s: 2.0, duration_s: 0.25}\n')
    schedule = faults.load_schedule(str(schedule_file))
    clean = tmp_path / 'clean.csv'
    faulty = tmp_path / 'faulty.csv'
    for out, extra in ((clean, []), (faulty, ['--faults', str(schedule_file)])):
        assert cli.main(['simulate', '--profile', 'static', '--duration-s', '3',
                         '--rate-hz', '100', '--seed', '4', '--out', str(out)] + extra) == 0
    a = csvio.read_csv(str(clean))
    b = csvio.read_csv(str(faulty))
    assert len(a['time_s']) == 300 and len(b['time_s']) == 275   # 25 samples dropped
    kept = ~((a['time_s'] >= 2.0) & (a['time_s'] < 2.25))
    assert np.array_equal(b['time_s'], a['time_s'][kept])
    diff = b['gyro_z_rad_s'] - a['gyro_z_rad_s'][kept]
    inside = (b['time_s'] >= 1.0) & (b['time_s'] < 1.5)
    assert np.allclose(diff[inside], 0.02, atol=1e-9) and not diff[~inside].any()
    path = str(tmp_path / 'bag')
    simulate.write_record(path, 'paper', 'static', 3.0, 100.0, seed=4, faults=schedule,
                          start_time_ns=0)
    reader = bag.BagReader(path)
    assert reader.topics['/imu/data_raw'].message_count == 275
    assert reader.topics['/gyro_emulator/truth/rate'].message_count == 300
    assert 'dropout on all' in reader.custom_data['faults']


def test_a_simulated_bag_carries_the_nodes_truth_imu_attitude_and_force(tmp_path):
    """The node's ~/truth/imu in simulate's bag: 90 deg about y then x puts gravity on -x."""
    from pathlib import Path

    from gyro_emulator.physics import kinematics
    from rosbags.highlevel import AnyReader

    profile = tmp_path / 'turns.yaml'
    profile.write_text('segments:\n'
                       '  - {duration_s: 1, rate_deg_s: [0, 0, 0], temp_c: 25}\n'
                       '  - {duration_s: 1, rate_deg_s: [0, 90, 0]}\n'
                       '  - {duration_s: 1, rate_deg_s: [90, 0, 0]}\n'
                       '  - {duration_s: 1, rate_deg_s: [0, 0, 0]}\n')
    path = str(tmp_path / 'bag')
    simulate.write_record(path, 'paper', str(profile), 4.0, 200.0, seed=3, start_time_ns=0)
    with AnyReader([Path(path)]) as reader:
        def read(topic):
            conns = [c for c in reader.connections if c.topic == topic]
            return [reader.deserialize(raw, c.msgtype)
                    for c, _, raw in reader.messages(connections=conns)]
        truth = read('/gyro_emulator/truth/imu')
        rate = read('/cmd/angular_velocity')
        truth_rate = read('/gyro_emulator/truth/rate')
        assert {'/gyro_emulator/truth/imu', '/gyro_emulator/truth/rate',
                '/gyro_emulator/truth/bias', '/gyro_emulator/truth/scale_factor'} <= set(
                    reader.topics)
    assert len(truth) == len(rate) == 800
    assert [m.header.stamp for m in truth] == [m.header.stamp for m in truth_rate]
    rates = np.array([(m.vector.x, m.vector.y, m.vector.z) for m in rate])
    want, _ = kinematics.propagate(kinematics.LEVEL_WXYZ, rates, 1.0 / 200.0)
    got = np.array([(m.orientation.w, m.orientation.x, m.orientation.y, m.orientation.z)
                    for m in truth])
    np.testing.assert_allclose(got, want, rtol=0.0, atol=1e-12)
    force = np.array([(m.linear_acceleration.x, m.linear_acceleration.y,
                       m.linear_acceleration.z) for m in truth])
    np.testing.assert_allclose(force, kinematics.specific_force(want), rtol=0.0, atol=1e-12)
    assert force[0].tolist() == [0.0, 0.0, units.STANDARD_GRAVITY_M_S2]
    np.testing.assert_allclose(force[-1], (-units.STANDARD_GRAVITY_M_S2, 0.0, 0.0), atol=1e-9)
    np.testing.assert_allclose([(m.angular_velocity.x, m.angular_velocity.y,
                                 m.angular_velocity.z) for m in truth], rates, atol=0.0)
    assert all(not any(m.orientation_covariance) and not any(m.linear_acceleration_covariance)
               for m in truth)


def test_a_bag_with_the_nodes_truth_imu_is_read_from_its_measured_imu(tmp_path):
    """Calibrate and allan take imu/data_raw, not ~/truth/imu, from a bag that has both."""
    from gyro_emulator.recording import bag, record, topics

    assert topics.is_truth('/gyro_emulator/truth/imu') and topics.is_truth('/a/b/truth/rate')
    assert not topics.is_truth('/imu/data_raw') and not topics.is_truth('/truth')
    path = str(tmp_path / 'bag')
    simulate.write_record(path, 'consumer', 'static', 30.0, 100.0, seed=2, start_time_ns=0)
    assert bag.BagReader(path).topics['/gyro_emulator/truth/imu'].message_count == 3000
    rec = record.load_record(path)
    csv = str(tmp_path / 'run.csv')
    simulate.write_record(csv, 'consumer', 'static', 30.0, 100.0, seed=2)
    from_csv = record.load_record(csv)
    assert rec.gyro_sources['x'].startswith('/imu/data_raw'), rec.gyro_sources
    for axis in 'xyz':
        np.testing.assert_allclose(rec.gyro[axis], from_csv.gyro[axis], rtol=1e-9, atol=0.0)
    assert cli.main(['calibrate', 'noise', path, '--format', 'kalibr', '-o',
                     str(tmp_path / 'imu.yaml')]) == 0
    assert 'rostopic: /imu/data_raw' in (tmp_path / 'imu.yaml').read_text()
