"""
Noise exports for Kalibr, OpenVINS, VINS-Fusion, ORB-SLAM3, Gazebo and this emulator.

Each writer returns the text of one file, with the provenance comments of
:mod:`.provenance` and the continuous-to-discrete convention its target
documents. N (angle random walk, two-sided white-noise density) and K (rate
random walk) are IEEE Std 952 continuous-time coefficients; sampled at
f_s = 1 / dt the white noise has per-sample sigma N sqrt(f_s) and the bias
walk per-sample increment K / sqrt(f_s) (Kalibr wiki "IMU Noise Model"):

=========  =====================================  ======================================
target     gyro white noise                       gyro bias walk
=========  =====================================  ======================================
kalibr     gyroscope_noise_density = N            gyroscope_random_walk = K
           rad/s/sqrt(Hz), continuous             rad/s^2/sqrt(Hz), continuous
openvins   same keys and units (kalibr_imu_chain.yaml)
vins       gyr_n = N sqrt(f_s), rad/s per sample  gyr_w = K sqrt(f_s) (its pre-integration
           (integration_base.h propagates them    adds (gyr_w dt)^2 per sample)
           as per-sample standard deviations)
orbslam3   IMU.NoiseGyro = N, continuous          IMU.GyroWalk = K, continuous (it
           (ORB-SLAM3 multiplies by sqrt(f_s))    divides by sqrt(f_s))
gazebo     stddev = N sqrt(f_s), per sample       dynamic_bias_stddev sigma_b with
                                                  dynamic_bias_correlation_time T: a
                                                  Gauss-Markov bias driven by sigma_b
                                                  (gz-sensors GaussianNoiseModel), fitted
                                                  to the B and K part of the curve
preset     electronics_arw_deg_sqrt_h, bias_instability_deg_h, rate_random_walk_deg_h_sqrt_h
=========  =====================================  ======================================

Accelerometer fields are written as ``FILL_IN`` with a comment: this is a
gyro log. The YAML files (kalibr, openvins, preset) are written by PyYAML,
numbers to 6 significant digits, with the comments added around it; the
VINS-Fusion and ORB-SLAM3 blocks are pasted into OpenCV ``FileStorage``
files and stay written by hand.
"""

from gyro_emulator import units
from gyro_emulator.analysis.calibrate.noise import axis_values, export_noise
from gyro_emulator.analysis.calibrate.provenance import (as_comments, MARKER, noise_lines,
                                                         NOT_MEASURED)
from gyro_emulator.analysis.calibrate.twin import emulator_fit, PER_DECADE
from gyro_emulator.analysis.calibrate.yaml_text import dump as dump_yaml, Figure, Flow, Quoted
from gyro_emulator.sensor import noise as sensor_noise
from gyro_emulator.sensor.config import ErrorTerms
import numpy as np
from scipy import optimize

FORMATS = ('kalibr', 'openvins', 'vins', 'orbslam3', 'gazebo', 'preset')

_CONTINUOUS = ('N and K are continuous-time densities (IEEE Std 952): the sampled white noise '
               'has sigma_d = N sqrt(f), the bias walk steps K / sqrt(f) per sample at rate f.')


def _num(value):
    return f'{float(value):.6g}'


def _identity(size, scale=1.0):
    return [Flow(scale if i == j else 0.0 for j in range(size)) for i in range(size)]


def _update_rate(calibration, rate_hz):
    return float(calibration.rate_hz if rate_hz is None else rate_hz)


def _topic(calibration):
    column = calibration.axes[0].column
    return column.split(' ')[0] if ' angular_velocity' in column else None


def kalibr(calibration, inflate=1.0, rate_hz=None):
    """Kalibr ``imu.yaml`` (gyroscope_noise_density, gyroscope_random_walk; continuous)."""
    ex = export_noise(calibration, inflate)
    rate = _update_rate(calibration, rate_hz)
    convention = (_CONTINUOUS + ' Kalibr uses gyroscope_noise_density / sqrt(dt) and '
                  'gyroscope_random_walk * sqrt(dt) with dt = 1 / update_rate.')
    topic = _topic(calibration)
    text = as_comments(noise_lines(calibration, ex, 'kalibr', convention))
    bound = ' (upper bound)' if ex.rrw_is_bound else ''
    data = {'rostopic': topic or MARKER, 'update_rate': Figure(rate),
            'accelerometer_noise_density': MARKER, 'accelerometer_random_walk': MARKER,
            'gyroscope_noise_density': Figure(ex.arw_rad_s_sqrt_hz),
            'gyroscope_random_walk': Figure(ex.rrw_rad_s_sqrt_s)}
    comments = {'update_rate': 'Hz',
                'accelerometer_noise_density': f'm/s^2/sqrt(Hz); {NOT_MEASURED}',
                'accelerometer_random_walk': f'm/s^3/sqrt(Hz); {NOT_MEASURED}',
                'gyroscope_noise_density': 'rad/s/sqrt(Hz), N',
                'gyroscope_random_walk': 'rad/s^2/sqrt(Hz), K' + bound}
    if not topic:
        comments['rostopic'] = 'the IMU topic of your calibration bag'
    return text + dump_yaml(data, comments)


def openvins(calibration, inflate=1.0, rate_hz=None):
    """Write OpenVINS ``kalibr_imu_chain.yaml`` (Kalibr's keys and units, its intrinsics)."""
    ex = export_noise(calibration, inflate)
    rate = _update_rate(calibration, rate_hz)
    convention = (_CONTINUOUS + ' OpenVINS reads the Kalibr keys in the same continuous '
                  'units and discretises with the IMU sample period.')
    topic = _topic(calibration)
    bound = ' (upper bound)' if ex.rrw_is_bound else ''
    imu = {'T_i_b': _identity(4),
           'accelerometer_noise_density': MARKER, 'accelerometer_random_walk': MARKER,
           'gyroscope_noise_density': Figure(ex.arw_rad_s_sqrt_hz),
           'gyroscope_random_walk': Figure(ex.rrw_rad_s_sqrt_s),
           'rostopic': topic or MARKER, 'time_offset': 0.0, 'update_rate': Figure(rate),
           'model': Quoted('kalibr'), 'Tw': _identity(3), 'R_IMUtoGYRO': _identity(3),
           'Ta': _identity(3), 'R_IMUtoACC': _identity(3), 'Tg': _identity(3, 0.0)}
    comments = {'accelerometer_noise_density': f'm/s^2/sqrt(Hz); {NOT_MEASURED}',
                'accelerometer_random_walk': f'm/s^3/sqrt(Hz); {NOT_MEASURED}',
                'gyroscope_noise_density': 'rad/s/sqrt(Hz), N',
                'gyroscope_random_walk': 'rad/s^2/sqrt(Hz), K' + bound}
    text = '%YAML:1.0\n' + as_comments(noise_lines(calibration, ex, 'openvins', convention))
    text += ('# Intrinsics (T_i_b, Tw, R_IMUtoGYRO, Ta, R_IMUtoACC, Tg) and time_offset are\n'
             "# OpenVINS's uncalibrated defaults (identity, zero): this log does not give them.\n"
             '\n' + dump_yaml({'imu0': imu}, comments, gap='  '))
    return text


def vins(calibration, inflate=1.0, rate_hz=None):
    """VINS-Fusion's IMU block: gyr_n and gyr_w as per-sample standard deviations."""
    ex = export_noise(calibration, inflate)
    rate = _update_rate(calibration, rate_hz)
    gyr_n = float(units.density_to_sample_sigma(ex.arw_rad_s_sqrt_hz, rate))
    gyr_w = ex.rrw_rad_s_sqrt_s * np.sqrt(rate)
    convention = (
        _CONTINUOUS + ' VINS-Fusion documents gyr_n and gyr_w as standard deviations and '
        'its pre-integration (integration_base.h) adds (gyr_n dt / 2)^2 twice and '
        '(gyr_w dt)^2 per sample: per-sample values, so gyr_n = N sqrt(f) and '
        f'gyr_w = K sqrt(f) at f = {rate:g} Hz. The continuous N = '
        f'{_num(ex.arw_rad_s_sqrt_hz)} rad/s/sqrt(Hz) and K = {_num(ex.rrw_rad_s_sqrt_s)} '
        'rad/s^2/sqrt(Hz) are what imu_utils and Kalibr-style configs enter instead.')
    text = as_comments(noise_lines(calibration, ex, 'vins', convention))
    text += ('# Paste into your VINS-Fusion config in place of its IMU parameters.\n'
             '# VINS reads a text value as 0 without an error: replace every FILL_IN.\n'
             f'acc_n: {MARKER}   # {NOT_MEASURED}\n'
             f'gyr_n: {_num(gyr_n)}   # rad/s per sample at {rate:g} Hz\n'
             f'acc_w: {MARKER}   # {NOT_MEASURED}\n'
             f'gyr_w: {_num(gyr_w)}   # K sqrt(f): per-sample sd of the bias rate at {rate:g} Hz'
             + (' (upper bound of K)' if ex.rrw_is_bound else '') + '\n')
    return text


def orbslam3(calibration, inflate=1.0, rate_hz=None):
    """ORB-SLAM3 settings: IMU.NoiseGyro and IMU.GyroWalk (continuous) and IMU.Frequency."""
    ex = export_noise(calibration, inflate)
    rate = _update_rate(calibration, rate_hz)
    convention = (_CONTINUOUS + ' ORB-SLAM3 reads IMU.NoiseGyro in rad/s/sqrt(Hz) and '
                  'IMU.GyroWalk in rad/s^2/sqrt(Hz) and builds its discrete noise as '
                  'NoiseGyro sqrt(IMU.Frequency), GyroWalk / sqrt(IMU.Frequency).')
    text = as_comments(noise_lines(calibration, ex, 'orbslam3', convention))
    text += ('# Paste into your ORB-SLAM3 settings file (which starts with %YAML:1.0).\n'
             '# ORB-SLAM3 stops with "not a real number" while a FILL_IN is left.\n'
             f'IMU.NoiseGyro: {_num(ex.arw_rad_s_sqrt_hz)}   # rad/s/sqrt(Hz)\n'
             f'IMU.NoiseAcc: {MARKER}   # m/s^2/sqrt(Hz); {NOT_MEASURED}\n'
             f'IMU.GyroWalk: {_num(ex.rrw_rad_s_sqrt_s)}   # rad/s^2/sqrt(Hz)'
             + (' (upper bound)' if ex.rrw_is_bound else '') + '\n'
             f'IMU.AccWalk: {MARKER}   # m/s^3/sqrt(Hz); {NOT_MEASURED}\n'
             f'IMU.Frequency: {_num(rate)}   # Hz\n')
    return text


def gauss_markov_match(fit, taus_s):
    """
    Gauss-Markov bias (sigma_b, T) closest to the fit's B and K part over ``taus_s``.

    gz-sensors drives its dynamic bias as b[n] = phi b[n-1] + w, phi =
    exp(-dt/T), var(w) = sigma_b^2 T / 2 (1 - phi^2): steady variance
    sigma_b^2 T / 2, and a random walk of intensity sigma_b for tau << T.
    Least squares on the log of the Allan variance (white part included on
    both sides). Returns (sigma_b in rad/s/sqrt(s), T in s, largest relative
    deviation error over ``taus_s``).
    """
    taus = np.asarray(taus_s, dtype=float)
    white = fit.arw_rad_s_sqrt_hz ** 2 / taus
    target = fit.adev(taus) ** 2

    def gm(params):
        sigma_b, corr = np.exp(params)
        return white + sensor_noise.gauss_markov_avar(sigma_b ** 2 * corr / 2.0, corr, taus)

    start_corr = max(taus[-1], 1.0)
    start_sigma = max(fit.rrw_rad_s_sqrt_s, fit.bias_instability_rad_s / np.sqrt(start_corr),
                      1e-12)
    best = None
    for corr in (start_corr / 30.0, start_corr / 3.0, start_corr, 10.0 * start_corr):
        sol = optimize.least_squares(lambda p: np.log(gm(p)) - np.log(target),
                                     np.log([start_sigma, corr]))
        if best is None or sol.cost < best.cost:
            best = sol
    sigma_b, corr = np.exp(best.x)
    error = float(np.max(np.abs(np.sqrt(gm(best.x) / target) - 1.0)))
    return float(sigma_b), float(corr), error


def _gazebo_axis(item, rate, inflate, lsb):
    n, _, _, _ = axis_values(item)
    fit = item.fit
    taus = fit.taus_s
    sigma_b, corr, error = gauss_markov_match(fit, taus)
    kind = 'gaussian_quantized' if lsb > 0.0 else 'gaussian'
    lines = [f'    <{item.axis}>',
             f'      <!-- N {_num(n)} rad/s/sqrt(Hz) x sqrt({rate:g} Hz); Gauss-Markov bias '
             f'matches the B and K part of the curve within {100 * error:.0f} % over tau '
             f'{taus[0]:.3g} .. {taus[-1]:.4g} s -->',
             f'      <noise type="{kind}">',
             '        <mean>0.0</mean>',
             f'        <stddev>{_num(units.density_to_sample_sigma(n * inflate, rate))}</stddev>',
             '        <!-- turn-on bias: one log cannot measure its run-to-run spread -->',
             '        <bias_mean>0.0</bias_mean>',
             '        <bias_stddev>0.0</bias_stddev>',
             f'        <dynamic_bias_stddev>{_num(sigma_b * inflate)}</dynamic_bias_stddev>',
             f'        <dynamic_bias_correlation_time>{_num(corr)}'
             '</dynamic_bias_correlation_time>']
    if lsb > 0.0:
        lines.append(f'        <precision>{_num(lsb)}</precision>')
    lines += ['      </noise>', f'    </{item.axis}>']
    return lines


def gazebo(calibration, inflate=1.0, rate_hz=None):
    """Write a gz-sensors ``<imu>`` block: per-axis ``<noise>`` of ``<angular_velocity>``."""
    export_noise(calibration, inflate)
    rate = _update_rate(calibration, rate_hz)
    convention = (_CONTINUOUS + f' gz-sensors adds stddev per sample at <update_rate> = '
                  f'{rate:g} Hz (stddev = N sqrt(f)); its dynamic bias is a Gauss-Markov '
                  'process driven by dynamic_bias_stddev (steady sigma_b sqrt(T/2), a random '
                  'walk of K = sigma_b for tau << T). gz-sensors has no flicker (B) term: the '
                  'Gauss-Markov pair is fitted to the B and K part of the Allan curve.')
    header = as_comments(noise_lines(calibration, None, 'gazebo', convention)
                         + [f'Inflation factor: {inflate:g}'], style='xml')
    body = ['<imu>', '  <angular_velocity>']
    axes = {a.axis: a for a in calibration.axes}
    for name in ('x', 'y', 'z'):
        item = axes.get(name) or calibration.axes[0]
        if name not in axes:
            body.append(f'    <!-- axis {name}: copied from axis {item.axis} (not in the '
                        'calibration) -->')
        body += _gazebo_axis(item, rate, inflate, calibration.lsb_rad_s)
    body += ['  </angular_velocity>',
             f'  <!-- linear_acceleration: {NOT_MEASURED}. Template:',
             '  <linear_acceleration><x><noise type="gaussian"><mean>0</mean>'
             f'<stddev>{MARKER}</stddev>',
             f'    <dynamic_bias_stddev>{MARKER}</dynamic_bias_stddev>'
             f'<dynamic_bias_correlation_time>{MARKER}</dynamic_bias_correlation_time>',
             '  </noise></x> ... y, z ... </linear_acceleration> -->', '</imu>']
    return header + '\n'.join(body) + '\n'


def flicker_band(calibration):
    """Return the flicker correlation-time band that keeps B flat over the taus used, s."""
    lo, hi = calibration.tau_range_s
    low = float(np.clip(lo / 3.0, 1e-3, 0.03))
    high = float(min(max(3.0 * hi, 1000.0), 1e6))
    return low, high


def preset(calibration, inflate=1.0, rate_hz=None):
    """
    Write this emulator's sensor YAML: the twin's N, B, K per axis, flicker band, LSB.

    The values come from :func:`~gyro_emulator.analysis.calibrate.twin.emulator_fit`
    (the emulator's own noise model fitted to the log); the IEEE Std 952
    values are in the comments. Every term the log does not measure is off.
    """
    twin = emulator_fit(calibration, flicker_band(calibration))
    axes = [twin.per_axis.get(name) or next(iter(twin.per_axis.values()))
            for name in ('x', 'y', 'z')]
    means = {a.axis: a.mean_rad_s for a in calibration.axes}
    mean = [means.get(name, next(iter(means.values()))) for name in ('x', 'y', 'z')]
    on = {'electronics_noise', 'bias_instability', 'rate_random_walk', 'turn_on_bias'}
    if calibration.lsb_rad_s > 0.0:
        on.add('quantization')
    convention = (_CONTINUOUS + ' The emulator discretises exactly at the rate given to '
                  'simulate or the node: white sigma N / sqrt(dt), walk K sqrt(dt), flicker '
                  'as Gauss-Markov terms across bias_instability_band_s.')
    lines = noise_lines(calibration, export_noise(calibration, inflate), 'preset', convention)
    lines += [f"Twin: the emulator's noise model (white + flicker over correlation times "
              f'{twin.band_s[0]:.3g} .. {twin.band_s[1]:.4g} s + rate random walk) fitted to '
              'the same Allan curves'
              + (f'; the shorter flicker band saves {twin.saving:.1f} in the weighted sum of '
                 'squares (bias correlation times end there)' if twin.saving > 0 else '')
              + '. Its N excludes the quantisation noise of the LSB, which the quantiser adds.',
              'Only the fitted terms are on: the measured N carries the whole white noise '
              '(mechanical_noise off), no output filter (the band-limited taus were left out '
              'of the fit), no temperature terms.',
              'turn_on_bias_deg_s is the mean of this run (it includes the projection of '
              "Earth's rate); its run-to-run spread is not measured.",
              f"Simulate it at the log's rate: --rate-hz {calibration.rate_hz:g}."]
    if len(twin.per_axis) < 3:
        lines.append(f'Axes {", ".join(n for n in "xyz" if n not in twin.per_axis)} copy '
                     f'axis {next(iter(twin.per_axis))} (not in the calibration).')
    data = {'device': 'paper', 'terms': {name: name in on for name in ErrorTerms.names()},
            'electronics_arw_deg_sqrt_h': Flow(
                Figure(units.rad_s_sqrt_hz_to_arw_deg_sqrt_h(v[0] * inflate)) for v in axes),
            'bias_instability_deg_h': Flow(
                Figure(units.rad_s_to_deg_h(v[1] * inflate)) for v in axes),
            'bias_instability_band_s': Flow(Figure(t) for t in twin.band_s),
            'bias_instability_per_decade': Figure(PER_DECADE),
            'rate_random_walk_deg_h_sqrt_h': Flow(
                Figure(units.rad_s_sqrt_s_to_rrw_deg_h_sqrt_h(v[2] * inflate)) for v in axes),
            'turn_on_bias_deg_s': Flow(Figure(units.rad_s_to_deg_s(m)) for m in mean)}
    if calibration.lsb_rad_s > 0.0:
        data['lsb_deg_s'] = Figure(units.rad_s_to_deg_s(calibration.lsb_rad_s))
    return as_comments(lines) + dump_yaml(data)


WRITERS = {'kalibr': kalibr, 'openvins': openvins, 'vins': vins, 'orbslam3': orbslam3,
           'gazebo': gazebo, 'preset': preset}


def write_noise(calibration, fmt, inflate=1.0, rate_hz=None):
    """Return the text of format ``fmt`` (one of :data:`FORMATS`)."""
    if fmt not in WRITERS:
        raise ValueError(f'format = {fmt!r} is not allowed: choose {", ".join(FORMATS)}')
    if rate_hz is not None and not (np.isfinite(rate_hz) and 0.0 < rate_hz <= 1e6):
        raise ValueError(f'rate_hz = {rate_hz!r} is out of range: allowed (0, 1e6] Hz')
    return WRITERS[fmt](calibration, inflate, rate_hz)
