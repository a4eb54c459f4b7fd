"""
Models: the baseline plus a list of causes, fitted by weighted least squares.

A :class:`Model` composes causes (:mod:`.effects`, :mod:`.generic`)::

    gyro = b0 + s0 s Omega_s + sum of the causes' columns
    s = R(T) prod(sf_factor),  Omega_s = Omega(t - sum(delay))

Parameters that enter linearly are solved by weighted least squares on the
bin means (weights: samples per bin), the last cause's coefficients held to
its physical range by a ridge (:meth:`Model.penalty`: a Gaussian prior of
that width, so that a direction the training rows do not determine, such as
a step column equal to the rate column when every training row is past the
step, goes to zero instead of to a cancelling pair that blows up the
held-out prediction); the causes before it, already chosen, take such a
direction from it. The others, one set per cause, are
found by variable projection: a grid search, each point solving the linear
part, then a bounded refinement (:func:`fit_model`); a step time by an
exact search over every bin start (:func:`change_point`). When a cause is
added to a fitted model (forward selection), the non-linear parameters of
the causes already in it stay fixed and only the new one is searched.
"""

from dataclasses import dataclass

from gyro_emulator.analysis.diagnose.effects import Basis, cached, slow_temp
import numpy as np
from scipy.optimize import minimize, minimize_scalar
from scipy.stats import chi2

#: Rows kept at each end of a change-point search (share of the rows, and at least 3).
STEP_MARGIN = 0.02
#: Least ridge of a cause's column on the unit-scaled normal equations (:func:`solve_normal`).
MIN_RIDGE = 1e-6
#: Ridge of a cause before the last of a model on the unit-scaled normal equations: between
#: the baseline's (1e-12) and :data:`MIN_RIDGE`, so where the training rows cannot tell
#: columns apart the baseline takes it first, then the causes already chosen, and the cause
#: added last only what is left (:meth:`Model.penalty`).
HELD_RIDGE = 1e-9
#: :meth:`Model.penalty`'s mark of a column that gets :data:`HELD_RIDGE`.
HELD_BY_DATA = -1.0
#: chi^2 with 1 degree of freedom at 95 %: the profile limit of :func:`warm_up_resolved`.
PROFILE_CHI2 = float(chi2.ppf(0.95, 1))


@dataclass
class Fit:
    """One model fitted on a set of rows: linear coefficients, non-linear parameters, SSE."""

    beta: np.ndarray
    phis: tuple
    sse: float


class Model:
    """The baseline ``[1, s Omega_s]`` plus causes; ``Model(())`` is the recalibrated baseline."""

    def __init__(self, effects=()):
        self.effects = tuple(effects)

    @property
    def ids(self):
        """Return the causes' ids, in order."""
        return tuple(e.effect_id for e in self.effects)

    @property
    def n_columns(self):
        """Regressor columns (:meth:`columns`): the baseline's two and every cause's."""
        return 2 + sum(e.n_columns for e in self.effects)

    @property
    def n_params(self):
        """Free parameters, b0 and s0 included."""
        return 2 + sum(e.n_params for e in self.effects)

    def extend(self, effect):
        """Return this model with ``effect`` added last."""
        return Model(self.effects + (effect,))

    def basis(self, ctx, frame, phis):
        """Return the :class:`.effects.Basis` (s and s Omega_s) at ``frame``'s rows."""
        s_bins = base_ratio(ctx, frame)
        delay = 0.0
        for eff, phi in zip(self.effects, phis):
            factor = eff.sf_factor(ctx, frame, phi)
            if factor is not None:
                s_bins = s_bins * factor
            delay += eff.delay_s(phi)
        if delay == 0.0:
            rate = frame.rate
        elif frame.level == 'bins':
            rate = cached(frame, ('delayed', float(delay)), lambda: frame.delayed_rate(delay))
        else:
            rate = frame.delayed_rate(delay)
        s = frame.slow(s_bins)
        return Basis(s=s, sr=s * rate)

    def columns(self, ctx, frame, phis):
        """Regressor columns ``[1, s Omega_s, cause columns ...]`` at ``frame``'s rows."""
        basis = self.basis(ctx, frame, phis)
        cols = [np.ones(len(frame)), basis.sr]
        for eff, phi in zip(self.effects, phis):
            cols += eff.columns(ctx, frame, phi, basis)
        return cols

    def penalty(self, ctx, noise_var_rad2_s2=None):
        """
        Ridge weights of the columns (:meth:`columns`): 0 for ``[1, s Omega_s]``.

        The last cause's column with prior width r (its physical range,
        :meth:`.effects.Effect.column_scales`) gets sigma^2 / r^2, sigma^2
        the per-sample noise variance (``ctx.noise_var_rad2_s2``, or
        ``noise_var_rad2_s2``): the penalised weighted least squares is then
        the posterior mode under a N(0, r^2) prior on the coefficient. The
        causes before it are the model it extends, chosen on the data: they
        are marked :data:`HELD_BY_DATA` and get only :data:`HELD_RIDGE`, so
        that where the training rows cannot tell the last cause from them
        they take it, after the baseline's columns. With the least ridge of
        a cause (:data:`MIN_RIDGE`) on them too, a chosen Sutherland law's
        share went from 1.000 to 0.91-0.98 on every fold once an SF
        polynomial was added beside it, and the pair parted beyond the
        training temperatures: 1.21x the law's held-out RMSE on a truth
        record (seed 7), 7 of 9 seeds over the jackknife bound of
        ``bench/study_held_out_ratio.py``.
        """
        noise = ctx.noise_var_rad2_s2 if noise_var_rad2_s2 is None else noise_var_rad2_s2
        out = [0.0, 0.0]
        last = len(self.effects) - 1
        for i, eff in enumerate(self.effects):
            out += [noise / r ** 2 if i == last else HELD_BY_DATA for r in eff.column_scales()]
        return np.asarray(out)

    def report(self, beta, phis):
        """Return each cause's physical parameters (a list of dicts, in order)."""
        out, i = [], 2
        for eff, phi in zip(self.effects, phis):
            k = eff.n_columns
            out.append(eff.report(np.asarray(beta[i:i + k]), phi, float(beta[1])))
            i += k
        return out


def effective_bins(resid_bins, weight):
    """
    Effective number of independent bins: n (1 - rho) / (1 + rho), at least 2.

    rho is the lag-1 autocorrelation of the bin residuals standardised by
    their white-noise spread (residual x sqrt(samples in the bin)), clipped
    to [0, 0.999].
    """
    z = np.asarray(resid_bins) * np.sqrt(np.asarray(weight))
    z = z - np.mean(z)
    den = float(np.dot(z, z))
    n = len(z)
    if n < 3 or den <= 0.0:
        return float(max(n, 2))
    rho = min(max(float(np.dot(z[1:], z[:-1])) / den, 0.0), 0.999)
    return max(2.0, n * (1.0 - rho) / (1.0 + rho))


def base_ratio(ctx, frame):
    """Return the baseline's R(T) on the bins of ``frame`` (computed once per record)."""
    return cached(frame, 'base_ratio', lambda: ctx.phys.ratio(slow_temp(frame)))


def _regularised(gram, penalty):
    """Return the normal matrix scaled to a unit diagonal with its ridge, and the scale."""
    scale = np.sqrt(np.diag(gram))
    scale = np.where(scale > 0.0, scale, 1.0)
    g = gram / np.outer(scale, scale)
    if penalty is None:
        g[np.diag_indices_from(g)] += 1e-10
    else:
        pen = np.asarray(penalty, dtype=float)
        ridge = np.where(pen > 0.0, np.maximum(pen / scale ** 2, MIN_RIDGE), 1e-12)
        g[np.diag_indices_from(g)] += np.where(pen == HELD_BY_DATA, HELD_RIDGE, ridge)
    return g, scale


def coefficient_map(x, w, penalty=None):
    """
    Return the matrix that maps the weighted data ``x' W y`` to :func:`solve_normal`'s beta.

    beta = M^-1 x' W y with M the regularised normal matrix: the coefficients
    are linear in the data, so their covariance under any noise law is
    M^-1 x' W Cov(y) W x M^-1 (:mod:`.intervals`). (p, p).
    """
    gram = (x * w[:, None]).T @ x
    g, scale = _regularised(gram, penalty)
    return np.linalg.pinv(g) / np.outer(scale, scale)


def solve_normal(x, w, y, penalty=None):
    """
    Weighted least-squares coefficients of ``y`` (one column or several) on ``x``.

    The normal equations are scaled to a unit diagonal and solved with a
    1e-10 ridge, so an all-zero or duplicate column gets a zero (or shared)
    coefficient instead of an error. With ``penalty`` (one weight per
    column, :meth:`Model.penalty`), a penalised column gets that ridge but at
    least :data:`MIN_RIDGE` on the unit diagonal (a cause's column within
    1e-6 of the span of the others is not determined by the data), one
    marked :data:`HELD_BY_DATA` (a cause of the model extended) gets
    :data:`HELD_RIDGE` and an unpenalised one (the baseline's) only 1e-12,
    so that where the data cannot tell a cause's column from the baseline's
    the baseline takes it all, and from a cause already chosen that cause.
    Returns (beta, gram, rhs): ``gram`` without the penalty.
    """
    xw = x * w[:, None]
    gram = xw.T @ x
    rhs = xw.T @ y
    g, scale = _regularised(gram, penalty)
    shaped = scale if np.ndim(y) == 1 else scale[:, None]
    try:
        sol = np.linalg.solve(g, rhs / shaped)
    except np.linalg.LinAlgError:
        sol, *_ = np.linalg.lstsq(g, rhs / shaped, rcond=1e-11)
    return sol / shaped, gram, rhs


def wls(cols, y, w, penalty=None):
    """
    Weighted least squares of ``y`` on ``cols`` (:func:`solve_normal`); returns (beta, sse).

    The SSE is that of the data (the ridge ``penalty`` is not in it).
    """
    x = np.column_stack(cols)
    beta, gram, rhs = solve_normal(x, w, y, penalty)
    sse = float(np.dot(w * y, y) - 2.0 * np.dot(beta, rhs) + beta @ gram @ beta)
    return beta, max(sse, 0.0)


def step_gains(x, g, w, y, margin=STEP_MARGIN):
    """
    SSE reduction of a step g H(t - t_k) added to the columns ``x``, at every row k.

    Rows in time order; ``y`` one column or several (one search each).
    With r the residual of ``y`` on ``x`` and M the W-weighted residual
    maker of ``x``, the step at row k lowers the SSE by (h'W r)^2 / (h'W M h);
    suffix sums give h'W r, h'W h and x'W h for every k at once (O(n p^2)).
    Starts within ``margin`` (share of the rows, at least 3) of either end
    are not tried. Returns (reductions (rows, columns of y), the rows tried
    (bool), the SSE without the step per column of y).
    """
    scale = np.sqrt(np.sum(w[:, None] * x * x, axis=0))
    x = x / np.where(scale > 0.0, scale, 1.0)
    inv = np.linalg.pinv((x * w[:, None]).T @ x, rcond=1e-11)
    y2 = y if np.ndim(y) == 2 else y[:, None]
    r = y2 - x @ (inv @ ((x * w[:, None]).T @ y2))
    wg = w * g

    def suffix(v):
        return np.cumsum(v[::-1], axis=0)[::-1]

    a = suffix(wg[:, None] * r)
    c = suffix(wg * g)
    d = suffix(wg[:, None] * x)
    q = c - np.einsum('ij,jk,ik->i', d, inv, d)
    m = len(w)
    cut = max(3, int(margin * m))
    ok = np.zeros(m, bool)
    ok[cut:m - cut] = True
    ok &= q > 1e-12 * max(float(c[0]), 1e-300)
    gain = np.where(ok[:, None], a ** 2 / np.where(ok, q, 1.0)[:, None], -1.0)
    return gain, ok, np.sum(w[:, None] * r * r, axis=0)


def step_search(x, g, w, y, margin=STEP_MARGIN):
    """
    Exact least-squares start of a step g H(t - t_k) added to the columns ``x``.

    The row of the largest SSE reduction (:func:`step_gains`), one per
    column of ``y``; the middle row when no start can be tried.
    """
    gain, ok, _ = step_gains(x, g, w, y, margin)
    k = np.argmax(gain, axis=0) if np.any(ok) else np.full(gain.shape[1], len(w) // 2)
    return k if np.ndim(y) == 2 else int(k[0])


def _rows(frame, rows):
    return np.ones(len(frame), bool) if rows is None else rows


def fit_model(model, ctx, frame, rows=None, fixed=None, start=None):
    """
    Fit ``model`` on a binned frame; return a :class:`Fit`.

    Variable projection: the linear coefficients are solved in closed form
    (:func:`wls`) for each value of the non-linear parameters of the LAST
    cause, which a grid search and a bounded refinement choose
    (:func:`_search_1d`, :func:`_search_2d`) or, for a step, the exact
    search :func:`change_point`. The other causes' non-linear parameters
    are ``fixed`` (a tuple, one entry per cause but the last; default: the
    model has at most one cause). ``rows`` are the training rows (all when
    None). With ``start`` (the last cause's parameters fitted on all rows)
    the search is local: between the grid points two steps either side of
    it, or a Nelder-Mead simplex of one grid step around it; a step keeps
    the time found on all rows (it is an event of the record: a step in a
    held-out block cannot be located from the other blocks) and only its
    size is refitted. A warm-up fitted on rows that start after the
    record does searches its whole grid, and keeps the time constant of
    least SSE only where the rows resolve its extrapolation back to the
    start (:func:`unseen_s`, :func:`warm_up_resolved`). The search weighs
    the SSE with the ridge of the final fit (a law's share held against the
    law's own noise, :func:`law_noise_var`): with the record's noise, which
    counts a law the model holds as noise, a share shrunk by the ridge
    chose a mode split of 5 Hz, 0.1 Hz/K on one fold to stand in for it,
    and the final fit, its share free, predicted that fold 1.21x worse.
    """
    rows = _rows(frame, rows)
    y = frame.gyro[rows]
    w = frame.weight[rows]
    fixed = tuple(fixed or ())
    n = len(frame)
    search = searched(model)
    law = searched(model, every=True)

    def solve(phis, form=model, noise=None):
        cols = [np.broadcast_to(c, (n,))[rows] for c in form.columns(ctx, frame, phis)]
        return wls(cols, y, w, form.penalty(ctx, noise))

    def sse_of(phis):
        # the ridge of the final fit: the noise a law's share is held against
        return solve(phis, search, law_noise(phis))[1]

    def law_noise(phis):
        """Return the noise variance a share of a law is held against (:func:`law_noise_var`)."""
        if law is model:
            return None
        cols = [np.broadcast_to(c, (n,))[rows] for c in law.columns(ctx, frame, phis)]
        return law_noise_var(ctx, np.column_stack(cols), y, w, law.penalty(ctx))

    if len(fixed) == len(model.effects):
        beta, sse = solve(fixed, model, law_noise(fixed))
        return Fit(beta, fixed, sse)
    new = model.effects[-1]
    if getattr(new, 'change_point', False):
        phi = tuple(start) if start is not None else (
            change_point(Model(model.effects[:-1]), new, ctx, frame, rows, fixed),)
    else:
        grids = new.grids(ctx)
        unseen = unseen_s(new, frame, rows)
        if not grids:
            phi = ()
        else:
            if start is not None and unseen == 0.0:
                grids = [_around(g, v) for g, v in zip(grids, start)]
            if not getattr(new, 'refine', True):
                phi = _search_grid(lambda p: sse_of(fixed + (p,)), grids[0])
            elif len(grids) == 1:
                phi = _search_1d(lambda p: sse_of(fixed + (p,)), *grids)
            else:
                phi = _search_2d(lambda p: sse_of(fixed + (p,)), *grids,
                                 max_evals=40 if start is not None else 120)
            if unseen:
                x = np.column_stack([np.broadcast_to(c, (n,))[rows] for c in
                                     search.columns(ctx, frame, fixed + (phi,))])
                n_eff = effective_bins(
                    y - x @ solve(fixed + (phi,), search, law_noise(fixed + (phi,)))[0], w)
                phi = _warm_up(lambda p: sse_of(fixed + (p,)), grids[0], phi, unseen, n_eff)
    beta, sse = solve(fixed + (phi,), model, law_noise(fixed + (phi,)))
    return Fit(beta, fixed + (phi,), sse)


def unseen_s(effect, frame, rows):
    """
    Return the time from the record's start to a fold's first training row, s (0: none).

    Nonzero only for a cause whose shape starts with the record
    (:attr:`.effects.Effect.starts_with_record`: a warm-up) fitted on
    ``rows`` (bool, on the bins of ``frame``) that leave out the first bin:
    its fit predicts the rows before that from their tail, and chooses its
    time constant by :func:`warm_up_resolved`. The one place this is
    decided, for the fits of the folds (:func:`fit_model`) and the
    noise-only simulations of the fold test
    (:meth:`.selection.Selector.null_reduction`), so that the simulations
    give noise exactly the freedom the real fit has.
    """
    if not effect.starts_with_record or rows is None or rows[0]:
        return 0.0
    start = frame.bins.bin_start_s
    return float(start[rows][0] - start[0])


def held_grid(grid, unseen):
    """Return the time constants of ``grid`` of at least ``unseen`` s, and ``unseen`` itself."""
    g = np.asarray(grid, dtype=float)
    return np.unique(np.r_[unseen, g[g > unseen]])


def warm_up_resolved(values, sses, n_eff, unseen, level=PROFILE_CHI2):
    """
    Tell whether training rows from ``unseen`` s on fix a warm-up's extrapolation to within e.

    ``values`` are time constants in ascending order, ``sses`` their
    training SSEs (values, then any further axes: one search per column).
    The time constants within the 95 % profile-likelihood interval (SSE at
    most ``level`` (chi^2_1) times the noise per effective bin,
    SSE_min / ``n_eff``, above the least: :func:`effective_bins`) give
    the warm-up at the record's start e^(unseen / tau) times what the
    training rows see at their first row; the rows resolve it when that
    factor varies by at most e over the interval, unseen (1/tau_lo -
    1/tau_hi) <= 1, and the interval ends below the grid's top. Then the
    fit keeps the time constant of least SSE (a 900 s warm-up seen from
    1800 s on under white noise). Otherwise the warm-up is held to at most
    e times what the rows see, tau >= unseen (:func:`held_grid`): from the
    tail of a wander or of another effect, a time constant of least SSE
    multiplied it by up to e^(unseen / tau) (a fold of 1300 s and tau 290
    s: 87; 8.3x the RMSE of the model without it on the first fold).
    """
    v = np.asarray(values, dtype=float)
    sses = np.asarray(sses, dtype=float)
    within = sses <= sses.min(axis=0) * (1.0 + level / np.asarray(n_eff, dtype=float))
    lo = v[np.argmax(within, axis=0)]
    top = len(v) - 1 - np.argmax(within[::-1], axis=0)
    return (top < len(v) - 1) & (unseen * (1.0 / lo - 1.0 / v[top]) <= 1.0)


def law_noise_var(ctx, x, y, w, penalty):
    """
    Return the noise variance that holds a share of a law: the record's or the law's, the lower.

    The record's (``ctx.noise_var_rad2_s2``) is the recalibrated
    baseline's residual SSE / n_eff, which counts a large effect as noise:
    on a part whose gas follows Sutherland's law it is 4e8 times the white
    noise, and the ridge shrank the share of the law that fits the record
    to 0.995 (a fold's held-out RMSE up to 5.8 times the law's). The
    law's own residual at share 1 (columns ``x``, :meth:`.effects.Effect.search_form`)
    gives its SSE / n_eff instead where that is lower: the share is held
    against the noise the law leaves, and by the record's where the law
    does not fit (a part with constant viscosity).
    """
    beta, _, _ = solve_normal(x, w, y, penalty)
    resid = y - x @ beta
    own = float(np.sum(w * resid * resid)) / effective_bins(resid, w)
    return min(ctx.noise_var_rad2_s2, own)


def searched(model, every=False):
    """
    Return ``model`` with causes in the form whose SSE chooses their non-linear parameters.

    The model itself, but for a share of a law (:meth:`.effects.Effect.search_form`):
    the law's constant is chosen with the law at share 1. The last cause
    (the one searched), or with ``every`` each cause (the law's own
    residual, :func:`law_noise_var`).
    """
    last = len(model.effects) - 1
    forms = tuple(e.search_form() if every or i == last else e
                  for i, e in enumerate(model.effects))
    same = all(f is e for f, e in zip(forms, model.effects))
    return model if same else Model(forms)


def change_point(partial, step, ctx, frame, rows, fixed):
    """
    Exact least-squares step time: the bin start that minimises the SSE.

    The columns of ``partial`` (the model without the step) and the step's
    multiplier (1 or s Omega) on the training rows go to :func:`step_search`.
    """
    x, g = _step_inputs(partial, step, ctx, frame, rows, fixed)
    k = step_search(x, g, frame.weight[rows], frame.gyro[rows])
    return float(frame.bins.bin_start_s[np.flatnonzero(rows)[k]])


def _step_inputs(partial, step, ctx, frame, rows, fixed):
    """Return the columns of ``partial`` and the step's multiplier on ``rows``."""
    n = len(frame)
    basis = partial.basis(ctx, frame, fixed)
    x = np.column_stack([np.broadcast_to(c, (n,))[rows]
                         for c in partial.columns(ctx, frame, fixed)])
    return x, np.broadcast_to(step.multiplier(frame, basis), (n,))[rows]


def step_profile(partial, step, ctx, frame, fixed):
    """
    Return the SSE of a step at every bin start: (bin starts s, SSE; inf where not tried).

    The profile of the step time (:func:`step_gains`), for its likelihood interval.
    """
    rows = np.ones(len(frame), bool)
    x, g = _step_inputs(partial, step, ctx, frame, rows, fixed)
    gain, ok, rss = step_gains(x, g, frame.weight, frame.gyro)
    return frame.bins.bin_start_s, np.where(ok, rss[0] - gain[:, 0], np.inf)


def _warm_up(sse_of, grid, phi, unseen, n_eff):
    """
    Return the time constant of a warm-up fitted on rows ``unseen`` s after the start.

    ``phi`` (the least SSE's, refined) when the rows resolve the
    extrapolation (:func:`warm_up_resolved`, over the grid and ``phi``,
    the noise per effective bin from ``n_eff``), else the least SSE over
    :func:`held_grid`.
    """
    values = np.unique(np.r_[np.asarray(grid, dtype=float), phi[0]])
    if warm_up_resolved(values, [sse_of((float(v),)) for v in values], n_eff, unseen):
        return phi
    return _search_1d(sse_of, held_grid(grid, unseen))


def _around(grid, value, steps=2):
    """Return the grid points within ``steps`` of ``value`` (and ``value``), sorted."""
    g = np.asarray(grid, dtype=float)
    i = int(np.searchsorted(g, value))
    near = g[max(i - steps, 0):min(i + steps, len(g))]
    return np.unique(np.r_[near, value])


def _search_grid(sse_of, g):
    """Return the grid point with the least SSE (no refinement: a costly parameter)."""
    sses = [sse_of((float(v),)) for v in g]
    return (float(g[int(np.argmin(sses))]),)


def _search_1d(sse_of, g):
    """Grid search over ``g``, then bounded refinement between the best point's neighbours."""
    sses = np.array([sse_of((v,)) for v in g])
    i = int(np.argmin(sses))
    lo, hi = g[max(i - 1, 0)], g[min(i + 1, len(g) - 1)]
    best_phi, best_sse = (float(g[i]),), sses[i]
    if hi > lo:
        res = minimize_scalar(lambda v: sse_of((v,)), bounds=(lo, hi),
                              method='bounded', options={'xatol': 1e-3 * (hi - lo)})
        if res.fun < best_sse:
            best_phi = (float(res.x),)
    return best_phi


def _search_2d(sse_of, g0, g1, max_evals=120):
    """Grid search over ``g0 x g1``, then a Nelder-Mead refinement inside the grid's range."""
    sses = np.array([[sse_of((a, b)) for b in g1] for a in g0])
    i, j = np.unravel_index(int(np.argmin(sses)), sses.shape)
    best_phi, best_sse = (float(g0[i]), float(g1[j])), sses[i, j]
    step = np.array([
        max(np.diff(g0).min(), 0.5 * (g0[min(i + 1, len(g0) - 1)] - g0[max(i - 1, 0)])),
        max(np.diff(g1).min(), 0.5 * (g1[min(j + 1, len(g1) - 1)] - g1[max(j - 1, 0)]))])
    start = np.array(best_phi)
    # the refinement stays inside the grid: the grid is the cause's physical range
    lo = np.array([np.min(g0), np.min(g1)])
    hi = np.array([np.max(g0), np.max(g1)])
    step = np.where(start + step <= hi, step, -step)
    simplex = np.array([start, start + [step[0], 0], start + [0, step[1]]])
    res = minimize(lambda p: sse_of(tuple(p)), start, method='Nelder-Mead',
                   bounds=list(zip(lo, hi)),
                   options={'initial_simplex': simplex, 'maxfev': max_evals,
                            'xatol': 1e-3, 'fatol': 1e-9 * best_sse})
    if res.fun < best_sse:
        best_phi = tuple(float(v) for v in res.x)
    return best_phi


def predict(model, ctx, frame, fit):
    """Prediction of a fitted model at every row of ``frame``, rad/s."""
    out = np.zeros(len(frame))
    for c, b in zip(model.columns(ctx, frame, fit.phis), fit.beta):
        out = out + b * np.asarray(c)
    return out
