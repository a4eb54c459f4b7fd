"""
``diagnose``: a measured record against the paper's physics, end to end.

1. Outliers are set aside (:mod:`.screening`).
2. The record is binned and cut into contiguous folds (:mod:`.data`,
   :mod:`.cv`); the user-calibrated baseline (:mod:`.baseline`) is scored
   on held-out data.
3. Causes are added by forward selection while one gives a significant
   held-out gain (:mod:`.selection`).
4. What remains is compared with the record's own noise floor and the
   verdict is decided (:mod:`.verdict`); :mod:`.document` makes the typed
   :class:`.diagnosis.Diagnosis`, once.
"""

from dataclasses import replace
import math

from gyro_emulator.analysis.diagnose import baseline as base
from gyro_emulator.analysis.diagnose import cv as cvmod
from gyro_emulator.analysis.diagnose import (document, emulated, generic, models, screening,
                                             selection)
from gyro_emulator.analysis.diagnose import verdict as vd
from gyro_emulator.analysis.diagnose.cv import CrossValidation
from gyro_emulator.analysis.diagnose.data import DEFAULT_MAX_BINS, measured, Prepared
from gyro_emulator.analysis.diagnose.diagnosis import ResidualPlots
from gyro_emulator.analysis.diagnose.effects import Context
from gyro_emulator.analysis.diagnose.noise_model import SuperBins
from gyro_emulator.analysis.diagnose.reference import check_independent, reference_noise
from gyro_emulator.physics.presets import physics_preset
from gyro_emulator.units import AXES
from gyro_emulator.validation import check_range
import numpy as np

DEFAULT_FOLDS = 8


def _physics(data, device, ref_temp_c):
    """Return the baseline's DevicePhysics of ``device`` for the record."""
    tref = device.calibration_temp_c if ref_temp_c is None else float(ref_temp_c)
    temps = data.temp_c if data.has_temp else np.array([tref])
    return base.DevicePhysics(device, tref, float(temps.min()), float(temps.max()))


def prior_noise_variance(prep, ctx):
    """
    Return the noise variance that weighs the causes' ridge, (rad/s)^2 per sample.

    The recalibrated baseline's weighted residual on the bins, SSE / n_eff
    (:func:`.cv.effective_bins`): the per-sample variance for white noise,
    inflated by (1 + rho) / (1 - rho) for the bins' correlation. A column
    the training rows barely show is then held by its physical range
    against the wander that can fake it, not against white noise alone
    (a dT/dt column at the start of a one-way ramp, unseen in the other
    folds: 94 rad/s per K/s against white noise, 0 against the wander).
    """
    b = prep.binned
    fit = models.fit_model(models.Model(()), ctx, b)
    resid = b.gyro - models.predict(models.Model(()), ctx, b, fit)
    return fit.sse / cvmod.effective_bins(resid, b.weight)


def _setup(data, phys, folds, max_bins, outlier_threshold):
    """Screen, bin and cut the folds; return (cv, screening result)."""
    check_range('diagnose', 'folds', folds, 3, 50, '', low_open=False)
    tref = phys.ref_temp_c
    screen = screening.screen(data, phys.ratio, outlier_threshold)
    prep = Prepared(data, max_bins=max_bins, keep=screen['keep'], fill_temp_c=tref)
    ctx = Context(phys=phys, ref_temp_c=tref,
                  time_span_s=(float(data.time_s[0]), float(data.time_s[-1])),
                  duration_s=prep.duration_s)
    ctx = replace(ctx, noise_var_rad2_s2=prior_noise_variance(prep, ctx))
    return CrossValidation(prep, ctx, int(folds)), screen


def _baseline_rmse(cv):
    """Held-out RMSE of the user-calibrated baseline, recalibrated on each fold's training rows."""
    prep, phys = cv.prep, cv.ctx.phys
    cals = {k: base.calibrate(prep.binned, phys, rows=cv.fold_of_bin != k)
            for k in cv.used_folds}
    _, sse = cv.held_out(lambda k: base.baseline_prediction(prep.samples, phys, cals[k]))
    return math.sqrt(float(np.sum(sse)) / len(cv.y)), cals, sse


def _all_samples_rms(cv, kept_rmse, predict_at):
    """RMS over every sample, set-aside ones included, of a held-out prediction."""
    prep = cv.prep
    dropped = np.flatnonzero(~prep.keep)
    sse = kept_rmse ** 2 * len(cv.y)
    if len(dropped):
        frame = prep.sample_frame(dropped)
        fold = cv.fold_of_bin[frame.bin_index]
        for k in cv.used_folds:
            m = fold == k
            if np.any(m):
                sse += float(np.sum((frame.gyro[m] - predict_at(k, frame)[m]) ** 2))
    return math.sqrt(sse / prep.data.rows)


def _polynomial_order(prep, have):
    """Return the order of the temperature polynomials the record carries, with its reason."""
    if 'temp' not in have:
        return {'order': None, 'span_k': None, 'note': None}
    temps = prep.binned.temp_c
    span = float(temps.max() - temps.min())
    order, note = generic.polynomial_order(span, temps)
    return {'order': order, 'span_k': span, 'note': note}


def _testable(catalogue, have, data):
    """Split the catalogue into the causes the record can show and the others (with reasons)."""
    testable, not_tested = [], []
    for eff in catalogue:
        missing = [need for need in eff.needs if need not in have]
        if missing:
            not_tested.append({'effect': eff.effect_id,
                               'reason': selection.not_testable_reason(missing[0], data)})
        else:
            testable.append(eff)
    return testable, not_tested


#: A reference shorter than this share of the record does not measure its slow noise.
MIN_REFERENCE_SHARE = 0.99


def _reference(reference, axis, duration_s):
    """
    Return the noise of the reference record, checked to be long enough.

    Its slow noise (flicker, walk) is held fixed in the null at the scales of
    the diagnosed record: a shorter reference has not measured them there
    (its fit gives zero for what it cannot see), so it is a one-line error.
    """
    ref = reference_noise(measured(reference, axis, True))
    if ref.duration_s < MIN_REFERENCE_SHARE * duration_s:
        raise ValueError(f'diagnose: reference {ref.source!r} lasts {ref.duration_s:.6g} s'
                         f'{"" if ref.gap_free else " (its logging gaps left out)"}, '
                         f'shorter than the record ({duration_s:.6g} s): allowed: a static '
                         'record of the part at least as long as the diagnosed one, so that '
                         'its slow noise is measured at the scales of the record')
    return ref


def diagnose(data, preset='paper', ref_temp_c=None, folds=DEFAULT_FOLDS,
             max_bins=DEFAULT_MAX_BINS, effects=None, alpha=selection.ALPHA,
             outlier_threshold=screening.THRESHOLD, max_causes=selection.MAX_CAUSES, seed=0,
             config=None, axis='z', reference=None):
    """
    Diagnose a measured record against the paper's physics.

    Parameters
    ----------
    data : gyro_emulator.analysis.diagnose.data.MeasuredData or Record
        The record (a :class:`gyro_emulator.recording.record.Record` is
        taken through :func:`~gyro_emulator.analysis.diagnose.data.measured`).
    preset : str
        Physics preset of the baseline device (``presets.physics_preset``).
    ref_temp_c : float, optional
        Calibration (reference) temperature, deg C; default the device's.
    folds : int
        Contiguous cross-validation blocks, [3, 50].
    max_bins : int
        Largest number of bins the fits run on.
    effects : sequence of str, optional
        Catalogue entries to test (default: all).
    alpha : float
        Family-wise false-alarm level of each selection step, (0, 1).
    outlier_threshold : float
        Robust standard deviations beyond which samples are set aside
        (``math.inf``: none).
    max_causes : int
        Most causes forward selection adds.
    seed : int
        Seed of the noise simulations (the result is deterministic).
    config : str, optional
        A sensor configuration (preset name or YAML file) whose deterministic
        output is the baseline (:mod:`.emulated`); ``preset`` is then unused.
    axis : str
        The configuration's axis the record measures ('x', 'y' or 'z').
    reference : MeasuredData or Record, optional
        A second, static record of the same part (the same axis): its noise
        (white, flicker, walk) is held fixed in every null
        (:mod:`.reference`).

    Returns
    -------
    gyro_emulator.analysis.diagnose.diagnosis.Diagnosis

    """
    check_range('diagnose', 'alpha', alpha, 0.0, 1.0, '', high_open=True)
    catalogue = generic.CATALOGUE if effects is None else tuple(
        generic.effect(e) for e in effects)
    data = measured(data)
    if reference is not None:
        reference = measured(reference, axis, True)
        check_independent(data, reference)
    if np.ptp(data.gyro_rad_s) == 0.0:
        raise ValueError(
            f'diagnose: gyro_rad_s = {float(data.gyro_rad_s[0])!r} in all {data.rows} samples: '
            'a stuck or unconnected output has no noise to diagnose against; allowed: an '
            'output that varies')
    if config is None:
        phys = _physics(data, physics_preset(preset), ref_temp_c)
    else:
        sensor = emulated.load(config)
        phys = _physics(data, sensor.device[AXES.index(axis)], ref_temp_c)
        data = emulated.transform(data, sensor, axis, phys.ratio)
    cv, screen = _setup(data, phys, folds, max_bins, outlier_threshold)
    prep, ctx = cv.prep, cv.ctx
    rmse_base, cals, sse_base = _baseline_rmse(cv)
    null = cv.evaluate(models.Model(()))
    have = selection.excitation(prep, data)
    poly = _polynomial_order(prep, have)
    catalogue = generic.with_polynomial_order(catalogue, poly['order'])
    testable, not_tested = _testable(catalogue, have, data)
    superbins = SuperBins(prep.binned, cv.fold_of_bin, prep.dt_s)
    ref = None if reference is None else _reference(reference, axis, prep.duration_s)
    selector = selection.Selector(cv, superbins, alpha, seed, ref)
    steps, final = selection.forward_selection(selector, null, testable, max_causes)
    chosen = [c for _, c in steps if c is not None]
    res = vd.residual_floor(selector, final, have)
    res['r2'], res['strongest_correlate'] = vd.correlates(prep, final.resid, have)
    confound = vd.confounded(prep, have)
    rms_all = {
        'baseline': _all_samples_rms(cv, rmse_base, lambda k, f: base.baseline_prediction(
            f, ctx.phys, cals[k])),
        'best': None if not chosen else _all_samples_rms(
            cv, chosen[0].evaluated.rmse, lambda k, f: chosen[0].evaluated.predict(ctx, f, k))}
    b = prep.binned
    cal_all = base.calibrate(b, ctx.phys)
    plots = ResidualPlots(
        prepared=prep, before=b.gyro - base.baseline_prediction(b, ctx.phys, cal_all),
        after=b.gyro - models.predict(final.model, ctx, b, final.full),
        after_label=' + '.join(final.model.ids) or 'recalibrated baseline (no cause found)')
    return document.build(data=data, cv=cv, screen=screen, rmse_base=rmse_base,
                          sse_base=sse_base, null=null, rms_all=rms_all, steps=steps, res=res,
                          confound=confound, not_tested=not_tested, poly=poly, preset=preset,
                          config=config, axis=axis, alpha=alpha, plots=plots, reference=ref)
