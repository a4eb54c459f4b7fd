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
from gyro_emulator.analysis.diagnose.baseline import MIN_RATE_RMS_RAD_S
from gyro_emulator.sensor import noise as sensor_noise
import numpy as np
from scipy import linalg, stats


@dataclass(frozen=True)
class ReferenceNoise:
    """
    The noise of a reference record: white density N, bias instability B, random walk K.

    ``duration_s`` is the time it covers, its logging gaps (``gaps_s``) left out.
    """

    source: str
    duration_s: float
    arw_rad_s_sqrt_hz: float
    bias_instability_rad_s: float
    rrw_rad_s_sqrt_s: float
    allan_tau_max_s: float
    gaps_s: float = 0.0

    @property
    def gap_free(self):
        """Return whether the reference has no logging gap (``duration_s`` is its span)."""
        return self.gaps_s == 0.0

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
    averaging times, whose output does not vary, or whose applied rate is not
    at rest (rms of at least :data:`.baseline.MIN_RATE_RMS_RAD_S`: its output
    holds the motion, not only the noise) is a one-line error. Its
    ``duration_s`` is the time it covers, its logging gaps left out.
    """
    gyro = np.asarray(data.gyro_rad_s, dtype=float)
    t = np.asarray(data.time_s, dtype=float)
    if len(t) < 16 or np.ptp(gyro) == 0.0:
        raise ValueError(f'diagnose: reference {data.source!r} has {len(t)} samples and an '
                         'output that does not vary: allowed: a static record of the same '
                         'part, long enough for an Allan deviation')
    rate_rms = float(np.sqrt(np.mean(np.asarray(data.rate_cmd_rad_s, float) ** 2)))
    if rate_rms >= MIN_RATE_RMS_RAD_S:
        raise ValueError(f'diagnose: reference {data.source!r} is not static: its applied rate '
                         f'is {rate_rms:.3g} rad/s rms: allowed: below {MIN_RATE_RMS_RAD_S:g} '
                         'rad/s rms (a record of the part at rest)')
    dt = np.diff(t)
    dt_s = float(np.median(dt[dt > 0.0]))
    span = float(t[-1] - t[0] + dt_s)
    fit = noise_model.fit_noise(gyro - gyro.mean(), t, dt_s, span)
    if fit.tau_max_s <= 0.0:
        raise ValueError(f'diagnose: reference {data.source!r} ({span:.4g} s) is too short or '
                         'gappy for an Allan deviation over three averaging times: allowed: a '
                         'longer static record of the same part')
    covered = covered_s(t, dt_s)
    return ReferenceNoise(source=str(data.source), duration_s=covered,
                          arw_rad_s_sqrt_hz=fit.arw_rad_s_sqrt_hz,
                          bias_instability_rad_s=fit.bias_instability_rad_s,
                          rrw_rad_s_sqrt_s=fit.rrw_rad_s_sqrt_s,
                          allan_tau_max_s=fit.tau_max_s,
                          gaps_s=max(span - covered, 0.0))


def covered_s(time_s, dt_s):
    """
    Return the time a record covers, s: its span less its logging gaps.

    A gap ends a stretch as :func:`.noise_model.fit_noise` splits them
    (:func:`.noise_model.stretch_starts`); each stretch counts its
    samples' span plus one dt.
    """
    t = np.asarray(time_s, float)
    starts = noise_model.stretch_starts(t, dt_s)
    gaps = t[starts] - t[starts - 1]
    return float(t[-1] - t[0] - np.sum(gaps) + dt_s * (1 + len(gaps)))


#: Consecutive output samples compared between the record and the reference.
SHARED_WINDOW = 32
#: Share of the record's windows found in the reference above which they are one record.
MAX_SHARED_SHARE = 0.01


def _window_hashes(values):
    """Return a 64-bit hash of every :data:`SHARED_WINDOW` consecutive values (bit exact)."""
    # + 0.0 makes -0.0 and 0.0 one value
    u = np.ascontiguousarray(np.asarray(values, dtype=np.float64) + 0.0).view(np.uint64)
    u = u * np.uint64(0x9E3779B97F4A7C15)
    m = len(u) - SHARED_WINDOW + 1
    h = np.zeros(max(m, 0), dtype=np.uint64)
    for j in range(SHARED_WINDOW if m > 0 else 0):
        h = h * np.uint64(1099511628211) + (u[j:j + m] ^ (u[j:j + m] >> np.uint64(29)))
    return h


def shared_share(record_values, reference_values):
    """
    Return the share of the record's windows found in the reference at one offset.

    A copy or an overlap holds the record's windows at one constant offset
    in the reference; windows that repeat by chance (an output whose noise
    is below its LSB) fall at scattered offsets and are not counted.
    """
    with np.errstate(over='ignore'):
        mine = _window_hashes(record_values)
        theirs = _window_hashes(reference_values)
    if len(mine) == 0 or len(theirs) == 0:
        return 0.0
    keys, first = np.unique(theirs, return_index=True)
    pos = np.minimum(np.searchsorted(keys, mine), len(keys) - 1)
    hit = keys[pos] == mine
    if not np.any(hit):
        return 0.0
    offsets = first[pos[hit]] - np.flatnonzero(hit)
    return float(np.max(np.unique(offsets, return_counts=True)[1]) / len(mine))


def check_independent(record, reference):
    """
    Refuse a reference that holds the record's own samples (one-line ValueError).

    The null holds the reference's noise fixed as measured independently of
    the record; the record itself (the same file, a link or a copy), or a
    log that contains it, measures the record's own wander, effect included,
    and makes the null too tight. Runs of :data:`SHARED_WINDOW` output
    values equal bit for bit in both, at one offset, are counted
    (:func:`shared_share`); more than :data:`MAX_SHARED_SHARE` of the
    record's is refused.
    """
    shared = shared_share(record.gyro_rad_s, reference.gyro_rad_s)
    if shared > MAX_SHARED_SHARE:
        raise ValueError(f'diagnose: reference {reference.source!r} holds {100 * shared:.3g} % '
                         f"of the record's output samples ({record.source!r}): its noise is "
                         'not measured independently of the record; allowed: a separate static '
                         f'record of the same part (at most {100 * MAX_SHARED_SHARE:g} % shared)')


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


__all__ = ['check_independent', 'covered_s', 'flicker_covariance', 'KnownNoise', 'reference_noise',
           'ReferenceNoise']
