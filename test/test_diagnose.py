"""
``diagnose`` finds the effect hidden in simulated measured data.

The truth generator hides ONE effect of random magnitude in a seeded random
lab profile with noise; the record goes through a CSV file and diagnose sees
nothing else. Every catalogue entry is covered over several seeds, plus
clean data (no false alarm), the paper's validation experiment and the
real LSM6DSM thermal-chamber log.
"""

import json
import os
import subprocess
import sys

from gyro_emulator.analysis.diagnose import baseline as base
from gyro_emulator.analysis.diagnose import (diagnose, EFFECT_IDS, load_csv, make_truth,
                                             write_measured_csv)
from gyro_emulator.analysis.diagnose.truth import TRUTH_EFFECTS
from gyro_emulator.physics.presets import physics_preset
import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
REAL = os.path.join(os.path.dirname(ROOT), 'shared', 'data', 'real',
                    'lsm6dsm_thermal_chamber')
SEEDS = (0, 1, 2)
#: Modest records for the test run: 10 Hz, four temperature levels.
RATE_HZ = 10.0
LEVELS = 4

#: The parameter each effect must measure, and a relative tolerance.
PRIMARY = {
    'viscosity_temperature': ('sutherland_constant_k', 0.02),
    'bias_temperature': ('bias_temp_coeff_rad_s_k', 0.1),
    'thermal_lag': ('thermal_time_constant_s', 0.1),
    'scale_factor_nonlinearity': ('nonlinearity_cubic_s2_rad2', 0.1),
    'g_sensitivity': (None, 0.1),
    'time_delay': ('delay_s', 0.05),
    'pressure_drift': ('pressure_rate_per_h', 0.1),
    'mode_split_drift': ('mode_split_temp_coeff_hz_k', 0.1),
    'temperature_rate_bias': ('bias_per_temp_rate_rad_s_per_k_s', 0.1),
}


def _through_csv(tmp_path, record):
    path = tmp_path / 'measured.csv'
    write_measured_csv(path, record)
    return load_csv(path)


def test_every_catalogue_entry_has_a_truth_and_a_check():
    assert set(PRIMARY) == set(EFFECT_IDS)
    assert set(TRUTH_EFFECTS) == set(EFFECT_IDS) | {'none'}


def test_truth_csv_holds_only_the_contract(tmp_path):
    record, truth = make_truth('random', 5, sample_rate_hz=2.0, levels=3)
    path = tmp_path / 'm.csv'
    write_measured_csv(path, record)
    header = path.read_text().splitlines()[0].split(',')
    assert header == ['time_s', 'rate_cmd_rad_s', 'temp_c', 'gyro_rad_s',
                      'accel_x_m_s2', 'accel_y_m_s2', 'accel_z_m_s2']
    assert truth['effect'] in TRUTH_EFFECTS
    again, truth2 = make_truth('random', 5, sample_rate_hz=2.0, levels=3)
    assert truth2 == truth
    np.testing.assert_array_equal(again.gyro_rad_s, record.gyro_rad_s)


@pytest.mark.slow
@pytest.mark.parametrize('seed', SEEDS)
@pytest.mark.parametrize('effect', EFFECT_IDS)
def test_hidden_effect_is_named_with_a_real_gain(tmp_path, effect, seed):
    record, truth = make_truth(effect, seed, sample_rate_hz=RATE_HZ, levels=LEVELS)
    doc = diagnose(_through_csv(tmp_path, record)).doc
    best = doc['best']
    ranked = [(f['effect'], round(f['gain'], 4), f['significant'])
              for f in doc['findings']]
    assert best['effect'] == effect, (truth, ranked)
    assert best['gain'] > 0.1
    assert best['rmse_rad_s'] < doc['baseline']['rmse_rad_s']
    finding = next(f for f in doc['findings'] if f['effect'] == effect)
    assert finding['significant'] and finding['p_value'] < 1e-3
    name, rel = PRIMARY[effect]
    got = {k: v['value'] for k, v in best['parameters'].items()}
    want = truth['parameters']
    if effect == 'g_sensitivity':
        keys = sorted(want)
        g_got = np.array([got[k] for k in keys])
        g_want = np.array([want[k] for k in keys])
        assert np.linalg.norm(g_got - g_want) < rel * np.linalg.norm(g_want)
        return
    expected = want[name]
    if effect == 'mode_split_drift':
        expected = abs(expected)      # the model is even in the split
    assert got[name] == pytest.approx(expected, rel=rel), (got, want)


@pytest.mark.slow
@pytest.mark.parametrize('seed', (0, 1, 2, 3))
def test_clean_data_gives_none(tmp_path, seed):
    record, truth = make_truth('none', seed, sample_rate_hz=RATE_HZ, levels=LEVELS)
    doc = diagnose(_through_csv(tmp_path, record)).doc
    assert doc['best']['effect'] == 'none', [
        (f['effect'], f['gain_over_recalibrated'], f['p_value'])
        for f in doc['findings']]
    assert doc['best']['gain'] == 0.0
    assert doc['best']['rmse_rad_s'] == doc['baseline']['rmse_rad_s']
    assert not any(f['significant'] for f in doc['findings'])


@pytest.mark.slow
@pytest.mark.parametrize('effect,seed,correlate', [
    ('g_sensitivity', 0, 'acceleration'),
    ('temperature_rate_bias', 1, 'temperature_rate'),
    ('bias_temperature', 2, 'temperature'),
    ('scale_factor_nonlinearity', 0, 'rate')])
def test_unexplained_structure_names_its_correlate(effect, seed, correlate):
    # hide an effect, then offer diagnose only causes that cannot explain it
    record, _ = make_truth(effect, seed, sample_rate_hz=RATE_HZ, levels=LEVELS)
    doc = diagnose(record, effects=['thermal_lag', 'time_delay',
                                    'pressure_drift']).doc
    assert doc['best']['effect'] == 'none'
    assert doc['residual']['structure_remains']
    assert doc['residual']['strongest_correlate'] == correlate
    assert 'No cause in the catalogue explains it' in doc['residual']['message']


def test_sutherland_ratio_inside_the_physics_matches_the_preset():
    phys = base.DevicePhysics(physics_preset('paper'), 25.0, 20.0, 90.0)
    temps = np.array([25.0, 40.0, 85.0])
    from gyro_emulator.physics import first_order
    expected = first_order.scale_factor_ratio(physics_preset('paper_sutherland'), temps)
    np.testing.assert_allclose(phys.sutherland_ratio(temps, 110.4), expected,
                               rtol=1e-6)
    np.testing.assert_allclose(phys.pressure_factor(temps, np.ones(3)), 1.0,
                               rtol=1e-6)
    assert phys.pressure_factor(np.array([25.0]), np.array([0.9]))[0] > 1.0
    np.testing.assert_allclose(phys.mode_split_factor(temps, 0.0), 1.0)
    # 100 Hz split at Q ~ 44, f = 14 kHz costs about 15 % (docs/physics.md)
    assert phys.mode_split_factor(np.array([25.0]), 100.0)[0] == pytest.approx(
        0.846, abs=0.01)


def test_calibration_window_widens_to_five_percent():
    temps = np.linspace(10.0, 20.0, 1000)
    rows, width = base.calibration_rows(temps, np.ones(1000), 25.0)
    assert rows.sum() == pytest.approx(50, abs=1)
    assert width == pytest.approx(5.0 + 0.5, abs=0.02)
    rows, width = base.calibration_rows(temps + 10.0, np.ones(1000), 25.0)
    assert width == 2.0 and rows.sum() == pytest.approx(400, abs=2)


@pytest.mark.slow
def test_the_papers_validation_experiment_with_sutherland_air(tmp_path):
    record, truth = make_truth('viscosity_temperature', 0, profile='paper',
                               sample_rate_hz=2.0,
                               params={'sutherland_constant_k': 110.4})
    result = diagnose(_through_csv(tmp_path, record))
    doc = result.doc
    assert doc['best']['effect'] == 'viscosity_temperature'
    assert doc['best']['parameters']['sutherland_constant_k']['value'] == \
        pytest.approx(110.4, rel=0.01)
    assert doc['best']['gain'] > 0.9
    # the paper's model over-reads the rate when hot: at 85 C and 40 RPM the
    # residual (measured - model) is strongly negative before the extension
    b = result.prepared.binned
    hot = (b.temp_c > 84.0) & (b.rate > 4.0)
    assert np.mean(result.residual_before[hot]) < -0.5
    assert abs(np.mean(result.residual_after[hot])) < 0.01


@pytest.mark.skipif(not os.path.isdir(REAL), reason='real data not present')
def test_real_lsm6dsm_static_log(tmp_path):
    doc = diagnose(load_csv(os.path.join(REAL, 'lsm6dsm_tvc_x.csv'))).doc
    untested = {nt['effect'] for nt in doc['not_tested']}
    # static: the scale-factor causes cannot be observed, and say so
    assert {'viscosity_temperature', 'thermal_lag', 'time_delay',
            'pressure_drift', 'mode_split_drift',
            'scale_factor_nonlinearity', 'g_sensitivity'} <= untested
    assert not doc['calibration']['scale_factor_calibrated']
    # the bias drift with die temperature is plain in this log
    assert doc['best']['effect'] == 'bias_temperature'
    assert doc['best']['gain'] > 0.5


def _cli(*args):
    env = dict(os.environ, MPLBACKEND='Agg',
               PYTHONPATH=ROOT + os.pathsep + os.environ.get('PYTHONPATH', ''))
    return subprocess.run([sys.executable, '-m', 'gyro_emulator.cli', *args],
                          cwd=ROOT, capture_output=True, text=True, env=env)


@pytest.mark.slow
def test_cli_truth_then_diagnose_writes_json_and_report(tmp_path):
    csv = tmp_path / 'm.csv'
    answer = tmp_path / 'answer.json'
    proc = _cli('truth', str(csv), '--effect', 'g_sensitivity', '--seed', '3',
                '--rate', '5', '--answer', str(answer))
    assert proc.returncode == 0, proc.stderr
    assert 'g_sensitivity' not in proc.stdout and 'g_sensitivity' not in \
        csv.read_text()[:200]
    out = tmp_path / 'd.json'
    report = tmp_path / 'report'
    proc = _cli('diagnose', str(csv), '--json', str(out), '--report', str(report))
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(out.read_text())
    assert set(doc['baseline']) >= {'rmse_rad_s'}
    assert set(doc['best']) == {'effect', 'cause', 'parameters', 'rmse_rad_s',
                                'gain'}
    assert doc['best']['effect'] == json.loads(answer.read_text())['effect']
    for f in doc['findings']:
        assert set(f) >= {'effect', 'cause', 'parameters', 'rmse_rad_s', 'gain'}
    rmses = [f['rmse_rad_s'] for f in doc['findings']]
    assert rmses == sorted(rmses)
    page = (report / 'report.md').read_text()
    assert 'g_sensitivity' in page and '1 sigma' in page
    for name in ('temperature', 'rate', 'time'):
        png = (report / f'residuals_{name}.png').read_bytes()
        assert png[:8] == b'\x89PNG\r\n\x1a\n'
        assert f'residuals_{name}.png' in page


def test_cli_reports_bad_input_cleanly(tmp_path):
    bad = tmp_path / 'bad.csv'
    bad.write_text('time_s,rate_cmd_rad_s,gyro_rad_s\n0,0,0\n')
    proc = _cli('diagnose', str(bad))
    assert proc.returncode == 2
    assert 'missing required column(s) temp_c' in proc.stderr
    assert 'Traceback' not in proc.stderr
    proc = _cli('truth', str(tmp_path / 'x.csv'), '--effect', 'none',
                '--set', 'delay_s=0.01')
    assert proc.returncode == 2 and 'not a parameter of none' in proc.stderr
