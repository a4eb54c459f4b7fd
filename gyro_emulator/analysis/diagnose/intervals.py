"""
An interval for every fitted number, and whether a cause's size stands clear of zero.

Every parameter a cause reports gets a 95 % interval and a 1-sigma:

- a parameter that enters linearly (a coefficient: a tempco, a step size,
  a g-sensitivity): the larger of two sigmas, and the interval theta +-
  t_{K-1} sigma. One is the delete-a-block jackknife over the folds (Efron
  & Stein 1981), sigma^2 = (K-1)/K sum_k (theta_(k) - mean)^2. The other
  is the sandwich of the linear estimator under the record's noise law
  (:func:`wander_sigmas`): white noise plus the random walk the
  maximum-likelihood local level sees over the whole record
  (:func:`.sandwich.wander_law`). The
  jackknife alone misses a wander slower than a fold: every fold is
  biased alike (a drift beside a bias step, a walk beside a staircase of
  soaks), and its spread does not show it. The t_{K-1} quantile of both
  carries the uncertainty of a walk measured from one record. A step's
  size is refitted at every admissible step time (the step time's profile
  region) and its interval is the union (:func:`_step_size_union`): the
  size at the best time alone is biased where a wander moves the time. Its
  sandwich also holds a drift beside the step as a random slope
  (:func:`drift_variance`): the walk, fitted beside the step's column,
  misses a drift over the whole record, which biases the size. A
  coefficient whose column the record does not vary (a g-sensitivity
  along an axis gravity never tilts into) is not measured, and says so
  (no interval; its sigma 0 says only that);
- a parameter found by search (a step time, a delay, a time constant, a
  hysteresis width, a Sutherland constant, a mode split): where the
  per-fold fits cannot spread (a step time is an event of the whole
  record; a grid-only width lands on the same grid point) the jackknife
  degenerates to 0, so the interval is the profile likelihood's (Venzon &
  Moolgavkar 1988): every value whose best fit of the other parameters
  has an SSE within chi^2_1(0.95) SSE_min / n_eff of the minimum, n_eff
  the effective number of independent bins of the fit's residual
  (:func:`.cv.effective_bins`: white noise needs no inflation, wander
  widens it). A step time's profile is evaluated at every bin start, and
  its likelihood ratio is not chi^2_1: with the jump known it is twice the
  larger maximum of two Brownian motions with drift, P(LR > 2x) = 1 -
  (1 - e^-x)^2 (Hinkley 1970, the continuous limit), so its threshold is
  :data:`STEP_LR` (7.35 at 95 %); its interval runs from the start of the
  bin before the first admissible start to the last one (a step inside a
  bin moves its mean partly); a
  continuous parameter's ends are found by bisection between the grid
  points, a grid-only or two-dimensional one's are the first grid points
  outside. Its sigma is the interval's half width / 1.96. An end at the
  edge of the searched range is marked (``open``). A delay is also
  profiled with the applied rate taken as PCHIP and as a cubic spline
  between its samples (:meth:`.data.Prepared.reshaped`), and its interval
  is the union of the three (:func:`_shape_union`): where the rate
  changes within a few samples, its samples do not fix its shape between
  them, nor a delay shorter than that (a 12 ms delay under 2000 deg/s^2
  steps sampled at 10 Hz: 8.7 [8.6, 8.8] ms with the linear shape alone).
  A continuous one-dimensional one (a time constant, a delay) is then
  widened as a coefficient is: the union of its profile interval and phi
  +- t_{K-1} sigma, sigma the larger of the jackknife over the folds and
  the sandwich under the record's noise law, linearised in phi
  (:func:`.searched.widen`): a warm-up's time constant trades with a
  random walk that the profile's effective bins do not see.

:func:`clear_of_zero` is the selection's rule that a cause's estimate
is not within ``z`` sigma of zero: a cause with coefficients needs one of
them beyond z sigma of the estimates it is given (the selection gives the
jackknife's, :func:`linear_estimates` without a :class:`.sandwich.Wander`, so that
detection keeps its calibration), or all of them together beyond the same
level on the folds' joint spread (Hotelling's T^2, :func:`hotelling_p`:
the columns of a temperature polynomial are correlated through cycles);
the verdict's :func:`interval_clear_of_zero` reads each stated interval; a
cause that only changes the scale factor or the delay (a delay, a lag, a
pressure drift, a mode split) needs its
profile's SSE at the no-effect value (the model without it) to exceed the
minimum by z^2 SSE_min / n_eff.
"""

from dataclasses import dataclass, replace
import math

from gyro_emulator.analysis.diagnose import models, searched
from gyro_emulator.analysis.diagnose.data import RATE_SHAPES
from gyro_emulator.analysis.diagnose.sandwich import LEVEL, linear_variance, measured
import numpy as np
from scipy import optimize
from scipy.special import stdtrit
from scipy.stats import chi2, f as f_dist, t as t_dist

#: Profile likelihood threshold in units of SSE_min / n_eff (chi^2_1 at LEVEL).
PROFILE_CHI2 = float(chi2.ppf(LEVEL, 1))
#: The same for a step time (module docstring): 2 (-ln(1 - sqrt(LEVEL))).
STEP_LR = -2.0 * float(np.log(1.0 - np.sqrt(LEVEL)))
#: Normal quantile that turns a profile interval's half width into a sigma.
Z_LEVEL = 1.959963984540054
#: Step times at which :func:`_step_size_union` refits a step's size.
STEP_TIMES = 24
#: ``method`` of a coefficient interval from the record's noise law (:func:`wander_sigmas`).
WANDER_METHOD = 'sandwich under the noise law of the record (white noise and a random walk)'
#: The same for a step's size, whose law holds a drift beside it (:func:`drift_variance`).
STEP_METHOD = WANDER_METHOD + ', a drift beside the step as a random slope'


@dataclass(frozen=True)
class Estimate:
    """One parameter: value, 1-sigma, 95 % interval (None: not measured) and how."""

    value: float
    sigma: float
    interval: tuple
    method: str
    open_low: bool = False
    open_high: bool = False


def _fold_values(effect, evaluated, names):
    """Return the full fit's values of ``names`` (p,) and the per-fold fits' values (K, p)."""
    values = evaluated.model.report(evaluated.full.beta, evaluated.full.phis)[-1]
    per_fold = [evaluated.model.report(f.beta, f.phis)[-1] for f in evaluated.fits.values()]
    full = np.array([values[n] for n in names], dtype=float)
    return full, np.array([[d[n] for n in names] for d in per_fold], dtype=float).reshape(
        len(per_fold), len(names))


def jackknife(effect, evaluated):
    """Return the last cause's parameters: {name: (value, jackknife sigma, number of folds)}."""
    names = [p.name for p in effect.params]
    full, arr = _fold_values(effect, evaluated, names)
    kf = len(arr)
    out = {}
    for j, name in enumerate(names):
        sigma = math.sqrt((kf - 1) / kf * float(np.sum((arr[:, j] - arr[:, j].mean()) ** 2))) \
            if kf > 1 else float('nan')
        out[name] = (float(full[j]), sigma, kf)
    return out


def hotelling_p(theta, per_fold):
    """
    Return the p-value of Hotelling's T^2 that the coefficients ``theta`` are all zero.

    ``per_fold`` (K, p): the delete-a-fold estimates. Their jackknife
    covariance, S = (K-1)/K sum_k (theta_(k) - mean)(theta_(k) - mean)'
    (its diagonal is each coefficient's jackknife sigma^2), gives T^2 =
    theta' S^-1 theta, referred to Hotelling's law on K - 1 degrees of
    freedom: (K - p) T^2 / (p (K - 1)) ~ F(p, K - p) (Hotelling 1931). For
    one coefficient T^2 = (theta / sigma)^2 ~ t_{K-1}^2, the rule of a
    single coefficient. Through temperature cycles the columns of a
    polynomial (dT, dT^2) are correlated: each coefficient's own spread is
    wide where the pair together is not, and only the joint test sees it.
    1 where there are too few folds or S is singular.
    """
    theta = np.asarray(theta, dtype=float)
    arr = np.asarray(per_fold, dtype=float).reshape(-1, len(theta))
    kf, p = arr.shape
    if p == 0 or kf - p < 1:
        return 1.0
    dev = arr - arr.mean(axis=0)
    scale = np.sqrt(np.sum(dev * dev, axis=0))
    if not np.all(scale > 0.0):
        return 1.0
    cov = (kf - 1) / kf * (dev / scale).T @ (dev / scale)       # in units of each spread
    try:
        t2 = float((theta / scale) @ np.linalg.solve(cov, theta / scale))
    except np.linalg.LinAlgError:
        return 1.0
    if not np.isfinite(t2):
        return 1.0
    return float(f_dist.sf((kf - p) * t2 / (p * (kf - 1)), p, kf - p))


def joint_p(effect, evaluated, names):
    """Return :func:`hotelling_p` of the last cause's coefficients ``names`` over its folds."""
    return hotelling_p(*_fold_values(effect, evaluated, names))


def n_nonlinear(effect, ctx):
    """Return how many of ``effect``'s parameters are found by search (they come first)."""
    return len(effect.grids(ctx))


def _cause_columns(evaluated, ctx, frame):
    """Return the last cause's columns on ``frame`` at the full fit."""
    model = evaluated.model
    cols = model.columns(ctx, frame, evaluated.full.phis)
    start = model.n_columns - model.effects[-1].n_columns
    return cols[start:]


def _cause_weights(model, ctx, frame, phis):
    """Return the last cause's coefficients' weights on the bin means, (k, bins), and x."""
    n = len(frame)
    x = np.column_stack([np.broadcast_to(c, (n,)) for c in model.columns(ctx, frame, phis)])
    start = model.n_columns - model.effects[-1].n_columns
    rows = models.coefficient_map(x, frame.weight, model.penalty(ctx))[start:]
    return rows @ (x * frame.weight[:, None]).T, x


def wander_sigmas(evaluated, ctx, frame, wander, law=None):
    """
    Return the 1-sigma of the last cause's reported coefficients under the record's noise law.

    The full fit is beta = M^-1 X' W ybar (:func:`.models.coefficient_map`),
    ybar the bin means, W their sample counts. Under white noise of
    density N plus the wander of ``wander.noise`` (flicker and random walk,
    :func:`.noise_model.wander_covariance`, evaluated at the super-bins,
    within which it barely moves), Cov(beta) = M^-1 (N^2/dt X' W X + H' C H)
    M^-1, H the rows of W X summed over each super-bin: the sandwich of a
    linear estimator (Newey & West 1987; here with the covariance taken
    from the fitted noise model, not from the residuals' own lags, which a
    few blocks of a slow walk cannot give): :func:`_linear_variance` of the
    weights M^-1 X' W (:func:`_cause_weights`). ``law``: the model's noise
    law when already fitted (:meth:`.sandwich.Wander.law`).
    """
    model, full = evaluated.model, evaluated.full
    u, _ = _cause_weights(model, ctx, frame, full.phis)
    noise = wander.law(model, ctx, frame, full.phis) if law is None else law
    var = linear_variance(u, frame.weight, noise, wander.superbins)
    return np.sqrt(np.maximum(var, 0.0)) * _report_factors(model.effects[-1], full)


def drift_variance(evaluated, ctx, frame, law, superbins):
    """
    Return the variance a drift beside the last cause adds to its reported coefficients.

    The random walk of the noise law is fitted on all averaging times, and
    a drift over the whole record (a warm-up's tail, a slow temperature
    trend: wander whose power sits at the record's own scale) barely raises
    it, least of all beside a step, whose column takes up the drift's first
    mode (a level that falls over the record is a step at its middle). A
    step's size is then biased by the drift times the step's lever on it,
    l = u . t (u the size's weights on the bin means, t the centred time),
    and the walk does not say so. The drift is taken as a random slope in
    the noise law, Cov(ybar) += s^2 t t', s^2 estimated from the record by
    its moment: the slope of the model's residual on the time beside the
    model's columns, s_hat, with its variance v under ``law`` (which holds
    the walk's share), s^2 = max(0, s_hat^2 - v). The variance added is
    s^2 l^2 (in the reported unit); 0 where the residual shows no drift
    beyond its noise, or the model holds a drift already.
    """
    model, full = evaluated.model, evaluated.full
    u, x = _cause_weights(model, ctx, frame, full.phis)
    w = frame.weight
    t = np.asarray(frame.time_s, float)
    span = max(float(t.max() - t.min()), 1e-300)
    tc = (t - float(np.sum(w * t) / np.sum(w))) / span
    xw = x * w[:, None]
    perp = tc - x @ (np.linalg.pinv(xw.T @ x) @ (xw.T @ tc))
    norm = float(np.sum(w * perp * perp))
    if not norm > 1e-9 * float(np.sum(w * tc * tc)):
        return np.zeros(len(u))
    resid = frame.gyro - models.predict(model, ctx, frame, full)
    slope = float(np.sum(w * perp * resid)) / norm
    v = float(linear_variance((w * perp / norm)[None, :], w, law, superbins)[0])
    lever = (u @ tc) * _report_factors(model.effects[-1], full)
    return max(slope * slope - v, 0.0) * lever * lever


def _report_factors(effect, full):
    """Return d(reported value)/d(coefficient) of the last cause's columns (1/s0 or 1)."""
    k = effect.n_columns
    names = [p.name for p in effect.params[len(effect.params) - k:]]
    phi, s0 = full.phis[-1], float(full.beta[1])
    return np.array([abs(effect.report(np.eye(k)[i], phi, s0)[names[i]]) for i in range(k)])


def noise_sigmas(effect, evaluated, ctx, frame, wander, drift=None):
    """
    Return the sandwich's 1-sigmas of the last cause's coefficients (:func:`wander_sigmas`).

    A step's size (a change-point cause) adds the variance of the drift
    beside it in quadrature: ``drift``, or :func:`drift_variance` at this fit.
    """
    model, full = evaluated.model, evaluated.full
    law = wander.law(model, ctx, frame, full.phis)
    sigma = wander_sigmas(evaluated, ctx, frame, wander, law)
    if getattr(effect, 'change_point', False):
        if drift is None:
            drift = drift_variance(evaluated, ctx, frame, law, wander.superbins)
        sigma = np.sqrt(sigma ** 2 + drift)
    return sigma


def linear_estimates(effect, evaluated, ctx, frame, wander=None):
    """
    Return {name: Estimate} of the cause's coefficients (module docstring).

    The jackknife over the folds and, given ``wander`` (a :class:`.sandwich.Wander`),
    the sandwich under the record's noise law (:func:`wander_sigmas`): the
    larger sigma is the one stated, its name the ``method``, the interval
    +- t_{K-1} sigma.
    """
    jack = jackknife(effect, evaluated)
    skip = n_nonlinear(effect, ctx)
    cols = _cause_columns(evaluated, ctx, frame)
    noise_sig = None if wander is None else noise_sigmas(effect, evaluated, ctx, frame, wander)
    label = STEP_METHOD if getattr(effect, 'change_point', False) else WANDER_METHOD
    out = {}
    for i, p in enumerate(effect.params[skip:]):
        value, sigma, kf = jack[p.name]
        col = cols[i] if i < len(cols) else None
        if col is None or not measured(col, frame.weight) or not sigma > 0.0:
            # sigma 0 and no interval: nothing was measured, not a zero-width interval
            out[p.name] = Estimate(value, 0.0, None, 'not measured: the record does not '
                                   'vary what this coefficient multiplies')
            continue
        method = f'jackknife over {kf} folds, t_{kf - 1}'
        if noise_sig is not None and noise_sig[i] > sigma:
            sigma, method = float(noise_sig[i]), label + f', t_{kf - 1}'
        half = float(stdtrit(kf - 1, 0.5 + LEVEL / 2.0)) * sigma
        out[p.name] = Estimate(value, sigma, (value - half, value + half), method)
    return out


def _threshold(sse_min, n_eff, lr=PROFILE_CHI2):
    return sse_min * (1.0 + lr / max(n_eff, 1.0))


def _sse_at(model, ctx, frame, fixed):
    return models.fit_model(model, ctx, frame, None, fixed).sse


def _walk(points, sses, best, thr, sse_of, continuous):
    """Return (low, high, open_low, open_high) of the admissible run around index ``best``."""
    ends = []
    for step in (-1, 1):
        j = best
        while 0 <= j + step < len(points) and sses[j + step] <= thr:
            j += step
        out = j + step
        if not 0 <= out < len(points):
            ends.append((points[j], True))
        elif continuous:
            ends.append((_crossing(sse_of, thr, points[j], points[out]), False))
        else:
            ends.append((points[out], False))
    (lo, open_lo), (hi, open_hi) = ends
    return lo, hi, open_lo, open_hi


def _crossing(sse_of, thr, inside, outside):
    """Return where the profile crosses ``thr`` between an admissible and an excluded point."""
    a, b = sorted((inside, outside))
    try:
        return optimize.brentq(lambda v: sse_of(v) - thr, a, b, xtol=1e-4 * (b - a) + 1e-12)
    except ValueError:                 # no sign change after all: the grid point bounds it
        return outside


#: The method of a searched parameter's interval (:func:`nonlinear_estimates`).
PROFILE = 'profile likelihood'
#: Said of a delay's interval that the shapes of the applied rate widened.
SHAPES_NOTE = ("; the union over the applied rate's shapes between its samples "
               '(linear, PCHIP, cubic spline)')


def _profile_1d(evaluated, ctx, frame, n_eff):
    """Profile interval of the last cause's one searched parameter (not a step)."""
    model, full = evaluated.model, evaluated.full
    eff = model.effects[-1]
    fixed = tuple(full.phis[:-1])
    best = float(full.phis[-1][0])
    grid = np.asarray(eff.grids(ctx)[0], dtype=float)
    points = np.unique(np.r_[grid, best])

    search = models.searched(model)

    def sse_of(v):
        return _sse_at(search, ctx, frame, fixed + ((float(v),),))

    sses = np.array([full.sse if v == best and search is model else sse_of(v)
                     for v in points])
    thr = _threshold(float(sses.min()), n_eff)
    i = int(np.flatnonzero(points == best)[0])
    lo, hi, olo, ohi = _walk(points, sses, i, thr, sse_of, getattr(eff, 'refine', True))
    return [(min(lo, best), max(hi, best), olo, ohi)]


def _profile_in_shape(sse_of, near, within, n_eff):
    """
    Profile interval of a delay with the record's rate in another shape.

    ``sse_of(v)``: the SSE of the fit at delay v in that shape. A shape
    moves a delay by less than a sample period (``near``, the linear
    shape's best delay, +- one period, inside the searched range
    ``within``): the least SSE is found there (Brent), and each end is
    stepped out from it in eighths of that window until the SSE exceeds
    the threshold, then found by bisection (:func:`_crossing`); an end that
    reaches the searched range is open. Returns (low, high, open_low,
    open_high).
    """
    a, b = near
    best = float(optimize.minimize_scalar(sse_of, bounds=(a, b), method='bounded',
                                          options={'xatol': 1e-6 * (b - a) + 1e-12}).x)
    thr = _threshold(sse_of(best), n_eff)
    step = (b - a) / 8.0
    out = []
    for sign, limit in ((-1.0, within[0]), (1.0, within[1])):
        inside = best
        while True:
            nxt = min(max(inside + sign * step, within[0]), within[1])
            if sse_of(nxt) > thr:
                out.append((_crossing(sse_of, thr, inside, nxt), False))
                break
            if nxt == limit:
                out.append((limit, True))
                break
            inside = nxt
    (lo, olo), (hi, ohi) = out
    return min(lo, best), max(hi, best), olo, ohi


def _shape_union(evaluated, ctx, frame, n_eff, ends):
    """
    Widen a delay's profile interval ``ends`` to the union over the rate's shapes.

    The applied rate is known at its samples only: between them it is
    taken as linear by the fits, and here also as PCHIP and as a cubic
    spline (:data:`.data.RATE_SHAPES`). Each shape's profile interval
    (:func:`_profile_in_shape`, within a sample period of the linear
    shape's best delay) joins the linear one. Returns the widened
    (low, high, open_low, open_high) and whether a shape widened it.
    """
    model, full = evaluated.model, evaluated.full
    fixed = tuple(full.phis[:-1])
    grid = np.asarray(model.effects[-1].grids(ctx)[0], dtype=float)
    within = (float(grid[0]), float(grid[-1]))
    best, period = float(full.phis[-1][0]), float(frame.bins.dt_s)
    near = (max(within[0], best - period), min(within[1], best + period))
    search = models.searched(model)
    lo, hi, olo, ohi = ends
    widened = False
    for shape in RATE_SHAPES[1:]:
        other = frame.bins.reshaped(shape)
        if other is None:
            continue
        s_lo, s_hi, s_olo, s_ohi = _profile_in_shape(
            lambda v, f=other.binned: _sse_at(search, ctx, f, fixed + ((float(v),),)), near,
            within, n_eff)
        if s_lo < lo:
            lo, olo, widened = s_lo, s_olo, True
        if s_hi > hi:
            hi, ohi, widened = s_hi, s_ohi, True
    return (lo, hi, olo, ohi), widened


def _profile_2d(evaluated, ctx, frame, n_eff):
    """Profile intervals of the last cause's two searched parameters, on its grid."""
    model, full = evaluated.model, evaluated.full
    eff = model.effects[-1]
    fixed = tuple(full.phis[:-1])
    best = tuple(float(v) for v in full.phis[-1])
    g0, g1 = (np.asarray(g, dtype=float) for g in eff.grids(ctx))
    p0, p1 = np.unique(np.r_[g0, best[0]]), np.unique(np.r_[g1, best[1]])
    sse = np.array([[_sse_at(model, ctx, frame, fixed + ((a, b),)) for b in p1] for a in p0])
    thr = _threshold(min(float(sse.min()), full.sse), n_eff)
    out = []
    for axis, points, b in ((0, p0, best[0]), (1, p1, best[1])):
        prof = sse.min(axis=1 - axis)
        i = int(np.flatnonzero(points == b)[0])
        prof[i] = min(prof[i], full.sse)
        lo, hi, olo, ohi = _walk(points, prof, i, thr, None, False)
        out.append((min(lo, b), max(hi, b), olo, ohi))
    return out


def _profile_step(evaluated, ctx, frame, n_eff):
    """Profile interval of a step time over every bin start (module docstring)."""
    model, full = evaluated.model, evaluated.full
    starts, sse = models.step_profile(models.Model(model.effects[:-1]), model.effects[-1], ctx,
                                      frame, tuple(full.phis[:-1]))
    thr = _threshold(float(np.min(sse)), n_eff, STEP_LR)
    ok = np.flatnonzero(sse <= thr)
    best = float(full.phis[-1][0])
    first, last = int(ok.min()), int(ok.max())
    bin_s = float(frame.bins.bin_s)
    lo = float(starts[first - 1]) if first > 0 else float(starts[first]) - bin_s
    return [(min(lo, best - bin_s), max(float(starts[last]), best), first <= 0,
             last >= len(starts) - 1)]


def nonlinear_estimates(effect, evaluated, ctx, frame, n_eff, wander=None):
    """
    Return {name: Estimate} of the cause's searched parameters (profile likelihood).

    With ``wander`` a continuous one-dimensional one is widened to the
    sandwich under the record's noise law (:func:`.searched.widen`).
    """
    k = n_nonlinear(effect, ctx)
    if k == 0:
        return {}
    if getattr(effect, 'change_point', False):
        ends = _profile_step(evaluated, ctx, frame, n_eff)
    elif k == 1:
        ends = _profile_1d(evaluated, ctx, frame, n_eff)
    else:
        ends = _profile_2d(evaluated, ctx, frame, n_eff)
    method = PROFILE
    if k == 1 and effect.delay_s((1.0,)) != 0.0:        # a delay: every shape of the rate
        ends[0], widened = _shape_union(evaluated, ctx, frame, n_eff, ends[0])
        method += SHAPES_NOTE if widened else ''
    if (wander is not None and k == 1 and getattr(effect, 'refine', True)
            and not getattr(effect, 'change_point', False)):
        ends[0], widened = searched.widen(effect, evaluated, ctx, frame, wander, ends[0])
        method += f'{searched.NOTE}, t_{len(evaluated.fits) - 1}' if widened else ''
    fitted = [float(v) for v in evaluated.full.phis[-1]]
    values = evaluated.model.report(evaluated.full.beta, evaluated.full.phis)[-1]
    out = {}
    for p, v_fit, (lo, hi, olo, ohi) in zip(effect.params[:k], fitted, ends):
        value = float(values[p.name])
        if value == -v_fit and v_fit != 0.0:       # a report that flips the sign (mode split)
            lo, hi, olo, ohi = -hi, -lo, ohi, olo
        out[p.name] = Estimate(value, (hi - lo) / (2.0 * Z_LEVEL), (lo, hi), method, olo, ohi)
    return out


def _step_size_union(effect, evaluated, ctx, frame, n_eff, wander, size):
    """
    Return a step's size interval over every admissible step time (module docstring).

    The size ``size`` (an :class:`Estimate`) is that at the best time; at
    each of up to :data:`STEP_TIMES` times inside the step time's profile
    region (:func:`_profile_step`'s threshold) the size is refitted and its
    sigma taken as the larger of the best time's and the sandwich's there
    (:func:`noise_sigmas`, with the drift measured at the best time); the
    interval is the union of theirs.
    """
    model, full = evaluated.model, evaluated.full
    fixed = tuple(full.phis[:-1])
    starts, sse = models.step_profile(models.Model(model.effects[:-1]), effect, ctx, frame,
                                      fixed)
    ok = np.flatnonzero(sse <= _threshold(float(np.min(sse)), n_eff, STEP_LR))
    if size.interval is None or len(ok) == 0:
        return size
    q = (size.interval[1] - size.interval[0]) / (2.0 * size.sigma)
    lo, hi = size.interval
    name = effect.params[-1].name
    # the drift is the record's, measured beside the step at its best time (beside a
    # step at a worse time the residual's own misfit would read as a drift)
    drift = drift_variance(evaluated, ctx, frame, wander.law(model, ctx, frame, full.phis),
                           wander.superbins)
    for k in np.unique(ok[np.linspace(0, len(ok) - 1, min(len(ok), STEP_TIMES)).astype(int)]):
        fit = models.fit_model(model, ctx, frame, None, fixed + ((float(starts[k]),),))
        at = replace(evaluated, full=fit)
        value = float(model.report(fit.beta, fit.phis)[-1][name])
        sigma = max(size.sigma, float(noise_sigmas(effect, at, ctx, frame, wander, drift)[0]))
        lo, hi = min(lo, value - q * sigma), max(hi, value + q * sigma)
    if (lo, hi) == tuple(size.interval):
        return size
    return Estimate(size.value, (hi - lo) / (2.0 * q), (lo, hi),
                    size.method + '; the union over the admissible step times')


def estimates(effect, evaluated, ctx, frame, n_eff, wander=None):
    """Return {name: Estimate} for every parameter of the last cause, in the cause's order."""
    found = {**nonlinear_estimates(effect, evaluated, ctx, frame, n_eff, wander),
             **linear_estimates(effect, evaluated, ctx, frame, wander)}
    if wander is not None and getattr(effect, 'change_point', False):
        name = effect.params[-1].name
        found[name] = _step_size_union(effect, evaluated, ctx, frame, n_eff, wander,
                                       found[name])
    return {p.name: found[p.name] for p in effect.params}


def _null_excluded(effect, ctx, current_sse, sse, n_eff, level):
    """Tell whether a scale-factor or delay cause's no-effect value is outside its region."""
    q = max(n_nonlinear(effect, ctx), 1)
    return current_sse - sse > float(chi2.ppf(level, q)) * sse / max(n_eff, 1.0)


def clear_of_zero(effect, found, ctx, current_sse, sse, n_eff, z, evaluated=None):
    """
    Tell whether a cause's size is more than ``z`` sigma from zero (module docstring).

    ``found``: the cause's :class:`Estimate` s; ``current_sse``, ``sse``: the
    full-fit SSE without and with the cause. A cause with coefficients is
    clear when one of them is beyond ``z`` sigma or, given its
    ``evaluated`` fits and two or more measured coefficients, when they are
    together (:func:`joint_p`) at the level of one coefficient at ``z``
    sigma on the same folds, 2 P(t_{K-1} > z) (z = 2, K = 8: 0.086). A
    cause without coefficients is judged on its profile at the equivalent
    level (chi^2 with one degree of freedom per searched parameter at the
    two-sided normal level of ``z``).
    """
    if effect.n_columns > 0:
        if any(abs(found[name].value) > z * found[name].sigma
               for name in _measured_names(found)):
            return True
        joint = size_joint_p(effect, found, evaluated)
        return joint is not None and joint < 2.0 * float(t_dist.sf(z, len(evaluated.fits) - 1))
    level = float(chi2.cdf(z * z, 1))          # z = 2: 0.9545
    return _null_excluded(effect, ctx, current_sse, sse, n_eff, level)


def _measured_names(found):
    """Return the names of the coefficients measured with an interval (not by a profile)."""
    return [name for name, e in found.items()
            if e.interval is not None and not e.method.startswith(PROFILE)]


def size_joint_p(effect, found, evaluated):
    """
    Return :func:`joint_p` of a cause's measured coefficients together, or None.

    None without ``evaluated`` fits or with fewer than two measured
    coefficients (``found``'s :class:`Estimate` s): the joint half of the
    size rule of :func:`clear_of_zero`, and the figure a report states
    beside an interval that includes zero.
    """
    measured = _measured_names(found)
    if evaluated is None or len(measured) < 2:
        return None
    return joint_p(effect, evaluated, measured)


def interval_clear_of_zero(effect, found, ctx, current_sse, sse, n_eff):
    """Tell whether the cause's 95 % interval excludes zero (the verdict's ``explained`` rule)."""
    if effect.n_columns > 0:
        return any(e.interval is not None and (e.interval[0] > 0.0 or e.interval[1] < 0.0)
                   for e in found.values() if not e.method.startswith(PROFILE))
    return _null_excluded(effect, ctx, current_sse, sse, n_eff, LEVEL)
