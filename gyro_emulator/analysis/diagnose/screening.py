"""
Setting outliers aside: spikes and motion segments must not decide the answer.

A handling bump in a thermal log or a logger glitch is a few samples that
no cause in any catalogue should explain, yet in a least-squares fit and in
an RMSE they can outweigh hours of data. ``diagnose`` finds them first and
leaves them out of every fit and every score (:func:`screen`):

1. a flexible *nuisance* model is fitted to the bin means with a Huber loss
   (iteratively reweighted least squares, scale from the median absolute
   deviation): the baseline, rate^2 and rate^3, the scale factor and the
   bias polynomial in temperature, dT/dt, the acceleration, the rate's
   derivative (a short delay) and, against anything else slow, a bias and
   a scale factor piecewise linear in time (16 pieces). It follows every
   catalogue cause and most others;
2. what is left is high-passed per sample
   (:func:`gyro_emulator.analysis.outliers.high_pass_flags`): a leave-one-out local fit of
   a bias and the rate at the previous, same and next sample over +-2 s
   (at least +-5 samples), within each contiguous stretch, removes what
   changes slowly or follows the rate through short dynamics; at the
   corners of rate steps, where that fit follows whatever the sample does,
   a spike must stand out from the local medians on both sides instead
   (:func:`_corner_flags`);
   it is refitted once with samples far out down-weighted, so that a
   spike does not spoil its neighbours;
3. a sample is an outlier when this, divided by its prediction standard
   error, exceeds ``threshold`` (6) robust standard deviations (1.4826 x
   the median absolute deviation); a second pass repeats 1-2 without the first pass's outliers
   and adds what it finds;
4. flagged samples closer than 1 s are one segment; a segment of two or
   more samples (motion) is widened by 1 s each side to cover its settling.

Gaussian noise crosses 6 sigma once in 5e8 samples, so clean records lose
nothing. The report says how many samples were set aside, and when.
"""

import math

from gyro_emulator.analysis import outliers
from gyro_emulator.analysis.diagnose.data import Prepared
from gyro_emulator.analysis.diagnose.effects import TimeDelay
import numpy as np

#: Robust standard deviations beyond which a sample is an outlier (the shared default).
THRESHOLD = outliers.THRESHOLD
HATS = 16
HUBER_K = 2.0
#: Delays (s) a rate-step edge may show before its samples can be outliers: the
#: catalogue's time-delay search range (:class:`.effects.TimeDelay`).
DELAY_RANGE_S = (float(TimeDelay.grid[0][0]), float(TimeDelay.grid[0][-1]))
#: Delays tried when the record's own is estimated at its edges, s.
DELAY_GRID_S = np.linspace(DELAY_RANGE_S[0], DELAY_RANGE_S[1], 351)


def _hats(t, t0, t1, count=HATS):
    """Piecewise-linear hat functions of time on ``count`` pieces over [t0, t1]."""
    knots = np.linspace(t0, t1, count + 1)
    eye = np.eye(count + 1)
    return [np.interp(t, knots, eye[j]) for j in range(count + 1)]


def nuisance_columns(prep, frame, ratio, hats=HATS):
    """
    Yield the nuisance model's columns at ``frame``'s rows, one at a time.

    ``ratio`` is the baseline R(T) on ``prep``'s bins; ``hats`` the pieces
    of the bias and scale factor piecewise linear in time.
    """
    slow = frame.slow
    s = slow(ratio)
    dtemp = slow(prep.binned.temp_c - 25.0)
    sr = s * frame.rate
    yield np.ones(len(frame))
    for col in (sr, s * frame.rate2, s * frame.rate3, sr * dtemp, sr * dtemp ** 2,
                dtemp, dtemp ** 2, slow(prep.temp_rate_on_bins)):
        yield col
    if frame.accel is not None:
        for k in range(3):
            yield frame.accel[:, k]
    yield s * frame.rate_derivative()
    if hats:
        t = prep.data.time_s
        for hat in _hats(prep.binned.time_s, t[0], t[-1], hats):
            yield slow(hat)
            yield sr * slow(hat)


def _huber_fit(prep, ratio):
    """Huber IRLS of the nuisance model on the bin means; return the coefficients."""
    b = prep.binned
    x = np.column_stack(list(nuisance_columns(prep, b, ratio)))
    scale = np.sqrt(np.sum(b.weight[:, None] * x * x, axis=0))
    x = x / np.where(scale > 0.0, scale, 1.0)
    robust = np.ones(len(b))
    beta = np.zeros(x.shape[1])
    for _ in range(6):
        w = np.sqrt(b.weight * robust)
        beta, *_ = np.linalg.lstsq(x * w[:, None], b.gyro * w, rcond=1e-10)
        z = (b.gyro - x @ beta) * np.sqrt(b.weight)
        sigma = 1.4826 * float(np.median(np.abs(z - np.median(z)))) or 1e-300
        u = np.abs(z) / (HUBER_K * sigma)
        robust = np.where(u <= 1.0, 1.0, 1.0 / np.maximum(u, 1e-12))
    return beta / np.where(scale > 0.0, scale, 1.0)


def nuisance_residual(prep, ratio_fn, hats=0):
    """
    Residual of the nuisance model (least squares on the bins) at the kept samples, rad/s.

    With ``hats=0`` (no pieces in time) this is what a flexible description
    of everything that follows the regressors leaves: the record's noise,
    its slow wander included, for
    :func:`gyro_emulator.analysis.diagnose.noise_model.fit_noise`.
    """
    b = prep.binned
    ratio = ratio_fn(b.temp_c)
    x = np.column_stack(list(nuisance_columns(prep, b, ratio, hats)))
    scale = np.sqrt(np.sum(b.weight[:, None] * x * x, axis=0))
    scale = np.where(scale > 0.0, scale, 1.0)
    w = np.sqrt(b.weight)
    beta, *_ = np.linalg.lstsq(x / scale * w[:, None], b.gyro * w, rcond=1e-10)
    beta = beta / scale
    s = prep.samples
    pred = np.zeros(len(s))
    for coef, col in zip(beta, nuisance_columns(prep, s, ratio, hats)):
        pred += coef * col
    return s.gyro - pred


def _corners(rate, tol_rad_s=1e-3):
    """
    Return the corners of rate steps: samples where the rate changes, next to a dwell.

    The rate moves between the sample's neighbours by more than ``tol`` (or
    1 % of its range), and it holds on one side (the two samples before, or
    the two after, are equal within ``tol``): the start or end of a ramp
    between dwells, not a sample inside a swept sine.
    """
    n = len(rate)
    if n < 5:
        return np.zeros(n, bool)
    tol = max(tol_rad_s, 0.01 * float(np.ptp(rate)))
    step = np.abs(np.diff(rate))
    moving = np.r_[step[0], np.maximum(step[:-1], step[1:]), step[-1]] > tol
    still_before = np.r_[True, True, step[:-1] <= tol]
    still_after = np.r_[step[1:] <= tol, True, True]
    return moving & (still_before | still_after)


def _corner_flags(r, rate, keep, half, threshold):
    """
    Flag spikes at the corners of rate steps, where the local fit cannot see them.

    There a sample is unlike its neighbours, and the flexible local fit
    follows it. A spike still stands out from both sides: the nuisance
    residual minus the median of the ``half`` samples before it, and minus
    the median of the ``half`` after it, are both large and of one sign (a
    level change at the corner, such as a scale-factor misfit that jumps
    with the rate, differs from one side only). Each is judged against its
    robust spread over all corners (at least the record's), so a dynamic
    response the nuisance model misses at every corner (a delay) is not
    taken for spikes.
    """
    corner = np.flatnonzero(_corners(rate))
    flag = np.zeros(len(r), bool)
    if len(corner) < 20:
        return flag
    padded = np.pad(r, half, mode='edge')
    windows = np.lib.stride_tricks.sliding_window_view(padded, half)
    # windows[i] covers r[i - half:i]; windows[i + half + 1] covers r[i + 1:i + half + 1]
    some = np.flatnonzero(keep)
    some = some[::max(1, len(some) // 5000)]
    sides = []
    for offset in (0, half + 1):
        stat = np.empty(len(corner))
        for lo in range(0, len(corner), 5000):
            idx = corner[lo:lo + 5000]
            stat[lo:lo + 5000] = r[idx] - np.median(windows[idx + offset], axis=1)
        typical = r[some] - np.median(windows[some + offset], axis=1)
        sigma = max(outliers.robust_scale(stat[keep[corner]]), outliers.robust_scale(typical))
        sides.append(stat / sigma)
    left, right = sides
    spike = (np.abs(left) > threshold) & (np.abs(right) > threshold) & (left * right > 0.0)
    flag[corner[spike]] = True
    return flag


def _flag_pass(data, prep_all, keep, ratio_fn, threshold):
    """
    One pass: nuisance fit on the kept samples, local high-pass, robust threshold.

    The local fit (:func:`gyro_emulator.analysis.outliers.high_pass_flags`)
    is run twice: the second time every sample beyond 4 robust sigma of the
    first is down-weighted by (4 sigma / |h|)^2, so a spike does not drag its
    neighbours' predictions (and get them flagged).
    """
    prep = Prepared(data, max_bins=min(4000, len(data.time_s)), keep=keep)
    ratio = ratio_fn(prep.binned.temp_c)
    beta = _huber_fit(prep, ratio)
    full = prep_all.samples
    pred = np.zeros(len(full))
    for coef, col in zip(beta, nuisance_columns(prep_all, full, ratio_fn(
            prep_all.binned.temp_c))):
        pred += coef * col
    r = full.gyro - pred
    t = data.time_s
    half = max(outliers.LOCAL_MIN_SAMPLES, int(round(outliers.LOCAL_HALF_S / prep.dt_s)))
    flag, sigma, _ = outliers.high_pass_flags(r, data.rate_cmd_rad_s, keep, t, prep.dt_s,
                                              threshold)
    for lo, hi in outliers.stretches(t, prep.dt_s):
        flag[lo:hi] |= _corner_flags(r[lo:hi], data.rate_cmd_rad_s[lo:hi], keep[lo:hi], half,
                                     threshold)
    if np.any(flag):
        model = _SampleModel(prep_all, beta, ratio_fn(prep_all.binned.temp_c))
        flag &= ~explained_by_delay(data, r, model, keep, flag, half, threshold * sigma)
    return flag, sigma


class _SampleModel:
    """The nuisance prediction at samples, for any applied rate put in their place."""

    def __init__(self, prep_all, beta, ratio):
        self.prep, self.beta, self.ratio = prep_all, beta, ratio

    def at(self, index, rate):
        """
        Prediction at samples ``index`` had the applied rate been ``rate`` (rad/s).

        Without the rate-derivative term: the delay it stands for is what the
        caller models.
        """
        frame = self.prep.sample_frame(index)
        frame.rate, frame.rate2, frame.rate3 = rate, rate * rate, rate ** 3
        frame.rate_derivative = lambda: np.zeros(len(index))
        pred = np.zeros(len(index))
        for coef, col in zip(self.beta, nuisance_columns(self.prep, frame, self.ratio)):
            pred += coef * col
        return pred


def _edge_samples(data, dt_s):
    """Return the samples within the settling window of a corner (DELAY_RANGE_S, +-1 sample)."""
    corner = np.flatnonzero(_corners(data.rate_cmd_rad_s))
    near = np.zeros(data.rows, bool)
    if not len(corner):
        return near
    before = int(math.ceil(-DELAY_RANGE_S[0] / dt_s)) + 1
    after = int(math.ceil(DELAY_RANGE_S[1] / dt_s)) + 1
    marks = np.zeros(data.rows + 1, int)
    np.add.at(marks, np.clip(corner - before, 0, data.rows), 1)
    np.add.at(marks, np.clip(corner + after + 1, 0, data.rows), -1)
    return np.cumsum(marks)[:-1] > 0


def _local_level(r, usable, index, half):
    """Return the median of the usable ``r`` within +-half of each of ``index`` (0: none)."""
    padded = np.pad(np.where(usable, r, np.nan), half, constant_values=np.nan)
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1)[index]
    empty = ~np.any(np.isfinite(windows), axis=1)
    windows = np.where(empty[:, None], 0.0, windows)
    return np.nanmedian(windows, axis=1)


def _delay_estimate(t, rate, idx, excess, gain):
    """
    Return the delay on ``DELAY_GRID_S`` that best explains the edge residuals.

    Least absolute error.

    ``excess`` is the residual at the edge samples ``idx`` less its local
    level; ``gain`` the model's d(output)/d(rate) there. Absolute error, so
    that a spike does not pull the estimate.
    """
    cost = [np.sum(np.abs(excess - gain * (np.interp(t[idx] - d, t, rate) - rate[idx])))
            for d in DELAY_GRID_S]
    return float(DELAY_GRID_S[int(np.argmin(cost))])


def explained_by_delay(data, r, model, keep, flag, half, tolerance):
    """
    Return which flagged samples a delayed output explains: not outliers.

    At the corners of rate steps a delayed output differs from the model
    driven by the undelayed rate by up to the whole step, for as long as
    the delay; set aside, those samples would take the delay's evidence
    with them. The record's delay ``d`` is estimated from the residuals of
    every sample near an edge (:func:`_delay_estimate`); a sample then is
    explained when its output, less the local level of the residual, lies
    within ``tolerance`` (the threshold times the noise scale) of the model
    driven by the rate ``floor(d/dt)`` or ``ceil(d/dt)`` samples before it
    (or anywhere between: within a sample the edge's timing is unknown). A
    spike stands out from that as from the model; a record without a delay
    gets ``d = 0`` and loses none of its flags.
    """
    near = _edge_samples(data, float(np.median(np.diff(data.time_s))))
    out = np.zeros(data.rows, bool)
    if np.count_nonzero(near & keep) < 10 or not np.any(flag & near):
        return out
    t, rate, y = data.time_s, data.rate_cmd_rad_s, data.gyro_rad_s
    idx = np.flatnonzero(near & keep)
    base = model.at(idx, rate[idx])
    gain = (model.at(idx, rate[idx] + 1e-3) - base) / 1e-3
    level = _local_level(r, keep & ~near, idx, half)
    d = _delay_estimate(t, rate, idx, y[idx] - base - level, gain)
    dt = float(np.median(np.diff(t)))
    idx = np.flatnonzero(near & flag)
    base = model.at(idx, rate[idx])
    u = y[idx] - base - _local_level(r, keep & ~near, idx, half)
    shift = d / dt
    lags = [0] if abs(shift) < 0.25 else range(
        int(math.floor(shift - 0.5)), int(math.ceil(shift + 0.5)) + 1)
    bands = [model.at(idx, rate[np.clip(idx - k, 0, data.rows - 1)]) - base for k in lags]
    lo, hi = np.min(bands, axis=0), np.max(bands, axis=0)
    out[idx] = np.abs(u - np.clip(u, lo, hi)) <= tolerance
    return out


def screen(data, ratio_fn, threshold=THRESHOLD):
    """
    Find the samples to set aside (see the module docstring).

    Parameters
    ----------
    data : gyro_emulator.analysis.diagnose.data.MeasuredData
        The record.
    ratio_fn : callable
        The baseline's scale-factor ratio R(T) of a temperature array.
    threshold : float
        Robust standard deviations beyond which a sample is an outlier
        (``math.inf``: set nothing aside).

    Returns
    -------
    dict
        ``keep`` (bool per sample), ``count``, ``fraction``, ``segments``
        (``[start_s, end_s, samples]`` of each stretch set aside),
        ``sigma_rad_s`` (the robust scale of the high-passed residual) and
        ``threshold``.

    """
    n = data.rows
    keep = np.ones(n, bool)
    sigma = float('nan')
    if math.isfinite(threshold):
        prep_all = Prepared(data, max_bins=min(4000, n))
        flag = np.zeros(n, bool)
        for _ in range(2):
            new, sigma = _flag_pass(data, prep_all, ~flag, ratio_fn, threshold)
            flag |= new
            drop, spans = outliers.flag_segments(flag, data.time_s, prep_all.dt_s)
            if drop.sum() > outliers.MAX_FRACTION * n:
                drop, spans = np.zeros(n, bool), []
            keep = ~drop
    else:
        spans = []
    count = int(n - keep.sum())
    return {'keep': keep, 'count': count, 'fraction': count / n,
            'segments': [list(s) for s in spans], 'sigma_rad_s': sigma,
            'threshold': threshold}
