"""
The one place a :class:`.diagnosis.Diagnosis` is made, and where its verdict is decided.

:func:`build` takes what the pipeline measured (the screening, the folds,
the selection steps, the residual against its floor, the confounded
regressors), decides the verdict (:func:`_decide`: the residual's verdict,
made ``partly_explained`` or ``unexplained`` by a suggestive candidate and
``partly_explained`` by a bias the record cannot place in temperature or
time), writes the message once (:func:`_message`), and returns the frozen
diagnosis. Every chosen cause carries ``gain_step``, ``gain_binned`` (the
held-out gain on the super-bin means, the verdict's averaging time),
``evidence`` (which test, fold or likelihood, and which gain the decision
rests on), and ``rmse_interval_rad_s`` and ``gain_interval``: the 95 %
delete-a-fold jackknife intervals of its held-out RMSE and of its gain over
the baseline (:meth:`.cv.CrossValidation.interval`); the baseline has the
RMSE's too. Against the paper's physics a chosen
``scale_factor_temperature`` also carries the part's own SF tempco
(:func:`own_tempco`).
"""

import math

from gyro_emulator.analysis.diagnose import baseline as base
from gyro_emulator.analysis.diagnose import (intervals, models, noise_model, ruled_out,
                                             screening, selection)
from gyro_emulator.analysis.diagnose import verdict as vd
from gyro_emulator.analysis.diagnose.diagnosis import (
    Baseline, Bound, Candidate, Cause, Confound, ConfoundedPair, Diagnosis, Evidence, Finding,
    Follows, frozen_mapping, InSampleOnly, Method, NotTested, OwnTempco, Parameter,
    RecordSummary, Residual, SetAside, Step, Suggestive, TemperaturePolynomial)
import numpy as np


def _interval(cv, sse_fold, sse_base=None):
    """Return the 95 % jackknife interval of a held-out RMSE, or of its gain (cv.interval)."""
    found = cv.interval(sse_fold) if sse_base is None else cv.interval(sse_fold, sse_base)
    return None if found is None else tuple(found)


def _parameters(cand, ctx, frame):
    """Return a candidate's parameters with their sigmas and 95 % intervals (read-only mapping)."""
    found = ruled_out.estimates_of(cand, ctx, frame)
    out = {}
    for p in cand.effect.params:
        e = found[p.name]
        method = e.method
        edges = [side for side, is_open in (('low', e.open_low), ('high', e.open_high))
                 if is_open]
        if edges:
            method += (f"; its {' and '.join(edges)} end at the edge of the searched range: "
                       'the interval may reach beyond it')
        out[p.name] = Parameter(value=e.value, sigma=e.sigma, unit=p.unit, meaning=p.meaning,
                                interval=None if e.interval is None else tuple(e.interval),
                                method=method)
    return frozen_mapping(out), found


def _evidence(cand):
    """Return what the significance rests on: the route, its p-values and its gain."""
    return Evidence(route=cand.route, p_fold_test=cand.p_fold,
                    p_state_space=cand.p_statespace, likelihood_ratio=cand.lr,
                    gain_predictive=cand.gain_predictive,
                    gain='gain_step' if cand.route == 'fold_test' else 'gain_predictive')


#: The datasheet figure a part's own SF tempco is compared with, 1/K: the typical
#: scale-factor temperature coefficient of a factory-compensated part.
COMPENSATED_SF_TEMPCO_PER_K = 40e-6
#: Where that figure comes from, as the JSON and the message name it.
COMPENSATED_SOURCE = ('40 ppm/K, the typical SF tempco of a factory-compensated part (the '
                      "ADIS16405 datasheet's figure, as the project's real-noise studies inject "
                      'it)')


def own_tempco(c1, phys):
    """
    Return the part's own SF tempco of a ``scale_factor_temperature`` cause (:class:`OwnTempco`).

    The cause's c1 (a :class:`.diagnosis.Parameter`) is relative to the
    baseline's R(T) (Eq 13-20): the part's own relative slope at T_ref is
    c1 + R'(T_ref) (R(T_ref) = 1), its sigma and 95 % interval those of c1
    shifted. The part reads as temperature-compensated (real parts are
    trimmed at the factory) when its interval excludes the physics' slope
    and its lower end in magnitude is within the datasheet figure of a
    compensated part (:data:`COMPENSATED_SF_TEMPCO_PER_K`): the data show it
    far from the physics and do not rule out that it meets the figure. A part
    whose whole interval lies beyond the figure (-148 +- 2 ppm/K, an
    uncompensated datasheet figure; +50 +- 1) is not.
    """
    ref = phys.ref_temp_c
    physics = float(phys.ratio(ref + 0.5) - phys.ratio(ref - 0.5))   # over 1 K about T_ref
    own = c1.value + physics
    interval = None if c1.interval is None else (c1.interval[0] + physics,
                                                 c1.interval[1] + physics)
    compensated = False
    if interval is not None:
        near = (0.0 if interval[0] <= 0.0 <= interval[1]
                else min(abs(interval[0]), abs(interval[1])))
        compensated = (not interval[0] <= physics <= interval[1]
                       and near <= COMPENSATED_SF_TEMPCO_PER_K)
    return OwnTempco(value=own, sigma=c1.sigma, physics_per_k=physics,
                     meaning="the part's own relative SF slope at T_ref: c1 plus the physics' "
                             "R'(T_ref)", compensated=compensated, interval=interval,
                     datasheet_per_k=COMPENSATED_SF_TEMPCO_PER_K, datasheet=COMPENSATED_SOURCE)


def _compensation_text(cause, phys):
    """Return what the message says of the part's own SF tempco (empty without one)."""
    own = cause.part_sf_temp_coeff_per_k
    if own is None or own.interval is None:
        return ''
    lo, hi = (1e6 * v for v in own.interval)
    said = (f" The part's own scale-factor tempco is {1e6 * own.value:+.3g} ppm/K at "
            f'{phys.ref_temp_c:g} C (95 % {lo:+.3g} to {hi:+.3g}), against '
            f"{1e6 * own.physics_per_k:+.3g} ppm/K of the paper's physics and "
            f'{1e6 * own.datasheet_per_k:.3g} ppm/K of a compensated part ({own.datasheet}): ')
    if own.compensated:
        return said + ('it behaves as a temperature-compensated part '
                       '(scale_factor_temperature is relative to the physics).')
    return said + 'it is not read as a compensated part.'


def _cause(cand, current, rmse_base, cv, sse_base, twins, phys):
    """
    One chosen cause (:class:`Cause`); ``twins`` join what it cannot be told from.

    ``current`` is the model it was added to. Given ``phys`` (a baseline of
    the paper's physics), a ``scale_factor_temperature`` cause carries the
    part's own SF tempco and, on a compensated part, lists the factory trim
    first among its mechanisms.
    """
    eff, ev = cand.effect, cand.evaluated
    alike = list(cand.indistinguishable)
    alike += [t for t in twins if t not in alike]
    params, found = _parameters(cand, cv.ctx, cv.prep.binned)
    # the verdict's rule reads the interval the cause states (the wider of the
    # folds' jackknife and the sandwich): explained never beside an interval
    # that holds zero
    clear = intervals.interval_clear_of_zero(eff, found, cv.ctx, current.full.sse,
                                             ev.full.sse, cand.n_eff)
    joint = None if clear else intervals.size_joint_p(eff, found, ev)
    own = None
    mechanisms = list(eff.mechanisms)
    if phys is not None and eff.effect_id == 'scale_factor_temperature':
        own = own_tempco(params['sf_temp_coeff_per_k'], phys)
        if own.compensated:
            first = [m for m in mechanisms if m.startswith('factory')]
            mechanisms = first + [m for m in mechanisms if m not in first]
    return Cause(effect=eff.effect_id, cause=eff.cause, kind=eff.kind, parameters=params,
                 rmse_rad_s=ev.rmse, gain=1.0 - ev.rmse / rmse_base, gain_step=cand.gain_step,
                 gain_binned=cand.gain_binned, p_value=cand.p_value, evidence=_evidence(cand),
                 delta_bic=cand.delta_bic, effective_bins=cand.n_eff,
                 noise_share_of_gain=cand.null_share, indistinguishable_from=tuple(alike),
                 rmse_interval_rad_s=_interval(cv, ev.sse_fold),
                 gain_interval=_interval(cv, ev.sse_fold, sse_base),
                 mechanisms=tuple(mechanisms), competitors=tuple(eff.competitors),
                 part_sf_temp_coeff_per_k=own, interval_excludes_zero=bool(clear),
                 joint_p_value=joint)


def _finding(cand, rmse_base, rmse_null, cv):
    """One candidate of the first step (the ``findings`` table)."""
    ev = cand.evaluated
    return Finding(effect=cand.effect.effect_id, cause=cand.effect.cause,
                   kind=cand.effect.kind,
                   parameters=_parameters(cand, cv.ctx, cv.prep.binned)[0],
                   rmse_rad_s=ev.rmse, gain=1.0 - ev.rmse / rmse_base,
                   gain_over_recalibrated=1.0 - ev.rmse / rmse_null,
                   gain_binned=cand.gain_binned, p_value=cand.p_value,
                   evidence=_evidence(cand), delta_bic=cand.delta_bic,
                   n_params=2 + cand.effect.n_params, significant=cand.significant,
                   in_sample_only=cand.in_sample_only)


def _record(data, cv):
    prep = cv.prep
    return RecordSummary(
        source=data.source, rows=data.rows, duration_s=prep.duration_s,
        time_span_s=(float(data.time_s[0]), float(data.time_s[-1])),
        sample_interval_s=prep.dt_s, bins=cv.n_rows, bin_s=prep.bin_s,
        temp_range_c=((float(data.temp_c.min()), float(data.temp_c.max()))
                      if data.has_temp else None),
        has_temp=data.has_temp,
        rate_rms_rad_s=math.sqrt(float(np.mean(data.rate_cmd_rad_s ** 2))),
        has_accel=data.has_accel, recovery=tuple(data.recovery))


def _set_aside(screen, rms_all, best_gain):
    return SetAside(count=screen['count'], fraction=screen['fraction'],
                    segments=tuple(screen['segments'][:50]),
                    segments_total=len(screen['segments']),
                    threshold_sigma=screen['threshold'], sigma_rad_s=screen['sigma_rad_s'],
                    baseline_rmse_all_samples_rad_s=rms_all['baseline'],
                    best_gain_all_samples=best_gain)


def _steps(steps):
    return tuple(Step(added=None if chosen is None else chosen.effect.effect_id,
                      candidates=tuple(Candidate(
                          effect=c.effect.effect_id, rmse_rad_s=c.evaluated.rmse,
                          gain_step=c.gain_step, gain_binned=c.gain_binned, p_value=c.p_value,
                          route=c.route, p_state_space=c.p_statespace, delta_bic=c.delta_bic,
                          significant=c.significant, in_sample_only=c.in_sample_only)
                          for c in cands))
                 for cands, chosen in steps)


def _baseline(cv, rmse_base, sse_base, null, preset, config, axis):
    if config is None:
        model = (f'paper first-order physics (preset {preset!r}), one bias and one scale '
                 'factor calibrated at the reference temperature')
    else:
        model = (f'the deterministic output of sensor config {str(config)!r} (axis {axis}, '
                 'noise off), one bias and one scale factor calibrated at the reference '
                 'temperature')
    return Baseline(rmse_rad_s=rmse_base, rmse_interval_rad_s=_interval(cv, sse_base),
                    model=model, recalibrated_rmse_rad_s=null.rmse)


def _decide(selected, res, steps, confound, cv, null, in_sample):
    """
    Return (verdict, suggestive candidate or None, confounded pair or None).

    The residual's verdict (:func:`.verdict.verdict`); ``explained`` only
    when every chosen cause's 95 % interval excludes zero (and it gained on
    held-out data, which choosing it required), else ``partly_explained``;
    a candidate of the step that added nothing with a large gain it could
    not establish, or one the tests support only in-sample (``in_sample``),
    makes it ``partly_explained`` or ``unexplained``; a bias that follows
    temperature or time far beyond noise where the record cannot say which
    makes it ``partly_explained``, never ``no_mismatch``.
    """
    result = vd.verdict(selected, res['consistent'])
    if result == 'explained' and not all(
            e.interval_excludes_zero and (e.gain_step > 0.0 or e.gain_binned > 0.0)
            for e in selected):
        result = 'partly_explained'
    hint = None
    if steps and steps[-1][1] is None:
        hint = vd.suggestive([(c.effect.effect_id, c.gain_step, c.p_value)
                              for c in steps[-1][0]], confound)
        if hint is not None:
            result = 'partly_explained' if selected else 'unexplained'
    if in_sample and not selected:
        result = 'unexplained'
    pair = vd.confounded_pair(cv.prep, _null_resid_bins(cv, null), confound, selected, res)
    if pair is not None:
        result = 'partly_explained'
    return result, hint, pair


def _message(result, selected, res, coverage, pair, hint, steps, alpha, extra):
    """
    Return the verdict's message, whole: the residual, the pair, the hint and ``extra``.

    ``extra``: (what the data rule out, the causes supported in-sample only,
    the part's own SF tempco), as text.
    """
    bounds, in_sample, compensation = extra
    text = vd.message(result, selected, res, coverage,
                      suggestive=hint is not None or bool(in_sample), ruled_out=bounds)
    for e in selected:
        if not e.interval_excludes_zero:
            text += (f" {e.effect}'s 95 % interval includes zero: it gains on held-out data "
                     'but its size is not established')
            if e.joint_p_value is not None:
                text += (f' (its coefficients together: p = {e.joint_p_value:.2g} over the '
                         "folds, Hotelling's T^2)")
            text += '.'
    if pair is not None:
        text += (f" The record cannot separate the two: {pair['text']}. To tell "
                 f"them apart, {pair['experiment']}.")
    if hint is not None:
        effect, gain, p = hint
        n = len(steps[-1][0])
        text += (
            f' {effect} removes {100 * gain:.0f} % of the held-out error (p = {p:.2g} before '
            f'the correction for the {n} candidates; the bar is {alpha / n:.2g}): suggestive, '
            'not established. The wander measured from a residual that still holds such an '
            'effect is inflated by it, and with it the bar: a longer run, or more '
            'temperature cycles, would settle it.')
    for e in in_sample:
        text += (f' {e.effect} is supported in-sample (p = {e.p_value:.2g}), not confirmed on '
                 f'held-out data: {e.reason}.')
    return text + compensation


def _in_sample(steps):
    """Return the last step's candidates supported only in-sample (:class:`InSampleOnly`)."""
    if not steps:
        return ()
    cands, chosen = steps[-1]
    return tuple(InSampleOnly(effect=c.effect.effect_id, p_value=c.p_value,
                              gain_step=c.gain_step, gain_binned=c.gain_binned,
                              reason=c.in_sample_only)
                 for c in cands if c.in_sample_only and c is not chosen)


def _ruled_out(steps, cv, data):
    """
    Return the 95 % upper bounds of the causes tested and not chosen (:class:`Bound`).

    Each from its fit in the last step, beside the final model (:mod:`.ruled_out`).
    """
    if not steps:
        return ()
    chosen = {c.effect.effect_id for _, c in steps if c is not None}
    info = {'max_rate_rad_s': float(np.max(np.abs(data.rate_cmd_rad_s))),
            'nonlinearity_measured': ruled_out.nonlinearity_measured(data.rate_cmd_rad_s)}
    out = []
    for cand in steps[-1][0]:
        if cand.effect.effect_id in chosen or cand.effect.effect_id not in ruled_out.BOUNDS:
            continue
        found = ruled_out.estimates_of(cand, cv.ctx, cv.prep.binned)
        out += [Bound(effect=cand.effect.effect_id, quantity=q, upper=v, unit=u)
                for q, v, u in ruled_out.bounds_of(cand.effect.effect_id, found, info)]
    return tuple(out)


def _residual(res, result, message, tested, hint):
    """Return the typed residual of :func:`.verdict.residual_floor` with the final message."""
    n = res['noise']
    noise = noise_model.NoiseModel(n['white_sigma_rad_s'], n['arw_rad_s_sqrt_hz'],
                                   n['bias_instability_rad_s'], n['rrw_rad_s_sqrt_s'],
                                   n['allan_tau_max_s'])
    return Residual(
        rms_rad_s=res['rms_rad_s'], floor_rad_s=res['floor_rad_s'], excess=res['excess'],
        excess_limit=res['excess_limit'], averaging_s=res['averaging_s'],
        excess_slow=res['excess_slow'], excess_slow_limit=res['excess_slow_limit'],
        follows=Follows(**res['follows']), consistent=res['consistent'],
        wander_measured_to_s=res['wander_measured_to_s'], noise=noise,
        r2=frozen_mapping(res['r2']), strongest_correlate=res['strongest_correlate'],
        structure_remains=result in ('partly_explained', 'unexplained'),
        excess_over_noise=res['excess'], noise_rad_s=n['white_sigma_rad_s'], message=message,
        causes_tested=tuple(tested),
        suggestive=None if hint is None else Suggestive(*hint))


def build(*, data, cv, screen, rmse_base, sse_base, null, rms_all, steps, res, confound,
          not_tested, poly, preset, config, axis, alpha, plots=None, reference=None):
    """
    Return the :class:`Diagnosis` (see the module docstring).

    What the pipeline measured: the record ``data``, the folds ``cv``, the
    ``screen``-ing result, the baseline's held-out RMSE and fold SSEs
    (``rmse_base``, ``sse_base``), the recalibrated baseline ``null``, the
    RMS over every sample ``rms_all``, the selection ``steps``, the residual
    against its floor ``res`` (:func:`.verdict.residual_floor` with ``r2``
    and ``strongest_correlate``), the ``confound``-ed regressors, the causes
    ``not_tested`` and the temperature polynomial ``poly``; how it ran:
    ``preset``, ``config``, ``axis``, ``alpha``, the ``reference`` noise
    (:class:`.reference.ReferenceNoise` or None); ``plots`` for the report.
    """
    phys = cv.ctx.phys if config is None else None
    chosen, models_before, current = [], [], null
    for _, cand in steps:
        if cand is not None:
            chosen.append(cand)
            models_before.append(current)
            current = cand.evaluated
    selected = tuple(_cause(cand, before, rmse_base, cv, sse_base, twins, phys)
                     for cand, before, twins in zip(chosen, models_before,
                                                    vd.confounded_twins(steps, confound)))
    in_sample = _in_sample(steps)
    bounds = _ruled_out(steps, cv, data)
    result, hint, pair = _decide(selected, res, steps, confound, cv, null, in_sample)
    tested = [cand.effect.effect_id for cand in steps[0][0]] if steps else []
    coverage = vd.coverage_text(tested, len(tested) + len(not_tested))
    trim = ''.join(_compensation_text(e, phys) for e in selected)
    message = _message(result, selected, res, coverage, pair, hint, steps, alpha,
                       (ruled_out.text(bounds), in_sample, trim))
    best_gain = None
    if chosen and rms_all['best'] is not None:
        best_gain = 1.0 - rms_all['best'] / rms_all['baseline']
    remains = result in ('partly_explained', 'unexplained')
    return Diagnosis(
        record=_record(data, cv), device_preset=preset,
        calibration=base.calibrate(cv.prep.binned, cv.ctx.phys),
        baseline=_baseline(cv, rmse_base, sse_base, null, preset, config, axis),
        set_aside=_set_aside(screen, rms_all, best_gain), selected=selected,
        verdict=result, residual=_residual(res, result, message, tested, hint),
        confounded=tuple(Confound(**x) for x in confound),
        confounded_pair=None if pair is None else ConfoundedPair(**pair),
        experiments=tuple(vd.experiments(selected, confound, remains, vd.follows(res))),
        findings=tuple(_finding(cand, rmse_base, null.rmse, cv) for cand in steps[0][0])
        if steps else (),
        steps=_steps(steps), not_tested=tuple(NotTested(**x) for x in not_tested),
        method=_method(cv, alpha), temperature_polynomial=TemperaturePolynomial(**poly),
        config=None if config is None else str(config), plots=plots,
        supported_in_sample=in_sample, ruled_out=bounds, reference=reference)


def _null_resid_bins(cv, null):
    """Return the recalibrated baseline's residual on the bins (its fit on every bin)."""
    b = cv.prep.binned
    return b.gyro - models.predict(null.model, cv.ctx, b, null.full)


def _method(cv, alpha):
    return Method(
        folds=len(cv.used_folds), sub_blocks=len(cv.used_folds), alpha=alpha,
        alpha_tie=selection.ALPHA_TIE, min_gain=selection.MIN_GAIN,
        min_gain_rate=selection.MIN_GAIN_RATE, delta_bic_max=selection.DELTA_BIC_MAX,
        outlier_threshold_sigma=screening.THRESHOLD, null_simulations=noise_model.N_SIM,
        rmse='held-out, every kept sample, rad/s',
        test='fold test of the held-out SSE reduction less the reduction the '
             "record's own noise gives, Nadeau-Bengio corrected; for causes with "
             'fixed columns also the likelihood ratio of a local level (white '
             'noise plus a random walk capped by the Allan deviation at short '
             'averaging times) with and without the cause on the group means, '
             'Bartlett-corrected by a parametric bootstrap (with --reference: the '
             "reference's noise held fixed, chi^2); p = min(p_LR / 0.9, p_fold / 0.1); "
             'a cause is chosen only when it also gains on held-out data and its size '
             'stands 2 sigma clear of zero; '
             'Bonferroni over the candidates of each step',
        information_criterion='BIC on the effective number of independent bins',
        uncertainty='1 sigma and 95 % intervals: coefficients by the larger of the '
                    'delete-a-block jackknife over the folds and the sandwich under the '
                    "record's noise law (white noise and a random walk), t; a step's size "
                    'over every admissible step time; searched parameters (step times, '
                    'delays, time constants, widths) by the profile likelihood',
        blocks='the paired test counts folds (sub_blocks = folds)')
