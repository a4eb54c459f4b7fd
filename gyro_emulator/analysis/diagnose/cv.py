"""
Held-out evidence: contiguous folds, a fold-level test and an effective-sample BIC.

The record is cut into ``folds`` contiguous blocks of equal duration; a
model is fitted on all other blocks (bin means, :mod:`.models`) and
predicts each block sample by sample. Residuals of neighbouring samples
and blocks are correlated (bias wander, slow unmodelled structure), so the
evidence is counted in folds, not samples:

- :func:`fold_test`: the held-out SSE reduction relative to the reference
  model, fold by fold, u_k = (SSE_ref,k - SSE_new,k - E0_k) / SSE_ref,k,
  where E0_k is the reduction the record's own noise would give
  (:func:`.noise_model.null_gain`); a one-sided t-test of mean(u) > 0 with
  K - 1 degrees of freedom and the variance inflated for the overlap of
  the training sets, var (1/K + 1/(K - 1)) (Nadeau & Bengio 2003, the
  corrected resampled t-test);
- :func:`effective_bic`: BIC on the bin means with the number of
  observations replaced by the effective number of independent bins,
  n (1 - rho) / (1 + rho), rho the lag-1 autocorrelation of the richer
  model's bin residuals;
- :meth:`CrossValidation.interval`: the delete-a-fold jackknife interval of
  a held-out RMSE, or of the gain 1 - RMSE / RMSE_ref over a reference
  scored on the same folds (Efron & Stein 1981: sigma^2 = (K - 1)/K
  sum_k (theta_(k) - mean theta_(.))^2; theta_(k) the figure with fold k
  left out; half width t_{K-1} sigma at :data:`INTERVAL_LEVEL`). It is the
  spread the claimed figure has over the record's own blocks: an emulator
  that reproduces the extension scores within it.
"""

from dataclasses import dataclass, field
import math

from gyro_emulator.analysis.diagnose import models
import numpy as np
from scipy.special import stdtr, stdtrit

#: Two-sided level of the held-out RMSE and gain intervals.
INTERVAL_LEVEL = 0.95


@dataclass
class Evaluated:
    """
    One model under cross-validation: per-fold fits, held-out residuals, full fit.

    ``kept_back`` holds, for a held-out end fold where the model's shapes in
    time are not carried on (:meth:`CrossValidation.evaluate`), the model
    without them and its fit on that fold's training rows: {fold: (model, fit)}.
    """

    model: object
    fits: dict
    resid: np.ndarray
    sse_fold: np.ndarray
    full: object
    rmse: float
    kept_back: dict = field(default_factory=dict)

    def predict(self, ctx, frame, k):
        """Return the held-out prediction of fold ``k`` at ``frame``'s rows, rad/s."""
        model, fit = self.kept_back.get(k, (self.model, self.fits[k]))
        return models.predict(model, ctx, frame, fit)


class CrossValidation:
    """
    Contiguous folds of a prepared record.

    Parameters
    ----------
    prep : gyro_emulator.analysis.diagnose.data.Prepared
        The record (kept samples, bins).
    ctx : gyro_emulator.analysis.diagnose.effects.Context
        Physics and reference points.
    folds : int
        Number of folds.

    """

    def __init__(self, prep, ctx, folds):
        b = prep.binned
        t0 = float(prep.data.time_s[0])
        span = prep.duration_s
        self.fold_of_bin = np.minimum(((b.time_s - t0) / span * folds).astype(int), folds - 1)
        self.fold_of_sample = self.fold_of_bin[prep.sample_bin]
        self.used_folds = [k for k in range(folds) if np.any(self.fold_of_bin == k)]
        self.y = prep.samples.gyro
        self.prep, self.ctx = prep, ctx
        self.n_rows = len(b)

    def held_out(self, pred_for_fold):
        """Return the held-out residual of every kept sample and the SSE per used fold."""
        resid = np.empty(len(self.y))
        for k in self.used_folds:
            mask = self.fold_of_sample == k
            resid[mask] = self.y[mask] - pred_for_fold(k)[mask]
        sse = np.bincount(self.fold_of_sample, weights=resid * resid,
                          minlength=max(self.used_folds) + 1)[self.used_folds]
        return resid, sse

    def fold_samples(self):
        """Return the number of kept samples in each used fold."""
        return np.bincount(self.fold_of_sample,
                           minlength=max(self.used_folds) + 1)[self.used_folds].astype(float)

    def interval(self, sse_fold, sse_ref=None, level=INTERVAL_LEVEL):
        """
        Delete-a-fold jackknife interval of a held-out RMSE, rad/s (module docstring).

        ``sse_fold`` is the SSE per used fold; with ``sse_ref`` (a
        reference's, on the same folds) the interval is that of the gain
        1 - RMSE / RMSE_ref. Returns (low, high), or None with fewer than 3
        used folds.
        """
        spread = rmse_jackknife(sse_fold, self.fold_samples(), sse_ref, level)
        if spread is None:
            return None
        full, half = (float(v) for v in spread)
        return (full - half, full + half)

    def evaluate(self, model, fixed_by_fold=None, fixed_full=None, extends=None):
        """
        Fit ``model`` per fold and on everything; return an :class:`Evaluated`.

        ``fixed_by_fold`` ({fold: phis}) and ``fixed_full`` hold the
        non-linear parameters of every cause but the last (those of the
        model the last cause is added to); None for a model of at most one
        cause. The last cause's parameters are searched on all rows first,
        then locally around that fit for each fold. ``extends``: the
        :class:`Evaluated` model this one extends, whose held-out spread
        sets how much better a shape in time must predict the folds next to
        an end fold to be carried on (:func:`carries_on`).
        """
        b = self.prep.binned
        full = models.fit_model(model, self.ctx, b, None, fixed_full)
        start = full.phis[-1] if model.effects and full.phis[-1] else None
        fits = {k: models.fit_model(model, self.ctx, b, self.fold_of_bin != k,
                                    None if fixed_by_fold is None else fixed_by_fold[k],
                                    start=start)
                for k in self.used_folds}
        ev = Evaluated(model, fits, None, None, full, 0.0,
                       self._kept_back(model, fixed_by_fold, start,
                                       None if extends is None else extends.sse_fold))
        ev.resid, ev.sse_fold = self.held_out(
            lambda k: ev.predict(self.ctx, self.prep.samples, k))
        ev.rmse = math.sqrt(float(np.sum(ev.sse_fold)) / len(self.y))
        return ev

    def _kept_back(self, model, fixed_by_fold, start, sse_extended=None):
        """
        Return, for each end fold where the shapes in time stop, the model without them.

        A cause that is a shape in time (``time_shaped``: a warm-up and
        drift, a scale factor polynomial in time) predicts the first and
        last fold from the training rows on one side only: it carries the
        shape on one fold past them. It is carried on only where it does
        so on the training rows, at the origins next to the end fold
        (:func:`end_folds`: rolling-origin evaluation, Tashman 2000): fitted
        without the end fold, the origin and the folds between them, it
        predicts the nearest origin, and the origins together, better than
        the model without its shapes in time does by more than the
        jackknife spread of the held-out RMSE of the model extended over the
        other folds (``sse_extended``, :func:`fold_bound`,
        :func:`carries_on`: the held-out fold plays no part); otherwise the
        end fold is predicted by the model without them. A
        temperature-driven bias or scale factor taken up by a polynomial in
        time and carried into the end folds predicted them up to 1.5x
        (scale factor) and 8x (a warm-up from its tail) worse than the
        model it extends. Judged on the nearest origin alone, a scale
        factor tempco taken up by a polynomial in time passed where it
        happened to hold (0.52x; the next origin 3.1x) and missed the end
        fold 5.7x; judged on the origins together alone, a warm-up that
        missed the nearest origin (0.96x against a bound of 0.95x) passed
        on the next (0.90x) and missed the end fold 1.5x.
        Returns {fold: (model without the time shapes, its fit on the fold's
        training rows)}.
        """
        keep = [i for i, e in enumerate(model.effects) if not e.time_shaped]
        if len(keep) == len(model.effects):
            return {}
        base = models.Model([model.effects[i] for i in keep])
        searched = bool(keep) and keep[-1] == len(model.effects) - 1
        b, s = self.prep.binned, self.prep.samples
        base_start = start if searched else None
        n_fold = self.fold_samples()
        out = {}
        for k, origins in end_folds(self.used_folds):
            fixed = () if fixed_by_fold is None else tuple(fixed_by_fold[k])
            base_fixed = tuple(fixed[i] for i in keep if i < len(fixed))
            sse = np.zeros((2, len(origins)))
            for depth, origin in enumerate(origins):
                rows = ~np.isin(self.fold_of_bin, (k,) + origins[:depth + 1])
                mask = self.fold_of_sample == origin
                for j, (form, fx, st) in enumerate(((model, fixed or None, start),
                                                    (base, base_fixed, base_start))):
                    fit = models.fit_model(form, self.ctx, b, rows, fx or None, start=st)
                    sse[j, depth] = float(np.sum((self.y[mask] - models.predict(
                        form, self.ctx, s, fit)[mask]) ** 2))
            if not carries_on(*sse, fold_bound(sse_extended, n_fold, self.used_folds.index(k))):
                out[k] = (base, models.fit_model(base, self.ctx, b, self.fold_of_bin != k,
                                                 base_fixed or None, start=base_start))
        return out


def end_folds(folds, origins=2):
    """
    Return (end fold, its origins) for the first and the last of ``folds``.

    The held-out folds a shape in time is carried into from one side
    (:meth:`CrossValidation._kept_back`), each with the ``origins`` folds
    next to it, nearest first (a tuple), at which the carrying is judged:
    at most as many as leave training rows beyond them (K - 2 of K folds).
    None with fewer than 3 folds.
    """
    folds = list(folds)
    if len(folds) < 3:
        return []
    n = min(origins, len(folds) - 2)
    return [(folds[0], tuple(folds[1:1 + n])), (folds[-1], tuple(folds[-2:-2 - n:-1]))]


def rmse_jackknife(sse_fold, n_fold, sse_ref=None, level=INTERVAL_LEVEL):
    """
    Return (figure, half width) of the delete-a-fold jackknife interval of a held-out RMSE.

    ``sse_fold``: SSE per fold, (folds,) or (folds, records); ``n_fold``:
    samples per fold. The figure is the RMSE, or with ``sse_ref`` (a
    reference's, on the same folds) the gain 1 - RMSE / RMSE_ref; the half
    width t_{K-1} sigma, sigma^2 = (K-1)/K sum_k (figure_(k) - mean)^2 over
    the K figures without fold k (module docstring). None with fewer than
    3 folds. The one computation of :meth:`CrossValidation.interval` and
    :func:`rmse_bound`.
    """
    sse = np.asarray(sse_fold, dtype=float)
    ref = None if sse_ref is None else np.asarray(sse_ref, dtype=float)
    n = np.asarray(n_fold, dtype=float)
    k = len(n)
    if k < 3:
        return None

    def figure(keep):
        rmse = np.sqrt(np.sum(sse[keep], axis=0) / np.sum(n[keep]))
        return rmse if ref is None else 1.0 - rmse / np.sqrt(
            np.sum(ref[keep], axis=0) / np.sum(n[keep]))

    full = figure(np.ones(k, bool))
    loo = np.array([figure(np.arange(k) != j) for j in range(k)])
    sigma = np.sqrt((k - 1) / k * np.sum((loo - loo.mean(axis=0)) ** 2, axis=0))
    return full, float(stdtrit(k - 1, 0.5 + level / 2.0)) * sigma


def rmse_bound(sse_fold, n_fold, level=INTERVAL_LEVEL):
    """
    Upper end of the jackknife interval of a held-out RMSE over that RMSE (vectorised).

    ``sse_fold``: SSE per fold, (folds,) or (folds, records); ``n_fold``:
    samples per fold. The ratio high / RMSE of
    :meth:`CrossValidation.interval` (:func:`rmse_jackknife`); 1 with fewer than
    3 folds.
    """
    spread = rmse_jackknife(sse_fold, n_fold, level=level)
    if spread is None:
        sse = np.asarray(sse_fold)
        return np.ones(sse.shape[1:]) if sse.ndim > 1 else 1.0
    full, half = spread
    return 1.0 + half / full


def fold_bound(sse_fold, n_fold, i):
    """
    Return the carrying bound for the held-out fold at position ``i``: 1 without ``sse_fold``.

    :func:`rmse_bound` of the model extended over the folds other than the
    held-out one, so the decision to carry a shape into it does not see it;
    ``sse_fold`` (folds,) or (folds, records).
    """
    if sse_fold is None:
        return 1.0
    return rmse_bound(np.delete(np.asarray(sse_fold, dtype=float), i, axis=0),
                      np.delete(np.asarray(n_fold, dtype=float), i))


def carries_on(sse_shape, sse_without, bound=1.0):
    """
    Tell whether a model's shapes in time are carried into a held-out end fold.

    ``sse_shape`` and ``sse_without``: the SSE of the end fold's origins
    (:func:`end_folds`, nearest first: (origins,) or (origins, records);
    a scalar is one origin), each predicted from the rows beyond it, by the
    model and by the model without its shapes in time; ``bound``: the
    upper end of the jackknife interval of the held-out RMSE of the model
    extended over that RMSE, on the folds other than the end fold
    (:func:`fold_bound`). Carried on where the shape's RMSE is at most the
    other's divided by ``bound`` on the nearest origin (the extrapolation
    into the end fold, from the most rows) and on all origins together
    (that it holds beyond one fold): better by more than the record's own
    blocks move the held-out RMSE of the model extended, the spread within
    which the rule of the fits lets a candidate be worse. The one rule of
    the fits (:meth:`CrossValidation._kept_back`) and of the noise-only
    simulations (:func:`.noise_model.null_gain`).
    """
    shape = np.atleast_1d(np.asarray(sse_shape, dtype=float))
    without = np.atleast_1d(np.asarray(sse_without, dtype=float))
    b2 = np.square(bound)
    out = (shape[0] * b2 <= without[0]) & (np.sum(shape, axis=0) * b2 <= np.sum(without, axis=0))
    return bool(out) if np.ndim(out) == 0 else out


def fold_test(sse_ref, sse_new, null_reduction=None):
    """
    One-sided fold test that ``sse_new`` is lower than ``sse_ref``.

    Parameters
    ----------
    sse_ref, sse_new : numpy.ndarray
        Held-out SSE per fold of the reference and the new model.
    null_reduction : numpy.ndarray, optional
        SSE reduction per fold that noise alone would give (subtracted).

    Returns
    -------
    float
        p-value of mean(u) > 0 (see the module docstring); 1 with fewer
        than 3 folds.

    """
    ref = np.asarray(sse_ref, dtype=float)
    new = np.asarray(sse_new, dtype=float)
    null = np.zeros(len(ref)) if null_reduction is None else np.asarray(null_reduction)
    ok = ref > 0.0
    u = (ref[ok] - new[ok] - null[ok]) / ref[ok]
    k = len(u)
    if k < 3:
        return 1.0
    mean = float(np.mean(u))
    var = float(np.var(u, ddof=1)) * (1.0 / k + 1.0 / (k - 1))
    if var <= 0.0:
        return 0.0 if mean > 0.0 else 1.0
    return float(stdtr(k - 1, -mean / math.sqrt(var)))


def tail_bound(observed, null_totals):
    """
    Distribution-free p-value bound of an observed held-out SSE reduction.

    With m the median of the simulated null reductions, Markov's inequality
    on the squared upper excess gives P(X >= observed) <=
    E[(X - m)_+^2] / (observed - m)^2 for any law of X: no normal tail is
    assumed (the null is skewed and heavy-tailed), and the rare
    simulations where a candidate extrapolates badly (large negative
    reductions) do not widen it.
    """
    x = np.asarray(null_totals, dtype=float)
    m = float(np.median(x))
    if observed <= m:
        return 1.0
    upper = float(np.mean(np.maximum(x - m, 0.0) ** 2))
    return min(1.0, upper / (observed - m) ** 2)


#: Effective number of independent bins of a residual (:func:`.models.effective_bins`).
effective_bins = models.effective_bins


def effective_bic(sse_new, sse_ref, extra_params, n_eff):
    """
    BIC difference of the richer model on ``n_eff`` effective observations.

    n_eff ln(SSE_new / SSE_ref) + k ln(n_eff), SSEs of the full fits on the
    bin means (negative: the richer model is preferred).
    """
    ratio = max(sse_new, 1e-300) / max(sse_ref, 1e-300)
    return n_eff * math.log(ratio) + extra_params * math.log(n_eff)
