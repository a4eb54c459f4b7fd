"""
What remains after the chosen causes, and what to say about it.

- :func:`residual_floor`: the held-out RMS of the final model against the
  held-out RMS a correct model would leave on the record's own noise
  (white noise plus the correlated wander of its Allan deviation,
  :mod:`.noise_model`). ``excess = rms / floor``, and the same for means
  over about a sixtieth of a fold (``excess_slow``); the residual is
  *consistent with 1* when both are below the 99 % point of the same
  ratios over the simulated noise records (2 % always allowed per sample).
- :func:`correlates`: the share of the held-out residual (bin means)
  explained by quantile-group means of each regressor; the strongest is
  named when structure remains.
- :func:`confounded`: pairs of regressors that move together
  (|correlation| >= 0.9 over the bins), which no fit can separate.
- :func:`confounded_pair`: a bias that follows temperature or time on a
  record where the two are confounded (a one-way ramp): the pair is named
  with both slopes and the experiment that separates them, and the verdict
  is ``partly_explained``, never ``no_mismatch``.
- :func:`experiments`: what measurement would separate the candidates or
  the confounded regressors, or show what the remaining structure is.
- :func:`verdict`: ``no_mismatch`` (nothing chosen, residual at its
  floor), ``explained`` (causes chosen, residual at its floor),
  ``partly_explained`` (causes chosen, excess above the floor) or
  ``unexplained`` (nothing chosen, excess above the floor).
"""

import math

from gyro_emulator.analysis.diagnose import noise_model
from gyro_emulator.units import AXES
import numpy as np
from scipy import stats

#: |correlation| from which two regressors are reported as confounded.
CONFOUNDED_R = 0.9
#: Quantile of the simulated excess that "consistent with 1" allows.
EXCESS_QUANTILE_Z = 2.33
#: Relative excess of the per-sample RMS always allowed: the floor is an estimate.
MODEL_TOLERANCE = 0.02
#: A residual holds structure when it follows a regressor past its noise-alone
#: limit by this share of what the limit leaves: (R^2 - limit) / (1 - limit).
#: A share, not a test: the limit is a normal approximation from 64 simulations
#: (a bare "R^2 > limit" flagged 7 of 150 records without an effect, all by
#: less than 0.1; a sign-dependent bias went past it by 0.6).
STRUCTURE_MARGIN = 0.25

_CORRELATE_TEXT = {
    'temperature': 'temperature', 'temperature_rate': 'the rate of change of '
    'temperature (dT/dt)', 'rate': 'the applied rate',
    'rate_squared': 'the applied rate squared', 'time': 'time',
    'acceleration': 'acceleration'}

#: The regressor each cause follows (for experiments that separate two causes).
REGRESSOR_OF = {
    'viscosity_temperature': 'temperature', 'bias_temperature': 'temperature',
    'thermal_lag': 'temperature_rate', 'scale_factor_nonlinearity': 'rate',
    'g_sensitivity': 'acceleration', 'time_delay': 'rate', 'pressure_drift': 'time',
    'mode_split_drift': 'temperature', 'temperature_rate_bias': 'temperature_rate',
    'scale_factor_temperature': 'temperature', 'scale_factor_time': 'time',
    'scale_factor_step': 'time', 'bias_time': 'time', 'bias_step': 'time',
    'bias_hysteresis': 'temperature_history'}

_SEPARATE = {
    frozenset({'temperature', 'time'}):
        'cool back down (or heat back up) to the starting temperature, or hold a long '
        'soak: a temperature cause returns with the temperature, a drift in time does not',
    frozenset({'temperature', 'temperature_rate'}):
        'hold soaks long enough to settle at each temperature and ramp at two different '
        'rates: a dT/dt cause vanishes in a soak, a temperature cause does not',
    frozenset({'temperature_rate', 'time'}):
        'ramp up and down at different rates: a dT/dt cause changes sign with the ramp, '
        'a drift in time does not',
    frozenset({'rate', 'rate_squared'}):
        'apply the rate in both directions: odd and even rate terms then separate',
    frozenset({'temperature'}):
        'measure at more temperatures over a wider span: the candidate laws differ in '
        'curvature, which a narrow span hides',
    frozenset({'time'}):
        'repeat the run: a step or drift that is a property of the part comes back, '
        'wander does not',
    frozenset({'rate'}):
        'step the rate over the full range in both directions, with fast and slow changes',
    frozenset({'acceleration'}):
        'turn the part through several orientations at several times',
    frozenset({'temperature', 'temperature_history'}):
        'heat back up to a temperature visited while cooling and hold it: a bias that '
        'follows temperature returns to its value, hysteresis keeps the other branch',
    frozenset({'temperature_history', 'time'}):
        'cycle the temperature up and down more than once: hysteresis repeats with each '
        'cycle, a drift in time does not',
    frozenset({'temperature_history', 'temperature_rate'}):
        'hold long soaks after heating and after cooling: a dT/dt bias decays in the soak, '
        'hysteresis keeps its offset',
    frozenset({'temperature_rate'}):
        'hold soaks after heating and after cooling at the same temperature, and ramp at '
        'different rates: a bias following dT/dt vanishes in a soak, hysteresis does not',
}


def _limit(ratio):
    """Return the 99 % point of a simulated ratio (mean excess plus 2.33 sigma)."""
    return 1.0 + max(float(np.mean(ratio) - 1.0), 0.0) + \
        EXCESS_QUANTILE_Z * float(np.std(ratio, ddof=1))


def structure_limit(prep, superbins, means, sims, have):
    """
    Group R^2 of the held-out residual against the regressors, beside noise alone.

    ``means`` are the held-out residual's super-bin means and ``sims`` the
    simulated noise records' held-out residuals under the same model
    (:func:`.noise_model.held_out_residuals`), groups x simulations.
    The strongest share of the residual's super-bin means that quantile
    groups of one regressor explain (:func:`_group_r2`), for the record and
    for each simulated noise record under the same model
    (:func:`.noise_model.held_out_residuals`). Wander can follow time (or
    anything slow) by chance, and the simulations say how far; a residual
    that follows a regressor beyond the simulations' point for that
    regressor (mean plus z sigma, z for 1 % Bonferroni-shared over the
    regressors) holds structure, whatever its RMS says: an effect left in
    the residual also inflates the wander measured from it, and with it the
    floor. Returns (observed R^2, its limit, regressor, margin) of the
    regressor that passes its limit by most (or comes closest), the margin
    (R^2 - limit) / (1 - limit); :data:`STRUCTURE_MARGIN` decides.
    """
    sb = superbins
    found = regressors(prep, have)
    z = stats.norm.isf(0.01 / len(found))                 # 1 % over the regressors
    best = (0.0, 0.0, 1.0, None)
    for key, x in found.items():
        xg = sb.aggregate(x)
        r2 = _group_r2(xg, means, sb.weight)
        null = np.array([_group_r2(xg, sims[:, j], sb.weight) for j in range(sims.shape[1])])
        limit = min(1.0, float(np.mean(null)) + z * float(np.std(null, ddof=1)))
        margin = max(-1.0, (r2 - limit) / max(1.0 - limit, 1e-9))
        if best[3] is None or margin > best[0]:
            best = (margin, r2, limit, key)
    return best[1], best[2], best[3], best[0]


def residual_floor(selector, final, have=None):
    """
    Held-out residual of ``final`` against its noise floor, per sample and averaged.

    Per sample: ``excess = rms / floor``, the floor the expected held-out RMS
    of a correct model on the record's noise. Averaged over super-bins
    (``averaging_s``, about a sixtieth of a fold): ``excess_slow``, the same
    ratio for the held-out group means, where white noise is averaged down
    and slow structure stands out whatever the sample rate. The residual is
    *consistent* with its floor when both are within their simulated 99 %
    points, the per-sample one allowing ``MODEL_TOLERANCE`` (the floor is an
    estimate itself), and (given ``have``, the regressors the record
    varies) when it follows no regressor beyond what its noise does
    (:func:`structure_limit`).
    """
    noise = selector.noise_of(final)
    sb = selector.superbins
    cols = selector.group_columns(final.model, final.full.phis)
    prep = selector.cv.prep
    n_kept = len(selector.cv.y)
    resid_sims = noise_model.held_out_residuals(cols, sb, selector.sims_of(noise),
                                                final.model.penalty(selector.ctx))
    floor, rms_sims, ms_sims = noise_model.held_out_floor(noise, resid_sims, sb, n_kept)
    group = sb.group[prep.sample_bin]
    means = np.bincount(group, weights=final.resid, minlength=len(sb)) / sb.weight
    ms_obs = float(np.sum(sb.weight * means ** 2) / np.sum(sb.weight))
    slow_floor = float(np.sqrt(np.mean(ms_sims)))
    excess, excess_slow = final.rmse / floor, math.sqrt(ms_obs) / slow_floor
    limit = max(_limit(rms_sims / floor), 1.0 + MODEL_TOLERANCE)
    limit_slow = _limit(np.sqrt(ms_sims) / slow_floor)
    r2, r2_limit, follows, margin = (structure_limit(prep, sb, means, resid_sims, have)
                                     if have is not None else (0.0, 1.0, None, 0.0))
    return {'rms_rad_s': final.rmse, 'floor_rad_s': floor, 'excess': excess,
            'excess_limit': limit, 'averaging_s': float(np.median(np.diff(sb.time_s))),
            'excess_slow': excess_slow, 'excess_slow_limit': limit_slow,
            'follows': {'regressor': follows, 'r2': r2, 'r2_limit': r2_limit,
                        'margin': margin},
            'consistent': bool(excess <= limit and excess_slow <= limit_slow
                               and margin < STRUCTURE_MARGIN),
            'wander_measured_to_s': noise.tau_max_s, 'noise': noise.as_dict()}


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


def regressors(prep, have):
    """Return the regressors on the bins that the record varies: name -> array."""
    b = prep.binned
    out = {'time': b.time_s}
    if 'temp' in have:
        out['temperature'] = b.temp_c
        out['temperature_rate'] = prep.temp_rate_on_bins
    if 'rate' in have:
        out['rate'] = b.rate
        out['rate_squared'] = b.rate2
    if 'accel' in have and b.accel is not None:
        for k, axis in enumerate(AXES):
            if np.ptp(b.accel[:, k]) > 0.0:
                out[f'acceleration_{axis}'] = b.accel[:, k]
    return out


def correlates(prep, resid_samples, have):
    """Group R^2 of the held-out bin residual against each regressor; returns (r2, strongest)."""
    b = prep.binned
    rb = np.bincount(prep.sample_bin, weights=resid_samples, minlength=len(b)) / b.weight
    r2 = {}
    for name, x in regressors(prep, have).items():
        key = 'acceleration' if name.startswith('acceleration') else name
        r2[key] = max(r2.get(key, 0.0), _group_r2(x, rb, b.weight))
    strongest = max(r2, key=r2.get)
    return r2, strongest


def confounded(prep, have):
    """Pairs of regressors with |weighted correlation| >= CONFOUNDED_R: [{a, b, correlation}]."""
    w = prep.binned.weight
    regs = regressors(prep, have)
    names = list(regs)
    out = []
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            xa, xb = regs[a] - np.average(regs[a], weights=w), regs[b] - np.average(
                regs[b], weights=w)
            den = math.sqrt(float(np.sum(w * xa * xa) * np.sum(w * xb * xb)))
            if den <= 0.0:
                continue
            r = float(np.sum(w * xa * xb)) / den
            if abs(r) >= CONFOUNDED_R:
                out.append({'a': a, 'b': b, 'correlation': r})
    return out


def _kind(name):
    return 'acceleration' if name.startswith('acceleration') else name


def experiments(selected, confound, remains, strongest):
    """Return sentences: what would separate the candidates, regressors or what remains."""
    out = []
    for pair in confound:
        key = frozenset({_kind(pair['a']), _kind(pair['b'])})
        if key in _SEPARATE:
            out.append(f"{pair['a']} and {pair['b']} are confounded "
                       f"(r = {pair['correlation']:+.4f}): {_SEPARATE[key]}.")
    for entry in selected:
        for other in entry.indistinguishable_from:
            key = frozenset({REGRESSOR_OF.get(entry.effect, 'time'),
                             REGRESSOR_OF.get(other, 'time')})
            text = _SEPARATE.get(key)
            if text:
                out.append(f'{entry.effect} cannot be told from {other}: {text}.')
    if remains:
        text = _SEPARATE.get(frozenset({strongest}))
        if text:
            out.append(f'The remaining structure follows {_CORRELATE_TEXT[strongest]}: '
                       f'{text}.')
    return list(dict.fromkeys(out))


#: A candidate that follows one of these regressors (not time, which wander
#: follows by chance) and gains this much held-out with p below SUGGESTIVE_P
#: before the correction over the candidates makes "no mismatch" untrue.
SUGGESTIVE_REGRESSORS = ('temperature', 'temperature_rate', 'rate', 'acceleration')
SUGGESTIVE_GAIN = 0.25
SUGGESTIVE_P = 0.05


def suggestive(candidates, confound):
    """
    Return the last step's strongest candidate that is suggestive but not established.

    ``candidates``: (effect id, held-out gain over the step before,
    uncorrected p) of the step that added nothing; ``confound``: the
    confounded pairs. A candidate counts when its
    regressor (:data:`REGRESSOR_OF`) is one of :data:`SUGGESTIVE_REGRESSORS`
    and not confounded with time, its gain is at least
    :data:`SUGGESTIVE_GAIN` and its p below :data:`SUGGESTIVE_P`. In 150
    seeded records without an effect (thermal ramps, static runs, lab runs,
    four noise colours) none did; a bias tempco over a chamber cycle whose
    wander estimate it inflated did (gain 48 %, p = 0.016).
    """
    with_time = {c['a'] if c['b'] == 'time' else c['b'] for c in confound
                 if 'time' in (c['a'], c['b'])}
    found = None
    for effect, gain, p in candidates:
        regressor = REGRESSOR_OF.get(effect)
        if (regressor in SUGGESTIVE_REGRESSORS and regressor not in with_time
                and gain >= SUGGESTIVE_GAIN and p < SUGGESTIVE_P
                and (found is None or gain > found[1])):
            found = (effect, gain, p)
    return found


#: |correlation| of temperature and time from which a bias that follows
#: either is reported as the pair (a one-way ramp or a staircase of soaks).
PAIR_R = 0.95
#: Causes whose bias follows temperature or time.
_PAIR_CAUSES = ('bias_temperature', 'bias_time', 'temperature_rate_bias', 'bias_hysteresis',
                'bias_step')


#: Causes of one quantity, one following temperature and the other time,
#: each to its twin: where the two are confounded, the record cannot choose.
_TWIN_OF = {'bias_temperature': 'bias_time', 'bias_time': 'bias_temperature',
            'scale_factor_temperature': 'scale_factor_time',
            'scale_factor_time': 'scale_factor_temperature'}


def _time_temperature_pair(confound):
    """Return the confounded pair of temperature and time with |r| >= PAIR_R, or None."""
    return next((c for c in confound if {c['a'], c['b']} == {'temperature', 'time'}
                 and abs(c['correlation']) >= PAIR_R), None)


def confounded_twins(steps, confound):
    """
    Return, per chosen cause of ``steps``, the twin it cannot be told from.

    When temperature and time are confounded (|r| >= :data:`PAIR_R`), a bias
    or scale factor that follows one follows the other as well: the cause
    chosen of a pair in :data:`_TWIN_OF` cannot be told from its twin when the
    twin was significant in the same step, whatever the fold test between
    them says (their polynomial orders differ, and a cause not yet in the
    model, such as a bias drift under a rate held through a cooling, can
    favour either). ``steps`` are (candidates, chosen or None).
    """
    confounded = _time_temperature_pair(confound) is not None
    out = []
    for cands, chosen in steps:
        if chosen is None:
            continue
        twin = _TWIN_OF.get(chosen.effect.effect_id)
        named = confounded and any(c.significant and c.effect.effect_id == twin for c in cands)
        out.append([twin] if named else [])
    return out


def _slope(x, r, w):
    """Weighted least-squares slope of r on [1, x]."""
    xc = x - np.average(x, weights=w)
    den = float(np.sum(w * xc * xc))
    return float(np.sum(w * xc * (r - np.average(r, weights=w)))) / den if den > 0 else 0.0


def confounded_pair(prep, resid_bins, confound, selected, res):
    """
    Name a bias that follows temperature or time when the record cannot say which.

    Given when temperature and time are confounded (|r| >= :data:`PAIR_R`)
    and a chosen cause is a bias that follows one of them. ``resid_bins`` is the recalibrated
    baseline's residual on the bins: the two slopes are fitted to it alone,
    each the whole answer if that regressor is the cause.

    Returns
    -------
    dict or None
        ``correlation``, ``bias_temp_coeff_rad_s_k``, ``bias_drift_rad_s_per_h``,
        ``experiment`` and ``text``.

    """
    pair = _time_temperature_pair(confound)
    # only a chosen cause names the pair: on raw ADIS16405 y stretches the
    # residual's wander passes the structure limit against time on a ramp
    # (3 of 12 records without an effect), which is not evidence of a bias
    chosen = any(e.effect in _PAIR_CAUSES for e in selected)
    if not pair or not chosen:
        return None
    b = prep.binned
    per_k = _slope(b.temp_c, resid_bins, b.weight)
    per_h = _slope(b.time_s, resid_bins, b.weight) * 3600.0
    r = pair['correlation']
    deg = 180.0 / math.pi
    text = (f'the bias follows temperature or time (r = {r:.3f}): '
            f'{per_k * deg:.3g} deg/s/K or {per_h * deg:.3g} deg/s/h')
    return {'correlation': r, 'bias_temp_coeff_rad_s_k': per_k,
            'bias_drift_rad_s_per_h': per_h,
            'experiment': _SEPARATE[frozenset({'temperature', 'time'})], 'text': text}


def verdict(selected, consistent):
    """Return the verdict: no_mismatch, explained, partly_explained or unexplained."""
    if selected:
        return 'explained' if consistent else 'partly_explained'
    return 'no_mismatch' if consistent else 'unexplained'


def coverage_text(tested, total):
    """Return "2 of 15 causes could be tested (a, b)", or None when every cause could."""
    if len(tested) >= total:
        return None
    return (f'{len(tested)} of {total} causes could be tested'
            + (f" ({', '.join(tested)})" if tested else ''))


def structure_text(res):
    """
    Return what the averaged residual follows, in the numbers the verdict's rule used.

    The rule (:func:`structure_limit`) compares the R^2 of the super-bin means
    against one regressor with what noise alone reaches; a regressor is said
    to be followed only past that point.
    """
    f = res['follows']
    if f['regressor'] is None:
        return None
    what = _CORRELATE_TEXT[_kind(f['regressor'])]
    means = f"its {res['averaging_s']:.3g} s means"
    if f['r2'] > f['r2_limit']:
        return (f"{means} follow {what} (R^2 = {f['r2']:.2f}; noise alone reaches "
                f"{f['r2_limit']:.2f})")
    return (f'{means} follow no regressor beyond what noise does (the closest is {what}, '
            f"R^2 = {f['r2']:.2f}; noise alone reaches {f['r2_limit']:.2f})")


def follows(res):
    """Return the regressor the averaged residual follows past its noise-alone limit, or None."""
    f = res['follows']
    return _kind(f['regressor']) if f['regressor'] and f['r2'] > f['r2_limit'] else None


def _failed(res):
    """Return which comparisons put the residual above its floor, as a phrase (or None)."""
    out = []
    if res['excess'] > res['excess_limit']:
        out.append('per sample')
    if res['excess_slow'] > res['excess_slow_limit']:
        out.append(f"in {res['averaging_s']:.3g} s means")
    if res['follows']['margin'] >= STRUCTURE_MARGIN:
        out.append('in what those means follow')
    return (', '.join(out[:-1]) + ' and ' + out[-1] if len(out) > 1 else
            out[0] if out else None)


#: What a ``no_mismatch`` says where the data bound no tested cause's size.
NOTHING_BOUNDED = (' The data bound the size of none of them (95 %): an effect of any '
                   'size in the searched ranges could still hide.')


def message(result, selected, res, coverage=None, suggestive=False, ruled_out=None):
    """
    One paragraph on the verdict, the residual and what remains.

    Every comparison is given with what noise alone reaches, the one that
    decides is named, and a regressor is said to be followed only past its
    own noise-alone point. ``coverage`` (:func:`coverage_text`) says how
    few causes the record could test; with a ``suggestive`` candidate
    (:func:`suggestive`) no cause is established rather than none explains.
    ``selected``: the chosen causes (:class:`.diagnosis.Cause`). ``ruled_out``:
    what the data rule out (:func:`.ruled_out.text`); a ``no_mismatch``
    states it, or that it bounds none (:data:`NOTHING_BOUNDED`), never that
    the baseline explains what was tested.
    """
    names = ', '.join(e.effect for e in selected)
    level = (f"the held-out residual is {res['excess']:.3f}x its noise floor "
             f"({res['rms_rad_s']:.3g} vs {res['floor_rad_s']:.3g} rad/s; noise alone "
             f"reaches {res['excess_limit']:.3f}x), {res['excess_slow']:.2f}x in "
             f"{res['averaging_s']:.3g} s means (noise alone: "
             f"{res['excess_slow_limit']:.2f}x)")
    if res['wander_measured_to_s'] < res['averaging_s']:
        level += ('; the record is too short or gappy to measure its slow wander, so '
                  'the floor holds its fast noise only')
    structure = structure_text(res)
    if result == 'no_mismatch':
        rules = (f' The data rule out (95 %), beyond the baseline: {ruled_out}.'
                 if ruled_out else NOTHING_BOUNDED)
        if coverage:
            return (f'{coverage}; nothing testable was found: none of them improves the '
                    f'held-out fit significantly and {level}.' + rules)
        return 'No cause improves the held-out fit significantly and ' + level + '.' + rules
    if result == 'explained':
        return f'Explained by {names}: ' + level + '.'
    if result == 'partly_explained':
        lead = f'Partly explained by {names}'
    else:
        lead = ('No cause is established' if suggestive else 'No cause explains the mismatch'
                if coverage else 'No cause in the catalogue explains the mismatch')
        lead += f'; {coverage}' if coverage else ''
    failed = _failed(res)
    above = '' if failed is None else f'; it exceeds what noise alone reaches {failed}'
    noise = res['noise']
    if (failed and res['wander_measured_to_s'] >= res['averaging_s']
            and noise['bias_instability_rad_s'] == 0.0 and noise['rrw_rad_s_sqrt_s'] == 0.0):
        above += (' (the floor holds no wander: none shows up to '
                  f"{res['wander_measured_to_s']:.3g} s, so wander slower than the record can "
                  'measure would do this as well as a drift)')
    return f'{lead}: {level}{above}' + (f'; {structure}.' if structure else '.')
