"""What a new user met (issue 34): one rule for records, bag topics, seeds, true comments, NaN."""

from dataclasses import replace
import os

from gyro_emulator import cli
from gyro_emulator.analysis.calibrate import export_noise
from gyro_emulator.analysis.diagnose import export
from gyro_emulator.recording import bag, cdr, csvio, metadata
from gyro_emulator.sensor import extensions
from gyro_emulator.sensor.config import load_sensor_config, SensorConfig
from gyro_emulator.sensor.model import GyroModel, NonFiniteOutput
import numpy as np
import pytest
import yaml

IMU = 'sensor_msgs/msg/Imu'


def _imu_bag(path, topics, n=400):
    """Write a bag with the Imu ``topics`` (name -> whether it has messages)."""
    stamps = 1_700_000_000_000_000_000 + np.arange(n, dtype=np.int64) * 10_000_000
    values = 1e-3 * np.random.default_rng(2).standard_normal((n, len(cdr.LAYOUTS[IMU].fields)))
    with bag.BagWriter(str(path)) as writer:
        for topic, full in topics.items():
            writer.add_topic(topic, IMU)
            if full:
                writer.write_batches([(topic, cdr.encode(IMU, stamps, values, 'imu'), stamps)])
    return str(path)


def test_simulate_takes_the_imu_topic_of_a_bag_with_several(tmp_path, capsys):
    path = _imu_bag(tmp_path / 'two', {'/imu/a': True, '/imu/b': True})
    out = tmp_path / 'out.csv'
    assert cli.main(['simulate', '--profile', path, '--static', '--out', str(out)]) == 2
    assert 'choose one with --topic' in capsys.readouterr().err
    assert cli.main(['simulate', '--profile', path, '--static', '--topic', '/imu/b', '--out',
                     str(out)]) == 0
    assert len(csvio.read_csv(str(out))['time_s']) == 400
    assert cli.main(['simulate', '--topic', '/imu/b', '--out', str(tmp_path / 'x.csv')]) == 2
    assert '--topic is for a measured bag --profile' in capsys.readouterr().err


def test_allan_takes_the_only_imu_topic_with_messages_and_says_so(tmp_path, capsys):
    path = _imu_bag(tmp_path / 'rec', {'/imu/ideal': False, '/imu/data_raw': True})
    assert cli.main(['allan', path, '--axis', 'z']) == 0
    out, err = capsys.readouterr()
    assert ('warning: 2 sensor_msgs/Imu topics: using /imu/data_raw, the only one with messages '
            '(/imu/ideal has none)') in err
    assert '400 samples' in out
    both = _imu_bag(tmp_path / 'both', {'/imu/a': True, '/imu/b': True})
    assert cli.main(['allan', both]) == 2
    assert '2 sensor_msgs/Imu topics (/imu/a, /imu/b): choose one with --topic' in \
        capsys.readouterr().err


def _set_custom(bag_dir, **items):
    path = os.path.join(bag_dir, metadata.METADATA_FILE)
    doc = yaml.safe_load(open(path))
    doc['rosbag2_bagfile_information']['custom_data'].update(items)
    with open(path, 'w') as handle:
        yaml.safe_dump(doc, handle)


def test_replay_of_a_node_recording_with_seed_minus_one(tmp_path, capsys):
    run = str(tmp_path / 'run')
    assert cli.main(['simulate', '--profile', 'steps', '--duration-s', '5', '--rate-hz', '100',
                     '--out', run, '--start-time', '0']) == 0
    _set_custom(run, seed='-1')
    assert cli.main(['replay', run, '--out', str(tmp_path / 'r1'), '--no-plots']) == 2
    err = capsys.readouterr().err.strip()
    assert 'custom_data seed = -1: the node drew its seed from its name' in err
    assert 'give --seed N' in err and len(err.splitlines()) == 1
    assert cli.main(['replay', run, '--out', str(tmp_path / 'r2'), '--no-plots',
                     '--seed', '4']) == 0
    _set_custom(run, node='/robot/gyro_emulator')          # the name gives the seed
    assert cli.main(['replay', run, '--out', str(tmp_path / 'r3'), '--no-plots']) == 0
    from gyro_emulator.sensor.streams import seed_from_name
    assert f'seed: {seed_from_name("/robot/gyro_emulator")}' in capsys.readouterr().out


def test_write_config_comments_say_where_the_other_axes_come_from(tmp_path):
    start = tmp_path / 'start.yaml'
    start.write_text('bias_temp_coeff_rad_s_k: [1.0e-3, 0.0, 0.0]\n')
    from test_diagnose_export import _cause, _doc
    doc = _doc(_cause('bias_temperature', bias_temp_coeff_rad_s_k=2e-5))
    text = export.extended_model(doc, str(start), axis='y').text()
    line = next(t for t in text.splitlines() if t.startswith('bias_temp_coeff_rad_s_k:'))
    assert "diagnosed axis y; x, z: the starting configuration's, not measured here" in line
    assert '0: not measured' not in line
    text = export.extended_model(doc, 'paper', axis='y').text()
    assert 'diagnosed axis y; x, z 0: not measured' in text


def test_a_one_axis_twin_gives_the_other_axes_no_turn_on_bias(tmp_path):
    rng = np.random.default_rng(5)
    n = 60_000
    path = tmp_path / 'one.csv'
    csvio.write_csv(str(path), {'time_s': np.arange(n) / 100.0,
                                'gyro_rad_s': 0.02 + 1e-3 * rng.standard_normal(n)})
    out = tmp_path / 'twin.yaml'
    assert cli.main(['calibrate', 'noise', str(path), '--format', 'preset', '-o', str(out)]) == 0
    twin = load_sensor_config(str(out))
    assert twin.turn_on_bias_rad_s[0] == pytest.approx(0.02, rel=1e-3)
    assert twin.turn_on_bias_rad_s[1:] == (0.0, 0.0)
    assert twin.electronics_noise_rad_s_sqrt_hz[1] == twin.electronics_noise_rad_s_sqrt_hz[0]
    assert "their turn-on bias is 0: a bias is the axis's own" in out.read_text()
    assert export_noise.twin_config is not None


def _epoch_log(path, rate_cell=None):
    n = 3000
    t = 1.7e9 + 0.02 * np.arange(n)
    rate = np.zeros(n)
    if rate_cell is not None:
        rate[100] = rate_cell
    csvio.write_csv(str(path), {'time_s': t, 'rate_cmd_rad_s': rate,
                                'temp_c': np.linspace(20.0, 30.0, n),
                                'gyro_rad_s': 1e-3 * np.random.default_rng(1).standard_normal(n)},
                    '%.9f')
    return str(path)


def test_epoch_second_times_drive_the_extended_terms(tmp_path, capsys):
    log = _epoch_log(tmp_path / 'epoch.csv')
    part = tmp_path / 'part.yaml'
    part.write_text('extended:\n  bias_time: {warmup_time_constant_s: 100.0, '
                    'warmup_rad_s: 1.0e-3}\n')
    out = tmp_path / 'out.csv'
    assert cli.main(['simulate', '--config', str(part), '--profile', log, '--out', str(out)]) == 0
    sim = csvio.read_csv(str(out))
    assert sim['time_s'][0] == pytest.approx(1.7e9)
    assert cli.main(['diagnose', log, '--config', str(part), '--effects', 'bias_time']) == 0
    assert 'out of range' not in capsys.readouterr().err


def test_one_rule_refuses_a_rate_cell_beyond_any_gyro_in_every_command(tmp_path, capsys):
    log = _epoch_log(tmp_path / 'cell.csv', rate_cell=5000.0)
    want = ('rate_cmd_rad_s = 5000.0 at sample 100 (data row 101) is beyond [-1000, 1000] rad/s')
    assert cli.main(['simulate', '--profile', log, '--out', str(tmp_path / 'o.csv')]) == 2
    assert want in capsys.readouterr().err
    assert cli.main(['diagnose', log]) == 2
    assert want in capsys.readouterr().err


def _hysteresis_config(width_k):
    term = extensions.BiasHysteresis(hysteresis_width_k=1.0, bias_hysteresis_rad_s=0.01)
    object.__setattr__(term, 'hysteresis_width_k', width_k)     # past the validation
    return replace(SensorConfig(), extended=extensions.ExtendedTerms(bias_hysteresis=term))


def test_the_model_names_the_term_of_a_non_finite_sample():
    """Behind the ranges: a term forced past them makes the model stop or flag, never emit."""
    rate, temp = np.zeros((300, 3)), np.linspace(20.0, 30.0, 300)
    model = GyroModel(_hysteresis_config(1e-310), 100.0, np.random.default_rng(0))
    with pytest.raises(NonFiniteOutput, match='sample 0 would be .* not finite: the extended '
                                              'term bias_hysteresis') as caught:
        model.run(rate, temp)
    assert 'bias_hysteresis' in caught.value.cause and '\n' not in str(caught.value)
    flagged = GyroModel(_hysteresis_config(1e-310), 100.0, np.random.default_rng(0))
    flagged.on_non_finite = 'flag'
    out = flagged.run(rate, temp)
    assert flagged.non_finite_samples == 300 and not np.isfinite(out.gyro_rad_s).any()
    assert 'bias_hysteresis' in flagged.non_finite_cause
    fine = GyroModel(_hysteresis_config(1.0), 100.0, np.random.default_rng(0))
    assert np.isfinite(fine.run(rate, temp).gyro_rad_s).all() and fine.non_finite_samples == 0


@pytest.mark.parametrize('order,fraction', [(1, 1e-6), (2, 1e-5), (3, 1e-3), (4, 1e-2)])
def test_an_output_filter_too_low_for_its_order_is_refused(order, fraction):
    """Down to its fraction of the sample rate a filter keeps its DC gain, no lower."""
    import warnings
    from scipy import signal
    fs = 1000.0
    b, a = signal.butter(order, fraction * fs, fs=fs)
    assert abs(b.sum() / a.sum() - 1.0) < 1e-6 and np.abs(np.roots(a)).max() < 1.0
    with warnings.catch_warnings():
        warnings.simplefilter('error')            # the noise gain is well conditioned
        GyroModel(SensorConfig(output_filter_hz=fraction * fs, output_filter_order=order), fs,
                  np.random.default_rng(0))
    config = SensorConfig(output_filter_hz=fraction * fs, output_filter_order=order)
    GyroModel(config, fs, np.random.default_rng(0))
    with pytest.raises(ValueError, match=rf'output_filter_hz = .* order {order}: allowed '):
        GyroModel(replace(config, output_filter_hz=0.5 * fraction * fs), fs,
                  np.random.default_rng(0))


def test_a_fleet_clips_a_drawn_width_to_its_physical_range(tmp_path, capsys):
    fleet = tmp_path / 'fleet.yaml'
    nominal = open(os.path.join(os.path.dirname(__file__), '..', 'config',
                                'fleet_paper_etch2.yaml')).read()
    nominal = nominal.replace('tolerances:', 'tolerances:\n  extended.bias_hysteresis.'
                              'hysteresis_width_k: {normal: 50.0}', 1)
    nominal = nominal.split('\nsensor_runs:')[0]       # a few sensor runs, given below
    fleet.write_text(nominal + '\nextended:\n  bias_hysteresis: {hysteresis_width_k: 0.5, '
                     'bias_hysteresis_rad_s: 1.0e-3}\ninvalid: clip\n'
                     'sensor_runs: {devices: 3, duration_s: 60, rate_hz: 50}\n')
    assert cli.main(['fleet', str(fleet), '--devices', '200', '--seed', '3', '--out',
                     str(tmp_path / 'out'), '--no-parquet']) == 0, capsys.readouterr().err
    assert 'clipped' in capsys.readouterr().out
