"""
Calibrate the accelerometer from the same log as the gyro (issue 32 item 4, item 5's check).

One IEEE Std 952 identification for both channels (``calibrate_noise(...,
sense=ACCEL)``), gravity a level the Allan deviation and the screening do not
see, the exports complete from the log alone, the user's figures in their
place, a log in g refused, the twin's accelerometer, PX4's and ArduPilot's
accelerometer thermal parameters, and ``diagnose --write-config --noise``.
The consumers' own parsers read the files in test_calibrate_consumers.py.
"""

from dataclasses import replace
import os

import allantools
from gyro_emulator import cli, units
from gyro_emulator.analysis.calibrate import (export_noise, export_thermal, noise, thermal,
                                              twin)
from gyro_emulator.analysis.calibrate.accel_figures import accel_figures
from gyro_emulator.analysis.diagnose import record_noise
from gyro_emulator.analysis.diagnose.data import MeasuredData
from gyro_emulator.analysis.sense import ACCEL
from gyro_emulator.emulation import profiles, simulate
from gyro_emulator.recording import csvio
from gyro_emulator.recording.record import load_record, Record
from gyro_emulator.sensor.accel import AccelConfig, AccelTerms
from gyro_emulator.sensor.config import config_from_mapping, load_sensor_config, SensorConfig
from gyro_emulator.sensor.imu import ImuModel
import numpy as np
import pytest
import yaml

REAL = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), '..',
                    'shared', 'data', 'real')
MPU = os.path.join(REAL, 'mpu6050_static', 'mpu6050_static_100hz.csv')
needs_mpu = pytest.mark.skipif(not os.path.isfile(MPU), reason='shared real data not present')
needs_real = pytest.mark.skipif(not os.path.isdir(REAL), reason='shared real data not present')
RATE_HZ = 100.0
G = units.STANDARD_GRAVITY_M_S2
#: Gravity on a part tilted 30 deg about y, then 20 deg about x: every axis sees some.
TILT = np.array([np.sin(np.radians(30)) * np.cos(np.radians(20)),
                 -np.sin(np.radians(20)),
                 np.cos(np.radians(30)) * np.cos(np.radians(20))])
BIAS_M_S2 = np.array([0.05, -0.03, 0.10])
N_M_S2_SQRT_HZ = 2.0e-3
K_M_S3_SQRT_HZ = 2.0e-3


def _imu_record(accel, samples, seed, path='tilted.csv'):
    """Return a static IMU record: gyro white noise, ``accel`` under tilted gravity."""
    config = replace(SensorConfig.ideal().with_terms(electronics_noise=True),
                     electronics_noise_rad_s_sqrt_hz=1e-4, accelerometer=accel)
    batch = ImuModel(config, RATE_HZ, np.random.default_rng(seed)).run(
        np.zeros((samples, 3)), 25.0, G * TILT)
    return Record.from_arrays(np.arange(samples) / RATE_HZ, batch.gyro_rad_s,
                              accel_m_s2=batch.accel_m_s2, path=path)


@pytest.fixture(scope='module')
def walk_record():
    """30 min at 100 Hz: accelerometer N 2e-3 m/s^2/sqrt(Hz), K 2e-3 m/s^3/sqrt(Hz), tilted."""
    accel = AccelConfig(terms=AccelTerms(
        **{name: name in ('electronics_noise', 'random_walk') for name in AccelTerms.names()}),
        electronics_noise_m_s2_sqrt_hz=N_M_S2_SQRT_HZ, random_walk_m_s3_sqrt_hz=K_M_S3_SQRT_HZ)
    return _imu_record(accel, 180_000, seed=32)


def test_accelerometer_terms_are_the_gyro_fit_on_its_axes(walk_record):
    """
    N and K recovered on every axis; gravity neither fitted nor screened.

    Tolerances are five of the fit's own standard errors here (its 95 %
    intervals: N +-0.4 %, K +-8 %; seeds 32-34 gave N within 0.5 % and K
    within 9 %): N to 1 %, K to 20 %, and K resolved.
    """
    cal = noise.calibrate_noise(walk_record, sense=ACCEL)
    assert cal.sense is ACCEL and [a.axis for a in cal.axes] == ['x', 'y', 'z']
    for item in cal.axes:
        fit = item.fit
        assert fit.value('arw') == pytest.approx(N_M_S2_SQRT_HZ, rel=0.01), item.axis
        assert fit.value('rrw') == pytest.approx(K_M_S3_SQRT_HZ, rel=0.20), item.axis
        assert fit.resolved('rrw')
        assert item.set_aside['count'] == 0          # gravity is a level, not an outlier
        assert item.column == f'accel_{item.axis}_m_s2'
    # the same function on the same samples, whichever channel they came from
    as_gyro = noise.calibrate_noise(Record.from_arrays(
        walk_record.time_s, walk_record.accel.values, path='tilted.csv'))
    for a, b in zip(cal.axes, as_gyro.axes):
        assert a.fit.value('arw') == b.fit.value('arw')
        assert a.fit.value('rrw') == b.fit.value('rrw')
    assert cal.gravity_m_s2 is not None and cal.notes == ()


def test_turn_on_bias_is_the_mean_less_gravity_along_its_direction():
    """The bias along gravity is recovered; across gravity one attitude cannot tell it."""
    accel = AccelConfig(terms=AccelTerms(
        **{name: name in ('electronics_noise', 'turn_on_bias') for name in AccelTerms.names()}),
        electronics_noise_m_s2_sqrt_hz=N_M_S2_SQRT_HZ, turn_on_bias_m_s2=tuple(BIAS_M_S2))
    record = _imu_record(accel, 60_000, seed=5)
    cal = noise.calibrate_noise(record, sense=ACCEL)
    along = float(BIAS_M_S2 @ TILT)
    got = np.array([cal.turn_on_bias(item) for item in cal.axes])
    # noise of a mean of 60k samples: N sqrt(f) / sqrt(n) = 8e-5 m/s^2
    np.testing.assert_allclose(got, along * TILT, atol=5e-4)
    np.testing.assert_allclose(cal.gravity_m_s2, G * TILT + (BIAS_M_S2 - along * TILT),
                               atol=5e-4)


@needs_mpu
def test_mpu6050_accelerometer_fit_agrees_with_allantools_at_one_second():
    """Item 5: the fit's Allan deviation at tau 1 s within 10 % of allantools' per axis."""
    record = load_record(MPU)
    cal = noise.calibrate_noise(record, sense=ACCEL)
    for item in cal.axes:
        samples = record.accel_axis(item.axis)[0]
        _, reference, _, _ = allantools.oadev(samples, rate=RATE_HZ, data_type='freq',
                                              taus=[1.0])
        assert item.fit.adev([1.0])[0] == pytest.approx(reference[0], rel=0.10), item.axis
        # the datasheet's 400 ug/sqrt(Hz) and the log agree in magnitude
        assert 250.0 < ACCEL.show('arw', item.fit.value('arw')) < 500.0


@pytest.fixture(scope='module')
def mpu():
    """Return the MPU-6050 log's gyro and accelerometer calibrations."""
    if not os.path.isfile(MPU):
        pytest.skip('shared real data not present')
    record = load_record(MPU)
    return noise.calibrate_noise(record), noise.calibrate_noise(record, sense=ACCEL)


def test_mpu6050_twin_round_trip_carries_the_accelerometer(mpu, tmp_path):
    """
    The written preset, simulated, matches the log's accelerometer ADEV as the gyro twin must.

    The gyro twin's bands: at every octave tau within 10 % or inside the
    log's own 95 % interval (``NoiseCheck.consistent``).
    """
    cal, accel = mpu
    text = export_noise.write_noise(cal, 'preset', accel=accel_figures(accel))
    path = tmp_path / 'mpu.yaml'
    path.write_text(text)
    config = load_sensor_config(str(path))
    acc = config.accelerometer
    assert not acc.terms.mechanical_noise and acc.terms.electronics_noise
    assert acc.terms.random_walk and acc.terms.turn_on_bias and acc.terms.quantization
    for i, item in enumerate(accel.axes):
        assert acc.electronics_noise_m_s2_sqrt_hz[i] == pytest.approx(item.fit.value('arw'),
                                                                      rel=0.02)
        assert acc.turn_on_bias_m_s2[i] == pytest.approx(accel.turn_on_bias(item), abs=1e-6)
    assert acc.lsb_m_s2[0] == pytest.approx(accel.lsb, rel=1e-5)
    check = twin.check_noise(cal, config, seeds=8, accel=accel)
    assert check.accel is not None
    for axis, ratio in check.accel.ratio.items():
        assert check.accel.consistent[axis], (axis, ratio)
        assert np.all(np.abs(ratio[:5]) <= 0.10), (axis, ratio)     # 0.1 .. 1.6 s
    assert all(check.consistent.values())


def _cli(args, capsys):
    code = cli.main(args)
    out = capsys.readouterr()
    assert 'Traceback' not in out.err
    return code, out


@needs_mpu
def test_a_log_in_g_is_refused_naming_accel_scale_which_takes_it(tmp_path, capsys):
    cols = csvio.read_csv(MPU, required=('time_s',))
    in_g = {k: (v / G if k.startswith('accel_') else v) for k, v in cols.items()}
    path = tmp_path / 'mpu_g.csv'
    csvio.write_csv(str(path), in_g)
    out = tmp_path / 'imu.yaml'
    code, got = _cli(['calibrate', 'noise', str(path), '--format', 'kalibr',
                      '-o', str(out), '--overwrite'],
                     capsys)
    lines = got.err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and not out.exists()
    assert 'look like g, not m/s^2' in lines[0] and '--accel-scale 9.80665' in lines[0]
    code, got = _cli(['calibrate', 'noise', str(path), '--format', 'kalibr',
                      '-o', str(out), '--overwrite',
                      '--accel-scale', '9.80665'], capsys)
    assert code == 0
    assert 'the logged accelerometer was multiplied by 9.80665 first (--accel-scale)' in got.err
    scaled = yaml.safe_load(out.read_text())
    code, _ = _cli(['calibrate', 'noise', MPU, '--format', 'kalibr',
                    '-o', str(out), '--overwrite'], capsys)
    assert code == 0
    direct = yaml.safe_load(out.read_text())
    for key in ('accelerometer_noise_density', 'accelerometer_random_walk'):
        assert scaled[key] == pytest.approx(direct[key], rel=1e-3)


@needs_mpu
def test_magnitude_far_from_g_is_noted_and_the_user_figures_override(tmp_path, capsys):
    out = tmp_path / 'imu.yaml'
    code, got = _cli(['calibrate', 'noise', MPU, '--format', 'kalibr',
                      '-o', str(out), '--overwrite',
                      '--accel-scale', '0.5'], capsys)
    assert code == 0 and 'from g = 9.80665: is the log static' in got.err
    assert 'from g = 9.80665: is the log static' in out.read_text()
    code, got = _cli(['calibrate', 'noise', MPU, '--format', 'kalibr',
                      '-o', str(out), '--overwrite',
                      '--accel-noise-density', '2e-3', '--accel-random-walk', '3e-3'], capsys)
    assert code == 0
    text = out.read_text()
    doc = yaml.safe_load(text)
    assert doc['accelerometer_noise_density'] == 2e-3
    assert doc['accelerometer_random_walk'] == 3e-3
    assert ('accelerometer_noise_density: 0.002   # m/s^2/sqrt(Hz); given by the user '
            "(--accel-noise-density), in place of the log's 0.00452172") in text
    assert '# Accelerometer written: the figures given by the user (not inflated)' in text
    assert '# Axis z (accel_z_m_s2):' in text                   # the log's fit, stated


@needs_mpu
def test_rostopic_and_vins_from_the_log(tmp_path, capsys):
    out = tmp_path / 'imu.yaml'
    code, _ = _cli(['calibrate', 'noise', MPU, '--format', 'kalibr',
                    '-o', str(out), '--overwrite'], capsys)
    assert yaml.safe_load(out.read_text())['rostopic'] == '/imu0'
    code, _ = _cli(['calibrate', 'noise', MPU, '--format', 'openvins',
                    '-o', str(out), '--overwrite',
                    '--rostopic', '/mpu/imu'], capsys)
    assert code == 0 and 'rostopic: /mpu/imu' in out.read_text()
    code, got = _cli(['calibrate', 'noise', MPU, '--format', 'kalibr',
                      '-o', str(out), '--overwrite',
                      '--rostopic', 'two words'], capsys)
    assert code == 2 and "--rostopic 'two words' is not a topic name" in got.err
    code, got = _cli(['calibrate', 'noise', MPU, '--format', 'vins',
                      '-o', str(out), '--overwrite'], capsys)
    assert code == 0                               # no longer refused: the log has them
    doc = yaml.safe_load(out.read_text())
    n_a = float(got.out.split('exported accelerometer: N_a ')[1].split()[0])
    assert doc['acc_n'] == pytest.approx(n_a * np.sqrt(RATE_HZ), rel=1e-3)


def test_an_accelerometer_reading_zero_throughout_is_taken_as_absent(walk_record, tmp_path,
                                                                     capsys):
    """A gyro-only driver's placeholder (0, 0, 0): the gyro's files, a warning, no crash."""
    path = tmp_path / 'zeros.csv'
    gyro = walk_record.gyro
    csvio.write_csv(str(path), {'time_s': walk_record.time_s[:30_000],
                                **{f'gyro_{a}_rad_s': gyro[a][:30_000] for a in 'xyz'},
                                **{f'accel_{a}_m_s2': np.zeros(30_000) for a in 'xyz'}})
    out = tmp_path / 'imu.yaml'
    code, got = _cli(['calibrate', 'noise', str(path), '--format', 'kalibr',
                      '-o', str(out), '--overwrite'],
                     capsys)
    assert code == 0 and 'reads exactly 0 throughout' in got.err
    assert 'accelerometer_noise_density:' not in out.read_text().replace('# ', '#')
    code, got = _cli(['calibrate', 'noise', str(path), '--format', 'vins',
                      '-o', str(out), '--overwrite'],
                     capsys)
    assert code == 2 and '--format vins needs --accel-noise-density' in got.err


def test_a_gyro_only_preset_writes_the_accelerometer_figures_given(walk_record, tmp_path,
                                                                   capsys):
    """
    ``--format preset`` of a gyro-only log writes the figures given as its accelerometer.

    Before, the console said ``exported accelerometer: N_a 0.002 ... (given by
    the user)`` and the preset held no accelerometer: the twin ran the paper
    device's (6.5 ug/sqrt(Hz)). Without figures, the file's first line says so.
    """
    path = tmp_path / 'gyro_only.csv'
    gyro = walk_record.gyro
    csvio.write_csv(str(path), {'time_s': walk_record.time_s[:30_000],
                                **{f'gyro_{a}_rad_s': gyro[a][:30_000] for a in 'xyz'}})
    out = tmp_path / 'twin.yaml'
    code, got = _cli(['calibrate', 'noise', str(path), '--format', 'preset', '-o', str(out),
                      '--accel-noise-density', '0.002', '--accel-random-walk', '1e-4'], capsys)
    assert code == 0 and 'exported accelerometer: N_a 0.002 ' in got.out
    assert 'figures given by the user' in out.read_text().splitlines()[0]
    accel = load_sensor_config(str(out)).accelerometer
    assert accel.electronics_noise_m_s2_sqrt_hz == (0.002,) * 3
    assert accel.random_walk_m_s3_sqrt_hz == (1e-4,) * 3
    assert sorted(n for n in AccelTerms.names() if getattr(accel.terms, n)) == [
        'electronics_noise', 'random_walk']
    sim = tmp_path / 'sim.csv'
    assert cli.main(['simulate', '--config', str(out), '--duration-s', '60', '--rate-hz',
                     '100', '--seed', '3', '--out', str(sim)]) == 0
    values = csvio.read_csv(str(sim), required=('accel_x_m_s2',))
    for axis in 'xyz':                  # white: 0.002 sqrt(100 Hz) per sample; the walk adds 0.1 %
        spread = np.std(np.diff(values[f'accel_{axis}_m_s2'])) / np.sqrt(2.0)
        assert spread == pytest.approx(0.02, rel=0.03)
    code, got = _cli(['calibrate', 'noise', str(path), '--format', 'preset', '-o', str(out),
                      '--overwrite'], capsys)
    assert code == 0
    assert "the paper device's accelerometer" in out.read_text().splitlines()[0]


def test_a_bag_gives_its_imu_topic_and_linear_acceleration(tmp_path, capsys):
    """The consumer preset (accelerometer 400 ug/sqrt(Hz)) in a simulated bag."""
    bag = str(tmp_path / 'bag')
    simulate.write_record(bag, 'consumer', 'static', 120.0, RATE_HZ, seed=7,
                          start_time_ns=1_700_000_000_000_000_000)
    out = tmp_path / 'imu.yaml'
    code, got = _cli(['calibrate', 'noise', bag, '--format', 'kalibr',
                      '-o', str(out), '--overwrite'], capsys)
    assert code == 0, got.err
    doc = yaml.safe_load(out.read_text())
    assert doc['rostopic'] == '/imu/data_raw'
    assert doc['accelerometer_noise_density'] == pytest.approx(
        float(units.ug_sqrt_hz_to_m_s2_sqrt_hz(400.0)), rel=0.05)
    assert '(/imu/data_raw linear_acceleration.x)' in out.read_text()


# --- thermal -----------------------------------------------------------------

ACCEL_TC_M_S2_K = (4e-3, -3e-3, 6e-3)


@pytest.fixture(scope='module')
def accel_thermal_log(tmp_path_factory):
    """Ramp a static part 5 -> 45 C over 40 min at 50 Hz: accelerometer tempco, gravity on z."""
    accel = AccelConfig(terms=AccelTerms(
        **{n: n in ('electronics_noise', 'bias_temperature', 'turn_on_bias')
           for n in AccelTerms.names()}),
        electronics_noise_m_s2_sqrt_hz=1e-3, bias_temp_coeff_m_s2_k=ACCEL_TC_M_S2_K,
        turn_on_bias_m_s2=(0.02, -0.01, 0.05))
    config = replace(SensorConfig.ideal(device={'preset': 'paper', 'calibration_temp_c': 25.0})
                     .with_terms(electronics_noise=True, bias_temperature=True),
                     electronics_noise_rad_s_sqrt_hz=1e-4,
                     bias_temp_coeff_rad_s_k=1e-4, accelerometer=accel)
    zero = (0.0, 0.0, 0.0)
    ramp = profiles.ScriptedProfile('ramp', (profiles.Segment(2400.0, zero, zero, 5.0, 45.0),))
    path = str(tmp_path_factory.mktemp('thermal') / 'ramp.csv')
    simulate.write_record(path, config, ramp, 2400.0, 50.0, seed=4)
    return path


def _accel_fit(path):
    records = [load_record(path, required=thermal.REQUIRED_COLUMNS)]
    log = thermal.accel_thermal_log(records)
    return log, thermal.fit_thermal(log)


def test_accelerometer_thermal_fit_and_px4_ardupilot_files(accel_thermal_log):
    """PX4's TC_A0_* and ArduPilot's INS_TCAL1_ACC*, by their own formulas, give the fit."""
    gyro_log = thermal.thermal_log([load_record(accel_thermal_log,
                                                required=thermal.REQUIRED_COLUMNS)])
    gyro = thermal.fit_thermal(gyro_log)
    _, accel = _accel_fit(accel_thermal_log)
    assert accel.sense is ACCEL
    for i, axis in enumerate('xyz'):
        assert accel.coefficients[axis][1] == pytest.approx(ACCEL_TC_M_S2_K[i],
                                                            abs=4 * accel.errors[axis][1])
    text = export_thermal.write_thermal(gyro, 'px4', accel=accel, px4_accel_id=1310988)
    params = export_thermal.read_px4_params(text)
    assert params['TC_A_ENABLE'] == 1 and params['TC_A0_ID'] == 1310988
    assert params['TC_A0_TREF'] == pytest.approx(accel.temp_ref_c)
    temps = np.linspace(accel.temp_min_c - 5.0, accel.temp_max_c + 5.0, 31)
    for axis in 'xyz':
        # PX4's offset is the fit less the axis's median (process_sensor_caldata.py)
        np.testing.assert_allclose(thermal.px4_offset(params, axis, temps, 'TC_A0'),
                                   accel.bias(axis, temps) - accel.median[axis],
                                   rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(thermal.px4_offset(params, axis, temps),
                                   gyro.bias(axis, temps), rtol=1e-7, atol=1e-10)
    # ArduPilot: p(T - 35) - p(T_cal - 35), p without its constant, times 1e-6
    parm = dict(line.split() for line in export_thermal.write_thermal(
        gyro, 'ardupilot', accel=accel).splitlines() if line and not line.startswith('#'))
    cal_temp = 20.0
    for axis in 'xyz':
        coeffs = [float(parm[f'INS_TCAL1_ACC{k}_{axis.upper()}']) * 1e-6 for k in (1, 2, 3)]
        t = np.clip(temps, float(parm['INS_TCAL1_TMIN']), float(parm['INS_TCAL1_TMAX']))

        def poly(d):
            return sum(c * d ** (k + 1) for k, c in enumerate(coeffs))
        expected = accel.bias(axis, t, clamp=False) - accel.bias(axis, cal_temp, clamp=False)
        np.testing.assert_allclose(poly(t - 35.0) - poly(cal_temp - 35.0), expected,
                                   rtol=1e-6, atol=1e-9)


def test_accelerometer_thermal_preset_and_what_a_gyro_log_says(accel_thermal_log, tmp_path,
                                                               capsys):
    out = tmp_path / 'preset.yaml'
    code, got = _cli(['calibrate', 'thermal', accel_thermal_log, '--format', 'preset', '-o',
                      str(out)], capsys)
    assert code == 0, got.err
    config = load_sensor_config(str(out))
    acc = config.accelerometer
    assert acc.terms.bias_temperature and not acc.terms.mechanical_noise
    np.testing.assert_allclose(acc.bias_temp_coeff_m_s2_k, ACCEL_TC_M_S2_K, atol=2e-4)
    # the turn-on bias at calibration_temp_c less gravity along the mean (nearly z): the
    # bias along it is z's; x's and y's, across gravity, read as a tilt (taken as none)
    t_cal = config.device[0].calibration_temp_c
    expected = np.array([0.0, 0.0, 0.05 + ACCEL_TC_M_S2_K[2] * (t_cal - 25.0)])
    np.testing.assert_allclose(acc.turn_on_bias_m_s2, expected, atol=2e-3)
    assert acc.electronics_noise_m_s2_sqrt_hz[0] == pytest.approx(1e-3, rel=0.05)
    params = tmp_path / 'p.params'
    code, got = _cli(['calibrate', 'thermal', accel_thermal_log, '--format', 'px4', '-o',
                      str(params)], capsys)
    assert code == 0 and 'TC_A0_ID is not in the PX4 file' in got.err
    assert '\tTC_A0_X1_2\t' in params.read_text()
    # the same log in g is refused before any fit, naming --accel-scale, which takes it
    cols = csvio.read_csv(accel_thermal_log, required=('time_s',))
    in_g = tmp_path / 'in_g.csv'
    csvio.write_csv(str(in_g), {k: (v / G if k.startswith('accel_') else v)
                                for k, v in cols.items()})
    code, got = _cli(['calibrate', 'thermal', str(in_g), '--format', 'px4', '-o',
                      str(tmp_path / 'g.params')], capsys)
    assert code == 2 and got.out == '' and '--accel-scale 9.80665' in got.err
    code, got = _cli(['calibrate', 'thermal', str(in_g), '--format', 'px4', '-o',
                      str(tmp_path / 'g.params'), '--accel-scale', str(G)], capsys)
    scaled = export_thermal.read_px4_params((tmp_path / 'g.params').read_text())
    direct = export_thermal.read_px4_params(params.read_text())
    assert code == 0 and scaled['TC_A0_X1_2'] == pytest.approx(direct['TC_A0_X1_2'], rel=1e-3)


@needs_real
def test_a_gyro_only_thermal_log_says_why_the_accelerometer_is_not_written(tmp_path, capsys):
    folder = os.path.join(REAL, 'lsm6dsm_thermal_chamber')
    logs = [os.path.join(folder, f'lsm6dsm_tvc_{a}.csv') for a in 'xyz']
    for fmt, marker in (('px4', 'TC_A* (accelerometer): not measured by this gyro log'),
                        ('ardupilot', 'INS_TCAL1_ACC* (accelerometer): not measured by this '),
                        ('preset', 'Accelerometer: not measured by this gyro log')):
        out = tmp_path / f'lsm.{fmt}'
        code, _ = _cli(['calibrate', 'thermal', *logs, '--format', fmt,
                        '-o', str(out), '--overwrite'], capsys)
        text = out.read_text()
        assert code == 0 and marker in text
        assert 'TC_A0' not in text and 'INS_TCAL1_ACC1' not in text


# --- diagnose --write-config --noise -----------------------------------------

@needs_mpu
def test_diagnose_noise_carries_the_accelerometer_of_a_static_record(tmp_path, capsys):
    out = tmp_path / 'part.yaml'
    code, got = _cli(['diagnose', MPU, '--axis', 'y', '--static', '--write-config', str(out),
                      '--noise'], capsys)
    assert code == 0, got.err
    text = out.read_text()
    assert "# Accelerometer (--noise): IEEE Std 952 fit of calibrate noise on the record's" in text
    acc = load_sensor_config(str(out)).accelerometer
    cal = noise.calibrate_noise(load_record(MPU), sense=ACCEL)
    fields = export_noise.accel_twin_noise(accel_figures(cal))
    for i, axis in enumerate('xyz'):
        assert acc.electronics_noise_m_s2_sqrt_hz[i] == pytest.approx(
            fields.per_axis[axis]['electronics_noise_m_s2_sqrt_hz'], rel=1e-9)
        assert acc.turn_on_bias_m_s2[i] == pytest.approx(
            fields.per_axis[axis]['turn_on_bias_m_s2'], rel=1e-9)
    assert not acc.terms.mechanical_noise and acc.terms.random_walk


def test_a_moving_record_gives_no_accelerometer_noise(walk_record):
    time_s = walk_record.time_s
    data = MeasuredData(time_s=time_s, rate_cmd_rad_s=0.5 * np.sin(time_s),
                        temp_c=None, gyro_rad_s=walk_record.gyro['x'],
                        accel_m_s2=walk_record.accel.values, source='moving.csv')
    got = record_noise.identify_accel(data, 6.0)
    assert got.fields is None and 'the record is not static' in got.why
    assert got.comment_lines()[0].startswith('Accelerometer (--noise): not identified:')
    still = replace(data, rate_cmd_rad_s=np.zeros(len(time_s)))
    got = record_noise.identify_accel(still, 6.0)
    assert got.fields is not None and set(got.fields.per_axis) == {'x', 'y', 'z'}
    assert record_noise.identify_accel(replace(still, accel_m_s2=None), 6.0) is None


def test_config_from_mapping_reads_the_preset_accelerometer(mpu):
    """The preset's ``accelerometer:`` reads back as written (no rounding lost)."""
    cal, accel = mpu
    text = export_noise.write_noise(cal, 'preset', 2.0, accel=accel_figures(accel, 2.0))
    config = config_from_mapping(yaml.safe_load(text))
    fields = export_noise.accel_twin_noise(accel_figures(accel, 2.0), 2.0)
    got = config.accelerometer.electronics_noise_m_s2_sqrt_hz[2]
    assert got == pytest.approx(fields.per_axis['z']['electronics_noise_m_s2_sqrt_hz'],
                                rel=1e-5)
    assert '# Accelerometer written: N_a' in text and 'inflation factor 2' in text


@needs_mpu
def test_accelerometer_axes_the_log_lacks_get_no_turn_on_bias(mpu):
    """As the gyro's twin: a missing axis copies the noise, not the measured bias; said."""
    cal, _ = mpu
    record = load_record(MPU)
    only_z = noise.calibrate_noise(record, axes=('z',), sense=ACCEL)
    fields = export_noise.accel_twin_noise(accel_figures(only_z))
    assert set(fields.per_axis) == {'z'}
    measured = fields.per_axis['z']
    assert measured['turn_on_bias_m_s2'] != 0.0      # the z axis's own bias is measured
    acc = export_noise.accel_config(fields)
    assert acc.turn_on_bias_m_s2[:2] == (0.0, 0.0)
    assert acc.turn_on_bias_m_s2[2] == pytest.approx(measured['turn_on_bias_m_s2'], rel=1e-5)
    for key in ('electronics_noise_m_s2_sqrt_hz', 'bias_instability_m_s2',
                'random_walk_m_s3_sqrt_hz'):
        values = getattr(acc, key)
        assert values[0] == values[1] == values[2] == pytest.approx(measured[key], rel=1e-5)
    lines = export_noise.accel_twin_lines(accel_figures(only_z), fields)
    assert "Accelerometer axes x, y copy axis z's noise (not in the log); their turn-on bias " \
        'is 0' in lines[-1]
    text = export_noise.write_noise(cal, 'preset', accel=accel_figures(only_z))
    assert "# Accelerometer axes x, y copy axis z's noise" in text
    written = config_from_mapping(yaml.safe_load(text)).accelerometer
    assert written.turn_on_bias_m_s2[:2] == (0.0, 0.0)
