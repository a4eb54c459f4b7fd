"""
The loop is scored on the emulator's real output (issue 33 item 7).

* ``diagnose RECORD --write-config part.yaml``, then ``simulate --config
  part.yaml --profile RECORD``: on rate-table records with a scale-factor
  tempco and with a scale-factor step, the emulated output lines up with the
  record (cross-correlation lag 0), its noise-free RMSE is inside the
  interval diagnose claimed for the extension, and with its own noise it is
  within that claim combined with the emulator's own noise.
* ``diagnose --config`` scores what ``simulate --profile`` outputs: its
  baseline is that output, sample for sample.
* The emulator's own bag, diagnosed against the configuration that made it,
  shows no ``time_delay`` (nor any other cause).
"""

from dataclasses import replace
import functools
import json
import os
import subprocess
import sys

from gyro_emulator.analysis.diagnose import diagnose, emulated, export, to_json, write_measured_csv
from gyro_emulator.analysis.diagnose.data import load_measured
from gyro_emulator.emulation.recorded_profile import recorded_profile
from gyro_emulator.emulation.simulate import iter_simulation
from gyro_emulator.emulation.truth.generator import make_truth
from gyro_emulator.recording.record import Record
from gyro_emulator.sensor.config import load_sensor_config
import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: Lags of the cross-correlation searched, samples.
LAGS = np.arange(-4, 5)


def _cli(*args):
    env = dict(os.environ, MPLBACKEND='Agg',
               PYTHONPATH=ROOT + os.pathsep + os.environ.get('PYTHONPATH', ''))
    return subprocess.run([sys.executable, '-m', 'gyro_emulator.cli', *args],
                          cwd=ROOT, capture_output=True, text=True, env=env)


def _lag(measured, emulated_output):
    """Return the lag (samples) of the emulated output's steps behind the measured ones."""
    dm, de = np.diff(measured), np.diff(emulated_output)
    k = LAGS[-1]
    corr = [np.dot(dm[k:-k], np.roll(de, -j)[k:-k]) for j in LAGS]
    return int(LAGS[int(np.argmax(corr))])


def _calibrated_rmse(measured, emulated_output):
    """RMSE after the user's calibration (bias and scale factor, least squares), rad/s."""
    design = np.column_stack([np.ones(len(emulated_output)), emulated_output])
    coef = np.linalg.lstsq(design, measured, rcond=None)[0]
    return float(np.sqrt(np.mean((measured - design @ coef) ** 2)))


@functools.lru_cache(maxsize=None)
def _round_trip(planted, folder):
    """Return (record CSV, part.yaml, first diagnosis JSON) of a planted cause (seed 5)."""
    record, _ = make_truth(planted, seed=5)
    csv = os.path.join(folder, f'{planted}.csv')
    write_measured_csv(csv, record)
    diagnosis = diagnose(load_measured(csv))
    part = os.path.join(folder, f'{planted}.yaml')
    export.write_text(part, export.extended_model(diagnosis, 'paper').text())
    return csv, part, to_json(diagnosis)


@pytest.fixture(scope='module')
def folder(tmp_path_factory):
    return str(tmp_path_factory.mktemp('loop'))


@pytest.mark.slow
@pytest.mark.parametrize('planted,found', [('electronics_sf_tempco', 'scale_factor_temperature'),
                                           ('scale_factor_step', 'scale_factor_step')])
def test_simulate_over_the_record_lines_up_and_scores_the_claim(folder, planted, found):
    csv, part, first = _round_trip(planted, folder)
    assert [e['effect'] for e in first['selected']] == [found]
    claim = first['selected'][0]
    lo, hi = claim['rmse_interval_rad_s']
    data = load_measured(csv)
    config = load_sensor_config(part)
    # noise-free: what simulate --profile RECORD outputs with the noise terms off
    quiet = emulated.emulated_output(config, data, 'z')
    assert _lag(data.gyro_rad_s, quiet) == 0
    assert lo <= _calibrated_rmse(data.gyro_rad_s, quiet) <= hi
    # the command itself, noise on: within the claim and the emulator's own noise
    out = os.path.join(folder, f'{planted}_emu.csv')
    proc = _cli('simulate', '--config', part, '--profile', csv, '--seed', '1', '--out', out)
    assert proc.returncode == 0, proc.stderr
    emu = np.genfromtxt(out, delimiter=',', names=True)
    assert np.array_equal(emu['time_s'], np.round(data.time_s, 9))
    noisy = emu['gyro_z_rad_s']
    own = float(np.sqrt(np.mean((noisy - quiet) ** 2)))
    assert 0.0 < own < hi
    assert _lag(data.gyro_rad_s, noisy) == 0
    assert _calibrated_rmse(data.gyro_rad_s, noisy) <= np.hypot(hi, own)


def test_diagnose_config_scores_what_simulate_outputs(tmp_path):
    # a part with sense dynamics, an output filter and a nonlinearity on a rate table
    record, _ = make_truth('none', seed=3, duration_s=300.0, sample_rate_hz=50.0)
    csv = tmp_path / 'm.csv'
    write_measured_csv(str(csv), record)
    cfg = tmp_path / 'part.yaml'
    cfg.write_text('device: paper\nmode_split_hz: [0.0, 0.0, 40.0]\noutput_filter_hz: 12.0\n'
                   'nonlinearity_s_rad: [0.0, 0.0, 0.01]\n'
                   'bias_temp_coeff_rad_s_k: [0.0, 0.0, 2.0e-4]\n')
    config = load_sensor_config(str(cfg))
    data = load_measured(str(csv))
    quiet = emulated.deterministic(config, data.time_s[0])
    chunks = iter_simulation(quiet, recorded_profile(str(csv), axis='z'), 0.0, 0.0)
    simulated = np.concatenate([c.batch.gyro_rad_s[c.published, 2] for c in chunks])
    np.testing.assert_array_equal(emulated.emulated_output(config, data, 'z'), simulated)
    offset, rate_part = emulated.offset_and_rate(config, data, 'z')
    np.testing.assert_allclose(offset + rate_part, simulated, rtol=0.0, atol=1e-15)
    # the rate part carries the filter: it is not the rate times a gain
    gain = rate_part[np.abs(data.rate_cmd_rad_s) > 0.1] / data.rate_cmd_rad_s[
        np.abs(data.rate_cmd_rad_s) > 0.1]
    assert np.ptp(gain) > 0.05
    # the part's own output over the same table, with its noise: diagnose against the
    # configuration takes the filter and the nonlinearity and finds nothing to add
    chunks = iter_simulation(config, recorded_profile(str(csv), axis='z'), 0.0, 0.0, seed=4)
    own = np.concatenate([c.batch.gyro_rad_s[c.published, 2] for c in chunks])
    record = Record.from_arrays(data.time_s, own, data.rate_cmd_rad_s, data.temp_c,
                                path='own output')
    doc = to_json(diagnose(record, config=str(cfg)))
    assert doc['selected'] == [], [e['effect'] for e in doc['selected']]


@pytest.mark.parametrize('config,rate_hz', [('paper', 100.0), ('paper', 25.0)])
def test_the_emulators_own_bag_shows_no_time_delay(tmp_path, config, rate_hz):
    bag, report = tmp_path / 'bag', tmp_path / 'd.json'
    proc = _cli('simulate', '--config', config, '--profile', 'steps', '--duration-s', '300',
                '--rate-hz', str(rate_hz), '--seed', '2', '--out', str(bag),
                '--start-time', '0')
    assert proc.returncode == 0, proc.stderr
    proc = _cli('diagnose', str(bag), '--config', config, '--json', str(report))
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(report.read_text())
    assert doc['selected'] == [], [e['effect'] for e in doc['selected']]
    delay = [f for f in doc['findings'] if f['effect'] == 'time_delay']
    assert delay and not delay[0].get('significant', False)


def test_diagnose_config_runs_latency_and_clock_drift_as_simulate_does(tmp_path):
    # a latency moves the node's stamps, a clock drift the model's grid: diagnose --config
    # takes both, and its baseline is still what simulate --profile writes, value for value
    record, _ = make_truth('none', seed=5, duration_s=200.0, sample_rate_hz=50.0)
    csv = tmp_path / 'm.csv'
    write_measured_csv(str(csv), record)
    cfg = tmp_path / 'part.yaml'
    cfg.write_text('device: paper\noutput_filter_hz: 12.0\nlatency_s: 0.02\n'
                   'clock_drift_ppm: 800.0\n')
    config = load_sensor_config(str(cfg))
    assert config.latency_s == 0.02 and config.clock_drift_ppm == 800.0
    data = load_measured(str(csv))
    out = tmp_path / 'emu.csv'
    proc = _cli('simulate', '--config', str(cfg), '--profile', str(csv), '--seed', '1',
                '--out', str(out))
    assert proc.returncode == 0, proc.stderr
    emu = np.genfromtxt(out, delimiter=',', names=True)
    assert np.array_equal(emu['time_s'], np.round(data.time_s, 9))
    quiet = emulated.deterministic(config, data.time_s[0])
    chunks = iter_simulation(quiet, recorded_profile(str(csv), axis='z'), 0.0, 0.0)
    simulated = np.concatenate([c.batch.gyro_rad_s[c.published, 2] for c in chunks])
    baseline = emulated.emulated_output(config, data, 'z')
    np.testing.assert_array_equal(baseline, simulated)
    # the drift's grid is not the nominal one: the filter ran on the part's own clock
    nominal = emulated.emulated_output(replace(config, clock_drift_ppm=0.0), data, 'z')
    assert len(baseline) == len(data.time_s) and np.all(np.isfinite(baseline))
    assert not np.array_equal(baseline, nominal)
    # the noisy output written by simulate sits on that baseline within its own noise
    assert float(np.sqrt(np.mean((emu['gyro_z_rad_s'] - baseline) ** 2))) < 0.05
    proc = _cli('diagnose', str(csv), '--axis', 'z', '--config', str(cfg), '--json',
                str(tmp_path / 'd.json'))
    assert proc.returncode == 0 and proc.stderr == '', proc.stderr
    assert json.loads((tmp_path / 'd.json').read_text())['verdict']


def test_a_record_beyond_the_starting_full_scale_widens_the_written_range(tmp_path):
    # a part that measured 330 deg/s, where the paper preset clips at 300: the written
    # model must not clip what the record measured, or simulate misses the claim
    rng = np.random.default_rng(12)
    t = np.arange(12_000) / 100.0
    top = np.deg2rad(330.0)
    rate = np.interp(t, [0, 10, 11, 30, 31, 50, 51, 70, 71, 90, 91, 120],
                     [0, 0, top, top, 0, 0, -top, -top, 0.5 * top, 0.5 * top, 0, 0])
    gyro = 1.002 * rate + 0.01 + 1e-3 * rng.standard_normal(len(t))
    csv = tmp_path / 'wide.csv'
    write_measured_csv(str(csv), Record.from_arrays(t, gyro, rate, np.full(len(t), 25.0),
                                                    path='wide'))
    part = tmp_path / 'part.yaml'
    proc = _cli('diagnose', str(csv), '--write-config', str(part), '--json',
                str(tmp_path / 'd.json'))
    assert proc.returncode == 0 and proc.stderr == '', proc.stderr
    config = load_sensor_config(str(part))
    data = load_measured(str(csv))
    quiet = emulated.emulated_output(config, data, 'z')
    claim = json.loads((tmp_path / 'd.json').read_text())['baseline']['rmse_interval_rad_s']
    assert _calibrated_rmse(data.gyro_rad_s, quiet) <= claim[1]
    assert config.range_rad_s[2] >= np.max(np.abs(gyro)) and config.range_rad_s[:2] == (
        load_sensor_config('paper').range_rad_s[:2])
    text = part.read_text()
    assert 'range_deg_s' not in text and '# Full scale of axis z widened from 5.23599' in text
    # within the range, the starting range stays as written
    inside = replace(data, gyro_rad_s=np.clip(data.gyro_rad_s, -5.0, 5.0))
    model = export.extended_model(diagnose(data), 'paper')
    assert model.with_measured_range(inside) is model
