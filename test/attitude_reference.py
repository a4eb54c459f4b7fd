"""
The tilt-and-turn scenario, its noise-only IMU and the error bounds the noise predicts.

Shared by the attitude-filter consumer tests (``test_ahrs_consumers.py``) and
``bench/attitude_filter_plot.py``.

The part: the ``consumer`` preset with only its noise terms on (white noise,
bias instability, random walk of both sensors, the gyro's turn-on bias, which
the consumer removes as known) so that what the filters show can be compared
with what the noise predicts:

* roll and pitch: an accelerometer-only tilt has, per sample and per axis,
  the error sigma_theta = sigma_a / g (small angles; sigma_a the
  accelerometer's white-noise sigma at the output rate, the published
  covariance). A filter that fuses the gyro averages several samples, so
  its RMS tilt error is at most sigma_theta; a Gaussian error of RMS
  sigma_theta exceeds 5 sigma_theta in fewer than 6e-7 of samples (the
  peak bound over a few thousand correlated samples).
* heading (no magnetometer: unobservable, it drifts as the integral of the
  gyro error about the vertical, the initial bias b(0) removed):
  Var psi(T) = N^2 T + K^2 T^3 / 3 + V_B(T) (IEEE Std 952 Annex C, the
  angle random walk and the rate random walk integrated), with N^2 = sigma_0^2
  dt (sigma_0 the white sigma without the output filter, which has unit DC
  gain) and V_B the bias-instability part computed exactly from the flicker
  model's Gauss-Markov sum: its autocovariance R(m) = 1' Phi^m P 1 (Phi the
  poles, P the stationary covariance), V_B = B^2 dt^2 sum_ij
  [R(i - j) - R(i) - R(j) + R(0)].
"""

from dataclasses import replace
import math

from gyro_emulator.physics import kinematics
from gyro_emulator.sensor import noise
from gyro_emulator.sensor.config import load_sensor_config
from gyro_emulator.sensor.imu import ImuModel
from gyro_emulator.units import STANDARD_GRAVITY_M_S2
import numpy as np

#: Output data rate of the scenario, Hz.
RATE_HZ = 100.0
#: (duration s, body rate deg/s (x, y, z)): rest, 20 deg about x, 15 deg about y,
#: a 90 deg turn about the tilted body z, -15 deg about y and -20 deg about x
#: (the turned body axes: the part ends tilted, roll 35 deg), a -90 deg turn, rest.
SEGMENTS = ((5.0, (0.0, 0.0, 0.0)), (2.0, (10.0, 0.0, 0.0)), (2.0, (0.0, 0.0, 0.0)),
            (2.0, (0.0, 7.5, 0.0)), (2.0, (0.0, 0.0, 0.0)), (6.0, (0.0, 0.0, 15.0)),
            (2.0, (0.0, 0.0, 0.0)), (2.0, (0.0, -7.5, 0.0)), (2.0, (-10.0, 0.0, 0.0)),
            (2.0, (0.0, 0.0, 0.0)), (6.0, (0.0, 0.0, -15.0)), (3.0, (0.0, 0.0, 0.0)))
#: Mahony's integral gain: its bias estimator all but off (ahrs refuses 0), the bias is known.
MAHONY_K_I = 1e-9
GYRO_NOISE = ('mechanical_noise', 'electronics_noise', 'bias_instability', 'rate_random_walk',
              'turn_on_bias', 'output_filter')
ACCEL_NOISE = ('mechanical_noise', 'electronics_noise', 'bias_instability', 'random_walk',
               'output_filter')


def noise_only_config(preset='consumer'):
    """Return the preset with only its noise terms on (module docstring)."""
    config = load_sensor_config(preset)
    terms = {name: name in GYRO_NOISE for name in type(config.terms).names()}
    accel = config.accelerometer
    accel_terms = {name: name in ACCEL_NOISE for name in type(accel.terms).names()}
    return replace(config.with_terms(**terms), accelerometer=replace(
        accel, terms=replace(accel.terms, **accel_terms)))


def scenario_rates(rate_hz=RATE_HZ):
    """Return the body rate of every sample, (N, 3) rad/s."""
    rows = []
    for duration_s, rate_deg_s in SEGMENTS:
        rows += [np.radians(rate_deg_s)] * int(round(duration_s * rate_hz))
    return np.array(rows)


def roll_pitch_yaw_deg(q_wxyz):
    """Return roll, pitch, yaw (REP 103 fixed axes), deg, of attitudes (N, 4) (w, x, y, z)."""
    w, x, y, z = np.asarray(q_wxyz, dtype=float).T
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.degrees(np.stack([roll, pitch, yaw], axis=1))


def tilt_sigma_deg(config, rate_hz=RATE_HZ):
    """Return sigma_theta = sigma_a / g per axis, deg (module docstring)."""
    model = ImuModel(config, rate_hz, np.random.default_rng(0))
    return np.degrees(model.accel_white_noise_sigma_m_s2 / STANDARD_GRAVITY_M_S2)


def _flicker_variance(config, dt_s, n):
    """V_B / B^2 of the flicker model over n samples, the first sample's bias removed, s^2."""
    plan = noise.flicker_plan(config.bias_instability_band_s, dt_s,
                              config.bias_instability_per_decade)
    cov = plan.stationary_factor @ plan.stationary_factor.T
    weight = cov.sum(axis=1)                                 # (P 1)_k
    m = np.arange(n)
    r = (weight[None, :] * plan.phi[None, :] ** m[:, None]).sum(axis=1)     # R(m)
    toeplitz = n * r[0] + 2.0 * np.sum((n - m[1:]) * r[1:])
    return dt_s ** 2 * (toeplitz - 2.0 * n * r.sum() + n * n * r[0])


def heading_sigma_deg(config, duration_s, rate_hz=RATE_HZ):
    """Return the predicted 1-sigma heading drift after ``duration_s``, deg (z axis)."""
    dt = 1.0 / rate_hz
    unfiltered = config.with_terms(output_filter=False)
    sigma0 = ImuModel(unfiltered, rate_hz, np.random.default_rng(0)).white_noise_sigma_rad_s[2]
    b = config.bias_instability_rad_s[2] if config.terms.bias_instability else 0.0
    k = config.rate_random_walk_rad_s_sqrt_s[2] if config.terms.rate_random_walk else 0.0
    n = int(round(duration_s * rate_hz))
    variance = (sigma0 ** 2 * dt * duration_s + k ** 2 * duration_s ** 3 / 3.0
                + b ** 2 * _flicker_variance(config, dt, n))
    return math.degrees(math.sqrt(variance))


def truth_attitudes(rates, rate_hz=RATE_HZ):
    """Return the true attitude of every sample, (N, 4), from level."""
    path, _ = kinematics.propagate(kinematics.LEVEL_WXYZ, rates, 1.0 / rate_hz)
    return path


def run_filters(gyro_rad_s, accel_m_s2, rate_hz=RATE_HZ):
    """
    Return {name: attitudes (N, 4)} of ahrs' Madgwick and Mahony over the samples.

    Both start from the first sample (their own accelerometer initialisation).
    Estimate k integrates the gyro sample k, so it is the attitude of sample
    k + 1 (the node's truth holds a sample's rate until the next sample).
    Mahony runs with its integral term (a gyro-bias estimator) all but off:
    the bias is known and removed.
    """
    from ahrs.filters import Madgwick, Mahony
    return {'Madgwick': Madgwick(gyr=gyro_rad_s, acc=accel_m_s2, frequency=rate_hz).Q,
            'Mahony': Mahony(gyr=gyro_rad_s, acc=accel_m_s2, frequency=rate_hz,
                             k_I=MAHONY_K_I).Q}


def errors_deg(estimate, truth):
    """Return roll, pitch, yaw errors (N - 1, 3), deg: estimate k against truth k + 1."""
    error = roll_pitch_yaw_deg(estimate[:-1]) - roll_pitch_yaw_deg(truth[1:])
    error[:, 2] = (error[:, 2] + 180.0) % 360.0 - 180.0
    return error
