"""
Overlapping Allan deviation of rate data, its degrees of freedom and confidence intervals.

Rate samples y[i] (rad/s) at f_s are treated as "frequency" data: the phase
(angle) is x[j] = dt sum_{i<j} y[i], and the overlapping Allan variance at
tau = m dt is (NIST SP 1065 Eq 14; IEEE Std 952 Annex C)::

    sigma^2(tau) = sum_j (x[j+2m] - 2 x[j+m] + x[j])^2 / (2 tau^2 (N + 1 - 2m))

The sum of squared second differences runs in one compiled pass per tau
(numba), with no temporary arrays. Confidence intervals use the chi-squared
distribution with the equivalent degrees of freedom of NIST SP 1065 Table 5
for the noise type that dominates at each tau (read from the local slope of
the curve; where the slope is ambiguous, the type with the fewest degrees of
freedom: :func:`conservative_edf`).
"""

from dataclasses import dataclass

import numba
import numpy as np
from scipy import stats

#: Noise types: (alpha of the frequency PSD, slope of the Allan deviation).
_NOISE_SLOPES = {2: -1.0, 0: -0.5, -1: 0.0, -2: 0.5}
#: Noise types within this of the local slope are all candidates for the edf.
SLOPE_AMBIGUITY = 0.3
#: White phase noise is a candidate only where white-FM noise would give this many dof.
WHITE_PM_MIN_EDF = 100.0


@dataclass(frozen=True)
class AllanResult:
    """
    Overlapping Allan deviation of rate data.

    Attributes
    ----------
    taus_s : numpy.ndarray
        Averaging times, s.
    adev : numpy.ndarray
        Allan deviation, in the data's unit (rad/s for gyro data).
    adev_lo, adev_hi : numpy.ndarray
        Confidence interval of ``adev`` at level ``ci``.
    edf : numpy.ndarray
        Equivalent degrees of freedom (NIST SP 1065 Table 5).
    alpha : numpy.ndarray
        Noise type used for ``edf`` (0 white, -1 flicker, -2 random walk of rate).
    n_terms : numpy.ndarray
        Number of second differences summed at each tau.
    rate_hz : float
        Sample rate, Hz.
    n_samples : int
        Samples used.
    ci : float
        Confidence level of the interval.
    segment_lengths : tuple of int
        Samples in each contiguous segment (one entry without gaps).

    """

    taus_s: np.ndarray
    adev: np.ndarray
    adev_lo: np.ndarray
    adev_hi: np.ndarray
    edf: np.ndarray
    alpha: np.ndarray
    n_terms: np.ndarray
    rate_hz: float
    n_samples: int
    ci: float
    segment_lengths: tuple = ()


def tau_multiples(n_samples, points_per_decade=10, max_fraction=0.25):
    """
    Log-spaced integer averaging factors m = tau f_s, unique and sorted.

    From 1 up to ``max_fraction`` of the record (at least 2 m <= N is needed;
    beyond N/4 fewer than ~3 degrees of freedom remain).
    """
    m_max = max(1, int(n_samples * max_fraction))
    count = max(2, int(np.ceil(np.log10(m_max) * points_per_decade)) + 1)
    return np.unique(np.round(np.logspace(0, np.log10(m_max), count)).astype(np.int64))


def _multiples(taus, n_longest, rate_hz):
    if taus is None or (isinstance(taus, str) and taus == 'decade'):
        return tau_multiples(n_longest)
    if isinstance(taus, str):
        if taus == 'octave':
            return 2 ** np.arange(int(np.log2(max(n_longest // 2, 1))) + 1)
        if taus == 'all':
            return np.arange(1, n_longest // 2 + 1)
        raise ValueError(f'overlapping_adev: taus = {taus!r} is not allowed: choose '
                         "seconds, 'decade', 'octave' or 'all'")
    m = np.unique(np.round(np.asarray(taus, dtype=float) * rate_hz).astype(np.int64))
    return m[(m >= 1) & (2 * m <= n_longest)]


def edf_overlapping(n_phase, m, alpha):
    """
    Equivalent degrees of freedom of the overlapping Allan variance.

    NIST SP 1065 Table 5 (Howe, Allan & Barnes 1981) for ``n_phase`` phase
    points, averaging factor ``m`` and frequency-noise exponent ``alpha``
    (2 white PM, 0 white FM, -1 flicker FM, -2 random-walk FM).
    """
    n = np.asarray(n_phase, dtype=float)
    m = np.asarray(m, dtype=float)
    alpha = np.asarray(alpha)
    with np.errstate(divide='ignore', invalid='ignore'):
        white_pm = (n + 1.0) * (n - 2.0 * m) / (2.0 * (n - m))
        white_fm = (3.0 * (n - 1.0) / (2.0 * m) - 2.0 * (n - 2.0) / n) * (
            4.0 * m ** 2 / (4.0 * m ** 2 + 5.0))
        flicker_fm = np.where(m == 1, 2.0 * (n - 2.0) ** 2 / (2.3 * n - 4.9),
                              5.0 * n ** 2 / (4.0 * m * (n + 3.0 * m)))
        rw_fm = (n - 2.0) / m * ((n - 1.0) ** 2 - 3.0 * m * (n - 1.0) + 4.0 * m ** 2) / (
            (n - 3.0) ** 2)
    edf = np.select([alpha >= 2, alpha == 0, alpha == -1], [white_pm, white_fm, flicker_fm],
                    rw_fm)
    return np.maximum(edf, 1.0)


def local_slopes(taus_s, adev, half_width=2):
    """
    Local log-log slope of an Allan deviation curve at each tau.

    Least-squares slope of ln(adev) on ln(tau) over the point and up to
    ``half_width`` neighbours each side: -1 quantisation (white phase),
    -1/2 white rate noise (N), 0 flicker (B), +1/2 rate random walk (K),
    +1 rate ramp (IEEE Std 952 Annex C, Table C.1).
    """
    lt = np.log(np.asarray(taus_s, dtype=float))
    la = np.log(np.maximum(np.asarray(adev, dtype=float), 1e-300))
    slopes = np.zeros(len(lt))
    for i in range(len(lt)):
        lo, hi = max(0, i - half_width), min(len(lt), i + half_width + 1)
        if hi - lo >= 2:
            x = lt[lo:hi] - lt[lo:hi].mean()
            slopes[i] = float(np.dot(x, la[lo:hi] - la[lo:hi].mean()) / np.dot(x, x))
    return slopes


def conservative_edf(segment_lengths, m, taus_s, adev):
    """
    Noise type and equivalent degrees of freedom at each tau, erring toward fewer dof.

    Every noise type whose Allan slope is within :data:`SLOPE_AMBIGUITY` of
    the local slope is a candidate (the nearest one always is); the edf is
    the smallest of theirs (NIST SP 1065 Table 5). White phase noise, whose
    edf does not fall with tau, is a candidate only where the curve is
    precise (white-FM edf >= 100): a noisy slope at long tau cannot pass for
    it and claim thousands of degrees of freedom. Returns (alpha, edf).
    """
    slopes = local_slopes(taus_s, adev)
    kinds = np.array(list(_NOISE_SLOPES))
    ref = np.array(list(_NOISE_SLOPES.values()))
    gap = np.abs(slopes[:, np.newaxis] - ref[np.newaxis, :])
    candidate = (gap <= SLOPE_AMBIGUITY) | (gap == gap.min(axis=1, keepdims=True))
    table = np.column_stack([pooled_edf(segment_lengths, m, np.full(len(m), k))
                             for k in kinds])
    # white phase noise claims ~N/2 dof at any tau: trust a slope of -1 only
    # where the curve is precise (white-FM edf >= 100), never at the long end
    white_pm = list(kinds).index(2)
    candidate[:, white_pm] &= table[:, list(kinds).index(0)] >= WHITE_PM_MIN_EDF
    candidate[~candidate.any(axis=1), list(kinds).index(0)] = True
    table = np.where(candidate, table, np.inf)
    pick = np.argmin(table, axis=1)
    return kinds[pick], table[np.arange(len(m)), pick]


@numba.njit(cache=True, fastmath=True)
def _second_difference_sums(phase, multiples):
    """Sum over j of (x[j+2m] - 2 x[j+m] + x[j])^2 for each m (one pass, no temporaries)."""
    n = phase.shape[0]
    out = np.zeros(multiples.shape[0])
    for k in range(multiples.shape[0]):
        m = multiples[k]
        total = 0.0
        for j in range(n - 2 * m):
            d = phase[j + 2 * m] - 2.0 * phase[j + m] + phase[j]
            total += d * d
        out[k] = total
    return out


def overlapping_adev(data, rate_hz, taus=None, ci=0.683):
    """
    Overlapping Allan deviation of rate data with chi-squared confidence intervals.

    Parameters
    ----------
    data : array_like or sequence of array_like
        Rate samples (e.g. rad/s), 1-D; or a list of contiguous segments
        (a record with gaps), pooled: the squared second differences of all
        segments are summed and divided by their total count.
    rate_hz : float
        Sample rate, Hz.
    taus : array_like or str, optional
        Averaging times in s (rounded to whole samples), or ``'decade'``
        (default, about 10 per decade up to a quarter of the record),
        ``'octave'`` or ``'all'``.
    ci : float
        Confidence level of the interval (0.683 = 1 sigma).

    Returns
    -------
    AllanResult

    """
    rate_hz = float(rate_hz)
    if not rate_hz > 0.0:
        raise ValueError(f'overlapping_adev: rate_hz = {rate_hz!r} is out of range: '
                         'allowed > 0 Hz')
    if isinstance(data, (list, tuple)) and len(data) and np.ndim(data[0]) == 1:
        segments = [np.asarray(s, dtype=float) for s in data]
    else:
        segments = [np.asarray(data, dtype=float)]
    for seg in segments:
        if seg.ndim != 1:
            raise ValueError(f'overlapping_adev: data has shape {seg.shape}: expected 1-D')
        if not np.all(np.isfinite(seg)):
            raise ValueError('overlapping_adev: data contains non-finite values')
    longest = max(len(s) for s in segments)
    if longest < 3:
        raise ValueError(f'overlapping_adev: {longest} samples is too few: need >= 3')
    m_all = _multiples(taus, longest, rate_hz)
    dt = 1.0 / rate_hz
    phases = []
    for seg in segments:
        phase = np.empty(len(seg) + 1)
        phase[0] = 0.0
        np.cumsum((seg - seg.mean()) * dt, out=phase[1:])
        phases.append(phase)
    avar = np.zeros(len(m_all))
    count = np.zeros(len(m_all), dtype=np.int64)
    for phase in phases:
        usable = len(phase) - 2 * m_all >= 1
        if np.any(usable):
            avar[usable] += _second_difference_sums(phase, m_all[usable])
            count[usable] += len(phase) - 2 * m_all[usable]
    keep = count > 0
    m_all, avar, count = m_all[keep], avar[keep], count[keep]
    taus_s = m_all * dt
    adev = np.sqrt(avar / (2.0 * taus_s ** 2 * count))
    lengths = tuple(len(s) for s in segments)
    alpha, edf = conservative_edf(lengths, m_all, taus_s, adev)
    lo, hi = confidence_interval(adev, edf, ci)
    return AllanResult(taus_s=taus_s, adev=adev, adev_lo=lo, adev_hi=hi, edf=edf,
                       alpha=alpha, n_terms=count, rate_hz=rate_hz,
                       n_samples=int(sum(lengths)), ci=float(ci), segment_lengths=lengths)


def pooled_edf(segment_lengths, m, alpha):
    """Sum of :func:`edf_overlapping` over independent segments long enough for m."""
    m = np.asarray(m, dtype=float)
    total = np.zeros(m.shape)
    for length in segment_lengths:
        n_phase = length + 1
        ok = n_phase - 2 * m >= 1
        total += np.where(ok, edf_overlapping(n_phase, np.where(ok, m, 1), alpha), 0.0)
    return np.maximum(total, 1.0)


def confidence_interval(adev, edf, ci=0.683):
    """
    Chi-squared interval of an Allan deviation with ``edf`` degrees of freedom.

    sigma^2 edf / chi2_{(1+ci)/2}(edf) <= sigma_true^2 <= sigma^2 edf / chi2_{(1-ci)/2}(edf)
    (NIST SP 1065 Sec 5.3).
    """
    adev = np.asarray(adev, dtype=float)
    edf = np.asarray(edf, dtype=float)
    lo = adev * np.sqrt(edf / stats.chi2.ppf(0.5 + ci / 2.0, edf))
    hi = adev * np.sqrt(edf / stats.chi2.ppf(0.5 - ci / 2.0, edf))
    return lo, hi
