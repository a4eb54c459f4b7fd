"""
Overlapping Allan deviation, confidence intervals and the N, B, K noise fit.

Rate samples y[i] (rad/s) at f_s are treated as "frequency" data: the phase
(angle) is x[j] = dt sum_{i<j} y[i], and the overlapping Allan variance at
tau = m dt is (NIST SP 1065 Eq 14; IEEE Std 952 Annex C)::

    sigma^2(tau) = sum_j (x[j+2m] - 2 x[j+m] + x[j])^2 / (2 tau^2 (N + 1 - 2m))

Confidence intervals use the chi-squared distribution with the equivalent
degrees of freedom of NIST SP 1065 Table 5 for the noise type that dominates
at each tau (read from the local slope of the curve).

The fit models the gyro's three IEEE Std 952 terms::

    sigma^2(tau) = N^2 / tau + (2 ln 2 / pi) B^2 + K^2 tau / 3

with N (angle random walk) in rad/s/sqrt(Hz) = rad/sqrt(s), B (bias
instability) in rad/s and K (rate random walk) in rad/s/sqrt(s); the
datasheet units deg/sqrt(h), deg/h and deg/h/sqrt(h) come from
:mod:`gyro_emulator.units`. It is a non-negative weighted least-squares fit
of the variances, each weighted by its estimation uncertainty
(sigma^2 sqrt(2 / edf)), iterated on the model.
"""

from dataclasses import dataclass
import os

from gyro_emulator import units
from gyro_emulator.recording import bag, csvio, records, topics
import numpy as np
from scipy import optimize, stats

#: Noise types: (alpha of the frequency PSD, slope of the Allan deviation).
_NOISE_SLOPES = {2: -1.0, 0: -0.5, -1: 0.0, -2: 0.5}


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


def _local_alpha(taus, adev):
    """Noise type per tau from the local log-log slope (least squares over +-2 points)."""
    lt, la = np.log(taus), np.log(np.maximum(adev, 1e-300))
    slopes = np.zeros(len(taus))
    for i in range(len(taus)):
        lo, hi = max(0, i - 2), min(len(taus), i + 3)
        if hi - lo >= 2:
            slopes[i] = np.polyfit(lt[lo:hi], la[lo:hi], 1)[0]
    kinds = np.array(list(_NOISE_SLOPES))
    ref = np.array(list(_NOISE_SLOPES.values()))
    return kinds[np.argmin(np.abs(slopes[:, np.newaxis] - ref[np.newaxis, :]), axis=1)]


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
        n = len(phase)
        for k, m in enumerate(m_all):
            if n - 2 * m < 1:
                continue
            d = phase[2 * m:] - 2.0 * phase[m:n - m] + phase[:n - 2 * m]
            avar[k] += np.dot(d, d)
            count[k] += n - 2 * m
    keep = count > 0
    m_all, avar, count = m_all[keep], avar[keep], count[keep]
    taus_s = m_all * dt
    adev = np.sqrt(avar / (2.0 * taus_s ** 2 * count))
    alpha = _local_alpha(taus_s, adev)
    lengths = tuple(len(s) for s in segments)
    edf = pooled_edf(lengths, m_all, alpha)
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


@dataclass(frozen=True)
class NoiseFit:
    """
    Fitted IEEE Std 952 gyro noise terms.

    Attributes
    ----------
    arw_rad_s_sqrt_hz : float
        N, angle random walk, rad/s/sqrt(Hz) (= rad/sqrt(s)).
    bias_instability_rad_s : float
        B, bias instability, rad/s (Allan floor 0.664 B).
    rrw_rad_s_sqrt_s : float
        K, rate random walk, rad/s/sqrt(s).
    taus_s : numpy.ndarray
        The averaging times used in the fit, s.

    """

    arw_rad_s_sqrt_hz: float
    bias_instability_rad_s: float
    rrw_rad_s_sqrt_s: float
    taus_s: np.ndarray

    @property
    def arw_deg_sqrt_h(self):
        """N in deg/sqrt(h)."""
        return float(units.rad_s_sqrt_hz_to_arw_deg_sqrt_h(self.arw_rad_s_sqrt_hz))

    @property
    def bias_instability_deg_h(self):
        """B in deg/h."""
        return float(units.rad_s_to_deg_h(self.bias_instability_rad_s))

    @property
    def rrw_deg_h_sqrt_h(self):
        """K in deg/h/sqrt(h)."""
        return float(units.rad_s_sqrt_s_to_rrw_deg_h_sqrt_h(self.rrw_rad_s_sqrt_s))

    def adev(self, taus_s):
        """Model Allan deviation at ``taus_s``, rad/s."""
        return model_adev(taus_s, self.arw_rad_s_sqrt_hz, self.bias_instability_rad_s,
                          self.rrw_rad_s_sqrt_s)


def _design(taus_s):
    t = np.asarray(taus_s, dtype=float)
    return np.column_stack([1.0 / t, np.full(t.shape, units.FLICKER_FLOOR_PER_B ** 2),
                            t / 3.0])


def model_adev(taus_s, arw_rad_s_sqrt_hz, bias_instability_rad_s, rrw_rad_s_sqrt_s):
    """
    Allan deviation of white + flicker + random-walk rate noise, rad/s.

    sqrt(N^2 / tau + (2 ln 2 / pi) B^2 + K^2 tau / 3) (IEEE Std 952 Annex C).
    """
    theta = np.array([arw_rad_s_sqrt_hz, bias_instability_rad_s, rrw_rad_s_sqrt_s]) ** 2
    return np.sqrt(_design(taus_s) @ theta)


def fit_noise_terms(result, tau_range_s=None, iterations=8):
    """
    Fit N (ARW), B (bias instability) and K (RRW) to an Allan deviation.

    Non-negative least squares on the Allan variances with the model
    N^2/tau + 0.4413 B^2 + K^2 tau/3; each point is weighted by its standard
    error sigma_model^2 sqrt(2/edf), re-evaluated on the model for a few
    iterations (edf from the model's dominant term).

    Parameters
    ----------
    result : AllanResult
        From :func:`overlapping_adev`.
    tau_range_s : tuple of float, optional
        Only use taus within (min, max), s.
    iterations : int
        Reweighting iterations.

    Returns
    -------
    NoiseFit
        N in rad/s/sqrt(Hz), B in rad/s, K in rad/s/sqrt(s) (datasheet
        units via its properties).

    """
    taus = np.asarray(result.taus_s)
    sel = np.ones(len(taus), dtype=bool)
    if tau_range_s is not None:
        sel = (taus >= tau_range_s[0]) & (taus <= tau_range_s[1])
    taus, avar = taus[sel], np.asarray(result.adev)[sel] ** 2
    if len(taus) < 3:
        raise ValueError(f'fit_noise_terms: {len(taus)} averaging times is too few: '
                         'need >= 3')
    m = np.round(taus * result.rate_hz)
    lengths = result.segment_lengths or (result.n_samples,)
    design = _design(taus)
    model = avar.copy()
    theta = np.zeros(3)
    for _ in range(iterations):
        parts = design * theta if np.any(theta) else None
        alpha = np.full(len(taus), 0) if parts is None else np.array([0, -1, -2])[
            np.argmax(parts, axis=1)]
        edf = pooled_edf(lengths, m, alpha)
        weight = np.sqrt(edf / 2.0) / np.maximum(model, 1e-300)
        theta, _ = optimize.nnls(design * weight[:, np.newaxis], avar * weight)
        model = np.maximum(design @ theta, 1e-300)
    n, b, k = np.sqrt(theta)
    return NoiseFit(arw_rad_s_sqrt_hz=float(n), bias_instability_rad_s=float(b),
                    rrw_rad_s_sqrt_s=float(k), taus_s=taus)


def classic_readings(result):
    """
    Datasheet-style readings of an Allan deviation (IEEE Std 952 Annex C).

    ``arw_at_1s``: the -1/2 slope line through the curve near tau = 1 s
    (sigma(tau) sqrt(tau) at the tau closest to 1 s where white noise
    dominates), rad/s/sqrt(Hz); ``bias_instability_min``: the minimum of the
    curve / 0.664, rad/s; ``tau_min_s``: where that minimum is.
    """
    taus, adev = np.asarray(result.taus_s), np.asarray(result.adev)
    i = int(np.argmin(np.abs(np.log(taus))))
    imin = int(np.argmin(adev))
    return {'arw_at_1s': float(adev[i] * np.sqrt(taus[i])),
            'bias_instability_min': float(adev[imin] / units.FLICKER_FLOOR_PER_B),
            'tau_min_s': float(taus[imin]), 'adev_min': float(adev[imin])}


def plot_adev(result, fit, path, title=''):
    """Write a log-log Allan deviation plot (deg/h) with the fit to ``path`` (PNG)."""
    import matplotlib
    matplotlib.use('Agg')
    from matplotlib import pyplot as plt

    to = units.rad_s_to_deg_h
    taus = result.taus_s
    fig, ax = plt.subplots(figsize=(7.0, 5.0))
    ax.fill_between(taus, to(result.adev_lo), to(result.adev_hi), color='C0', alpha=0.25,
                    label=f'{100 * result.ci:.0f} % confidence')
    ax.loglog(taus, to(result.adev), 'o-', color='C0', ms=3, label='overlapping ADEV')
    if fit is not None:
        dense = np.logspace(np.log10(taus[0]), np.log10(taus[-1]), 200)
        ax.loglog(dense, to(fit.adev(dense)), 'k--', lw=1.2, label='fit N + B + K')
        comps = (
            (fit.arw_rad_s_sqrt_hz / np.sqrt(dense),
             f'N = {fit.arw_deg_sqrt_h:.3g} deg/sqrt(h)'),
            (np.full(dense.shape, units.FLICKER_FLOOR_PER_B * fit.bias_instability_rad_s),
             f'B = {fit.bias_instability_deg_h:.3g} deg/h'),
            (fit.rrw_rad_s_sqrt_s * np.sqrt(dense / 3.0),
             f'K = {fit.rrw_deg_h_sqrt_h:.3g} deg/h/sqrt(h)'))
        for values, label in comps:
            if np.any(values > 0):
                ax.loglog(dense, to(values), ':', lw=1.0, label=label)
    lo = to(np.min(result.adev_lo[result.adev_lo > 0])) if np.any(
        result.adev_lo > 0) else None
    if lo is not None:
        ax.set_ylim(lo / 2.0, None)
    ax.set_xlabel('averaging time tau (s)')
    ax.set_ylabel('Allan deviation (deg/h)')
    ax.set_title(title or 'Overlapping Allan deviation')
    ax.grid(True, which='both', alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _read_bag(path, axis, topic):
    """Return (time_s from 0, rate, column label, recovery notes) of one Imu axis of a bag."""
    reader = bag.BagReader(path, tolerant=True)
    imu = [name for name, info in reader.topics.items() if info.type_name == topics.IMU]
    if topic is None:
        if len(imu) != 1:
            raise ValueError(f'{path}: {len(imu)} sensor_msgs/Imu topics '
                             f'({", ".join(imu) or "none"}): choose one with --topic')
        topic = imu[0]
    topic = records.find_topic(reader, 'gyro', topic, types=(topics.IMU,))
    arrays = reader.read_arrays(topic)
    times_ns, order = records.stream_times_ns(arrays)
    index = 'xyz'.index(axis or 'x')
    time_s = (times_ns - times_ns[0]) * 1e-9
    return time_s, arrays.field('angular_velocity')[order, index], \
        f'{topic} angular_velocity.{axis or "x"}', list(reader.problems)


def analyse_record(path, axis=None, topic=None, max_tau_fraction=0.25, gap_factor=3.0):
    """
    Analyse one record (CSV or bag) as ``gyro-emulator allan`` does.

    Segments split at gaps longer than ``gap_factor`` sample periods; the
    overlapping ADEV over all of them (:func:`overlapping_adev`), the N/B/K
    fit (:func:`fit_noise_terms`) and the classic read-offs. Returns
    ``(JSON-ready dict, AllanResult, NoiseFit)``.
    """
    if os.path.isdir(path) or str(path).endswith('.mcap'):
        time_s, rate, column, recovery = _read_bag(path, axis, topic)
        csvio.check_increasing(time_s, f'{path}: header stamps', strict=False)
    else:
        time_s, rate, column = csvio.read_gyro_csv(path, axis, time_order='nondecreasing')
        recovery = []
    rate_hz, bounds = csvio.sample_rate_and_segments(time_s, gap_factor)
    segments = [rate[a:b] for a, b in bounds if b - a >= 3]
    if not segments:
        raise ValueError(f'{path}: no segment has 3 or more samples')
    longest = max(len(s) for s in segments)
    taus = tau_multiples(longest, 10, max_tau_fraction) / rate_hz
    result = overlapping_adev(segments, rate_hz, taus=taus)
    fit = fit_noise_terms(result)
    classic = classic_readings(result)
    return {
        'file': str(path), 'column': column, 'sample_rate_hz': rate_hz,
        'recovery': recovery,
        'n_samples': result.n_samples, 'segments': len(segments),
        'repeated_timestamps': int(np.sum(np.diff(time_s) == 0.0)),
        'duration_s': float(time_s[-1] - time_s[0]),
        'arw_deg_sqrt_h': fit.arw_deg_sqrt_h,
        'bias_instability_deg_h': fit.bias_instability_deg_h,
        'rrw_deg_h_sqrt_h': fit.rrw_deg_h_sqrt_h,
        'arw_rad_s_sqrt_hz': fit.arw_rad_s_sqrt_hz,
        'bias_instability_rad_s': fit.bias_instability_rad_s,
        'rrw_rad_s_sqrt_s': fit.rrw_rad_s_sqrt_s,
        'arw_at_1s_deg_sqrt_h': float(units.rad_s_sqrt_hz_to_arw_deg_sqrt_h(
            classic['arw_at_1s'])),
        'bias_instability_min_deg_h': float(units.rad_s_to_deg_h(
            classic['bias_instability_min'])),
        'tau_at_min_s': classic['tau_min_s'],
        'taus_s': result.taus_s.tolist(), 'adev_rad_s': result.adev.tolist(),
        'adev_lo_rad_s': result.adev_lo.tolist(), 'adev_hi_rad_s': result.adev_hi.tolist(),
        'edf': result.edf.tolist(), 'ci': result.ci,
        'units': {'arw': 'deg/sqrt(h)', 'bias_instability': 'deg/h (Allan floor 0.664 B)',
                  'rrw': 'deg/h/sqrt(h)', 'adev': 'rad/s'},
    }, result, fit
