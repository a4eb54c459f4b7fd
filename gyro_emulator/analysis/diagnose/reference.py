"""
A second record of the same part: its noise measured there and held fixed (``--reference``).

One record cannot tell a slow effect from the part's own slow wander as well
as two can: the wander that the null must allow is then estimated on the
record that holds the effect, and an effect inflates it (docs/diagnose.md,
"What one record cannot show"). With a second, static record of the same
part (an Allan run), the noise is measured where no effect is:

- :func:`reference_noise`: white noise N, bias instability B (flicker) and
  rate random walk K of the reference, from its robust Allan deviation
  fitted with the three terms the simulations draw (IEEE Std 952;
  :func:`.noise_model.fit_noise`, averaging times up to a tenth of it).
- :meth:`ReferenceNoise.noise_model`: those terms as the null of the fold
  test's simulations and of the verdict's floor, for every model (the
  record's own short-term per-sample spread is kept for the per-sample
  floor: a record may be filtered or averaged differently).
- :class:`KnownNoise`: the likelihood-ratio test of a cause's columns on
  the record's group means with that noise fixed. The group means are
  white noise of density N averaged over each group (N^2 / L_i), flicker
  as a sum of Gauss-Markov terms one per decade from the groups' spacing to
  ten record lengths (the simulations' terms,
  :func:`gyro_emulator.sensor.noise.flicker_unit_variance`), each averaged
  exactly over its window, and a random walk of intensity K; the level is
  removed by differencing (as in :mod:`.statespace`). With the covariance
  known, the likelihood ratio is the generalised least-squares reduction,
  chi^2 with one degree of freedom per column: no noise is estimated, so
  none is inflated. It needs the dense covariance of the group
  differences (one Cholesky factor per record).
"""

from dataclasses import dataclass

from gyro_emulator.analysis.diagnose import noise_model, statespace
from gyro_emulator.sensor import noise as sensor_noise
import numpy as np
from scipy import linalg, stats


@dataclass(frozen=True)
class ReferenceNoise:
    """The noise of a reference record: white density N, bias instability B, random walk K."""

    source: str
    duration_s: float
    arw_rad_s_sqrt_hz: float
    bias_instability_rad_s: float
    rrw_rad_s_sqrt_s: float
    allan_tau_max_s: float

    def as_dict(self):
        """JSON-ready form."""
        return {'source': self.source, 'duration_s': self.duration_s,
                'arw_rad_s_sqrt_hz': self.arw_rad_s_sqrt_hz,
                'bias_instability_rad_s': self.bias_instability_rad_s,
                'rrw_rad_s_sqrt_s': self.rrw_rad_s_sqrt_s,
                'allan_tau_max_s': self.allan_tau_max_s,
                'held_fixed_in': 'the fold test simulations, the likelihood ratio of every '
                                 'cause with fixed columns, and the verdict floor'}

    def noise_model(self, white_sigma_rad_s):
        """Return the null's :class:`.noise_model.NoiseModel` with the record's own fast spread."""
        return noise_model.NoiseModel(white_sigma_rad_s, self.arw_rad_s_sqrt_hz,
                                      self.bias_instability_rad_s, self.rrw_rad_s_sqrt_s,
                                      self.allan_tau_max_s)


def reference_noise(data):
    """
    Measure the noise of a static reference record (a :class:`.data.MeasuredData`).

    Its output less its mean, fitted as :func:`.noise_model.fit_noise` fits a
    residual. A record too short or gappy for an Allan deviation over three
    averaging times, or whose output does not vary, is a one-line error.
    """
    gyro = np.asarray(data.gyro_rad_s, dtype=float)
    t = np.asarray(data.time_s, dtype=float)
    if len(t) < 16 or np.ptp(gyro) == 0.0:
        raise ValueError(f'diagnose: reference {data.source!r} has {len(t)} samples and an '
                         'output that does not vary: allowed: a static record of the same '
                         'part, long enough for an Allan deviation')
    dt = np.diff(t)
    dt_s = float(np.median(dt[dt > 0.0]))
    duration = float(t[-1] - t[0] + dt_s)
    fit = noise_model.fit_noise(gyro - gyro.mean(), t, dt_s, duration)
    if fit.tau_max_s <= 0.0:
        raise ValueError(f'diagnose: reference {data.source!r} ({duration:.4g} s) is too short '
                         'or gappy for an Allan deviation over three averaging times: allowed: '
                         'a longer static record of the same part')
    return ReferenceNoise(source=str(data.source), duration_s=duration,
                          arw_rad_s_sqrt_hz=fit.arw_rad_s_sqrt_hz,
                          bias_instability_rad_s=fit.bias_instability_rad_s,
                          rrw_rad_s_sqrt_s=fit.rrw_rad_s_sqrt_s,
                          allan_tau_max_s=fit.tau_max_s)


def _band_matrix(band):
    """Return the dense symmetric matrix of a (2, m) upper band (``Groups.bands``)."""
    m = band.shape[1]
    out = np.diag(band[1])
    i = np.arange(m - 1)
    out[i, i + 1] = out[i + 1, i] = band[0, 1:]
    return out


def flicker_covariance(groups, bias_instability_rad_s):
    """
    Covariance of the group means of flicker noise B (Gauss-Markov terms, window averages).

    Between windows of lengths L_i, L_j centred d apart (not overlapping):
    q e^{-d/T} S_i S_j, S = sinh(L/2T) / (L/2T); a window with itself:
    q 2 (u - 1 + e^{-u}) / u^2, u = L/T. The terms and their variances q are
    the simulations' (:func:`.noise_model.draw_noise_records`).
    """
    t = np.asarray(groups.time_s, float)
    length = np.asarray(groups.length_s, float)
    n = len(t)
    cov = np.zeros((n, n))
    if bias_instability_rad_s <= 0.0 or n < 2:
        return cov
    shortest = max(float(np.median(np.diff(t))), 1e-6)
    span = max(float(t[-1] - t[0]), shortest)
    taus = sensor_noise.flicker_corr_times_s((shortest, 10.0 * span))
    var = sensor_noise.flicker_unit_variance(taus) * bias_instability_rad_s ** 2
    d = np.abs(t[:, None] - t[None, :])
    for tau, q in zip(taus, var):
        a = length / (2.0 * tau)
        # e^{-d} sinh(a_i) sinh(a_j) / (a_i a_j), written without overflow
        s = (1.0 - np.exp(-2.0 * a)) / (2.0 * np.maximum(a, 1e-300))
        c = q * np.exp(-d / tau + a[:, None] + a[None, :]) * np.outer(s, s)
        u = length / tau
        c[np.diag_indices(n)] = q * 2.0 * (u - 1.0 + np.exp(-u)) / np.maximum(u * u, 1e-300)
        cov += c
    return cov


class KnownNoise:
    """
    The likelihood ratio of a cause's columns on group means, the noise known.

    See the module docstring.

    Parameters
    ----------
    ref : ReferenceNoise
        The noise.
    groups : gyro_emulator.analysis.diagnose.statespace.Groups
        The record's groups (samples, kept durations, mean times).
    dt_s : float
        The record's sample interval, s.

    """

    def __init__(self, ref, groups, dt_s):
        a, b = groups.bands()
        white = ref.arw_rad_s_sqrt_hz ** 2 / dt_s          # per-sample variance of density N
        flick = flicker_covariance(groups, ref.bias_instability_rad_s)
        flick_d = flick[1:, 1:] - flick[1:, :-1] - flick[:-1, 1:] + flick[:-1, :-1]
        cov = white * _band_matrix(a) + flick_d + ref.rrw_rad_s_sqrt_s ** 2 * _band_matrix(b)
        self._chol = linalg.cho_factor(cov, lower=True, check_finite=False)

    def _whiten(self, x):
        return linalg.solve_triangular(self._chol[0], x, lower=True, check_finite=False)

    def rss(self, dy, dx):
        """Return the generalised least-squares residual sum of squares of dy on dx."""
        if dx.shape[1] == 0:
            return float(dy @ dy)
        beta, *_ = np.linalg.lstsq(dx, dy, rcond=1e-12)
        r = dy - dx @ beta
        return float(r @ r)

    def lr_test(self, y, x0, x1):
        """
        Return the :class:`.statespace.LrResult` of ``x1`` given ``x0`` on the group means ``y``.

        LR = RSS(x0) - RSS(x0, x1) of the whitened differences, chi^2 with as
        many degrees of freedom as ``x1`` has independent columns.
        """
        y = np.asarray(y, float)
        x0 = np.asarray(x0, float).reshape(len(y), -1)
        x1 = np.asarray(x1, float).reshape(len(y), -1)
        w = self._whiten(np.column_stack([np.diff(y), np.diff(x0, axis=0), np.diff(x1, axis=0)]))
        dy, d0, d1 = w[:, 0], w[:, 1:1 + x0.shape[1]], w[:, 1 + x0.shape[1]:]
        keep = [c for c in range(d1.shape[1]) if np.any(d1[:, c] != 0.0)]
        q = max(int(np.linalg.matrix_rank(d1[:, keep])) if keep else 0, 1)
        lr = max(self.rss(dy, d0) - self.rss(dy, np.column_stack([d0, d1])), 0.0)
        p = float(stats.chi2.sf(lr, q))
        return statespace.LrResult(lr, q, p, p, 1.0, False, None, None, len(y) - 1)


__all__ = ['flicker_covariance', 'KnownNoise', 'reference_noise', 'ReferenceNoise']
