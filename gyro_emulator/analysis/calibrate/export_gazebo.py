"""
The gz-sensors ``<imu>`` noise block of a noise calibration (``calibrate noise --format gazebo``).

gz-sensors (``GaussianNoiseModel.cc``) adds ``stddev`` per sample at the
sensor's ``<update_rate>`` f (stddev = N sqrt(f): the exact discretisation of
white noise of two-sided density N) and drives a dynamic bias as a
Gauss-Markov process: b[n] = phi b[n-1] + w, phi = exp(-dt/T), steady
variance sigma_b^2 T / 2, a random walk of intensity sigma_b for tau << T.
It has no flicker term: :func:`gauss_markov_match` fits the pair (sigma_b,
T) to the B and K part of each axis's Allan curve.

Both vectors are written per axis. The accelerometer (``<linear_acceleration>``)
is fitted as the gyro is when the log has one (its own N_a, B_a, K_a per
axis); the figures a user gives are written on every axis, with K_a as
sigma_b at :data:`ACCEL_CORRELATION_TIME_S`; without either ``FILL_IN``
stands where sdformat parses a double, so that it stops by name
(docs/calibrate.md).
"""

from gyro_emulator import units
from gyro_emulator.analysis.calibrate.accel_figures import ACCEL_OPTIONS
from gyro_emulator.analysis.calibrate.noise import axis_values, export_noise
from gyro_emulator.analysis.calibrate.provenance import (as_comments, CONTINUOUS, MARKER,
                                                         noise_lines, NOT_MEASURED)
from gyro_emulator.sensor import noise as sensor_noise
from gyro_emulator.units import AXES
from gyro_emulator.yaml_text import float_text as _num
import numpy as np
from scipy import optimize

#: gz-sensors' dynamic bias is Gauss-Markov: the accelerometer's random walk K_a given
#: by the user is written as sigma_b = K_a with this correlation time (a walk of K_a for
#: tau << T; the value sdformat's noise.sdf calls typical), s.
ACCEL_CORRELATION_TIME_S = 3600.0


def gauss_markov_match(fit, taus_s):
    """
    Gauss-Markov bias (sigma_b, T) closest to the fit's B and K part over ``taus_s``.

    gz-sensors drives its dynamic bias as b[n] = phi b[n-1] + w, phi =
    exp(-dt/T), var(w) = sigma_b^2 T / 2 (1 - phi^2): steady variance
    sigma_b^2 T / 2, and a random walk of intensity sigma_b for tau << T.
    Least squares on the log of the Allan variance (white part included on
    both sides). Returns (sigma_b in the fit's unit per sqrt(s), T in s,
    largest relative deviation error over ``taus_s``).
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


def _gazebo_axis(item, rate, inflate, lsb, unit='rad/s/sqrt(Hz)'):
    n, _, _, _ = axis_values(item)
    fit = item.fit
    taus = fit.taus_s
    sigma_b, corr, error = gauss_markov_match(fit, taus)
    kind = 'gaussian_quantized' if lsb > 0.0 else 'gaussian'
    lines = [f'    <{item.axis}>',
             f'      <!-- N {_num(n)} {unit} x sqrt({rate:g} Hz); Gauss-Markov bias '
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


def _per_axis(calibration, rate, inflate):
    """Every axis of a calibration as :func:`_gazebo_axis` writes it (a missing one copied)."""
    axes = {a.axis: a for a in calibration.axes}
    body = []
    for name in AXES:
        item = axes.get(name) or calibration.axes[0]
        if name not in axes:
            body.append(f'    <!-- axis {name}: copied from axis {item.axis} (not in the '
                        'calibration) -->')
        body += _gazebo_axis(item, rate, inflate, calibration.lsb,
                             calibration.sense.si_units['arw'])
    return body


def _gazebo_accel(rate, accel, inflate):
    """``<linear_acceleration>``: the log's per axis, the figures given, or FILL_IN."""
    if accel is not None and not accel.given:
        return (['  <linear_acceleration>'] + _per_axis(accel.calibration, rate, inflate)
                + ['  </linear_acceleration>'])
    if accel is None:
        # no double hyphen inside an XML comment: the options are named in the header
        note = (f'      <!-- {NOT_MEASURED} (or give the accelerometer figures, see the top). '
                'Left as is, sdformat reports "Invalid argument. Unable to set value [FILL_IN] '
                'for key[stddev]." -->')
        stddev = sigma_b = MARKER
    else:
        note = (f'      <!-- {accel.source("noise_density")}: N_a '
                f'{_num(accel.noise_density_m_s2_sqrt_hz)} m/s^2/sqrt(Hz) x sqrt({rate:g} Hz); '
                f'K_a {_num(accel.random_walk_m_s3_sqrt_hz)} m/s^3/sqrt(Hz) as a Gauss-Markov '
                f'bias of correlation time {ACCEL_CORRELATION_TIME_S:g} s -->')
        stddev = _num(units.density_to_sample_sigma(accel.noise_density_m_s2_sqrt_hz, rate))
        sigma_b = _num(accel.random_walk_m_s3_sqrt_hz)
    lines = ['  <linear_acceleration>']
    for name in AXES:
        lines += [f'    <{name}>', note, '      <noise type="gaussian">',
                  '        <mean>0.0</mean>', f'        <stddev>{stddev}</stddev>',
                  '        <bias_mean>0.0</bias_mean>', '        <bias_stddev>0.0</bias_stddev>',
                  f'        <dynamic_bias_stddev>{sigma_b}</dynamic_bias_stddev>',
                  '        <dynamic_bias_correlation_time>'
                  f'{_num(ACCEL_CORRELATION_TIME_S)}</dynamic_bias_correlation_time>',
                  '      </noise>', f'    </{name}>']
    return lines + ['  </linear_acceleration>']


def gazebo(calibration, inflate=1.0, rate_hz=None, accel=None, topic=None):
    """
    Write a gz-sensors ``<imu>`` block: per-axis ``<noise>`` of both vectors (module docstring).

    ``<linear_acceleration>`` holds the log's accelerometer, the figures
    given, or ``FILL_IN`` where sdformat parses a double: it then reports
    "Unable to set value [FILL_IN] for key[stddev]" (src/Param.cc) instead
    of simulating a noise-free accelerometer, as a block without it would.
    ``topic`` is not used (an SDF sensor names no topic here).
    """
    export_noise(calibration, inflate)
    rate = float(calibration.rate_hz if rate_hz is None else rate_hz)
    convention = (CONTINUOUS + f' gz-sensors adds stddev per sample at <update_rate> = '
                  f'{rate:g} Hz (stddev = N sqrt(f)); its dynamic bias is a Gauss-Markov '
                  'process driven by dynamic_bias_stddev (steady sigma_b sqrt(T/2), a random '
                  'walk of K = sigma_b for tau << T). gz-sensors has no flicker (B) term: the '
                  'Gauss-Markov pair is fitted to the B and K part of the Allan curve.')
    header = as_comments(['gz-sensors imu element, a block, not a whole file: paste it into '
                          'your <sensor type="imu"> (SDF 1.9 to 1.12 element names).']
                         + noise_lines(calibration, None, 'gazebo', convention, accel)
                         + [f'Inflation factor: {inflate:g}']
                         + ([] if accel else [f'Accelerometer: {NOT_MEASURED}, or give '
                                              f'{ACCEL_OPTIONS}.']), style='xml')
    body = (['<imu>', '  <angular_velocity>'] + _per_axis(calibration, rate, inflate)
            + ['  </angular_velocity>'] + _gazebo_accel(rate, accel, inflate) + ['</imu>'])
    return header + '\n'.join(body) + '\n'
