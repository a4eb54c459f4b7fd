"""
Every fit held to what the noise can do (issue 33 item 2), on seeded records where fits blew up.

The rule: a candidate's held-out RMSE is within the upper end of the 95 %
jackknife interval of the held-out RMSE of the model it extends
(``CrossValidation.interval``: how far the record's own blocks move that
RMSE). Before the fixes, on these records, the Sutherland law predicted
202x worse than the recalibrated baseline on a part with constant
viscosity, a warm-up extrapolated from its tail 8.3x worse, and a thermal
lag forced to at least 5 s 1.032x (its bound 1.031x); shapes in time
carried into the end folds past a temperature-driven bias or scale factor
1.49-1.95x (bounds 1.13-1.44x).
"""

from dataclasses import replace

from gyro_emulator.analysis.diagnose import cv as cv_mod
from gyro_emulator.analysis.diagnose import (generic, intervals, models, noise_model, pipeline,
                                             screening, searched, selection)
from gyro_emulator.analysis.diagnose.data import DEFAULT_MAX_BINS, measured
from gyro_emulator.emulation.truth.generator import make_truth
from gyro_emulator.physics.presets import physics_preset
import numpy as np
import pytest


def _cv(record):
    data = measured(record)
    phys = pipeline._physics(data, physics_preset('paper'), None)
    cv, _ = pipeline._setup(data, phys, pipeline.DEFAULT_FOLDS, DEFAULT_MAX_BINS,
                            screening.THRESHOLD)
    return cv


def _ratio_and_bound(cv, effect_id):
    """Held-out RMSE of the cause over the recalibrated baseline's, and the rule's bound."""
    null = cv.evaluate(models.Model(()))
    ev = cv.evaluate(models.Model((generic.effect(effect_id),)), extends=null)
    return ev.rmse / null.rmse, cv.interval(null.sse_fold)[1] / null.rmse, ev


@pytest.mark.parametrize('truth, seed, effect_id', [
    ('none', 0, 'viscosity_temperature'),      # the law at share 1: 202x
    ('g_sensitivity', 1, 'bias_time'),         # a warm-up from its tail: 8.3x
    ('none', 0, 'thermal_lag'),                # a lag of at least 5 s: 1.032x
])
def test_a_cause_predicts_held_out_data_within_what_the_noise_can(truth, seed, effect_id):
    record, _ = make_truth(truth, seed)
    ratio, bound, _ = _ratio_and_bound(_cv(record), effect_id)
    assert 1.0 < bound < 1.1
    assert ratio <= bound, (ratio, bound)


def test_a_warm_up_seen_from_its_tail_is_held_to_e_times_what_the_rows_see():
    record, _ = make_truth('g_sensitivity', 1)
    cv = _cv(record)
    _, _, ev = _ratio_and_bound(cv, 'bias_time')
    b = cv.prep.binned
    effect = ev.model.effects[-1]
    unseen = models.unseen_s(effect, b, cv.fold_of_bin != 0)
    # the first fold's training rows start one fold in; the others' at the start
    assert unseen == pytest.approx(cv.prep.duration_s / 8, rel=0.01)
    assert all(models.unseen_s(effect, b, cv.fold_of_bin != k) == 0.0 for k in ev.fits if k)
    # its rows do not resolve the tail's time constant (its least SSE on the grid: 438 s) ...
    rows = cv.fold_of_bin != 0
    grid = effect.grids(cv.ctx)[0]
    fits = [models.fit_model(ev.model, cv.ctx, b, rows, fixed=((tau,),)) for tau in grid]
    least = fits[int(np.argmin([f.sse for f in fits]))]
    resid = b.gyro[rows] - models.predict(ev.model, cv.ctx, b, least)[rows]
    n_eff = models.effective_bins(resid, b.weight[rows])
    assert least.phis[-1][0] < unseen / 2.0
    assert not models.warm_up_resolved(grid, [f.sse for f in fits], n_eff, unseen)
    # ... so it is held: at most e times what they see at their first row
    assert ev.fits[0].phis[-1][0] >= unseen - 1e-9
    assert ev.full.phis[-1][0] < unseen              # the full fit is not held


def test_warm_up_resolved_by_the_spread_of_the_extrapolation_over_the_profile():
    values = np.array([100.0, 200.0, 400.0, 800.0])
    sses = np.array([[9.0, 5.0, 5.0], [8.0, 5.1, 5.0], [9.0, 5.1, 5.0], [9.0, 9.0, 5.0]])
    # profile limits 8 (1 + 3.84 / 100), 5 (1 + 3.84 / 100): intervals [200, 200],
    # [100, 400] and the whole grid (its top: not resolved)
    got = models.warm_up_resolved(values, sses, 100.0, 300.0)
    assert list(got) == [True, False, False]       # 300 (1/100 - 1/400) = 2.25 > 1
    assert list(models.warm_up_resolved(values, sses, 100.0, 100.0)) == [True, True, False]
    assert list(models.held_grid(values, 300.0)) == [300.0, 400.0, 800.0]


def test_the_sutherland_law_is_still_found_at_share_one():
    record, truth = make_truth('viscosity_temperature', 0)
    cv = _cv(record)
    ratio, bound, ev = _ratio_and_bound(cv, 'viscosity_temperature')
    assert ratio < 0.01                                  # the law explains the record
    found = ev.model.report(ev.full.beta, ev.full.phis)[-1]
    assert found['sutherland_constant_k'] == pytest.approx(
        truth['parameters']['sutherland_constant_k'], rel=0.02)
    assert found['sutherland_share'] == pytest.approx(1.0, abs=1e-3)
    # on a part with constant viscosity the share goes to zero instead
    none, _ = make_truth('none', 0)
    _, _, ev0 = _ratio_and_bound(_cv(none), 'viscosity_temperature')
    assert abs(ev0.model.report(ev0.full.beta, ev0.full.phis)[-1]['sutherland_share']) < 0.01


def test_a_cause_added_to_a_chosen_law_leaves_to_the_law_what_the_rows_cannot_part():
    # an SF polynomial beside the Sutherland law on a part that follows the law:
    # with the least ridge of a cause on the law's share too, every fold moved
    # the share to 0.91-0.98 and the polynomial took the rest, and the two
    # parted beyond the training temperatures: 1.21x the law's RMSE (bound 1.014x)
    record, _ = make_truth('viscosity_temperature', 7)
    cv = _cv(record)
    law = cv.evaluate(models.Model((generic.effect('viscosity_temperature'),)))
    both = models.Model(law.model.effects + (generic.effect('scale_factor_temperature'),))
    ev = cv.evaluate(both, {k: f.phis for k, f in law.fits.items()}, law.full.phis, law)
    bound = cv.interval(law.sse_fold)[1] / law.rmse
    assert ev.rmse / law.rmse <= bound, (ev.rmse / law.rmse, bound)
    for fit in list(ev.fits.values()) + [ev.full]:
        share = both.report(fit.beta, fit.phis)[0]['sutherland_share']
        assert share == pytest.approx(1.0, abs=0.01)
    penalty = both.penalty(cv.ctx)
    assert list(penalty[:3]) == [0.0, 0.0, models.HELD_BY_DATA] and np.all(penalty[3:] > 0.0)


def test_a_searched_parameter_at_the_end_of_its_range_gets_an_interval():
    # the Sutherland constant's range ends at 1000 K, where the gas model
    # refuses 1001 K: a derivative across that end stopped a held-out
    # round's diagnosis (mode_split_drift seed 4) with a range error
    record, _ = make_truth('viscosity_temperature', 0)
    cv = _cv(record)
    _, _, ev = _ratio_and_bound(cv, 'viscosity_temperature')
    effect = ev.model.effects[-1]
    last = float(np.max(effect.grids(cv.ctx)[0]))
    assert last == 1000.0
    ev.full = replace(ev.full, phis=((last,),))
    wander = selection.Selector(cv, noise_model.SuperBins(
        cv.prep.binned, cv.fold_of_bin, cv.prep.dt_s)).wander_of(ev)
    resid = cv.prep.binned.gyro - models.predict(ev.model, cv.ctx, cv.prep.binned, ev.full)
    n_eff = cv_mod.effective_bins(resid, cv.prep.binned.weight)
    found = intervals.estimates(effect, ev, cv.ctx, cv.prep.binned, n_eff, wander)
    low, high = found['sutherland_constant_k'].interval
    assert low < last and high == last            # open at the range's end, not past it
    sigma = searched.searched_sigma(ev, cv.ctx, cv.prep.binned, wander, (0.0, last))
    assert 0.0 < sigma < np.inf


def _origin_sses(cv, ev, k, model):
    """SSE of end fold ``k``'s origins, each predicted from the rows beyond it: (2, origins)."""
    origins = dict(cv_mod.end_folds(cv.used_folds))[k]
    s = cv.prep.samples
    sse = np.zeros((2, len(origins)))
    for depth, origin in enumerate(origins):
        rows = ~np.isin(cv.fold_of_bin, (k,) + origins[:depth + 1])
        near = cv.fold_of_sample == origin
        for j, m in enumerate((ev.model, model)):
            fit = models.fit_model(m, cv.ctx, cv.prep.binned, rows)
            sse[j, depth] = np.sum((s.gyro[near] - models.predict(m, cv.ctx, s, fit)[near]) ** 2)
    return sse


@pytest.mark.parametrize('truth, seed, effect_id', [
    ('temperature_rate_bias', 0, 'bias_time'),   # a warm-up from a dT/dt bias's tail: 1.95x
    ('bias_temperature', 0, 'bias_time'),        # a drift carried into both end folds: 1.57x
    ('thermal_lag', 2, 'scale_factor_time'),     # an SF polynomial in time likewise: 1.49x
    ('bias_temperature', 2, 'bias_time'),        # neighbour 18 % better, spread 1.26x: 1.62x
    ('thermal_lag', 1, 'scale_factor_time'),     # neighbour 13 % better, spread 1.27x: 1.39x
    # judged on the nearest origin alone (0.52x, the next 3.1x): 1.45x
    ('electronics_sf_tempco', 2, 'scale_factor_time'),
    ('bias_hysteresis', 1, 'bias_time'),         # nearest origin 0.77x, the next 3.1x: 1.20x
])
def test_a_shape_in_time_is_carried_into_an_end_fold_only_where_it_predicts(
        truth, seed, effect_id):
    record, _ = make_truth(truth, seed)
    cv = _cv(record)
    ratio, bound, ev = _ratio_and_bound(cv, effect_id)
    assert ratio <= bound, (ratio, bound)
    assert ev.kept_back and set(ev.kept_back) <= {cv.used_folds[0], cv.used_folds[-1]}
    null = cv.evaluate(models.Model(()))
    for k, (model, _) in ev.kept_back.items():
        assert model.effects == ()
        # the fold is predicted by the model without the shape, fitted on its training rows
        mask = cv.fold_of_sample == k
        assert np.allclose(ev.resid[mask], null.resid[mask], rtol=0.0, atol=1e-15)
        # decided on the training rows: at the two origins next to the end
        # fold, each fitted without the folds up to it, the shape predicted
        # them no better than the model without it by more than the spread
        # of the held-out RMSE of the model extended
        bound = cv_mod.fold_bound(null.sse_fold, cv.fold_samples(), cv.used_folds.index(k))
        assert not cv_mod.carries_on(*_origin_sses(cv, ev, k, model), bound)


def test_a_shape_in_time_that_predicts_is_carried_on():
    """A scale factor drifting in time with the cavity pressure: carried into both end folds."""
    record, _ = make_truth('pressure_drift', 0)
    cv = _cv(record)
    ratio, _, ev = _ratio_and_bound(cv, 'scale_factor_time')
    assert ratio < 0.5 and ev.kept_back == {}
    null = cv.evaluate(models.Model(()))
    for k, _ in cv_mod.end_folds(cv.used_folds):
        bound = cv_mod.fold_bound(null.sse_fold, cv.fold_samples(), cv.used_folds.index(k))
        assert cv_mod.carries_on(*_origin_sses(cv, ev, k, null.model), bound)


def test_end_folds_and_the_rule_that_carries_a_shape_on():
    assert cv_mod.end_folds(range(8)) == [(0, (1, 2)), (7, (6, 5))]
    assert cv_mod.end_folds([0, 1, 2, 3], origins=1) == [(0, (1,)), (3, (2,))]
    # an origin needs training rows beyond it: one of 3 folds
    assert cv_mod.end_folds([0, 1, 2]) == [(0, (1,)), (2, (1,))]
    assert cv_mod.end_folds([0, 1]) == []
    assert cv_mod.carries_on(1.0, 1.0) and not cv_mod.carries_on(1.0 + 1e-12, 1.0)
    # (origins, records): per record
    assert list(cv_mod.carries_on(np.array([[1.0, 3.0]]), np.array([[2.0, 2.0]]))) == \
        [True, False]
    # beyond a bound b the shape's RMSE must be at most 1/b of the other's
    assert cv_mod.carries_on(1.0, 1.22, 1.1) and not cv_mod.carries_on(1.0, 1.2, 1.1)
    assert list(cv_mod.carries_on(np.ones((1, 2)), np.full((1, 2), 1.3),
                                  np.array([1.1, 1.2]))) == [True, False]
    # on the nearest origin and on the origins together
    assert cv_mod.carries_on([1.0, 1.0], [2.0, 2.0])
    assert not cv_mod.carries_on([1.0, 4.0], [2.0, 2.0])      # together 5 > 4
    assert not cv_mod.carries_on([2.0, 0.5], [1.9, 2.0])      # nearest 2 > 1.9
    assert cv_mod.carries_on([1.0, 2.5], [2.0, 2.0])          # the next alone may miss


def test_the_carrying_bound_is_the_jackknife_interval_of_the_rule():
    """rmse_bound is CrossValidation.interval's upper end over the RMSE, per column too."""
    record, _ = make_truth('bias_temperature', 2)
    cv = _cv(record)
    null = cv.evaluate(models.Model(()))
    n = cv.fold_samples()
    bound = cv.interval(null.sse_fold)[1] / null.rmse
    assert cv_mod.rmse_bound(null.sse_fold, n) == pytest.approx(bound, rel=1e-12)
    assert bound > 1.1                          # the tempco left in: a wide spread
    both = cv_mod.rmse_bound(np.column_stack([null.sse_fold, 4.0 * null.sse_fold]), n)
    assert both == pytest.approx([bound, bound], rel=1e-12)
    assert cv_mod.rmse_bound(null.sse_fold[:2], n[:2]) == 1.0
    # an end fold's bound leaves that fold out; none without the model extended
    assert cv_mod.fold_bound(null.sse_fold, n, 0) == pytest.approx(
        cv_mod.rmse_bound(null.sse_fold[1:], n[1:]), rel=1e-12)
    assert cv_mod.fold_bound(None, n, 0) == 1.0


def test_the_simulations_carry_a_shape_in_time_on_as_the_fits_do():
    """Per end fold and simulation: the reduction carried on, or none (the current model's)."""
    rng = np.random.default_rng(4)
    fold_of_bin = np.repeat(np.arange(8), 40)
    t = np.arange(len(fold_of_bin), dtype=float)

    class _Bins:
        bin_start_s = t

    class _Binned:
        weight = np.ones(len(t))
        time_s = t
        bins = _Bins()

        def __len__(self):
            return len(t)

    sb = noise_model.SuperBins(_Binned(), fold_of_bin, 1.0, per_fold=10)
    current = np.ones((len(sb), 1))
    drift = ((sb.time_s - sb.time_s.mean()) / np.ptp(sb.time_s))[:, None]
    sims = rng.normal(size=(len(sb), 64)) + 1.0 * np.cumsum(rng.normal(size=(len(sb), 64)),
                                                            axis=0) / 10.0
    pen = (np.zeros(1), np.zeros(2))
    always = noise_model.null_gain(current, [drift], sb, sims, pen)
    shaped = noise_model.Searched(None, lambda v: drift, lambda train: 0.0, time_shaped=True)
    got = noise_model.null_gain(current, shaped, sb, sims, pen)
    assert np.array_equal(got[1:-1], always[1:-1])           # interior folds: unchanged
    folds = np.unique(sb.fold)
    w = sb.weight[:, None]

    def sse(cols, train, target):
        x = np.sqrt(w[train]) * cols[train]
        beta = np.linalg.lstsq(x, np.sqrt(w[train]) * sims[train], rcond=None)[0]
        return np.sum(w[target] * (sims[target] - cols[target] @ beta) ** 2, axis=0)

    both = np.column_stack([current, drift])
    sse_current = np.array([sse(current, sb.fold != k, sb.fold == k) for k in folds])
    for k, origins in cv_mod.end_folds(folds):
        carried = got[k] == always[k]
        assert np.all(carried | (got[k] == 0.0))
        assert 0 < np.sum(carried) < sims.shape[1]            # both happen on noise
        # each simulation decided by the rule of the fits, at both origins
        shape_sse, without_sse = [], []
        for depth, origin in enumerate(origins):
            train = ~np.isin(sb.fold, (k,) + origins[:depth + 1])
            shape_sse.append(sse(both, train, sb.fold == origin))
            without_sse.append(sse(current, train, sb.fold == origin))
        n_fold = [np.sum(sb.weight[sb.fold == j]) for j in folds]
        bound = cv_mod.fold_bound(sse_current, n_fold, list(folds).index(k))
        assert np.array_equal(carried, cv_mod.carries_on(np.array(shape_sse),
                                                         np.array(without_sse), bound))
    unshaped = noise_model.Searched(None, lambda v: drift, lambda train: 0.0)
    assert np.array_equal(noise_model.null_gain(current, unshaped, sb, sims, pen), always)


def test_a_cause_added_to_a_law_is_searched_with_the_ridge_of_its_final_fit():
    """
    A mode split added to the Sutherland law: each fold's search holds the share as the fit does.

    Searched with the record's noise, which counts the law as noise, the
    ridge shrank the share, and one fold chose a split of 5 Hz, 0.1 Hz/K
    to stand in for it; fitted with its share free, that fold was predicted
    1.21x worse than by the law alone (1.030x over the record, bound 1.011x).
    """
    record, _ = make_truth('viscosity_temperature', 0)
    cv = _cv(record)
    law = cv.evaluate(models.Model((generic.effect('viscosity_temperature'),)))
    model = law.model.extend(generic.effect('mode_split_drift'))
    ev = cv.evaluate(model, {k: f.phis for k, f in law.fits.items()}, law.full.phis, law)
    bound = cv.interval(law.sse_fold)[1] / law.rmse
    assert ev.rmse / law.rmse <= bound, (ev.rmse / law.rmse, bound)
    # no split drift in the record: every fold's slope stays within a grid
    # step of none (at no slope a split is a constant factor the scale factor takes)
    for k, fit in ev.fits.items():
        assert abs(fit.phis[-1][1]) < 0.1, (k, fit.phis[-1])
