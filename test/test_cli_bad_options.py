"""
Options and inputs a user gets wrong: one line naming the field, the value and the range.

Each case was a reproduction on the command line: a traceback
(``simulate --rate-hz inf``), numpy's words without the field (a NaN
duration, a negative seed), a bad value taken silently (``allan
--gap-factor nan``, ``fleet --workers 0``, ``calibrate --accel-scale
-9.8``, one thermal file given as two axes), numpy's warning on the
terminal (a CSV with a header and no rows) or a damaged bag read without a
word (``simulate --profile``).
"""

import json
import os
import shutil
import warnings

from gyro_emulator import cli
from gyro_emulator.analysis.allan import analyse
from gyro_emulator.emulation import simulate
from gyro_emulator.recording import csvio, timing
from gyro_emulator.validation import check_seed
import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
THERMAL_X = os.path.join(HERE, '..', '..', 'shared', 'data', 'real', 'lsm6dsm_thermal_chamber',
                         'lsm6dsm_tvc_x.csv')
MPU = os.path.join(HERE, '..', '..', 'shared', 'data', 'real', 'mpu6050_static',
                   'mpu6050_static_100hz.csv')


def _run(argv, capsys):
    """Run ``gyro-emulator argv``; return (status, stdout, stderr lines)."""
    status = cli.main(argv)
    out, err = capsys.readouterr()
    assert 'Traceback' not in err
    return status, out, err.strip().splitlines()


def _refused(argv, capsys, *words):
    """Assert ``argv`` stops with status 2 and one error line holding ``words``."""
    status, out, err = _run(argv, capsys)
    assert status == 2 and len(err) == 1 and 'error:' in err[0], err
    for word in words:
        assert word in err[0], err[0]
    return err[0]


def _static_csv(path, n=2000, rate_hz=100.0):
    rng = np.random.default_rng(3)
    csvio.write_csv(str(path), {'time_s': np.arange(n) / rate_hz,
                                'gyro_x_rad_s': 1e-3 * rng.standard_normal(n)})
    return str(path)


@pytest.mark.parametrize('option,value,words', [
    ('--rate-hz', 'inf', ('--rate-hz inf', '(0, 1e6] Hz')),
    ('--rate-hz', '-200', ('--rate-hz -200.0', '(0, 1e6] Hz')),
    ('--duration-s', 'nan', ('--duration-s nan', 'allowed > 0 s')),
    ('--duration-s', 'inf', ('--duration-s inf', 'allowed > 0 s')),
    ('--seed', '-1', ('simulate.seed = -1', 'allowed integers >= 0')),
    # named the model's field (Segment.temp_start_c = nan) instead of the option
    ('--temp-c', 'nan', ('--temp-c nan', 'allowed [-60, 200] C')),
    ('--temp-c', '-300', ('--temp-c -300.0', 'allowed [-60, 200] C')),
])
@pytest.mark.parametrize('out', ['out.csv', 'bag'])
def test_simulate_names_a_bad_duration_rate_or_seed_and_writes_nothing(
        tmp_path, capsys, option, value, words, out):
    target = tmp_path / out
    _refused(['simulate', '--duration-s', '1', option, value, '--out', str(target)], capsys,
             *words)
    assert os.listdir(tmp_path) == []


def test_the_library_checks_what_the_command_line_does(tmp_path):
    with pytest.raises(ValueError, match=r'^rate_hz = inf is out of range'):
        simulate.sample_count(1.0, float('inf'))
    with pytest.raises(ValueError, match=r'^duration_s = nan is out of range'):
        simulate.run_simulation('paper', 'static', float('nan'), 100.0)
    with pytest.raises(ValueError, match=r'^simulate\.seed = -2 is out of range'):
        simulate.write_record(str(tmp_path / 'x.csv'), 'paper', 'static', 1.0, 100.0, seed=-2)
    assert simulate.sample_count(1.0, 100.0) == 100
    assert not os.path.exists(tmp_path / 'x.csv')


@pytest.mark.parametrize('seed', [-1, 1.5, '3', None, True])
def test_check_seed_refuses_what_is_not_a_whole_number_from_zero(seed):
    with pytest.raises(ValueError, match=r'^truth\.seed = .* is out of range: allowed '
                                         r'integers >= 0$'):
        check_seed('truth', seed)


@pytest.mark.parametrize('seed', [0, 7, 2 ** 70, np.int64(5)])
def test_check_seed_returns_a_good_seed(seed):
    assert check_seed('simulate', seed) == seed


def test_truth_names_a_negative_seed_and_writes_nothing(tmp_path, capsys):
    _refused(['truth', str(tmp_path / 't.csv'), '--seed', '-3', '--profile', 'static'], capsys,
             'truth.seed = -3', 'allowed integers >= 0')
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize('option,value,words', [
    ('--gap-factor', 'nan', ('timing.gap_factor = nan', '(1.0, inf)')),
    ('--gap-factor', '0', ('timing.gap_factor = 0.0', '(1.0, inf)')),
    ('--gap-factor', '1', ('timing.gap_factor = 1.0', '(1.0, inf)')),
    ('--max-tau-fraction', 'nan', ('allan.max_tau_fraction = nan', '(0.0, 0.5]')),
    ('--max-tau-fraction', '0', ('allan.max_tau_fraction = 0.0', '(0.0, 0.5]')),
    ('--max-tau-fraction', '2', ('allan.max_tau_fraction = 2.0', '(0.0, 0.5]')),
])
def test_allan_names_a_bad_gap_factor_or_tau_fraction(tmp_path, capsys, option, value, words):
    path = _static_csv(tmp_path / 'static.csv')
    json_out = tmp_path / 'a.json'
    _refused(['allan', path, option, value, '--json', str(json_out)], capsys, *words)
    assert not json_out.exists()


def test_allan_takes_the_edges_of_the_ranges(tmp_path, capsys):
    path = _static_csv(tmp_path / 'static.csv')
    status, out, _ = _run(['allan', path, '--max-tau-fraction', '0.5', '--gap-factor',
                           '1e300'], capsys)
    assert status == 0 and '2000 samples at 100 Hz' in out


def test_the_timing_and_the_fit_check_their_own_arguments():
    with pytest.raises(ValueError, match=r'^timing\.gap_factor = nan is out of range'):
        timing.timing_of(np.arange(10.0), float('nan'))
    segment = np.random.default_rng(1).standard_normal(1000)
    with pytest.raises(ValueError, match=r'^allan\.max_tau_fraction = 0\.75 is out of range'):
        analyse.identify([segment], 100.0, 0.75)


@pytest.mark.parametrize('workers,scheduler', [
    ('0', 'local'), ('-4', 'in-process'), ('0', 'in-process'), ('2000', 'local')])
def test_fleet_names_a_bad_worker_count_before_any_work(tmp_path, capsys, workers, scheduler):
    config = os.path.join(HERE, '..', 'config', 'fleet_paper_etch2.yaml')
    out = tmp_path / 'fleet'
    _refused(['fleet', config, '--devices', '10', '--out', str(out), '--workers', workers,
              '--scheduler', scheduler], capsys, f'fleet.workers = {float(workers)!r}',
             '[1, 1024]')
    assert not out.exists() or os.listdir(out) == []


@pytest.mark.parametrize('rows', ['', '# a comment only\n'])
@pytest.mark.parametrize('argv', [['allan'], ['diagnose', '--static']])
def test_a_csv_without_data_rows_is_one_line_without_numpys_warning(tmp_path, capsys, rows,
                                                                    argv):
    path = tmp_path / 'header.csv'
    path.write_text('time_s,rate_cmd_rad_s,temp_c,gyro_rad_s\n' + rows)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always')
        _refused([argv[0], str(path)] + argv[1:], capsys, 'no data rows after the header')
    assert [str(w.message) for w in caught] == []


@pytest.mark.skipif(not os.path.exists(MPU), reason='the MPU-6050 log is not at ../shared')
@pytest.mark.parametrize('scale', ['0', 'nan', '-9.8', 'inf', '1e300'])
def test_calibrate_names_a_bad_accel_scale_before_any_fit(tmp_path, capsys, scale):
    out = tmp_path / 'imu.yaml'
    _refused(['calibrate', 'noise', MPU, '--format', 'kalibr', '-o', str(out),
              '--accel-scale', scale], capsys, 'calibrate.accel_scale = ',
             'allowed [1e-06, 1000000.0]')
    assert not out.exists()


@pytest.mark.skipif(not os.path.exists(THERMAL_X), reason='the LSM6DSM log is not at ../shared')
def test_calibrate_thermal_refuses_one_file_given_as_two_axes(tmp_path, capsys):
    link = tmp_path / 'link.csv'
    os.symlink(os.path.abspath(THERMAL_X), link)
    out = tmp_path / 'x.params'
    _refused(['calibrate', 'thermal', THERMAL_X, str(link), '--format', 'px4', '-o', str(out)],
             capsys, 'is given twice (as axes x and y)')
    assert not out.exists()


def _damaged_bag(tmp_path, capsys):
    """Return a simulate bag whose middle is zeroed: two chunks lost."""
    bag = tmp_path / 'bag'
    assert cli.main(['simulate', '--profile', 'steps', '--duration-s', '5', '--out', str(bag),
                     '--start-time', '0']) == 0
    capsys.readouterr()
    (mcap,) = [name for name in os.listdir(bag) if name.endswith('.mcap')]
    damaged = tmp_path / 'damaged'
    shutil.copytree(bag, damaged)
    with open(damaged / mcap, 'r+b') as handle:
        handle.seek(50_000)
        handle.write(b'\0' * 20_000)
    return str(damaged)


def test_simulate_says_what_a_damaged_bag_profile_lost(tmp_path, capsys):
    damaged = _damaged_bag(tmp_path, capsys)
    out = tmp_path / 'out.csv'
    status, printed, err = _run(['simulate', '--profile', damaged, '--out', str(out)], capsys)
    assert status == 0 and out.exists()
    assert any('corrupt chunk' in line for line in err), err
    lost = [line for line in err if 'messages the bag counts' in line]
    assert lost and all(line.startswith('simulate: note: ') for line in lost), err
    rows = int(printed.split(': ')[1].split()[0])
    assert rows == len(csvio.read_csv(str(out))['time_s']) < 1000


def test_allan_keep_outliers_writes_json_a_strict_reader_takes(tmp_path, capsys):
    path = _static_csv(tmp_path / 'static.csv')
    out = tmp_path / 'a.json'
    assert _run(['allan', path, '--keep-outliers', '--json', str(out)], capsys)[0] == 0

    def refuse(word):
        raise ValueError(f'{word} is not JSON')
    doc = json.loads(out.read_text(), parse_constant=refuse)
    assert doc['set_aside']['sigma_rad_s'] is None
    assert doc['set_aside']['threshold_sigma'] is None


@pytest.mark.parametrize('option,value', [('--effect', '+'), ('--effect', ''),
                                          ('--outliers', '+')])
def test_truth_refuses_an_effect_or_outlier_list_that_names_nothing(tmp_path, capsys, option,
                                                                    value):
    _refused(['truth', str(tmp_path / 't.csv'), option, value, '--profile', 'static'], capsys,
             f'truth.{option[2:]} = {value!r}')
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize('argv,words', [
    (['simulate', '--duration-s', '1', '--out', ''], "--out '': an empty name"),
    (['allan', '{csv}', '--json', ''], "--json '': an empty name; give a file name"),
    (['paper', '--out-dir', ''], "--out-dir '': an empty name; give a folder name"),
    (['bag', 'repair', '{bag}', '--out', ''], "--out '': an empty name; give a directory name"),
])
def test_an_empty_output_name_is_refused_not_taken_as_the_working_directory(
        tmp_path, capsys, monkeypatch, argv, words):
    monkeypatch.chdir(tmp_path)
    csv = _static_csv(tmp_path / 'static.csv')
    assert cli.main(['simulate', '--duration-s', '1', '--out', 'bag']) == 0
    capsys.readouterr()
    before = sorted(os.listdir(tmp_path))
    _refused([a.format(csv=csv, bag='bag') for a in argv], capsys, words)
    assert sorted(os.listdir(tmp_path)) == before


@pytest.mark.parametrize('segment,words', [
    ('rate_deg_s: .inf', 'rate_deg_s = inf is not allowed: give a finite number'),
    ('rate_rpm: .nan', 'rate_rpm = nan is not allowed: give a finite number'),
    ('rate_deg_s: [1, 2, .inf]', 'Segment.rate_start_rad_s = (0.017453292519943295, '
                                 '0.03490658503988659, inf) is not allowed'),
])
def test_a_profile_rate_that_is_not_finite_is_named_as_written(tmp_path, capsys, segment,
                                                               words):
    profile = tmp_path / 'profile.yaml'
    profile.write_text(f'segments:\n  - {{duration_s: 1, {segment}}}\n')
    out = tmp_path / 'out.csv'
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always')
        _refused(['simulate', '--profile', str(profile), '--duration-s', '1', '--out',
                  str(out)], capsys, 'segment 1: ' + words)
    assert [str(w.message) for w in caught] == [] and not out.exists()


@pytest.mark.parametrize('name', ['excel.csv', 'excel.csv.gz'])
def test_a_csv_with_a_byte_order_mark_reads_as_without(tmp_path, name):
    plain = _static_csv(tmp_path / 'plain.csv')
    text = b'\xef\xbb\xbf' + open(plain, 'rb').read()
    path = tmp_path / name
    if name.endswith('.gz'):
        import gzip
        text = gzip.compress(text)
    path.write_bytes(text)
    marked, clean = csvio.read_csv(str(path)), csvio.read_csv(plain)
    assert list(marked) == list(clean) == ['time_s', 'gyro_x_rad_s']
    for column in clean:
        np.testing.assert_array_equal(marked[column], clean[column])


@pytest.mark.parametrize('argv,words', [
    (['diagnose', '{csv}', '--config', 'paper', '--write-config', '{preset}'],
     'is the input {preset}'),
    (['calibrate', 'check-noise', '{csv}', '--config', 'paper', '--json', '{preset}'],
     'is the input {preset}'),
    (['simulate', '--config', 'paper', '--out', '{presets}'], 'holds the input {preset}'),
])
def test_no_output_replaces_the_sensor_preset_the_run_read(tmp_path, capsys, monkeypatch,
                                                           argv, words):
    from gyro_emulator.sensor import config as sensor_config
    presets = tmp_path / 'config'
    presets.mkdir()
    shutil.copy(sensor_config.preset_path('paper'), presets / 'sensor_paper.yaml')
    monkeypatch.setattr(sensor_config, 'config_dir', lambda: str(presets))
    preset = presets / 'sensor_paper.yaml'
    before = preset.read_bytes()
    csv = _static_csv(tmp_path / 'static.csv')
    line = _refused([a.format(csv=csv, preset=preset, presets=presets) for a in argv]
                    + ['--overwrite'], capsys, words.format(preset=preset))
    assert 'choose another' in line
    assert preset.read_bytes() == before and os.listdir(presets) == ['sensor_paper.yaml']


def test_diagnose_never_writes_over_its_reference_record(tmp_path, capsys):
    # --reference is an input like the record: --json naming it is refused, even with
    # --overwrite, before any work (it was written over, the reference lost)
    record = _static_csv(tmp_path / 'record.csv')
    reference = _static_csv(tmp_path / 'reference.csv', n=3000)
    before = open(reference, 'rb').read()
    line = _refused(['diagnose', record, '--static', '--axis', 'x', '--reference', reference,
                     '--json', reference, '--overwrite'], capsys, f'is the input {reference}')
    assert 'choose another' in line
    assert open(reference, 'rb').read() == before


def test_diagnose_names_the_reference_option_when_its_file_is_missing(tmp_path, capsys):
    record = _static_csv(tmp_path / 'record.csv')
    missing = str(tmp_path / 'allan_run.csv')
    _refused(['diagnose', record, '--static', '--axis', 'x', '--reference', missing], capsys,
             f'--reference {missing}: no such file or directory', 'allowed: a static record')


def test_an_error_names_the_option_typed_only_for_the_option_s_own_value():
    args = cli.build_parser().parse_args(['simulate', '--rate-hz', '0', '--out', 'x.csv'])
    assert cli.as_option(args, 'rate_hz = 0.0 is out of range: allowed (0, 1e6] Hz') == \
        '--rate-hz 0.0 is out of range: allowed (0, 1e6] Hz'
    # a field of the same name with another value (a file's, a log's) stays as it is
    assert cli.as_option(args, 'rate_hz = 50.0 is not the log rate') == \
        'rate_hz = 50.0 is not the log rate'
    # a field that is no option, and a dotted field, stay as they are
    assert cli.as_option(args, 'temp_c = 900.0 is beyond') == 'temp_c = 900.0 is beyond'
    assert cli.as_option(args, 'simulate.seed = -1 is out of range') == \
        'simulate.seed = -1 is out of range'
    # nested commands keep their own options: calibrate noise --inflate
    args = cli.build_parser().parse_args(['calibrate', 'noise', 'log.csv', '--format', 'kalibr',
                                          '-o', 'k.yaml', '--inflate', '0.5'])
    assert cli.as_option(args, 'inflate = 0.5 is out of range: allowed [1, 1000]') == \
        '--inflate 0.5 is out of range: allowed [1, 1000]'


@pytest.mark.parametrize('option,value,words', [
    ('--inflate', '0.5', ('--inflate 0.5', 'allowed [1, 1000]')),
    ('--inflate', 'nan', ('--inflate nan', 'allowed [1, 1000]')),
    ('--rate-hz', '-1', ('--rate-hz -1.0', 'allowed (0, 1e6] Hz')),
])
def test_calibrate_noise_refuses_a_bad_export_option_before_reading_the_log(
        tmp_path, capsys, option, value, words):
    # Before: the log was read and analysed, its figures printed, then refused.
    log = _static_csv(tmp_path / 'log.csv')
    status, out, err = _run(['calibrate', 'noise', log, '--format', 'kalibr', '-o',
                             str(tmp_path / 'k.yaml'), option, value], capsys)
    assert status == 2 and len(err) == 1 and all(w in err[0] for w in words), err
    assert out == ''
    assert sorted(os.listdir(tmp_path)) == ['log.csv']


@pytest.mark.parametrize('option,value', [('--rate-hz', '50'), ('--duration-s', '10')])
def test_simulate_refuses_its_own_timing_over_a_measured_record(tmp_path, capsys, option,
                                                                value):
    # a record runs at its own rate and length: a given --rate-hz or --duration-s was
    # ignored without a word (100 Hz and the record's span were written)
    record = _static_csv(tmp_path / 'rec.csv')
    out = tmp_path / 'out.csv'
    _refused(['simulate', '--profile', record, '--static', option, value, '--out', str(out)],
             capsys, f'{option} {value}', 'measured record runs at its own rate and length',
             f'drop {option}')
    assert not out.exists()
    status, _, err = _run(['simulate', '--profile', record, '--static', '--out', str(out)],
                          capsys)
    assert status == 0 and out.exists(), err
    assert len(np.genfromtxt(out, delimiter=',', names=True)) == 2000


def test_diagnose_refuses_a_preset_beside_a_config(tmp_path, capsys):
    # with --config the baseline is that configuration's output: --preset was ignored, and
    # the JSON's device_preset named the preset the baseline did not use
    record = _static_csv(tmp_path / 'rec.csv')
    report = tmp_path / 'd.json'
    _refused(['diagnose', record, '--static', '--axis', 'x', '--config', 'paper', '--preset',
              'paper_sealed', '--json', str(report)], capsys, '--preset paper_sealed',
             'with --config', 'drop --preset')
    assert not report.exists()
