"""
Choosing the cause: blocked cross-validation, a paired block test and BIC.

Procedure (:func:`diagnose`):

1. The record is cut into ``folds`` contiguous blocks of equal duration
   (default 6). For each block, every model is fitted on the other blocks
   (on bin means, :mod:`.data`) and predicts the held-out block sample by
   sample. The user-calibrated baseline is recalibrated per fold from the
   training blocks only (:func:`.baseline.calibrate`).
2. Held-out RMSE over all samples gives ``gain = 1 - rmse_cause /
   rmse_baseline``.
3. A cause is *significant* when, against the recalibrated baseline (same
   data, b0 and s0 refitted; :data:`.effects.NULL`):

   - its held-out RMSE gain is at least ``min_gain`` (0.5 %);
   - a one-sided paired t-test over ``8 x folds`` contiguous sub-blocks of
     the log ratio of held-out squared errors (a block Diebold-Mariano test
     on a scale-free loss) gives p < ``alpha`` (1e-3);
   - its BIC on the full record (bin means) is lower by more than 10.
4. Findings are ranked by held-out RMSE. The best finding is the top
   significant one, except that a significant finding with fewer parameters
   is preferred when the paired test cannot tell the two apart
   (p >= 0.01): parsimony between causes the data do not separate.
5. Residual structure: the held-out residual of the chosen model, averaged
   per bin, is compared with its white-noise floor (from sample-to-sample
   differences); when it exceeds the floor by 2x, the correlate (temperature,
   dT/dt, rate, rate^2, time, acceleration) whose 10-quantile group means
   explain most of it is named.

Parameter uncertainties are delete-a-block jackknife standard deviations
over the cross-validation fits, which stay honest under the slow bias
wander that makes least-squares formulas over-confident.
"""

from dataclasses import dataclass
import math

from gyro_emulator.analysis.diagnose import baseline as base
from gyro_emulator.analysis.diagnose import effects as fx
from gyro_emulator.analysis.diagnose.data import DEFAULT_MAX_BINS, Prepared
from gyro_emulator.physics.presets import physics_preset
import numpy as np

DEFAULT_FOLDS = 6
SUB_BLOCKS_PER_FOLD = 8
MIN_GAIN = 0.005
ALPHA = 1e-3
ALPHA_TIE = 0.01
DELTA_BIC_MAX = -10.0
EXCESS_MIN = 2.0
R2_MIN = 0.2
MIN_TEMP_SPAN_C = 1.0
MIN_ACCEL_STD_M_S2 = 0.05


@dataclass
class Fit:
    """One model fitted on a set of rows."""

    beta: np.ndarray
    phi: tuple
    sse: float


@dataclass
class Diagnosis:
    """Everything ``diagnose`` found: the JSON document and plot data."""

    doc: dict
    prepared: Prepared = None
    residual_before: np.ndarray = None
    residual_after: np.ndarray = None
    after_label: str = ''


def _wls(cols, y, w):
    """Weighted least squares on scaled normal equations; zero columns -> 0."""
    x = np.column_stack(cols)
    xw = x * w[:, None]
    gram = xw.T @ x
    rhs = xw.T @ y
    scale = np.sqrt(np.diag(gram))
    scale = np.where(scale > 0.0, scale, 1.0)
    sol, *_ = np.linalg.lstsq(gram / np.outer(scale, scale), rhs / scale,
                              rcond=1e-11)
    beta = sol / scale
    res = y - x @ beta
    return beta, float(np.sum(w * res * res))


def fit_effect(effect, ctx, frame, rows=None):
    """
    Fit ``effect`` (an :class:`~.effects.Effect`) on a binned frame; return a :class:`Fit`.

    Variable projection: the linear coefficients are solved in closed form
    (weighted least squares, :func:`_wls`) for each value of the nonlinear
    ones, which a grid search and a bounded refinement choose
    (:func:`_search_1d`, :func:`_search_2d`). ``ctx`` holds the physics and
    reference points, ``frame`` the bin means and ``rows`` the training rows
    (all when None).
    """
    rows = base.rows_or_all(frame, rows)
    y = frame.gyro[rows]
    w = frame.weight[rows]

    def solve(phi):
        cols = [np.broadcast_to(c, (len(frame),))[rows]
                for c in effect.columns(ctx, frame, phi)]
        return _wls(cols, y, w)

    grids = effect.grids(ctx)
    if not grids:
        beta, sse = solve(())
        return Fit(beta, (), sse)
    search = _search_1d if len(grids) == 1 else _search_2d
    best_phi = search(lambda phi: solve(phi)[1], *grids)
    beta, sse = solve(best_phi)
    return Fit(beta, best_phi, sse)


def _search_1d(sse_of, g):
    """Grid search over ``g``, then bounded refinement between the best point's neighbours."""
    from scipy.optimize import minimize_scalar

    sses = np.array([sse_of((v,)) for v in g])
    i = int(np.argmin(sses))
    lo, hi = g[max(i - 1, 0)], g[min(i + 1, len(g) - 1)]
    best_phi, best_sse = (float(g[i]),), sses[i]
    if hi > lo:
        res = minimize_scalar(lambda v: sse_of((v,)), bounds=(lo, hi),
                              method='bounded', options={'xatol': 1e-4 * (hi - lo)})
        if res.fun < best_sse:
            best_phi = (float(res.x),)
    return best_phi


def _search_2d(sse_of, g0, g1):
    """Grid search over ``g0 x g1``, then a Nelder-Mead refinement from the best point."""
    from scipy.optimize import minimize

    sses = np.array([[sse_of((a, b)) for b in g1] for a in g0])
    i, j = np.unravel_index(int(np.argmin(sses)), sses.shape)
    best_phi, best_sse = (float(g0[i]), float(g1[j])), sses[i, j]
    step = np.array([
        max(np.diff(g0).min(), 0.5 * (g0[min(i + 1, len(g0) - 1)] - g0[max(i - 1, 0)])),
        max(np.diff(g1).min(), 0.5 * (g1[min(j + 1, len(g1) - 1)] - g1[max(j - 1, 0)]))])
    start = np.array(best_phi)
    simplex = np.array([start, start + [step[0], 0], start + [0, step[1]]])
    res = minimize(lambda p: sse_of(tuple(p)), start, method='Nelder-Mead',
                   options={'initial_simplex': simplex, 'maxfev': 120,
                            'xatol': 1e-3, 'fatol': 1e-9 * best_sse})
    if res.fun < best_sse:
        best_phi = tuple(float(v) for v in res.x)
    return best_phi


def predict(effect, ctx, frame, fit):
    """Prediction of a fitted model at every row of ``frame``, rad/s."""
    cols = effect.columns(ctx, frame, fit.phi)
    out = np.zeros(len(frame))
    for c, b in zip(cols, fit.beta):
        out = out + b * np.asarray(c)
    return out


def _paired_p(sse_ref, sse_new):
    """
    One-sided paired test that ``sse_new`` is lower, over sub-blocks.

    A t-test on the per-sub-block log ratios ln(SSE_ref / SSE_new): scale
    free, so a few sub-blocks with large errors (fast rate changes, hot
    soaks) do not swamp the others.
    """
    from scipy.special import stdtr

    ref = np.asarray(sse_ref, dtype=float)
    new = np.asarray(sse_new, dtype=float)
    ok = (ref > 0.0) & (new > 0.0)
    d = np.log(ref[ok] / new[ok])
    n = len(d)
    if n < 3:
        return 1.0
    sd = float(np.std(d, ddof=1))
    mean = float(np.mean(d))
    if sd <= 0.0:
        return 0.0 if mean > 0.0 else 1.0
    return float(stdtr(n - 1, -mean / (sd / math.sqrt(n))))


def _bic(sse, weight_sum, n_rows, n_params):
    return n_rows * math.log(max(sse, 1e-300) / weight_sum) + \
        n_params * math.log(n_rows)


def _excitation(prep):
    """Which kinds of excitation the record has (for each effect's needs)."""
    d = prep.data
    b = prep.binned
    have = set()
    if math.sqrt(float(np.mean(d.rate_cmd_rad_s ** 2))) >= \
            base.MIN_RATE_RMS_RAD_S:
        have.add('rate')
    if float(b.temp_c.max() - b.temp_c.min()) >= MIN_TEMP_SPAN_C:
        have.add('temp')
    if d.has_accel and float(np.max(np.std(d.accel_m_s2, axis=0))) >= \
            MIN_ACCEL_STD_M_S2:
        have.add('accel')
    return have


_NEED_TEXT = {
    'rate': 'the applied rate is (nearly) zero, so scale-factor effects are '
            'not observable',
    'temp': f'the temperature spans less than {MIN_TEMP_SPAN_C} K',
    'accel': 'no acceleration columns (or no acceleration change) in the '
             'record',
}


def _group_r2(x, r, w, groups=10):
    """Share of the weighted variance of r explained by quantile groups of x."""
    if np.ptp(x) <= 0.0:
        return 0.0
    edges = np.unique(np.quantile(x, np.linspace(0, 1, groups + 1)[1:-1]))
    g = np.searchsorted(edges, x, side='right')
    sw = np.bincount(g, weights=w)
    sm = np.bincount(g, weights=w * r)
    mean_all = np.sum(w * r) / np.sum(w)
    ok = sw > 0
    between = np.sum((sm[ok] / sw[ok] - mean_all) ** 2 * sw[ok])
    total = np.sum(w * (r - mean_all) ** 2)
    return float(between / total) if total > 0 else 0.0


def residual_structure(prep, resid_samples):
    """
    Find structure left in held-out residuals and what it follows.

    Parameters
    ----------
    prep : gyro_emulator.analysis.diagnose.data.Prepared
        The record.
    resid_samples : numpy.ndarray
        Held-out residual of the chosen model at every sample, rad/s.

    Returns
    -------
    dict
        ``structure_remains``, ``excess_over_noise``, ``strongest_correlate``,
        ``r2`` (per correlate) and ``noise_rad_s`` (white-noise estimate).

    """
    b = prep.binned
    counts = b.weight
    rb = np.bincount(prep.sample_bin, weights=resid_samples) / counts
    white_var = 0.5 * float(np.var(np.diff(resid_samples)))
    floor = float(np.mean(white_var / counts))
    excess = float(np.mean((rb - np.mean(rb)) ** 2)) / max(floor, 1e-300)
    correlates = {'temperature': b.temp_c,
                  'temperature_rate': prep.temp_rate_on_bins,
                  'rate': b.rate, 'rate_squared': b.rate2, 'time': b.time_s}
    r2 = {name: _group_r2(x, rb, counts) for name, x in correlates.items()}
    if b.accel is not None:
        r2['acceleration'] = max(_group_r2(b.accel[:, k], rb, counts)
                                 for k in range(3))
    strongest = max(r2, key=r2.get)
    remains = excess >= EXCESS_MIN and r2[strongest] >= R2_MIN
    return {'structure_remains': bool(remains),
            'excess_over_noise': excess,
            'strongest_correlate': strongest,
            'r2': r2,
            'noise_rad_s': math.sqrt(white_var)}


def diagnose(data, preset='paper', ref_temp_c=None, folds=DEFAULT_FOLDS,
             max_bins=DEFAULT_MAX_BINS, effects=None):
    """
    Diagnose a measured record against the paper's physics.

    Parameters
    ----------
    data : gyro_emulator.analysis.diagnose.data.MeasuredData
        The record.
    preset : str
        Physics preset of the baseline device (``presets.physics_preset``).
    ref_temp_c : float, optional
        Calibration (reference) temperature, deg C; default the device's.
    folds : int
        Contiguous cross-validation blocks (>= 3).
    max_bins : int
        Largest number of bins the fits run on.
    effects : sequence of str, optional
        Catalogue entries to test (default: all).

    Returns
    -------
    Diagnosis

    """
    cv = _cross_validation(data, preset, ref_temp_c, folds, max_bins)
    catalogue = fx.CATALOGUE if effects is None else tuple(
        fx.effect(e) for e in effects)
    rmse_base = _baseline_rmse(cv)
    null = cv.evaluate(fx.NULL)
    findings, not_tested, evaluated = _test_catalogue(catalogue, cv, null, rmse_base)
    best = _choose(findings, evaluated)
    after_effect, after = (fx.NULL, null) if best is None else evaluated[best['effect']]
    structure = residual_structure(cv.prep, after.resid)
    structure['message'] = _structure_message(best, structure)
    cal_all = base.calibrate(cv.prep.binned, cv.ctx.phys)
    doc = _document(data, preset, cal_all, cv, rmse_base, null, _best_doc(best, rmse_base),
                    findings, not_tested, structure)
    label = best['effect'] if best else 'recalibrated baseline (no cause found)'
    return _diagnosis(doc, cv, cal_all, after_effect, after.full, label)


def _cross_validation(data, preset, ref_temp_c, folds, max_bins):
    """Check ``folds``, bin the record, evaluate the device physics over it, cut the folds."""
    if folds < 3 or folds > 50:
        raise ValueError(f'diagnose.folds = {folds!r} is out of range: '
                         'allowed [3, 50]')
    device = physics_preset(preset)
    tref = device.calibration_temp_c if ref_temp_c is None else float(
        ref_temp_c)
    prep = Prepared(data, max_bins=max_bins)
    b = prep.binned
    phys = base.DevicePhysics(device, tref, float(b.temp_c.min()),
                              float(b.temp_c.max()))
    ctx = fx.Context(phys=phys, ref_temp_c=tref,
                     time_span_s=(float(data.time_s[0]), float(data.time_s[-1])),
                     duration_s=prep.duration_s)
    return _CrossValidation(data, prep, folds, ctx)


def _baseline_rmse(cv):
    """Held-out RMSE of the user-calibrated baseline, recalibrated on each fold's training rows."""
    prep, phys = cv.prep, cv.ctx.phys
    _, base_sub = cv.held_out(lambda k: base.baseline_prediction(
        prep.samples, phys, base.calibrate(prep.binned, phys, rows=cv.fold_of_bin != k)))
    return math.sqrt(float(np.sum(base_sub)) / len(cv.y))


def _test_catalogue(catalogue, cv, null, rmse_base):
    """
    Evaluate every catalogue entry the record can show.

    Returns the findings ranked by held-out RMSE, the entries not tested
    (with the reason: the excitation they need is missing) and
    ``{effect_id: (effect, _Evaluated)}`` of those tested.
    """
    have = _excitation(cv.prep)
    findings, not_tested, evaluated = [], [], {}
    for eff in catalogue:
        missing = [need for need in eff.needs if need not in have]
        if missing:
            not_tested.append({'effect': eff.effect_id,
                               'reason': _NEED_TEXT[missing[0]]})
            continue
        result = cv.evaluate(eff)
        findings.append(_finding(eff, result, null, cv, rmse_base))
        evaluated[eff.effect_id] = (eff, result)
    findings.sort(key=lambda f: f['rmse_rad_s'])
    return findings, not_tested, evaluated


def _diagnosis(doc, cv, cal_all, after_effect, after_fit, after_label):
    """Return the :class:`Diagnosis`: the document and the bin-mean residuals before and after."""
    b = cv.prep.binned
    before = b.gyro - base.baseline_prediction(b, cv.ctx.phys, cal_all)
    after = b.gyro - predict(after_effect, cv.ctx, b, after_fit)
    return Diagnosis(doc=doc, prepared=cv.prep, residual_before=before,
                     residual_after=after, after_label=after_label)


@dataclass
class _Evaluated:
    """One effect under cross-validation: per-fold fits, held-out residuals, full fit."""

    fits: dict
    resid: np.ndarray
    sub: np.ndarray
    full: object
    rmse: float


class _CrossValidation:
    """
    Contiguous folds for held-out errors, sub-blocks for the paired test.

    The record is cut into ``folds`` blocks of equal duration; a fit on all
    other blocks predicts each block. Every fold is cut again into
    ``SUB_BLOCKS_PER_FOLD`` sub-blocks, whose squared-error sums pair two
    models in :func:`_paired_p`.
    """

    def __init__(self, data, prep, folds, ctx):
        b = prep.binned
        t0 = float(data.time_s[0])
        span = prep.duration_s
        self.fold_of_bin = np.minimum(((b.time_s - t0) / span * folds).astype(int),
                                      folds - 1)
        self.n_sub = folds * SUB_BLOCKS_PER_FOLD
        sub_of_bin = np.minimum(((b.time_s - t0) / span * self.n_sub).astype(int),
                                self.n_sub - 1)
        self.fold_of_sample = self.fold_of_bin[prep.sample_bin]
        self.sub_of_sample = sub_of_bin[prep.sample_bin]
        self.used_folds = [k for k in range(folds) if np.any(self.fold_of_bin == k)]
        self.sub_used = np.bincount(self.sub_of_sample, minlength=self.n_sub) > 0
        self.y = data.gyro_rad_s
        self.prep, self.ctx = prep, ctx
        self.weight_sum = float(np.sum(b.weight))
        self.n_rows = len(b)

    def held_out(self, pred_for_fold):
        """Return the held-out residual of every sample and the SSE per sub-block."""
        resid = np.empty(len(self.y))
        for k in self.used_folds:
            mask = self.fold_of_sample == k
            resid[mask] = self.y[mask] - pred_for_fold(k)[mask]
        sse_sub = np.bincount(self.sub_of_sample, weights=resid * resid,
                              minlength=self.n_sub)[self.sub_used]
        return resid, sse_sub

    def evaluate(self, effect):
        """Fit ``effect`` per fold and on everything; return an :class:`_Evaluated`."""
        b, s = self.prep.binned, self.prep.samples
        fits = {k: fit_effect(effect, self.ctx, b, self.fold_of_bin != k)
                for k in self.used_folds}
        resid, sub = self.held_out(lambda k: predict(effect, self.ctx, s, fits[k]))
        full = fit_effect(effect, self.ctx, b)
        return _Evaluated(fits, resid, sub, full, math.sqrt(float(np.sum(sub)) / len(self.y)))

    def bic(self, full, n_params):
        """BIC of a full fit (see :func:`_bic`)."""
        return _bic(full.sse, self.weight_sum, self.n_rows, n_params)


def _finding(eff, result, null, cv, rmse_base):
    """One catalogue entry's result: parameters with jackknife sigma, gains, tests."""
    values = eff.report(result.full.beta, result.full.phi)
    jack = {name: [eff.report(f.beta, f.phi)[name] for f in result.fits.values()]
            for name in values}
    kf = len(result.fits)
    params = {}
    for p in eff.params:
        arr = np.asarray(jack[p.name], dtype=float)
        sigma = math.sqrt((kf - 1) / kf * float(np.sum(
            (arr - arr.mean()) ** 2))) if kf > 1 else float('nan')
        params[p.name] = {'value': float(values[p.name]), 'sigma': sigma,
                          'unit': p.unit, 'meaning': p.meaning}
    gain_null = 1.0 - result.rmse / null.rmse
    p_value = _paired_p(null.sub, result.sub)
    d_bic = cv.bic(result.full, eff.n_params) - cv.bic(null.full, fx.NULL.n_params)
    significant = bool(gain_null >= MIN_GAIN and p_value < ALPHA
                       and d_bic < DELTA_BIC_MAX)
    return {'effect': eff.effect_id, 'cause': eff.cause, 'parameters': params,
            'rmse_rad_s': result.rmse, 'gain': 1.0 - result.rmse / rmse_base,
            'gain_over_recalibrated': gain_null, 'p_value': p_value,
            'delta_bic': d_bic, 'n_params': eff.n_params,
            'significant': significant}


def _document(data, preset, cal_all, cv, rmse_base, null, best_doc, findings,
              not_tested, structure):
    """Return the JSON document of a diagnosis."""
    prep = cv.prep
    return {
        'input': {'source': data.source, 'rows': data.rows,
                  'duration_s': prep.duration_s, 'sample_interval_s': prep.dt_s,
                  'bins': cv.n_rows, 'bin_s': prep.bin_s,
                  'temp_range_c': [float(data.temp_c.min()),
                                   float(data.temp_c.max())],
                  'rate_rms_rad_s': math.sqrt(float(np.mean(
                      data.rate_cmd_rad_s ** 2))),
                  'has_accel': data.has_accel, 'recovery': list(data.recovery)},
        'device_preset': preset,
        'calibration': cal_all.as_dict(),
        'baseline': {'rmse_rad_s': rmse_base,
                     'model': 'paper first-order physics (preset '
                              f'{preset!r}), one bias and one scale factor '
                              'calibrated at the reference temperature'},
        'recalibrated_baseline': {'rmse_rad_s': null.rmse},
        'best': best_doc,
        'findings': findings,
        'not_tested': not_tested,
        'residual': structure,
        'method': {'folds': len(cv.used_folds), 'sub_blocks': int(cv.sub_used.sum()),
                   'min_gain': MIN_GAIN, 'alpha': ALPHA,
                   'delta_bic_max': DELTA_BIC_MAX, 'alpha_tie': ALPHA_TIE,
                   'rmse': 'held-out, every sample, rad/s',
                   'uncertainty': 'delete-a-block jackknife over the folds, '
                                  '1 sigma'},
    }


def _choose(findings, evaluated):
    """Top significant finding, preferring fewer parameters when not separable."""
    sig = [f for f in findings if f['significant']]
    if not sig:
        return None
    top = sig[0]
    simpler = [f for f in sig[1:] if f['n_params'] < top['n_params']
               and _paired_p(evaluated[f['effect']][1].sub,
                             evaluated[top['effect']][1].sub) >= ALPHA_TIE]
    if simpler:
        simpler.sort(key=lambda f: (f['n_params'], f['rmse_rad_s']))
        return simpler[0]
    return top


def _best_doc(best, rmse_base):
    """Return the verdict's entry of the document ('none' when no cause is significant)."""
    if best is None:
        return {'effect': 'none', 'cause': None, 'parameters': {},
                'rmse_rad_s': rmse_base, 'gain': 0.0}
    return {k: best[k] for k in ('effect', 'cause', 'parameters',
                                 'rmse_rad_s', 'gain')}


_CORRELATE_TEXT = {
    'temperature': 'temperature', 'temperature_rate': 'the rate of change of '
    'temperature (dT/dt)', 'rate': 'the applied rate',
    'rate_squared': 'the applied rate squared', 'time': 'time',
    'acceleration': 'acceleration'}


def _structure_message(best, st):
    what = _CORRELATE_TEXT[st['strongest_correlate']]
    if best is None and not st['structure_remains']:
        return ('No cause in the catalogue improves the held-out fit '
                'significantly, and the residual is at its noise floor: the '
                'baseline explains the data.')
    if not st['structure_remains']:
        return (f"After adding {best['effect']}, the residual is at its noise "
                'floor (no remaining structure).')
    lead = ('No cause in the catalogue explains it' if best is None else
            f"After adding {best['effect']}, structure remains that no cause "
            'in the catalogue explains')
    share = st['r2'][st['strongest_correlate']]
    return (f"{lead}: the held-out residual is {st['excess_over_noise']:.1f}x "
            f'its white-noise floor; its strongest correlate is {what} '
            f'(R^2 = {share:.2f}).')
