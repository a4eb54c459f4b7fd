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
2. what is left is high-passed per sample: a leave-one-out local fit of
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

from gyro_emulator.analysis.diagnose.data import Prepared
import numpy as np

#: Robust standard deviations beyond which a sample is an outlier.
THRESHOLD = 6.0
#: Half width of the local high-pass window, s (at least LOCAL_MIN_SAMPLES).
LOCAL_HALF_S = 2.0
LOCAL_MIN_SAMPLES = 5
#: Flags closer than this are one segment; a segment is widened by it, s.
MERGE_S = 1.0
HATS = 16
HUBER_K = 2.0


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


def _moving_sum(v, half):
    """Sum over i-half..i+half (clipped to the array) of v, along axis 0."""
    c = np.concatenate([np.zeros((1,) + v.shape[1:]), np.cumsum(v, axis=0)])
    n = len(v)
    idx = np.arange(n)
    return c[np.minimum(idx + half + 1, n)] - c[np.maximum(idx - half, 0)]


def _local_high_pass(r, rate, weight, half):
    """
    Leave-one-out local least squares of ``r`` on [1, rate[i-1], rate[i], rate[i+1]].

    Over +-half samples: a bias, a scale factor and any short linear
    dynamics (a delay or a filter within a sample) that hold locally.
    Moving sums of the weighted cross products give each sample's normal
    equations without the sample itself; a small ridge keeps a window of
    constant rate solvable (a ridge of 1e-6 of the diagonal). The
    prediction error is divided by sqrt(1 + x' G^-1 x), its standard
    deviation in units of the noise: a sample unlike its neighbours (the
    corner of a rate step) is predicted less well, and that is not an
    outlier.
    """
    prev = np.r_[rate[:1], rate[:-1]]
    nxt = np.r_[rate[1:], rate[-1:]]
    basis = np.column_stack([np.ones(len(r)), prev, rate, nxt])
    p = basis.shape[1]
    bw = basis * weight[:, None]
    gram = _moving_sum(bw[:, :, None] * basis[:, None, :], half)
    gram -= bw[:, :, None] * basis[:, None, :]
    rhs = _moving_sum(bw * r[:, None], half) - bw * r[:, None]
    diag = np.einsum('nii->ni', gram)
    ridge = 1e-6 * diag + 1e-9 * np.max(diag, axis=1, keepdims=True) + 1e-300
    gram[:, np.arange(p), np.arange(p)] += ridge
    coef = np.linalg.solve(gram, rhs[:, :, None])[:, :, 0]
    lev = np.sum(basis * np.linalg.solve(gram, basis[:, :, None])[:, :, 0], axis=1)
    return (r - np.sum(basis * coef, axis=1)) / np.sqrt(1.0 + np.maximum(lev, 0.0))


def _stretches(t, dt_s):
    """Start and stop indices of the contiguous stretches (a gap > 3 dt splits)."""
    cuts = np.flatnonzero(np.diff(t) > 3.0 * dt_s) + 1
    edges = np.r_[0, cuts, len(t)]
    return list(zip(edges[:-1], edges[1:]))


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
        sigma = max(_robust_scale(stat[keep[corner]]), _robust_scale(typical))
        sides.append(stat / sigma)
    left, right = sides
    spike = (np.abs(left) > threshold) & (np.abs(right) > threshold) & (left * right > 0.0)
    flag[corner[spike]] = True
    return flag


def _robust_scale(h):
    """1.4826 x the median absolute deviation (the standard deviation for Gaussian data)."""
    sigma = 1.4826 * float(np.median(np.abs(h - np.median(h))))
    return sigma if sigma > 0.0 else (float(np.std(h)) or 1e-300)


def _flag_pass(data, prep_all, keep, ratio_fn, threshold):
    """
    One pass: nuisance fit on the kept samples, local high-pass, robust threshold.

    The local fit is run twice: the second time every sample beyond 4
    robust sigma of the first is down-weighted by (4 sigma / |h|)^2, so a
    spike does not drag its neighbours' predictions (and get them flagged).
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
    half = max(LOCAL_MIN_SAMPLES, int(round(LOCAL_HALF_S / prep.dt_s)))
    weight = keep.astype(float)
    h = np.zeros(len(r))
    for _ in range(2):
        for lo, hi in _stretches(t, prep.dt_s):
            h[lo:hi] = _local_high_pass(r[lo:hi], data.rate_cmd_rad_s[lo:hi],
                                        weight[lo:hi], half)
        sigma = _robust_scale(h[keep])
        u = np.abs(h) / (4.0 * sigma)
        weight = keep * np.where(u > 1.0, 1.0 / np.maximum(u, 1.0) ** 2, 1.0)
    flag = np.abs(h) > threshold * sigma
    for lo, hi in _stretches(t, prep.dt_s):
        flag[lo:hi] |= _corner_flags(r[lo:hi], data.rate_cmd_rad_s[lo:hi], keep[lo:hi], half,
                                     threshold)
    return flag, sigma


def _segments(flag, t, dt_s):
    """Group flags into segments; widen multi-sample ones. Returns (set-aside mask, spans)."""
    idx = np.flatnonzero(flag)
    out = np.zeros(len(t), bool)
    spans = []
    if not len(idx):
        return out, spans
    breaks = np.flatnonzero(np.diff(t[idx]) > MERGE_S) + 1
    for group in np.split(idx, breaks):
        lo, hi = t[group[0]], t[group[-1]]
        if len(group) > 1:
            lo, hi = lo - MERGE_S, hi + MERGE_S + 0.5 * dt_s
            sel = (t >= lo) & (t <= hi)
        else:
            sel = np.zeros(len(t), bool)
            sel[group[0]] = True
        out |= sel
        spans.append((float(t[sel][0]), float(t[sel][-1]), int(sel.sum())))
    return out, spans


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
            drop, spans = _segments(flag, data.time_s, prep_all.dt_s)
            if drop.sum() > 0.5 * n:
                drop, spans = np.zeros(n, bool), []
            keep = ~drop
    else:
        spans = []
    count = int(n - keep.sum())
    return {'keep': keep, 'count': count, 'fraction': count / n,
            'segments': [list(s) for s in spans], 'sigma_rad_s': sigma,
            'threshold': threshold}
