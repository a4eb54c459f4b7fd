"""
The record's own noise: white noise plus correlated bias wander, and what it can fake.

A residual that is only noise still has structure in time: bias instability
(flicker) and rate random walk wander slowly, and a cause that depends on
time (a drift, a step) or on anything that changes slowly (temperature on a
one-way ramp, the tilt of a table) can fit part of that wander and predict
held-out blocks a little better than the baseline. ``diagnose`` measures
the wander and asks how much held-out gain it alone would give:

1. :func:`fit_noise`: the short-term per-sample spread of a residual
   (about a 1 s moving average) and its Allan deviation, made robust to
   the minority of windows that still hold structure (:func:`robust_adev`:
   the median of the squared second differences), fitted with N, B, K
   (:func:`gyro_emulator.analysis.allan.fit_noise_terms`, IEEE Std 952) for
   averaging times up to a tenth of the record. The residual is that of
   the model with the cause under test (what is left if the cause is
   real); for the tail bound of the test, the wider of that and the
   current model's (:meth:`NoiseModel.wider`).
2. :func:`draw_noise_records`: Gaussian noise with those terms at the mean
   times of *super-bins* (a few hundred groups of bins, each inside one
   fold): white noise averaged over the group, flicker as a sum of
   Gauss-Markov terms one per decade from the group length to ten record lengths
   (:func:`gyro_emulator.sensor.noise.flicker_unit_variance`), and a random
   walk, each exactly discretised at the (irregular) group times.
3. :func:`null_gain`: the cross-validation of :mod:`.cv` run on the
   simulations (same folds, same columns averaged over the groups, the
   cause's own search per fold) gives the held-out SSE reduction the noise
   alone produces, fold by fold. :mod:`.selection` subtracts it before the
   fold test. :func:`held_out_floor` gives the held-out RMS a correct model
   would leave: the noise floor of the verdict.
"""

from dataclasses import dataclass, replace
import functools
import math

from gyro_emulator.analysis import allan
from gyro_emulator.analysis.diagnose import cv as cvmod
from gyro_emulator.analysis.diagnose import models
from gyro_emulator.sensor import noise as sensor_noise
import numpy as np

#: Super-bins per fold in the simulations.
SUPER_PER_FOLD = 60
#: Simulated records per null estimate.
N_SIM = 64
#: The Allan fit uses averaging times up to this share of the record.
TAU_MAX_SHARE = 0.1
#: The terms :func:`draw_noise_records` draws, and so the only ones fitted: a share
#: of the curve given to quantization or rate ramp would be lost to the null.
NOISE_TERMS = ('arw', 'bias_instability', 'rrw')


@dataclass(frozen=True)
class NoiseModel:
    """White noise per sample and the IEEE Std 952 terms of the correlated wander."""

    white_sigma_rad_s: float
    arw_rad_s_sqrt_hz: float
    bias_instability_rad_s: float
    rrw_rad_s_sqrt_s: float
    tau_max_s: float

    def wider(self, other):
        """Return this model with the larger bias instability and random walk of the two."""
        return replace(self, bias_instability_rad_s=max(self.bias_instability_rad_s,
                                                        other.bias_instability_rad_s),
                       rrw_rad_s_sqrt_s=max(self.rrw_rad_s_sqrt_s, other.rrw_rad_s_sqrt_s),
                       tau_max_s=min(self.tau_max_s, other.tau_max_s))

    def as_dict(self):
        """JSON-ready form."""
        return {'white_sigma_rad_s': self.white_sigma_rad_s,
                'arw_rad_s_sqrt_hz': self.arw_rad_s_sqrt_hz,
                'bias_instability_rad_s': self.bias_instability_rad_s,
                'rrw_rad_s_sqrt_s': self.rrw_rad_s_sqrt_s,
                'allan_tau_max_s': self.tau_max_s}


def stretch_starts(time_s, dt_s):
    """Return the indices where a new stretch starts: after a step longer than 3 dt (a gap)."""
    return np.flatnonzero(np.diff(time_s) > 3.0 * dt_s) + 1


def _segments(time_s, values, dt_s):
    """Contiguous stretches (:func:`stretch_starts`) of at least 8 samples."""
    parts = np.split(values, stretch_starts(time_s, dt_s))
    return [p for p in parts if len(p) >= 8]


#: Median of a chi-square variable with one degree of freedom (median of z^2).
CHI2_1_MEDIAN = 0.454936423


def robust_adev(parts, rate_hz, taus=None):
    """
    Allan deviation from the median of the squared second differences.

    The overlapping estimator of :func:`gyro_emulator.analysis.allan.overlapping_adev`
    (its averaging times, degrees of freedom and confidence intervals kept)
    with AVAR(tau) = median(d^2) / (2 tau^2 x 0.4549) instead of the mean:
    the same value for Gaussian noise, but a minority of windows that hold
    unmodelled structure (a step, a short misfit) does not raise it.
    """
    result = allan.overlapping_adev(parts if len(parts) > 1 else parts[0], rate_hz, taus)
    dt = 1.0 / rate_hz
    phases = [np.concatenate([[0.0], np.cumsum((p - p.mean()) * dt)]) for p in parts]
    adev = np.empty(len(result.taus_s))
    for i, tau in enumerate(result.taus_s):
        m = int(round(tau * rate_hz))
        d = [ph[2 * m:] - 2.0 * ph[m:len(ph) - m] + ph[:len(ph) - 2 * m]
             for ph in phases if len(ph) > 2 * m]
        d2 = np.concatenate(d) ** 2
        adev[i] = math.sqrt(float(np.median(d2)) / (2.0 * tau ** 2 * CHI2_1_MEDIAN))
    scale = adev / np.maximum(result.adev, 1e-300)
    return replace(result, adev=adev, adev_lo=result.adev_lo * scale,
                   adev_hi=result.adev_hi * scale)


def _short_term_sigma(parts, dt_s):
    """
    Per-sample standard deviation of the noise faster than about a second.

    The mean square of each stretch about its moving average over M samples
    (M = 1 s, 10 to 200 samples), times M / (M - 1): the per-sample variance
    for white noise, and for noise a part's own filter has correlated from
    sample to sample too (sample-to-sample differences would under-read it
    by the factor 1 - rho_1).
    """
    m = int(min(200, max(10, round(1.0 / dt_s))))
    total, count = 0.0, 0
    for p in parts:
        k = min(m, max(2, len(p) // 2))
        c = np.concatenate([[0.0], np.cumsum(p)])
        mean = (c[k:] - c[:-k]) / k
        centre = p[k // 2:k // 2 + len(mean)]
        total += float(np.sum((centre - mean) ** 2)) * k / (k - 1)
        count += len(mean)
    return math.sqrt(max(total / max(count, 1), 1e-300))


def fit_noise(resid, time_s, dt_s, duration_s, resid_bins=None, time_bins=None, bin_s=None):
    """
    Fit the noise of a residual: short-term sigma per sample and N, B, K.

    Parameters
    ----------
    resid : numpy.ndarray
        Residual at the kept samples, rad/s.
    time_s : numpy.ndarray
        Their times, s (set-aside samples and logging gaps split stretches).
    dt_s : float
        Sample interval, s.
    duration_s : float
        Length of the record, s.
    resid_bins, time_bins : numpy.ndarray, optional
        The residual's bin means and the bins' times: the Allan deviation is
        computed on them (the same values for averaging times of whole
        bins, and far fewer points); default the samples.
    bin_s : float, optional
        Bin length, s.

    Returns
    -------
    NoiseModel
        The short-term per-sample sigma (:func:`_short_term_sigma`); N, B
        and K fitted to the robust Allan deviation (:func:`robust_adev`) up
        to a tenth of the record. B and K are 0 when the stretches are too
        short for three averaging times.

    """
    parts = _segments(time_s, resid, dt_s) or [resid]
    white = _short_term_sigma(parts, dt_s)
    step, bins = dt_s, resid_bins is not None and bin_s is not None and bin_s > 1.5 * dt_s
    if bins:
        parts = _segments(time_bins, resid_bins, bin_s) or [resid_bins]
        step = bin_s
    tau_max = TAU_MAX_SHARE * duration_s
    arw, b, k = white * math.sqrt(dt_s), 0.0, 0.0
    try:
        fit = allan.fit_noise_terms(robust_adev(parts, 1.0 / step), (0.5 * step, tau_max),
                                    terms=NOISE_TERMS)
        arw, b, k = fit.arw_rad_s_sqrt_hz, fit.bias_instability_rad_s, fit.rrw_rad_s_sqrt_s
        tau_max = min(tau_max, float(fit.taus_s[-1]))
    except ValueError:
        tau_max = 0.0
    return NoiseModel(white_sigma_rad_s=white, arw_rad_s_sqrt_hz=float(arw),
                      bias_instability_rad_s=float(b), rrw_rad_s_sqrt_s=float(k),
                      tau_max_s=float(tau_max))


#: Longest averaging time, s, and share of the record, of the Allan bound on the walk.
CAP_TAU_S = 100.0
CAP_TAU_SHARE = 0.05


def random_walk_cap(resid, time_s, dt_s, duration_s, tau_max_s=None):
    """
    Largest rate random walk the residual's short- and middle-term wander allows.

    A random walk of intensity K has Allan deviation K sqrt(tau / 3) (IEEE
    Std 952, Annex C), and every other term only adds to the curve, so each
    averaging time tau up to min(``CAP_TAU_S``, ``CAP_TAU_SHARE`` x the
    record) bounds K^2 <= 3 sigma_hi(tau)^2 / tau, sigma_hi the upper end of
    the 68 % interval of the robust Allan deviation (:func:`robust_adev`,
    which a minority of windows holding an effect does not raise). The
    tightest bound is returned: a slow effect raises the wander it shows at
    long averaging times, not at these, so a walk large enough to mimic
    it is refuted here (issue 23, root 1). Flicker is not charged to K: it
    only loosens the bound. ``tau_max_s`` replaces that limit: the residual
    of a model that holds the effects (the sandwich's, :func:`.intervals.
    wander_law`) bounds K at every averaging time up to a quarter of its
    longest segment, where a walk shows most.

    Returns
    -------
    float
        The bound on K^2, rad^2/s^3 (``math.inf`` when the record is too
        short for two averaging times of at least 4 samples).

    """
    parts = _segments(time_s, resid, dt_s) or [resid]
    tau_max = min(CAP_TAU_S, CAP_TAU_SHARE * duration_s) if tau_max_s is None else tau_max_s
    longest = max(len(p) for p in parts) * dt_s
    tau_max = min(tau_max, 0.25 * longest)
    if tau_max < 8.0 * dt_s:
        return math.inf
    m = np.unique(np.round(np.geomspace(4.0, tau_max / dt_s, 8)).astype(int))
    try:
        res = robust_adev(parts, 1.0 / dt_s, m * dt_s)
    except ValueError:
        return math.inf
    bound = 3.0 * res.adev_hi ** 2 / res.taus_s
    bound = bound[np.isfinite(bound)]
    return float(np.min(bound)) if len(bound) else math.inf


class SuperBins:
    """
    Groups of contiguous bins, each inside one fold: the resolution of the simulations.

    Parameters
    ----------
    binned : gyro_emulator.analysis.diagnose.data.Frame
        The bin means.
    fold_of_bin : numpy.ndarray of int
        Fold of every bin.
    dt_s : float
        Sample interval, s.
    per_fold : int
        Groups per fold (fewer when a fold has fewer bins).

    """

    def __init__(self, binned, fold_of_bin, dt_s, per_fold=SUPER_PER_FOLD):
        self.dt_s = float(dt_s)
        group = np.empty(len(binned), dtype=np.int64)
        base = 0
        folds = []
        for k in np.unique(fold_of_bin):
            idx = np.flatnonzero(fold_of_bin == k)
            m = min(per_fold, len(idx))
            group[idx] = base + (np.arange(len(idx)) * m) // len(idx)
            folds += [k] * m
            base += m
        self.group = group
        self.fold = np.asarray(folds)
        self._bin_weight = binned.weight
        self.weight = np.bincount(group, weights=binned.weight)
        self.time_s = self.aggregate(binned.time_s)
        starts = np.flatnonzero(np.r_[True, group[1:] != group[:-1]])
        self.start_s = binned.bins.bin_start_s[starts]

    def __len__(self):
        """Return the number of groups."""
        return len(self.weight)

    def aggregate(self, values_on_bins):
        """Return the sample-weighted group means of a column given on the bins."""
        values = np.broadcast_to(values_on_bins, self.group.shape)
        return np.bincount(self.group, weights=values * self._bin_weight) / self.weight


def _flicker_terms(noise, time_s):
    """
    Return (correlation times s, variances rad^2/s^2) of the flicker's Gauss-Markov sum.

    One term per decade from the median gap of ``time_s`` to ten times its
    span (:func:`gyro_emulator.sensor.noise.flicker_corr_times_s`), scaled
    to the bias instability B.
    """
    t = np.asarray(time_s, dtype=float)
    span = max(float(t[-1] - t[0]), 1e-9)
    shortest = max(float(np.median(np.diff(t))) if len(t) > 1 else span, 1e-6)
    taus = sensor_noise.flicker_corr_times_s((shortest, 10.0 * span))
    return taus, sensor_noise.flicker_unit_variance(taus) * noise.bias_instability_rad_s ** 2


def wander_covariance(noise, superbins):
    """
    Covariance of the correlated wander at the super-bin times, rad^2/s^2: (groups, groups).

    The law :func:`draw_noise_records` draws, without its white part: a
    random walk from the first group, K^2 (min(t_i, t_j) - t_0), plus the
    flicker's stationary Gauss-Markov terms, sum_k q_k exp(-|t_i - t_j| /
    T_k) (:func:`_flicker_terms`).
    """
    t = superbins.time_s
    rel = t - t[0]
    cov = noise.rrw_rad_s_sqrt_s ** 2 * np.minimum.outer(rel, rel)
    if noise.bias_instability_rad_s > 0.0:
        lag = np.abs(np.subtract.outer(t, t))
        for tau, q in zip(*_flicker_terms(noise, t)):
            cov += q * np.exp(-lag / tau)
    return cov


def draw_noise_records(noise, superbins, n_sim, rng):
    """
    Noise records at the super-bin times: white averaged per group, flicker, random walk.

    Returns an array (groups, n_sim) of group means, rad/s: white noise of
    density N averaged over each group (variance N^2 / (n dt)). Exact
    discretisation at irregular times: a random walk adds K sqrt(dt_i) z; a
    Gauss-Markov term of variance q and correlation time T moves by
    x_i = phi_i x_{i-1} + sqrt(q (1 - phi_i^2)) z, phi_i = exp(-dt_i / T),
    from its stationary law.
    """
    t = superbins.time_s
    n = len(t)
    out = rng.standard_normal((n, n_sim)) * (
        noise.arw_rad_s_sqrt_hz / np.sqrt(superbins.weight * superbins.dt_s))[:, None]
    gaps = np.diff(t, prepend=t[0])
    if noise.rrw_rad_s_sqrt_s > 0.0:
        out += np.cumsum(rng.standard_normal((n, n_sim)) * np.sqrt(gaps)[:, None],
                         axis=0) * noise.rrw_rad_s_sqrt_s
    if noise.bias_instability_rad_s > 0.0:
        for tau, q in zip(*_flicker_terms(noise, t)):
            phi = np.exp(-gaps / tau)
            kick = np.sqrt(q * (1.0 - phi ** 2))
            z = rng.standard_normal((n, n_sim))
            x = np.empty((n, n_sim))
            x[0] = math.sqrt(q) * z[0]
            for i in range(1, n):
                x[i] = phi[i] * x[i - 1] + kick[i] * z[i]
            out += x
    return out


def _held_out(x_tr, w_tr, y_tr, x_ho, penalty=None, resid=False):
    """
    Fit every column of ``y_tr`` (training rows) on ``x_tr``; predict the held-out rows.

    :func:`gyro_emulator.analysis.diagnose.models.solve_normal`, with the
    causes' ridge ``penalty`` (:meth:`.models.Model.penalty`). Returns
    (predictions, training SSE per column), and with ``resid`` the
    training residuals.
    """
    beta, _, _ = models.solve_normal(x_tr, w_tr, y_tr, penalty)
    resid_tr = y_tr - x_tr @ beta
    out = (x_ho @ beta, np.sum(w_tr[:, None] * resid_tr ** 2, axis=0))
    return out + (resid_tr,) if resid else out


def _warm_up_pick(values, fits, w_tr, unseen):
    """
    Return the value each simulation's warm-up fit takes (:func:`.models.warm_up_resolved`).

    ``fits`` are :func:`_held_out`'s (with residuals) at ``values``: the
    least SSE where the rows resolve the extrapolation, else the least SSE
    at a time constant of at least ``unseen`` (:func:`.models.held_grid`).
    """
    sses = np.array([f[1] for f in fits])
    least = np.argmin(sses, axis=0)
    n_eff = np.array([models.effective_bins(fits[i][2][:, j], w_tr)
                      for j, i in enumerate(least)])
    held = np.where(np.asarray(values)[:, None] >= unseen, sses, np.inf)
    return np.where(models.warm_up_resolved(values, sses, n_eff, unseen), least,
                    np.argmin(held, axis=0))


@dataclass(frozen=True)
class Searched:
    """
    A candidate's added columns for the simulations, searched over its grid as its fits are.

    ``values`` are its grid values (None: no grid), ``column_set`` returns
    its columns on the groups at a value ((groups, q); at None without a
    grid), ``unseen_of`` the time a warm-up fitted on training groups (a
    bool mask) is held to (:func:`.models.unseen_s`; 0: none), and
    ``time_shaped`` says whether it is carried into the end folds only
    where it predicts their neighbour (:meth:`.cv.CrossValidation.evaluate`).
    """

    values: object
    column_set: object
    unseen_of: object
    time_shaped: bool = False

    def entry(self, train):
        """Return (values, column sets, unseen s) of a fit on the training groups ``train``."""
        if self.values is None:
            return None, [self.column_set(None)], 0.0
        unseen = self.unseen_of(train)
        values = np.unique(np.r_[self.values, unseen]) if unseen else self.values
        return values, [self.column_set(float(v)) for v in values], unseen


def _searched_fit(current_cols, candidate, w, sims, pen, tr, ho):
    """
    Return each simulation's prediction of the groups ``ho`` by the candidate fitted on ``tr``.

    ``candidate`` a :class:`Searched` (its grid searched as its fits search
    it: the least training SSE, or for a warm-up after the record's start
    :func:`_warm_up_pick`) or a list of column sets (the least SSE).
    """
    values, sets, unseen = candidate.entry(tr) if isinstance(candidate, Searched) else \
        (None, candidate, 0.0)
    fits = [_held_out(x[tr], w[tr], sims[tr], x[ho], pen, resid=bool(unseen))
            for x in (np.column_stack([current_cols, cols]) for cols in sets)]
    pick = _warm_up_pick(values, fits, w[tr], unseen) if unseen else \
        np.argmin(np.array([f[1] for f in fits]), axis=0)
    return np.array([f[0] for f in fits])[pick, :, np.arange(sims.shape[1])].T


def _carried_on(current_cols, fit, w, sims, pen0, origins, tr, pred1, pred0, bound, within):
    """
    Return an end fold's predictions: the candidate's where it is carried on, else the current's.

    Each simulation as :meth:`.cv.CrossValidation.evaluate` decides: at each
    origin (``origins``, group masks nearest first, :func:`.cv.end_folds`),
    fitted without it and the origins before it too, the candidate
    (``fit``) and the current model predict it; on the nearest origin and
    on all together the candidate must be better by the simulation's own
    ``bound`` (:func:`.cv.carries_on`). ``within`` is the groups'
    within-group noise SSE, which the fits' per-sample SSEs hold.
    """
    sse_c, sse_0 = [], []
    inner = tr.copy()
    for origin in origins:
        inner &= ~origin
        pc = fit(inner, origin)
        p0, _ = _held_out(current_cols[inner], w[inner], sims[inner], current_cols[origin], pen0)
        extra = float(np.sum(within[origin]))
        sse_c.append(np.sum(w[origin, None] * (sims[origin] - pc) ** 2, axis=0) + extra)
        sse_0.append(np.sum(w[origin, None] * (sims[origin] - p0) ** 2, axis=0) + extra)
    return np.where(cvmod.carries_on(np.array(sse_c), np.array(sse_0), bound)[None, :],
                    pred1, pred0)


def null_gain(current_cols, candidate, superbins, sims, penalty=None, white_sigma=0.0):
    """
    Held-out SSE reductions that noise alone gives a candidate, per fold and simulation.

    Parameters
    ----------
    current_cols : numpy.ndarray
        The current model's columns on the groups, (groups, p).
    candidate : list or Searched or tuple
        The candidate's added columns on the groups for each value of its
        grid (a list of (groups, q) arrays: the search picks, per fold and
        simulation, the value with the least training SSE), or a
        :class:`Searched` (searched per fold as its fits are, and for a
        shape in time carried into the end folds only where it predicts
        the folds next to them, :func:`_carried_on`), or
        ``('step', g, start_s)``: a step multiplying ``g`` that may start
        at any group start (located on all groups of each simulation with
        :func:`.models.step_search`, then its size refitted per fold, as
        :mod:`.models` does).
    superbins : SuperBins
        The groups.
    sims : numpy.ndarray
        Simulated noise, (groups, n_sim).
    penalty : tuple, optional
        The ridge of the current model's columns, and that of the model
        extended's, the current model's columns first, as they are in it
        (:meth:`.models.Model.penalty`: a cause before the last gets only
        :data:`.models.HELD_RIDGE`): (p,) and (p + q,) arrays.
    white_sigma : float, optional
        The noise's short-term per-sample spread, rad/s: each group's
        (n_g - 1) sigma^2 of within-group noise is added to the SSEs that
        decide whether a shape in time is carried on, as the fits'
        per-sample SSEs hold it.

    Returns
    -------
    numpy.ndarray
        SSE_current - SSE_candidate on each fold's held-out rows, weighted
        by samples: (folds in the order of ``numpy.unique(superbins.fold)``,
        simulations).

    """
    w = superbins.weight
    pen0, pen = (None, None) if penalty is None else penalty
    out = []
    if isinstance(candidate, tuple):
        _, g, start = candidate
        at = models.step_search(current_cols, g, w, sims)
        steps = g[:, None] * (start[:, None] >= start[at][None, :])
    folds = np.unique(superbins.fold)
    current = [_held_out(current_cols[~ho], w[~ho], sims[~ho], current_cols[ho], pen0)[0]
               for ho in (superbins.fold == k for k in folds)]
    sse_current = np.array([np.sum(w[superbins.fold == k, None] * (sims[superbins.fold == k] - p)
                                   ** 2, axis=0) for k, p in zip(folds, current)])
    kept, within = {}, np.maximum(w - 1.0, 0.0) * white_sigma ** 2
    if isinstance(candidate, Searched) and candidate.time_shaped:
        kept = dict(cvmod.end_folds(folds))
        within_fold = np.array([np.sum(within[superbins.fold == k]) for k in folds])
        n_fold = [np.sum(w[superbins.fold == k]) for k in folds]
    for i, k in enumerate(folds):
        ho = superbins.fold == k
        tr = ~ho
        pred0, sse0 = current[i], sse_current[i]
        if isinstance(candidate, tuple):
            pred1 = np.empty((int(ho.sum()), sims.shape[1]))
            for j in range(sims.shape[1]):
                x = np.column_stack([current_cols, steps[:, j]])
                pred1[:, j] = _held_out(x[tr], w[tr], sims[tr, j:j + 1], x[ho],
                                        pen)[0][:, 0]
        else:
            fit = functools.partial(_searched_fit, current_cols, candidate, w, sims, pen)
            pred1 = fit(tr, ho)
            if k in kept:
                origins = [superbins.fold == j for j in kept[k]]
                bound = cvmod.fold_bound(sse_current + within_fold[:, None], n_fold, i)
                pred1 = _carried_on(current_cols, fit, w, sims, pen0, origins, tr, pred1, pred0,
                                    bound, within)
        sse1 = np.sum(w[ho, None] * (sims[ho] - pred1) ** 2, axis=0)
        out.append(sse0 - sse1)
    return np.asarray(out)


def held_out_residuals(cols, superbins, sims, penalty=None):
    """
    Held-out residuals of the simulations under a model: (groups, simulations).

    The simulations are fitted with the model's columns averaged over the
    groups (and its ridge ``penalty``) and predicted fold by fold, as the
    cross-validation does.
    """
    w = superbins.weight
    out = np.empty_like(sims)
    for k in np.unique(superbins.fold):
        ho = superbins.fold == k
        pred, _ = _held_out(cols[~ho], w[~ho], sims[~ho], cols[ho], penalty)
        out[ho] = sims[ho] - pred
    return out


def held_out_floor(noise, resid, superbins, n_kept):
    """
    Held-out residual a correct model leaves on noise alone: the noise floor.

    ``resid`` are the held-out residuals of the simulations under the model
    (:func:`held_out_residuals`, groups x simulations); the within-group
    noise, (n_g - 1) sigma^2 per group (sigma the short-term per-sample
    spread), is added for the per-sample RMS.

    Returns
    -------
    (float, numpy.ndarray, numpy.ndarray)
        The floor of the per-sample RMS, rad/s; each simulation's per-sample
        RMS; each simulation's mean square of the held-out group means
        (weighted by samples), (rad/s)^2.

    """
    w = superbins.weight
    sse = np.sum(w[:, None] * resid ** 2, axis=0)
    within = float(np.sum(np.maximum(w - 1.0, 0.0))) * noise.white_sigma_rad_s ** 2
    rms = np.sqrt((sse + within) / n_kept)
    return float(np.sqrt(np.mean(rms ** 2))), rms, sse / float(np.sum(w))
