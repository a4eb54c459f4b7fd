"""
Every fit held to what the noise can do (issue 33 item 2), on seeded records where fits blew up.

The rule: a candidate's held-out RMSE is within the upper end of the 95 %
jackknife interval of the held-out RMSE of the model it extends
(``CrossValidation.interval``: how far the record's own blocks move that
RMSE). Before the fixes, on these records, the Sutherland law predicted
202x worse than the recalibrated baseline on a part with constant
viscosity and a thermal lag forced to at least 5 s 1.032x (its bound
1.031x). A warm-up extrapolated from its tail (8.3x) is not yet held: see
docs/diagnose.md.
"""

from gyro_emulator.analysis.diagnose import generic, models, pipeline, screening
from gyro_emulator.analysis.diagnose.data import DEFAULT_MAX_BINS, measured
from gyro_emulator.emulation.truth.generator import make_truth
from gyro_emulator.physics.presets import physics_preset
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
    ev = cv.evaluate(models.Model((generic.effect(effect_id),)))
    return ev.rmse / null.rmse, cv.interval(null.sse_fold)[1] / null.rmse, ev


@pytest.mark.parametrize('truth, seed, effect_id', [
    ('none', 0, 'viscosity_temperature'),      # the law at share 1: 202x
    ('none', 0, 'thermal_lag'),                # a lag of at least 5 s: 1.032x
])
def test_a_cause_predicts_held_out_data_within_what_the_noise_can(truth, seed, effect_id):
    record, _ = make_truth(truth, seed)
    ratio, bound, _ = _ratio_and_bound(_cv(record), effect_id)
    assert 1.0 < bound < 1.1
    assert ratio <= bound, (ratio, bound)


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
