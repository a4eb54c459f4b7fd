"""
Bad cells and unit mistakes in a CSV: a count or a one-line error, never a silently wrong output.

Each test is built from a reproducer of issue 26 (items 7, 8 and 9); the
last one is the CSV half of its fuzz test: seeded mutations of a small log
run through ``allan``, ``calibrate noise``, ``calibrate thermal`` and
``diagnose``, each compared with the intact log's output.
"""

import json
import os

from gyro_emulator import cli
from gyro_emulator.analysis import outliers
from gyro_emulator.analysis.calibrate import export_thermal, thermal
from gyro_emulator.recording import csvio, timing
from gyro_emulator.recording.record import load_record
import numpy as np
import pytest

N = 3000
RATE_HZ = 50.0
SLOPE_RAD_S_K = 2e-4


def _log_columns(seed=26):
    """Return a static 3-axis log, 60 s at 50 Hz, 15 -> 45 C: bias 0.01 + 2e-4 (T - 25) rad/s."""
    rng = np.random.default_rng(seed)
    t = np.arange(N) / RATE_HZ
    temp = 15.0 + 30.0 * t / t[-1] + rng.normal(0.0, 0.01, N)
    columns = {'time_s': t, 'rate_cmd_rad_s': np.zeros(N), 'temp_c': temp}
    for k, axis in enumerate('xyz'):
        bias = 0.01 * (k + 1) + SLOPE_RAD_S_K * (temp - 25.0)
        columns[f'gyro_{axis}_rad_s'] = bias + rng.normal(0.0, 2e-3, N)
    return columns


def _write(path, columns):
    csvio.write_csv(str(path), columns, '%.12g')
    return str(path)


def _fit(path, window_s=2.0, threshold=outliers.THRESHOLD):
    log = thermal.thermal_log([load_record(path, None, thermal.REQUIRED_COLUMNS)])
    return thermal.fit_thermal(log, window_s=window_s, outlier_threshold=threshold)


def _px4(fit):
    thermal.check_export(fit)
    return export_thermal.read_px4_params(export_thermal.write_thermal(fit, 'px4'))


@pytest.fixture(scope='module')
def clean(tmp_path_factory):
    path = _write(tmp_path_factory.mktemp('clean') / 'log.csv', _log_columns())
    return path, _px4(_fit(path))


# --- item 7: one bad cell, a wrong PX4 file with exit 0 -----------------------

@pytest.mark.parametrize('column,value', [
    ('temp_c', 1e6), ('temp_c', -300.0), ('temp_c', -273.15), ('temp_c', 5000.0),
    ('temp_c', 140.0), ('gyro_x_rad_s', -1e308), ('gyro_y_rad_s', 1e6)])
def test_one_bad_cell_is_set_aside_named_and_the_file_unchanged(clean, tmp_path, column, value):
    path, params = clean
    columns = _log_columns()
    columns[column][1234] = value
    fit = _fit(_write(tmp_path / 'bad.csv', columns))
    got = _px4(fit)
    # the file a bad cell gives is the clean one, to the noise of one sample in 3000
    assert got['TC_G0_TMIN'] == pytest.approx(params['TC_G0_TMIN'], abs=0.05)
    assert got['TC_G0_TMAX'] == pytest.approx(params['TC_G0_TMAX'], abs=0.05)
    for i in range(3):
        assert got[f'TC_G0_X1_{i}'] == pytest.approx(params[f'TC_G0_X1_{i}'], rel=0.02)
    said = [n for n in fit.notes if 'set aside' in n and '24.68 s' in n]
    assert said, fit.notes
    if column == 'temp_c' and not -60.0 <= value <= 200.0:
        assert any('1 beyond the physical limits [-60, 200] C' in n for n in said), said
    if column.startswith('gyro') and abs(value) > 1000.0:
        assert any('1 beyond the physical limits [-1000, 1000] rad/s' in n for n in said), said


def test_the_limits_hold_with_screening_off(clean, tmp_path):
    columns = _log_columns()
    columns['temp_c'][10] = 1e6
    fit = _fit(_write(tmp_path / 'bad.csv', columns), threshold=float('inf'))
    assert fit.temp_max_c < 46.0
    assert any('1 beyond the physical limits' in n and 'screening off' in n for n in fit.notes)


@pytest.mark.parametrize('offset,scale,unit', [(273.15, 1.0, 'kelvin'),
                                               (0.0, 1000.0, 'millidegrees C')])
def test_a_temperature_column_in_another_unit_is_refused_and_named(tmp_path, offset, scale,
                                                                   unit):
    columns = _log_columns()
    columns['temp_c'] = columns['temp_c'] * scale + offset
    with pytest.raises(ValueError, match=rf'temp_c: .* beyond the physical limits \[-60, 200\] '
                                         rf'C \(the first at data row 1: .*looks like {unit}'):
        _fit(_write(tmp_path / 'kelvin.csv', columns))


def test_a_file_beyond_the_data_is_refused(clean):
    fit = _fit(clean[0])
    low, high = fit.data_temp_c
    bad = [
        ({'temp_max_c': high + 50.0}, r'TMAX = .* outside the kept temperatures'),
        ({'coefficients': dict(fit.coefficients, y=np.array([0.02, 1e3]))},
         r'axis y: the fit predicts a bias of .* outside the kept rates'),
        ({'coefficients': dict(fit.coefficients, x=np.array([-8.3e303, 0.0]))},
         r'axis x coefficient 0 = -8.3e\+303|axis x: the fit predicts'),
        ({'residual_rms': dict(fit.residual_rms, z=float('inf'))}, r'residual rms = inf is '
                                                                   r'not finite')]
    for change, message in bad:
        with pytest.raises(ValueError, match='refusing to write .*' + message):
            thermal.check_export(thermal.replace(fit, **change))


# --- item 8: timestamps that are not seconds -----------------------------------

@pytest.mark.parametrize('times,message', [
    (1.7e18 + np.arange(N) * 2e7, r'data row 1 is 1.7e\+18, beyond \+-1e\+10 s .*looks like '
                                  r'nanoseconds since the epoch: divide by 1e9'),
    (1.7e12 + np.arange(N) * 20.0, r'looks like milliseconds since the epoch: divide by 1e3'),
    (np.arange(N) * 1e-300, r'the median step is 1e-300 s \(data row 2: .*allowed \[1e-06, '
                            r'3600\] s'),
    (np.arange(N) * 1e6, r'the median step is 1e\+06 s .*looks like microseconds or '
                         r'nanoseconds: divide by 1e6 or 1e9'),
    (np.r_[np.arange(N - 1) / RATE_HZ, 1e308], rf'data row {N} is 1e\+308, beyond \+-1e\+10 s'),
])
def test_a_time_base_that_is_not_seconds_is_named_before_anything_is_allocated(
        tmp_path, times, message):
    columns = _log_columns()
    columns['time_s'] = times
    path = _write(tmp_path / 'times.csv', columns)
    with pytest.raises(ValueError, match=r'times.csv: time_s: .*' + message):
        load_record(path)
    # the rule is the timing module's, for every reader of a record
    with pytest.raises(ValueError, match=message):
        timing.check_time_base(times)


def test_allocations_follow_the_samples_not_the_duration():
    """A record of 12 samples in two bursts 3e9 s apart: windows and level bins stay small."""
    t = np.r_[np.arange(6) * 0.01, 3e9 + np.arange(6) * 0.01]
    timing.check_time_base(t)
    assert len(thermal._windows(t, 0, 6, 1.0)) == 1
    assert len(thermal._windows(np.r_[0.0, 0.01, 0.02, 500.0, 500.01, 500.02], 0, 6, 1.0)) == 2
    means = outliers._window_means(t, np.ones(12), np.ones(12, bool), 10.0)
    assert len(means) == 0                  # two windows of 6: too few to compare


# --- item 9: errors that name nothing -------------------------------------------

@pytest.mark.parametrize('column,value,message', [
    ('gyro_rad_s', 1e308, r'gyro_rad_s = 1e\+308 at sample 100 \(data row 101\) is beyond '
                          r'\[-1000, 1000\] rad/s'),
    ('rate_cmd_rad_s', -1e308, r'rate_cmd_rad_s = -1e\+308 at sample 100 \(data row 101\)'),
    ('temp_c', 1e308, r'temp_c = 1e\+308 at sample 100 \(data row 101\) is beyond \[-60, 200\] C'),
])
def test_diagnose_names_the_column_the_row_and_the_limit(tmp_path, column, value, message):
    """Was "SVD did not converge" (gyro or rate) and a 300-digit temperature."""
    from gyro_emulator.analysis.diagnose.data import load_measured
    columns = _log_columns()
    columns['gyro_rad_s'] = columns.pop('gyro_x_rad_s')
    columns[column][100] = value
    with pytest.raises(ValueError, match=message):
        load_measured(_write(tmp_path / 'cell.csv', columns))


# --- the fuzz test, CSV half ----------------------------------------------------

def _run(argv, capsys):
    """Return (exit code, the outputs with the file name left out, stderr)."""
    code = cli.main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def _commands(path, out):
    return {
        'allan': ['allan', path, '--json', f'{out}.allan.json'],
        'noise': ['calibrate', 'noise', path, '--format', 'kalibr', '-o', f'{out}.yaml'],
        'thermal': ['calibrate', 'thermal', path, '--format', 'px4', '-o', f'{out}.params',
                    '--window-s', '2'],
        'diagnose': ['diagnose', path, '--axis', 'x', '--json', f'{out}.diag.json',
                     '--folds', '4', '--max-causes', '1'],
    }


def _result(command, out):
    """Return what a command wrote, to compare, without the source's name."""
    name = {'allan': f'{out}.allan.json', 'noise': f'{out}.yaml', 'thermal': f'{out}.params',
            'diagnose': f'{out}.diag.json'}[command]
    if not os.path.exists(name):
        return None
    text = open(name, encoding='utf-8').read()
    os.remove(name)
    if name.endswith('.json'):
        doc = json.loads(text)
        for key in ('file', 'source', 'sources'):
            doc.pop(key, None)
        return json.dumps(doc, sort_keys=True)
    return '\n'.join(line for line in text.splitlines() if not line.startswith('#'))


def _mutations(rng, count):
    """Seeded mutations of the log: (label, columns)."""
    kinds = [('gyro_x_rad_s', v) for v in (1e308, -1e308, 1e6, 3.0)] + \
            [('temp_c', v) for v in (1e6, -300.0, -273.15, 5000.0, 150.0)] + \
            [('time_s', v) for v in (1e308, -1e308)]
    units = [('time_s ns since the epoch', lambda c: 1.7e18 + c['time_s'] * 1e9),
             ('time_s ms since the epoch', lambda c: 1.7e12 + c['time_s'] * 1e3),
             ('time_s in us', lambda c: c['time_s'] * 1e6),
             ('time_s x 1e-300', lambda c: c['time_s'] * 1e-300),
             ('temp_c in kelvin', lambda c: c['temp_c'] + 273.15),
             ('temp_c in millidegrees', lambda c: c['temp_c'] * 1e3)]
    for k in range(count):
        columns = _log_columns()
        if k < len(units):
            label, change = units[k]
            columns[label.split()[0]] = change(columns)
            yield label, columns
            continue
        column, value = kinds[int(rng.integers(len(kinds)))]
        row = int(rng.integers(1, N - 1)) if column != 'time_s' else (
            N - 1 if value > 0 else 0)
        columns[column][row] = value
        yield f'{column}[{row}] = {value!r}', columns


@pytest.mark.filterwarnings('error::RuntimeWarning')  # a numpy warning would reach the terminal
def test_fuzz_csv_mutations_end_in_a_count_or_one_line_never_a_silent_difference(
        tmp_path, capsys):
    rng = np.random.default_rng(2026)
    path = _write(tmp_path / 'intact.csv', _log_columns())
    out = str(tmp_path / 'out')
    intact = {}
    for command, argv in _commands(path, out).items():
        code, _, err = _run(argv, capsys)
        assert code == 0, err
        intact[command] = _result(command, out)
    outcomes = {'same': 0, 'counted': 0, 'error': 0}
    for i, (label, columns) in enumerate(_mutations(rng, 16)):
        case = _write(tmp_path / f'case{i}.csv', columns)
        for command, argv in _commands(case, out).items():
            code, stdout, err = _run(argv, capsys)
            got = _result(command, out)
            if code != 0:
                lines = err.strip().splitlines()
                assert code == 2 and len(lines) == 1 and 'Traceback' not in err, (label, err)
                outcomes['error'] += 1
            elif got == intact[command]:
                outcomes['same'] += 1
            else:
                # a different output says what it set aside
                assert 'set aside' in stdout + err + (got or ''), (label, command)
                assert 'nothing set aside' not in stdout + err or 'beyond the physical' in (
                    stdout + err), (label, command)
                outcomes['counted'] += 1
    assert outcomes['error'] > 0 and outcomes['counted'] > 0, outcomes
