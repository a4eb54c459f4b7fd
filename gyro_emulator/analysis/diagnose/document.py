"""
The JSON document of a diagnosis.

Top level: ``input``, ``device_preset``, ``calibration``, ``baseline``,
``recalibrated_baseline``, ``set_aside``, ``best``, ``selected``,
``verdict``, ``residual``, ``confounded``, ``confounded_pair``, ``experiments``, ``findings``
(the first step's candidates, ranked), ``steps``, ``not_tested`` and
``method``. ``best`` is the first cause chosen (``effect: 'none'`` when
none is); every entry of ``selected`` has the same fields, among them the
per-sample ``gain_step``, ``gain_binned`` (the held-out gain on the
super-bin means, the verdict's averaging time) and ``evidence`` (which
test, fold or likelihood, and which gain the decision rests on), and
``rmse_interval_rad_s`` and ``gain_interval``: the 95 % delete-a-fold
jackknife intervals of its held-out RMSE and of its gain over the baseline
(:meth:`.cv.CrossValidation.interval`); ``baseline`` has the RMSE's too.
"""

import math

from gyro_emulator.analysis.diagnose import baseline as base
from gyro_emulator.analysis.diagnose import models, noise_model, screening, selection
from gyro_emulator.analysis.diagnose import verdict as vd
import numpy as np


def _intervals(cv, sse_fold, sse_base):
    """Return the 95 % jackknife intervals of a held-out RMSE and of its gain (cv.interval)."""
    if cv is None or sse_base is None:
        return {}
    rmse, gain = cv.interval(sse_fold), cv.interval(sse_fold, sse_base)
    return {'rmse_interval_rad_s': None if rmse is None else list(rmse),
            'gain_interval': None if gain is None else list(gain)}


def _entry(cand, rmse_base, mechanisms=True, cv=None, sse_base=None):
    """One chosen cause: the JSON fields of ``best`` and ``selected``."""
    eff = cand.effect
    out = {'effect': eff.effect_id, 'cause': eff.cause, 'kind': eff.kind,
           'parameters': selection.jackknife_parameters(eff, cand.evaluated),
           'rmse_rad_s': cand.evaluated.rmse,
           'gain': 1.0 - cand.evaluated.rmse / rmse_base,
           'gain_step': cand.gain_step, 'gain_binned': cand.gain_binned,
           'p_value': cand.p_value, 'evidence': _evidence(cand),
           'delta_bic': cand.delta_bic, 'effective_bins': cand.n_eff,
           'noise_share_of_gain': cand.null_share,
           'indistinguishable_from': list(cand.indistinguishable),
           **_intervals(cv, cand.evaluated.sse_fold, sse_base)}
    if mechanisms:
        out['mechanisms'] = list(eff.mechanisms)
        out['competitors'] = list(eff.competitors)
    return out


def _evidence(cand):
    """Return what the significance rests on: the route, its p-values and its gain."""
    return {'route': cand.route, 'p_fold_test': cand.p_fold,
            'p_state_space': cand.p_statespace, 'likelihood_ratio': cand.lr,
            'gain_predictive': cand.gain_predictive,
            'gain': 'gain_predictive' if cand.route == 'state_space' else 'gain_step'}


def _finding(cand, rmse_base, rmse_null):
    """One candidate of the first step (the ``findings`` table)."""
    ev = cand.evaluated
    return {'effect': cand.effect.effect_id, 'cause': cand.effect.cause,
            'kind': cand.effect.kind,
            'parameters': selection.jackknife_parameters(cand.effect, ev),
            'rmse_rad_s': ev.rmse, 'gain': 1.0 - ev.rmse / rmse_base,
            'gain_over_recalibrated': 1.0 - ev.rmse / rmse_null,
            'gain_binned': cand.gain_binned, 'p_value': cand.p_value,
            'evidence': _evidence(cand), 'delta_bic': cand.delta_bic,
            'n_params': 2 + cand.effect.n_params, 'significant': cand.significant}


def _none_entry(rmse_base):
    return {'effect': 'none', 'cause': None, 'kind': None, 'parameters': {},
            'rmse_rad_s': rmse_base, 'gain': 0.0, 'p_value': None,
            'indistinguishable_from': []}


def _input(data, cv):
    prep = cv.prep
    return {'source': data.source, 'rows': data.rows, 'duration_s': prep.duration_s,
            'time_span_s': [float(data.time_s[0]), float(data.time_s[-1])],
            'sample_interval_s': prep.dt_s, 'bins': cv.n_rows, 'bin_s': prep.bin_s,
            'temp_range_c': ([float(data.temp_c.min()), float(data.temp_c.max())]
                             if data.has_temp else None),
            'has_temp': data.has_temp,
            'rate_rms_rad_s': math.sqrt(float(np.mean(data.rate_cmd_rad_s ** 2))),
            'has_accel': data.has_accel, 'recovery': list(data.recovery)}


def _set_aside(screen, rms_all, best_gain):
    return {'count': screen['count'], 'fraction': screen['fraction'],
            'segments': screen['segments'][:50], 'segments_total': len(screen['segments']),
            'threshold_sigma': screen['threshold'], 'sigma_rad_s': screen['sigma_rad_s'],
            'baseline_rmse_all_samples_rad_s': rms_all['baseline'],
            'best_gain_all_samples': best_gain}


def _steps(steps):
    return [{'added': None if chosen is None else chosen.effect.effect_id,
             'candidates': [{'effect': c.effect.effect_id, 'rmse_rad_s': c.evaluated.rmse,
                             'gain_step': c.gain_step, 'gain_binned': c.gain_binned,
                             'p_value': c.p_value, 'route': c.route,
                             'p_state_space': c.p_statespace,
                             'delta_bic': c.delta_bic, 'significant': c.significant}
                            for c in cands]}
            for cands, chosen in steps]


def build(data, preset, cv, screen, rmse_base, null, steps, res, confound, not_tested,
          rms_all, alpha, sse_base=None):
    """Return the JSON document (see the module docstring)."""
    chosen = [c for _, c in steps if c is not None]
    selected = [_entry(c, rmse_base, cv=cv, sse_base=sse_base) for c in chosen]
    for entry, twins in zip(selected, vd.confounded_twins(steps, confound)):
        entry['indistinguishable_from'] += [t for t in twins
                                            if t not in entry['indistinguishable_from']]
    result = vd.verdict(selected, res['consistent'])
    hint = None
    if steps and steps[-1][1] is None:
        # the step that added nothing: a large gain it could not establish
        hint = vd.suggestive([(c.effect.effect_id, c.gain_step, c.p_value)
                              for c in steps[-1][0]], confound)
        if hint is not None:
            result = 'partly_explained' if selected else 'unexplained'
    pair = vd.confounded_pair(cv.prep, _null_resid_bins(cv, null), confound, selected, res)
    if pair is not None:
        # a bias that follows temperature or time far beyond noise: never no_mismatch
        result = 'partly_explained'
    remains = result in ('partly_explained', 'unexplained')
    best_gain = None
    if chosen and rms_all['best'] is not None:
        best_gain = 1.0 - rms_all['best'] / rms_all['baseline']
    res.update({'structure_remains': remains, 'excess_over_noise': res['excess'],
                'noise_rad_s': res['noise']['white_sigma_rad_s']})
    tested = [c.effect.effect_id for c in steps[0][0]] if steps else []
    res['message'] = vd.message(result, selected, res, vd.coverage_text(
        tested, len(tested) + len(not_tested)))
    res['causes_tested'] = tested
    res['suggestive'] = None
    if pair is not None:
        res['message'] += (f" The record cannot separate the two: {pair['text']}. To tell "
                           f"them apart, {pair['experiment']}.")
    if hint is not None:
        effect, gain, p = hint
        n = len(steps[-1][0])
        res['suggestive'] = {'effect': effect, 'gain': gain, 'p_value': p}
        for lead in ('No cause in the catalogue explains the mismatch',
                     'No cause explains the mismatch'):
            res['message'] = res['message'].replace(lead, 'No cause is established')
        res['message'] += (
            f' {effect} removes {100 * gain:.0f} % of the held-out error (p = {p:.2g} before '
            f'the correction for the {n} candidates; the bar is {alpha / n:.2g}): suggestive, '
            'not established. The wander measured from a residual that still holds such an '
            'effect is inflated by it, and with it the bar: a longer run, or more '
            'temperature cycles, would settle it.')
    best = dict(selected[0]) if selected else _none_entry(rmse_base)
    best['gain_all_samples'] = best_gain
    cal_all = base.calibrate(cv.prep.binned, cv.ctx.phys)
    return {
        'input': _input(data, cv),
        'device_preset': preset,
        'calibration': cal_all.as_dict(),
        'baseline': {'rmse_rad_s': rmse_base,
                     'rmse_interval_rad_s': _intervals(cv, sse_base, sse_base).get(
                         'rmse_interval_rad_s'),
                     'model': 'paper first-order physics (preset '
                              f'{preset!r}), one bias and one scale factor '
                              'calibrated at the reference temperature'},
        'recalibrated_baseline': {'rmse_rad_s': null.rmse},
        'set_aside': _set_aside(screen, rms_all, best_gain),
        'best': best,
        'selected': selected,
        'verdict': result,
        'residual': res,
        'confounded': confound,
        'confounded_pair': pair,
        'experiments': vd.experiments(selected, confound, remains, vd.follows(res)),
        'findings': [_finding(c, rmse_base, null.rmse) for c in steps[0][0]] if steps else [],
        'steps': _steps(steps),
        'not_tested': not_tested,
        'method': _method(cv, alpha),
    }


def _null_resid_bins(cv, null):
    """Return the recalibrated baseline's residual on the bins (its fit on every bin)."""
    b = cv.prep.binned
    return b.gyro - models.predict(null.model, cv.ctx, b, null.full)


def _method(cv, alpha):
    return {'folds': len(cv.used_folds), 'sub_blocks': len(cv.used_folds),
            'alpha': alpha, 'alpha_tie': selection.ALPHA_TIE,
            'min_gain': selection.MIN_GAIN, 'min_gain_rate': selection.MIN_GAIN_RATE,
            'delta_bic_max': selection.DELTA_BIC_MAX,
            'outlier_threshold_sigma': screening.THRESHOLD,
            'null_simulations': noise_model.N_SIM,
            'rmse': 'held-out, every kept sample, rad/s',
            'test': 'fold test of the held-out SSE reduction less the reduction the '
                    "record's own noise gives, Nadeau-Bengio corrected; for causes with "
                    'fixed columns also the likelihood ratio of a local level (white '
                    'noise plus a random walk capped by the Allan deviation at short '
                    'averaging times) with and without the cause on the group means, '
                    'Bartlett-corrected by a parametric bootstrap; p = 2 min of the two; '
                    'Bonferroni over the candidates of each step',
            'information_criterion': 'BIC on the effective number of independent bins',
            'uncertainty': 'delete-a-block jackknife over the folds, 1 sigma',
            'blocks': 'the paired test counts folds (sub_blocks = folds)'}


#: A part whose own SF tempco is below this share of the physics' reads as compensated.
COMPENSATED_SHARE = 1.0 / 3.0
#: Compensation is read only where the physics' slope is this many sigma of the fitted one.
COMPENSATED_SIGMAS = 5.0


def note_compensation(doc, phys):
    """
    Give a chosen ``scale_factor_temperature`` the part's own SF tempco; name compensation.

    The cause's c1 is relative to the baseline's R(T) (Eq 13-20): the part's
    own relative slope at T_ref is c1 + R'(T_ref) (R(T_ref) = 1), its
    1-sigma that of c1. Where the physics predicts a slope many sigma from
    zero and the part's own slope is below :data:`COMPENSATED_SHARE` of it,
    the part behaves as a temperature-compensated one (real parts are
    trimmed in temperature at the factory): that mechanism is listed first
    and the verdict's message says so.
    """
    ref = phys.ref_temp_c
    physics = float(phys.ratio(ref + 0.5) - phys.ratio(ref - 0.5))   # over 1 K about T_ref
    for entry in doc['selected']:
        if entry['effect'] != 'scale_factor_temperature':
            continue
        c1 = entry['parameters']['sf_temp_coeff_per_k']
        own = c1['value'] + physics
        # no sigma (None, 0 or NaN): compensation is not read
        sigma = c1['sigma'] if c1['sigma'] and math.isfinite(c1['sigma']) else math.inf
        compensated = (abs(physics) > COMPENSATED_SIGMAS * sigma
                       and abs(own) < COMPENSATED_SHARE * abs(physics))
        entry['part_sf_temp_coeff_per_k'] = {
            'value': own, 'sigma': c1['sigma'], 'physics_per_k': physics,
            'meaning': "the part's own relative SF slope at T_ref: c1 plus the physics' "
                       "R'(T_ref)", 'compensated': compensated}
        if not compensated:
            continue
        first = [m for m in entry['mechanisms'] if m.startswith('factory')]
        entry['mechanisms'] = first + [m for m in entry['mechanisms'] if m not in first]
        doc['residual']['message'] += (
            f" The part's own scale-factor tempco is {1e6 * own:+.3g} +- "
            f'{1e6 * sigma:.2g} ppm/K at {ref:g} C, far below the '
            f"{1e6 * physics:+.3g} ppm/K of the paper's physics: it behaves as a "
            'temperature-compensated part (scale_factor_temperature is relative to '
            'the physics).')
    best = doc['best']
    if doc['selected'] and 'part_sf_temp_coeff_per_k' in doc['selected'][0]:
        # best is the first selected cause (a copy of its entry)
        best['part_sf_temp_coeff_per_k'] = doc['selected'][0]['part_sf_temp_coeff_per_k']
        best['mechanisms'] = doc['selected'][0]['mechanisms']
