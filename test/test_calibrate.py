"""Calibrate from a log, export to estimators and autopilots, and emulate it back (issue 13)."""

from dataclasses import replace
import os
from types import SimpleNamespace
import xml.etree.ElementTree as ElementTree

from gyro_emulator import cli, units
from gyro_emulator.analysis.calibrate import (export_noise, export_thermal, noise, thermal,
                                              twin)
from gyro_emulator.emulation import profiles, simulate
from gyro_emulator.recording import csvio
from gyro_emulator.recording.record import load_record, Record
from gyro_emulator.sensor import noise as sensor_noise
from gyro_emulator.sensor.config import config_from_mapping, load_sensor_config, SensorConfig
from gyro_emulator.sensor.model import GyroModel
import numpy as np
import pytest
import yaml


def _read_log(paths):
    return thermal.thermal_log([load_record(p, required=thermal.REQUIRED_COLUMNS)
                                for p in paths])


REAL = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), '..',
                    'shared', 'data', 'real')
RATE_HZ = 100.0
LSB_RAD_S = float(units.deg_s_to_rad_s(0.01))


def _noise_config():
    config = SensorConfig.ideal().with_terms(electronics_noise=True, bias_instability=True,
                                             rate_random_walk=True, quantization=True)
    return replace(config, electronics_noise_rad_s_sqrt_hz=float(
        units.arw_deg_sqrt_h_to_rad_s_sqrt_hz(0.5)),
        bias_instability_rad_s=float(units.deg_h_to_rad_s(15.0)),
        rate_random_walk_rad_s_sqrt_s=float(units.rrw_deg_h_sqrt_h_to_rad_s_sqrt_s(40.0)),
        bias_instability_band_s=(0.01, 1e5), bias_instability_per_decade=2.0,
        lsb_rad_s=LSB_RAD_S)


@pytest.fixture(scope='module')
def noise_log(tmp_path_factory):
    """Write a 30 min static log at 100 Hz (N 0.5, B 15, K 40, LSB 0.01 deg/s) as CSV."""
    out = GyroModel(_noise_config(), RATE_HZ, np.random.default_rng(13)).run(
        np.zeros((180_000, 3)), 25.0).gyro_rad_s
    path = str(tmp_path_factory.mktemp('noise') / 'log.csv')
    csvio.write_csv(path, {'time_s': np.arange(len(out)) / RATE_HZ,
                           'gyro_x_rad_s': out[:, 0], 'gyro_y_rad_s': out[:, 1],
                           'gyro_z_rad_s': out[:, 2]})
    return path


@pytest.fixture(scope='module')
def calibration(noise_log):
    return noise.calibrate_noise(load_record(noise_log))


def test_consumer_preset_recovery_through_its_output_filter():
    """
    The consumer preset (42 Hz output filter, N 0.30, B 10, K 50) recovered from 2 h at 200 Hz.

    Before issue 13 the fit gave N 0.20 / B 70 / K 0. Over 18 simulated axes
    the spread was 0.7 % (N), 3.5 % (B) and 37 % (K, one axis per record,
    K dominant only above ~200 s): N to 3 %, B to 15 %, each axis's 95 %
    interval of K must hold 50 and the mean of the three axes lies within
    35 % of it.
    """
    time_s, _, batch = simulate.run_simulation('consumer', 'static', 7200.0, 200.0, seed=2026)
    record = Record(time_s, {a: batch.gyro_rad_s[:, i] for i, a in enumerate('xyz')},
                    {a: a for a in 'xyz'}, path='consumer')
    cal = noise.calibrate_noise(record)
    k_true = units.rrw_deg_h_sqrt_h_to_rad_s_sqrt_s(50.0)
    for item in cal.axes:
        fit = item.fit
        assert fit.band.tau_min_s > 0.1                    # the 42 Hz filter, found
        assert fit.arw_deg_sqrt_h == pytest.approx(0.30, rel=0.03)
        assert fit.bias_instability_deg_h == pytest.approx(10.0, rel=0.15)
        assert fit.intervals['rrw'].low <= k_true <= fit.intervals['rrw'].high
    mean_k = np.mean([a.fit.rrw_deg_h_sqrt_h for a in cal.axes])
    assert mean_k == pytest.approx(50.0, rel=0.35)


def _comments(text):
    return '\n'.join(line for line in text.splitlines() if line.lstrip().startswith(('#', '<!')))


@pytest.mark.parametrize('fmt', ['kalibr', 'openvins', 'vins', 'orbslam3'])
def test_estimator_exports_carry_the_fitted_n_and_k(calibration, fmt):
    """
    Each file's keys against the fitted N and K, and the units back again.

    Read as each consumer reads it: test_calibrate_consumers.py.
    """
    accel = export_noise.AccelFigures(2e-3, 3e-3)
    text = export_noise.write_noise(calibration, fmt, accel=accel)
    bare = '' if fmt == 'vins' else export_noise.write_noise(calibration, fmt)
    chosen = noise.export_noise(calibration)
    n, k = chosen.arw_rad_s_sqrt_hz, chosen.rrw_rad_s_sqrt_s
    assert n == max(a.fit.arw_rad_s_sqrt_hz for a in calibration.axes)
    doc = yaml.safe_load(text.replace('%YAML:1.0\n', ''))
    if fmt in ('kalibr', 'openvins'):
        doc = doc['imu0'] if fmt == 'openvins' else doc
        got_n, got_k = doc['gyroscope_noise_density'], doc['gyroscope_random_walk']
        assert doc['update_rate'] == pytest.approx(RATE_HZ)
        assert doc['accelerometer_noise_density'] == 2e-3
        assert doc['accelerometer_random_walk'] == 3e-3
        assert 'accelerometer_noise_density:' not in bare and 'FILL_IN' not in bare
    elif fmt == 'vins':
        # per-sample standard deviations: back to the densities through units
        got_n = float(units.sample_sigma_to_density(doc['gyr_n'], RATE_HZ))
        got_k = doc['gyr_w'] / np.sqrt(RATE_HZ)
        assert doc['gyr_n'] == pytest.approx(units.density_to_sample_sigma(n, RATE_HZ),
                                             rel=1e-5)
        assert doc['acc_n'] == pytest.approx(2e-3 * np.sqrt(RATE_HZ))
        assert doc['acc_w'] == pytest.approx(3e-3 * np.sqrt(RATE_HZ))
    else:
        got_n, got_k = doc['IMU.NoiseGyro'], doc['IMU.GyroWalk']
        assert doc['IMU.Frequency'] == pytest.approx(RATE_HZ)
        assert doc['IMU.NoiseAcc'] == 2e-3 and doc['IMU.AccWalk'] == 3e-3
        assert '\nIMU.NoiseAcc:' not in bare and 'FILL_IN' not in bare
        # ORB-SLAM3 builds its discrete noise as NoiseGyro sqrt(f): the exact discretisation
        assert got_n * np.sqrt(RATE_HZ) == pytest.approx(float(
            units.density_to_sample_sigma(n, RATE_HZ)), rel=1e-5)
    assert got_n == pytest.approx(n, rel=1e-5) and got_k == pytest.approx(k, rel=1e-5)
    notes = _comments(text)
    for needed in ('Source log:', calibration.source, 'tau', 'Convention:',
                   'Inflation factor: 1'):
        assert needed in notes


def test_inflation_is_applied_and_stated(calibration):
    base = yaml.safe_load(export_noise.write_noise(calibration, 'kalibr'))
    text = export_noise.write_noise(calibration, 'kalibr', inflate=3.0)
    doc = yaml.safe_load(text)
    assert doc['gyroscope_noise_density'] == pytest.approx(
        3.0 * base['gyroscope_noise_density'], rel=1e-5)
    assert doc['gyroscope_random_walk'] == pytest.approx(
        3.0 * base['gyroscope_random_walk'], rel=1e-5)
    assert 'Inflation factor: 3 (applied to N, B and K)' in text
    with pytest.raises(ValueError, match='inflate = 0.5 is out of range'):
        export_noise.write_noise(calibration, 'kalibr', inflate=0.5)


def test_gazebo_block_per_axis(calibration):
    text = export_noise.write_noise(calibration, 'gazebo')
    root = ElementTree.fromstring(text[text.index('<imu>'):])
    for item in calibration.axes:
        node = root.find(f'angular_velocity/{item.axis}/noise')
        assert node.get('type') == 'gaussian_quantized'       # the LSB grid was found
        stddev = float(node.find('stddev').text)
        assert float(units.sample_sigma_to_density(stddev, RATE_HZ)) == pytest.approx(
            item.fit.arw_rad_s_sqrt_hz, rel=1e-5)
        assert float(node.find('precision').text) == pytest.approx(LSB_RAD_S, rel=1e-3)
        sigma_b = float(node.find('dynamic_bias_stddev').text)
        corr = float(node.find('dynamic_bias_correlation_time').text)
        taus = item.fit.taus_s
        gm = np.sqrt(item.fit.arw_rad_s_sqrt_hz ** 2 / taus + sensor_noise.gauss_markov_avar(
            sigma_b ** 2 * corr / 2.0, corr, taus))
        _, _, error = export_noise.gauss_markov_match(item.fit, taus)
        np.testing.assert_allclose(gm / item.fit.adev(taus), 1.0, atol=error + 1e-4)  # 6 digits
        assert error < 0.3
    assert 'linear_acceleration' in text and 'FILL_IN' in text


def test_preset_is_a_sensor_yaml_the_emulator_loads(calibration, tmp_path):
    path = tmp_path / 'fitted.yaml'
    path.write_text(export_noise.write_noise(calibration, 'preset'))
    config = load_sensor_config(str(path))
    fitted = twin.emulator_fit(calibration, export_noise.flicker_band(calibration))
    for i, axis in enumerate('xyz'):
        n, b, k = fitted.per_axis[axis]
        assert config.electronics_noise_rad_s_sqrt_hz[i] == pytest.approx(n, rel=1e-5)
        assert config.bias_instability_rad_s[i] == pytest.approx(b, rel=1e-5)
        assert config.rate_random_walk_rad_s_sqrt_s[i] == pytest.approx(k, rel=1e-5)
        # the twin is the IEEE fit in the emulator's own model: close to it
        assert n == pytest.approx(calibration.axis(axis).fit.arw_rad_s_sqrt_hz, rel=0.02)
    assert config.lsb_rad_s[0] == pytest.approx(LSB_RAD_S, rel=1e-3)
    assert not config.terms.mechanical_noise and config.terms.quantization
    # the configured truth is recovered by the calibration
    assert np.mean([a.fit.arw_deg_sqrt_h for a in calibration.axes]) == pytest.approx(
        0.5, rel=0.03)


def test_preset_goes_through_the_node_parameters(calibration, tmp_path):
    """The node turns a sensor YAML into sensor.* parameters and back: the preset survives."""
    from gyro_emulator.emulation.driver import parameters as node_params

    path = tmp_path / 'fitted.yaml'
    path.write_text(export_noise.write_noise(calibration, 'preset'))
    config = load_sensor_config(str(path))
    again = node_params.apply_sensor_params(config, node_params.sensor_param_values(config))
    assert again == config
    out = GyroModel(again, 200.0, np.random.default_rng(0)).run(np.zeros((400, 3)), 25.0)
    assert np.all(np.isfinite(out.gyro_rad_s))


def test_noise_round_trip_on_a_short_log(calibration, tmp_path):
    """Check that `simulate --config fitted.yaml` reproduces the log's Allan deviation."""
    path = tmp_path / 'fitted.yaml'
    path.write_text(export_noise.write_noise(calibration, 'preset'))
    check = twin.check_noise(calibration, str(path), seeds=4)
    assert check.taus_s[0] == pytest.approx(0.1) and check.taus_s[-1] <= 180.0
    for axis, ratio in check.ratio.items():
        assert check.consistent[axis], (axis, ratio)
        assert np.all(np.abs(ratio[check.taus_s <= 10.0]) < 0.05), (axis, ratio)


def test_lsb_grid_detection():
    rng = np.random.default_rng(1)
    values = np.round(rng.standard_normal(10_000) / 0.05) * 0.05 + 0.0125
    assert noise.detect_lsb(values) == pytest.approx(0.05, rel=1e-9)
    assert noise.detect_lsb(rng.standard_normal(10_000)) == 0.0


def test_a_grid_coarser_than_the_noise_is_warned(tmp_path):
    """
    An LSB of 2.5 sigma (at 4 sigma a review read N 25 % high, silently): a warning.

    A grid of half sigma is the part's LSB and gets no warning.
    """
    rng = np.random.default_rng(12)
    n = 120_000
    t = np.arange(n) / 100.0
    x = 1e-3 * rng.standard_normal(n) + np.cumsum(2e-6 * rng.standard_normal(n))
    for lsb, warned in ((2.5e-3, True), (5e-4, False)):
        path = tmp_path / f'q{lsb:g}.csv'
        np.savetxt(path, np.column_stack([t, np.round(x / lsb) * lsb]), delimiter=',',
                   header='time_s,gyro_x_rad_s', comments='', fmt='%.10g')
        cal = noise.calibrate_noise(load_record(str(path)))
        notes = [w for w in cal.axes[0].fit.warnings if 'coarser than half' in w]
        assert bool(notes) == warned, (lsb, cal.axes[0].fit.warnings)
        assert cal.lsb_rad_s == (0.0 if warned else pytest.approx(lsb, rel=1e-6))


def test_a_gap_that_splits_the_log_is_said_in_the_output_and_every_file(tmp_path):
    """
    A 120 s gap: the header gives the 720 s span, the note the two segments and the longest tau.

    Before, ``calibrate noise`` said nothing of it (``allan`` did: 2 segments).
    """
    rng = np.random.default_rng(8)
    t = np.arange(60_000) / 100.0
    t[30_000:] += 120.0
    path = tmp_path / 'gap.csv'
    csvio.write_csv(str(path), {'time_s': t, 'gyro_rad_s': 1e-3 * rng.standard_normal(60_000)})
    cal = noise.calibrate_noise(load_record(str(path)))
    assert cal.timing == ('1 gap(s) in the stamps (longest 120 s) split the record into 2 '
                          'segments: the Allan deviation pools them, and its longest tau is set '
                          'by the longest segment (300 s), not by the 720 s span',)
    assert cal.axes[0].fit.tau_range_s[1] <= 75.0
    assert '# Timing: 1 gap(s) in the stamps' in export_noise.write_noise(cal, 'kalibr')
    whole = noise.calibrate_noise(load_record(noise_log_path(tmp_path, rng)))
    assert whole.timing == ()


def test_check_noise_on_a_log_split_by_gaps_uses_the_taus_its_segments_hold(tmp_path):
    """
    Short bursts far apart (the LSM6DSM chamber log): the octave taus stop at a tenth of a burst.

    Before, they ran to a tenth of the whole span, which the log's Allan
    deviation has not got: ``operands could not be broadcast together``.
    """
    rng = np.random.default_rng(11)
    t = np.concatenate([k * 300.0 + np.arange(1000) / 50.0 for k in range(4)])
    path = tmp_path / 'bursts.csv'
    csvio.write_csv(str(path), {'time_s': t, 'gyro_rad_s': 1e-3 * rng.standard_normal(len(t))})
    cal = noise.calibrate_noise(load_record(str(path)))
    assert cal.duration_s > 900.0
    config = load_sensor_config_text(export_noise.write_noise(cal, 'preset'))
    check = twin.check_noise(cal, config, seeds=2)
    np.testing.assert_allclose(check.taus_s, [0.1, 0.2, 0.4, 0.8, 1.6])
    assert len(check.ratio['x']) == len(check.taus_s)
    assert check.consistent['x'], check.ratio


def test_a_log_stamped_in_milliseconds_is_named_not_exported_silently(tmp_path):
    """
    100 Hz stamped in ms reads as 0.1 Hz, N sqrt(1e3) off: the note names the unit.

    Before, the export went out with exit 0 and no word (a 1 Hz log gets none).
    """
    rng = np.random.default_rng(9)
    for scale, rate, noted in ((1e3, 100.0, True), (1.0, 1.0, False)):
        path = tmp_path / f'log{rate:g}.csv'
        csvio.write_csv(str(path), {'time_s': np.arange(6000) / rate * scale,
                                    'gyro_rad_s': 1e-3 * rng.standard_normal(6000)})
        cal = noise.calibrate_noise(load_record(str(path)))
        notes = [n for n in cal.timing if 'looks like milliseconds: divide by 1e3' in n]
        assert bool(notes) == noted, cal.timing
    assert notes == [] and cal.rate_hz == 1.0


def noise_log_path(folder, rng):
    """Write 10 min at 100 Hz without a gap; return its path."""
    path = folder / 'whole.csv'
    csvio.write_csv(str(path), {'time_s': np.arange(60_000) / 100.0,
                                'gyro_rad_s': 1e-3 * rng.standard_normal(60_000)})
    return str(path)


# --- thermal ---------------------------------------------------------------

C1_RAD_S_K = float(units.deg_s_to_rad_s(0.02))
C2_RAD_S_K2 = float(units.deg_s_to_rad_s(5e-4))


@pytest.fixture(scope='module')
def thermal_log(tmp_path_factory):
    """Ramp a static part 5 -> 45 C over 40 min at 50 Hz: bias 0.1 + c1 dT + c2 dT^2 deg/s."""
    config = SensorConfig.ideal(device={'preset': 'paper', 'calibration_temp_c': 25.0}) \
        .with_terms(electronics_noise=True, bias_temperature=True, turn_on_bias=True)
    config = replace(config, electronics_noise_rad_s_sqrt_hz=float(
        units.arw_deg_sqrt_h_to_rad_s_sqrt_hz(0.3)),
        bias_temp_coeff_rad_s_k=C1_RAD_S_K, bias_temp_coeff2_rad_s_k2=C2_RAD_S_K2,
        turn_on_bias_rad_s=float(units.deg_s_to_rad_s(0.1)))
    zero = (0.0, 0.0, 0.0)
    ramp = profiles.ScriptedProfile('ramp', (profiles.Segment(2400.0, zero, zero, 5.0, 45.0),))
    path = str(tmp_path_factory.mktemp('thermal') / 'ramp.csv')
    simulate.write_record(path, config, ramp, 2400.0, 50.0, seed=3)
    return path


def test_thermal_fit_recovers_the_polynomial(thermal_log):
    log = _read_log([thermal_log])
    fit = thermal.fit_thermal(log)
    assert fit.order == 2 and fit.temp_ref_c == pytest.approx(25.0, abs=0.1)
    assert fit.span_k > 38.0 and fit.grouping.endswith('windows of 60 s')
    for axis in 'xyz':
        coef, err = fit.coefficients[axis], fit.errors[axis]
        dt_ref = fit.temp_ref_c - 25.0
        assert coef[1] == pytest.approx(C1_RAD_S_K + 2 * C2_RAD_S_K2 * dt_ref, abs=4 * err[1])
        assert coef[2] == pytest.approx(C2_RAD_S_K2, abs=4 * err[2])
    assert any('confounded' in n for n in fit.notes)       # a ramp: time moves with T


def test_px4_and_ardupilot_files_reproduce_the_fit(thermal_log):
    """PX4's and ArduPilot's own formulas, applied to the written values, give the fit."""
    log = _read_log([thermal_log])
    fit = thermal.fit_thermal(log)
    params = export_thermal.read_px4_params(export_thermal.write_thermal(fit, 'px4'))
    temps = np.linspace(fit.temp_min_c - 5.0, fit.temp_max_c + 5.0, 31)
    cal_temp = 20.0
    parm = {}
    for line in export_thermal.write_thermal(fit, 'ardupilot').splitlines():
        if line and not line.startswith('#'):
            name, value = line.split()
            parm[name] = float(value)
    for axis in 'xyz':
        np.testing.assert_allclose(thermal.px4_offset(params, axis, temps),
                                   fit.bias(axis, temps), rtol=1e-7, atol=1e-12)
        t = np.clip(temps, parm['INS_TCAL1_TMIN'], parm['INS_TCAL1_TMAX'])
        coeffs = [parm[f'INS_TCAL1_GYR{k}_{axis.upper()}'] * 1e-6 for k in (1, 2, 3)]

        def poly(d):
            return sum(c * d ** (k + 1) for k, c in enumerate(coeffs))
        correction = poly(t - 35.0) - poly(cal_temp - 35.0)
        expected = fit.bias(axis, t, clamp=False) - fit.bias(axis, cal_temp, clamp=False)
        np.testing.assert_allclose(correction, expected, rtol=1e-6, atol=1e-9)
    middle = 0.5 * (params['TC_G0_TMIN'] + params['TC_G0_TMAX'])
    assert params['TC_G0_TREF'] == pytest.approx(middle)


def test_thermal_round_trip_and_compensation(thermal_log, tmp_path):
    log = _read_log([thermal_log])
    fit = thermal.fit_thermal(log)
    path = tmp_path / 'fitted.yaml'
    path.write_text(export_thermal.write_thermal(thermal.with_white_noise(fit, log), 'preset'))
    config = load_sensor_config(str(path))
    assert config.device[0].calibration_temp_c == pytest.approx(fit.temp_ref_c, abs=1e-3)
    check = twin.check_thermal(fit, log, config)
    assert all(check.passed.values()), check
    params = export_thermal.read_px4_params(export_thermal.write_thermal(fit, 'px4'))
    for axis in 'xyz':
        comp = thermal.compensation_check(fit, params, axis)
        assert comp.after_std < comp.before_std / 20.0
        assert abs(comp.slope_rad_s_k) < 3.0 * comp.slope_error + 1e-12
        assert comp.held_out_std < 2.0 * comp.after_std


def test_thermal_refuses_too_little_span(thermal_log, tmp_path):
    cols = csvio.read_csv(thermal_log, required=('time_s',))
    keep = cols['temp_c'] < 8.0                                  # 3 K of the ramp
    short = tmp_path / 'short.csv'
    csvio.write_csv(str(short), {k: v[keep] for k, v in cols.items()})
    with pytest.raises(ValueError, match=r'spans 2\.\d+ K .*need, for order 1: 5 K'):
        thermal.fit_thermal(_read_log([str(short)]))
    assert thermal.allowed_order(8.2, 25) == 1
    assert thermal.allowed_order(40.0, 40) == 3
    assert thermal.allowed_order(20.0, 4) == 1                   # span for 2, not the count


# --- the real logs (skipped when ../shared/data/real is absent) ------------

@pytest.mark.skipif(not os.path.isdir(REAL), reason='shared real data not present')
def test_lsm6dsm_thermal_log():
    """8 K in 25 bursts: order 1, confounded with time, PX4 correction flattens x and y."""
    folder = os.path.join(REAL, 'lsm6dsm_thermal_chamber')
    log = _read_log([os.path.join(folder, f'lsm6dsm_tvc_{a}.csv') for a in 'xyz'])
    fit = thermal.fit_thermal(log)
    assert fit.order == 1 and fit.distinct_temps >= 20 and 8.0 < fit.span_k < 8.5
    assert fit.correlation < -0.99 and any('confounded' in n for n in fit.notes)
    params = export_thermal.read_px4_params(export_thermal.write_thermal(fit, 'px4'))
    for axis in 'xy':
        comp = thermal.compensation_check(fit, params, axis)
        assert comp.after_std < comp.before_std / 10.0
    check = twin.check_thermal(fit, log, load_sensor_config_text(
        export_thermal.write_thermal(thermal.with_white_noise(fit, log), 'preset')))
    assert all(check.passed.values())


def load_sensor_config_text(text):
    return config_from_mapping(yaml.safe_load(text))


@pytest.mark.skipif(not os.path.isdir(REAL), reason='shared real data not present')
def test_adis16405_round_trip():
    """The ADIS16405 twin: within 10 % up to 100 s, and within the log's interval beyond."""
    path = os.path.join(REAL, 'adis16405_static', 'adis16405_run1_100hz.csv.gz')
    cal = noise.calibrate_noise(load_record(path))
    config = load_sensor_config_text(export_noise.write_noise(cal, 'preset'))
    check = twin.check_noise(cal, config, seeds=4)
    assert check.taus_s[-1] == pytest.approx(819.2)
    # Kalibr's one K is z's, which the log resolves: a value, not an upper bound
    kalibr = export_noise.write_noise(cal, 'kalibr').splitlines()
    assert 'gyroscope_random_walk: 1.62126e-05   # rad/s^2/sqrt(Hz), K' in kalibr
    for axis, ratio in check.ratio.items():
        assert check.consistent[axis], (axis, ratio)
        assert np.all(np.abs(ratio[check.taus_s <= 100.0]) <= 0.10), (axis, ratio)


# --- command line ----------------------------------------------------------

def test_calibrate_cli(noise_log, thermal_log, tmp_path, capsys):
    out = tmp_path / 'imu.yaml'
    assert cli.main(['calibrate', 'noise', noise_log, '--axis', 'y', '--format', 'kalibr',
                     '-o', str(out), '--inflate', '2']) == 0
    assert yaml.safe_load(out.read_text())['gyroscope_noise_density'] > 0
    assert 'exported: N' in capsys.readouterr().out
    assert cli.main(['calibrate', 'noise', noise_log, '--format', 'kalibr', '-o', str(out),
                     '--inflate', '0', '--overwrite']) == 2
    err = capsys.readouterr().err
    # named as the option typed, not the field below it
    assert '--inflate 0.0 is out of range' in err and 'Traceback' not in err
    assert cli.main(['calibrate', 'noise', str(tmp_path / 'nope.csv'), '--format', 'vins',
                     '-o', str(out)]) == 2
    params = tmp_path / 'tc.params'
    assert cli.main(['calibrate', 'thermal', thermal_log, '--format', 'px4', '-o',
                     str(params)]) == 0
    assert '\tTC_G0_X2_0\t' in params.read_text()
    preset = tmp_path / 'thermal.yaml'
    assert cli.main(['calibrate', 'thermal', thermal_log, '--format', 'preset', '-o',
                     str(preset)]) == 0
    assert cli.main(['calibrate', 'check-thermal', thermal_log, '--config', str(preset),
                     '--px4', str(params)]) == 0
    out = capsys.readouterr().out
    assert 'PX4 correction: group-mean spread' in out
    assert out.count('group means within the noise') == 3
    # the twin of another part: each line says FAIL and, before, "within the noise" beside it
    assert cli.main(['calibrate', 'check-thermal', thermal_log, '--config', 'paper']) == 1
    lines = [line for line in capsys.readouterr().out.splitlines() if 'twin slope' in line]
    assert len(lines) == 3
    assert all('(FAIL)' in line and 'group means beyond the noise' in line for line in lines)


def _axis(name, k_rad_s_sqrt_s, k_high, resolved):
    """One axis of a calibration as ``export_noise`` reads it: N, B, K and K's interval."""
    interval = SimpleNamespace(high=k_high)
    fit = SimpleNamespace(arw_rad_s_sqrt_hz=1e-4, bias_instability_rad_s=1e-5,
                          rrw_rad_s_sqrt_s=k_rad_s_sqrt_s, intervals={'rrw': interval},
                          resolved=lambda term: resolved)
    return SimpleNamespace(axis=name, fit=fit)


def test_the_largest_k_is_a_bound_only_when_its_axis_does_not_resolve_it():
    """
    Kalibr's one K is the largest over the axes: a value if that axis resolves it.

    The ADIS16405 log resolves K on z (1.62e-5) and bounds it on x (9.8e-6):
    the file said 'K (upper bound)' of z's value.
    """
    value = SimpleNamespace(axes=[_axis('x', 6e-6, 9.8e-6, False),
                                  _axis('z', 1.62e-5, 2e-5, True)])
    chosen = noise.export_noise(value)
    assert chosen.rrw_rad_s_sqrt_s == 1.62e-5 and not chosen.rrw_is_bound
    assert chosen.note == ('largest of the axes; K not resolved on x: its upper bound is below '
                           'the K used')
    bound = SimpleNamespace(axes=[_axis('x', 6e-6, 3e-5, False), _axis('z', 1.62e-5, 2e-5, True)])
    chosen = noise.export_noise(bound)
    assert chosen.rrw_rad_s_sqrt_s == 3e-5 and chosen.rrw_is_bound
    assert chosen.note == 'largest of the axes; K not resolved on x: its upper bound is used'
