"""
The start-up bias calibration of a gyro driver, on the node's output (no ROS imports).

Many IMU drivers average the gyro over the first seconds after power-on,
with the part at rest, and subtract that mean from every later sample: the
turn-on bias (and whatever bias the part has then) is gone from the
published rate. The node does the same with ``startup_bias_calibration``
(seconds at rest; 0, the default, is off), on the rate it publishes (after
an injected fault: a driver sees what the part outputs):

* the window is the first round(N x rate) published samples, counted in
  sample periods (so a jumping clock does not stretch or cut it); they go
  out uncorrected;
* at its end the estimate b = the mean per axis is applied, y' = y - b,
  from the next sample on, unless the part moved during the window:
  a commanded (true) rate other than zero at any of its samples, or a
  spread (sample standard deviation) on an axis above :data:`MOTION_FACTOR`
  times the spread expected at rest (:func:`rest_spread_rad_s`). Then the
  estimate is reported and not applied; the output stays uncorrected;
* the truth topics keep the true bias; ``/diagnostics`` says the state,
  the estimate and why it was not applied.

The mean and spread are accumulated sample by sample (Welford's update),
so the window holds no samples in memory.
"""

import math

from gyro_emulator.units import AXES

#: Spread above this many times the spread expected at rest means motion.
MOTION_FACTOR = 3.0
#: Least spread limit, rad/s: a part without noise terms is still allowed rounding.
MOTION_FLOOR_RAD_S = 1e-9


def rest_spread_rad_s(config, sigma_rad_s, duration_s):
    """
    Return the spread (standard deviation) a part at rest shows over a window, per axis, rad/s.

    sqrt(sigma_w^2 + q^2 / 12 + B^2 + K^2 T): the white noise at the output
    (``sigma_rad_s``, the filter's gain included), the quantisation step q
    (uniform rounding error), the bias instability B (the flicker bias's
    own spread, at most about B) and the rate random walk K over the window
    T (its spread about its mean is K sqrt(T / 6); K sqrt(T) is the bound
    used). Terms that are switched off count zero. IEEE Std 952 (N, B, K).

    Parameters
    ----------
    config : gyro_emulator.sensor.config.SensorConfig
        The error model in force (noise terms off when the noise is disabled).
    sigma_rad_s : array_like, shape (3,)
        Per-sample sigma of the white noise at the output, rad/s.
    duration_s : float
        Length of the window, s.

    """
    terms = config.terms
    out = []
    for axis in range(3):
        variance = float(sigma_rad_s[axis]) ** 2
        if terms.quantization:
            variance += config.lsb_rad_s[axis] ** 2 / 12.0
        if terms.bias_instability:
            variance += config.bias_instability_rad_s[axis] ** 2
        if terms.rate_random_walk:
            variance += config.rate_random_walk_rad_s_sqrt_s[axis] ** 2 * duration_s
        out.append(math.sqrt(variance))
    return tuple(out)


class StartupBiasCalibration:
    """
    Estimate the bias over the first ``duration_s`` of output at rest, then remove it.

    Parameters
    ----------
    duration_s : float
        Length of the window, s (0: off).
    rest_spread : callable
        ``rest_spread(duration_s)`` -> the spread per axis expected at rest,
        rad/s (:func:`rest_spread_rad_s` of the model in force), asked once,
        at the end of the window.
    done : callable
        ``done(applied, line)``: called once at the end of the window with
        whether the estimate is applied and one line saying what happened.

    Attributes
    ----------
    state : str
        ``off``, ``running``, ``applied`` or ``not applied``.
    samples : int
        Samples in the window so far.
    estimate_rad_s, spread_rad_s, limit_rad_s : tuple of float or None
        Mean, spread and the spread limit per axis (x, y, z), rad/s, once
        the window is over.
    moved : str or None
        Why the estimate was not applied.

    """

    def __init__(self, duration_s, rest_spread, done):
        self.duration_s = float(duration_s)
        self.state = 'running' if self.duration_s > 0.0 else 'off'
        self.samples = 0
        self.estimate_rad_s = self.spread_rad_s = self.limit_rad_s = None
        self.moved = None
        self._rest_spread = rest_spread
        self._done = done
        self._elapsed_s = 0.0
        self._mean = [0.0, 0.0, 0.0]
        self._m2 = [0.0, 0.0, 0.0]
        self._commanded = False
        self._offset = None

    def take(self, rate_rad_s, commanded_rad_s, dt_s):
        """
        Return the rate to publish for one published sample.

        Parameters
        ----------
        rate_rad_s : tuple of float
            The rate the part outputs (x, y, z), rad/s.
        commanded_rad_s : tuple of float
            The true rate commanded at this sample, rad/s.
        dt_s : float
            The sample period, s.

        """
        offset = self._offset
        if offset is not None:
            return (rate_rad_s[0] - offset[0], rate_rad_s[1] - offset[1],
                    rate_rad_s[2] - offset[2])
        if self.state != 'running':
            return rate_rad_s
        self.samples += 1
        n = self.samples
        mean, m2 = self._mean, self._m2
        for axis in range(3):
            delta = rate_rad_s[axis] - mean[axis]
            mean[axis] += delta / n
            m2[axis] += delta * (rate_rad_s[axis] - mean[axis])
        if commanded_rad_s[0] or commanded_rad_s[1] or commanded_rad_s[2]:
            self._commanded = True
        self._elapsed_s += dt_s
        if self._elapsed_s >= self.duration_s - 0.5 * dt_s:
            self._finish()
        return rate_rad_s

    def _finish(self):
        n = self.samples
        self.estimate_rad_s = tuple(self._mean)
        self.spread_rad_s = tuple(math.sqrt(m / (n - 1)) if n > 1 else 0.0 for m in self._m2)
        self.limit_rad_s = tuple(max(MOTION_FACTOR * s, MOTION_FLOOR_RAD_S)
                                 for s in self._rest_spread(self.duration_s))
        over = [f'{a} ({s:.3g} rad/s > {lim:.3g} at rest)'
                for a, s, lim in zip(AXES, self.spread_rad_s, self.limit_rad_s) if s > lim]
        if self._commanded:
            self.moved = 'the commanded rate was not zero'
        elif over:
            self.moved = 'the spread says motion on ' + ', '.join(over)
        estimate = ', '.join(f'{a} {b:+.6g}' for a, b in zip(AXES, self.estimate_rad_s))
        window = f'{self.duration_s:g} s ({n} samples)'
        if self.moved is None:
            self.state = 'applied'
            self._offset = self.estimate_rad_s
            self._done(True, f'startup bias calibration over {window}: {estimate} rad/s, '
                             'removed from imu/data_raw from now on')
        else:
            self.state = 'not applied'
            self._done(False, f'startup bias calibration over {window} not applied: '
                              f'{self.moved}; estimate {estimate} rad/s')

    def situation(self):
        """Return the diagnostics key/values of the calibration."""
        out = {'bias_calibration': self.state}
        if self.state == 'off':
            return out
        out['bias_calibration_s'] = self.duration_s
        out['bias_calibration.samples'] = self.samples
        for index, axis in enumerate(AXES):
            out[f'bias_calibration.{axis}_rad_s'] = (
                None if self.estimate_rad_s is None else self.estimate_rad_s[index])
        out['bias_calibration.moved'] = self.moved or ''
        return out
