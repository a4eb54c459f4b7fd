"""
Issue 33: what a diagnosis may claim, held to held-out data, with an interval for every number.

The pieces, each checked against what it must do: the causes' ridge (a
direction the training rows do not determine goes to zero, not to a
cancelling pair), the profile-likelihood interval of a step time (never
+- 0, and it covers the truth at its stated rate over seeded records), the
2-sigma rule, the bounds of what the data rule out, the part's own SF
tempco against a named datasheet figure, the likelihood ratio with a
reference record's noise held fixed (chi^2 under the null), the effective
number of tests over a searched grid, and the real-noise injections'
profile as a kind of the one profile protocol.
"""

import math

from gyro_emulator.analysis.diagnose import cv as cvmod
from gyro_emulator.analysis.diagnose import (diagnose, document, generic, intervals, models,
                                             reference, ruled_out, selection, statespace,
                                             to_json)
from gyro_emulator.analysis.diagnose.baseline import DevicePhysics
from gyro_emulator.analysis.diagnose.data import MeasuredData, Prepared
from gyro_emulator.analysis.diagnose.diagnosis import Parameter
from gyro_emulator.analysis.diagnose.effects import Context
from gyro_emulator.emulation import profiles
from gyro_emulator.emulation.truth import injection as inj
from gyro_emulator.emulation.truth.generator import make_truth
from gyro_emulator.physics.presets import physics_preset
import numpy as np
import pytest
from scipy import stats


def _context(prep, noise_var=0.0):
    return Context(phys=DevicePhysics(physics_preset('paper'), 25.0, 25.0, 25.0),
                   ref_temp_c=25.0, time_span_s=(float(prep.data.time_s[0]),
                                                 float(prep.data.time_s[-1])),
                   duration_s=prep.duration_s, noise_var_rad2_s2=noise_var)


def test_the_ridge_sends_an_undetermined_step_to_zero():
    # every training row is past the step: its column equals the rate column
    rng = np.random.default_rng(0)
    n = 400
    rate = np.sin(np.arange(n) / 7.0)
    x = np.column_stack([np.ones(n), rate, rate])
    y = 0.01 + 1.002 * rate + 1e-3 * rng.standard_normal(n)
    w = np.ones(n)
    split, _ = models.wls(list(x.T), y, w)
    held, _ = models.wls(list(x.T), y, w, penalty=[0.0, 0.0, 1e-6 / 0.2 ** 2])
    # without the ridge the pair is shared out; with it the step gets nothing
    assert abs(split[2]) > 0.4
    assert abs(held[2]) < 1e-5 and held[1] == pytest.approx(1.002, abs=1e-3)
    # a held-out row before the step (its column 0) is predicted as the baseline
    before = np.array([1.0, 0.5, 0.0])
    assert abs(before @ held - (0.01 + 0.501)) < 1e-3
    assert abs(before @ split - (0.01 + 0.501)) > 0.2


def test_every_cause_column_has_a_physical_range():
    for eff in generic.CATALOGUE:
        scales = eff.column_scales()
        assert len(scales) == eff.n_columns
        assert all(0.0 < s < math.inf for s in scales), eff.effect_id


def _step_record(seed, t0=377.3, n=600, size=0.004):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 1.0
    gyro = 0.002 * rng.standard_normal(n) + np.where(t >= t0, size, 0.0)
    return MeasuredData(time_s=t, rate_cmd_rad_s=np.zeros(n), temp_c=np.full(n, 25.0),
                        gyro_rad_s=gyro)


def _step_interval(record):
    prep = Prepared(record, max_bins=len(record.time_s))
    ctx = _context(prep, 4e-6)
    cv = cvmod.CrossValidation(prep, ctx, 8)
    ev = cv.evaluate(models.Model((generic.effect('bias_step'),)))
    resid = prep.binned.gyro - models.predict(ev.model, ctx, prep.binned, ev.full)
    n_eff = cvmod.effective_bins(resid, prep.binned.weight)
    return intervals.estimates(generic.effect('bias_step'), ev, ctx, prep.binned, n_eff)


def test_a_step_time_has_a_profile_interval_never_zero_and_it_covers_the_truth():
    found = _step_interval(_step_record(3))
    step = found['step_time_s']
    assert step.method == 'profile likelihood'
    lo, hi = step.interval
    assert hi - lo >= 1.0 and step.sigma > 0.0            # at least a bin: never +- 0
    assert lo <= 377.3 <= hi and lo <= step.value <= hi
    assert found['bias_step_rad_s'].method.startswith('jackknife')
    # coverage over seeded records: the 95 % interval holds the true time
    n = 60
    covered = sum(lo <= 377.3 <= hi for lo, hi in (
        _step_interval(_step_record(100 + s, size=0.0015))['step_time_s'].interval
        for s in range(n)))
    assert stats.binom.cdf(covered, n, 0.95) > 0.01, covered


def test_a_coefficient_the_record_does_not_vary_is_not_measured_and_not_plus_minus_zero():
    n = 2000
    rng = np.random.default_rng(5)
    t = np.arange(n) * 1.0
    accel = np.column_stack([9.8 * np.sin(t / 300.0), np.zeros(n), 9.8 * np.cos(t / 300.0)])
    gyro = 1e-3 * rng.standard_normal(n) + 2e-4 * accel[:, 0]
    record = MeasuredData(time_s=t, rate_cmd_rad_s=np.zeros(n), temp_c=None, gyro_rad_s=gyro,
                          accel_m_s2=accel)
    doc = to_json(diagnose(record))
    entry = doc['selected'][0]
    assert entry['effect'] == 'g_sensitivity'
    y = entry['parameters']['g_sensitivity_y_rad_s_per_m_s2']
    assert y['interval'] is None and y['method'].startswith('not measured')
    x = entry['parameters']['g_sensitivity_x_rad_s_per_m_s2']
    assert x['interval'][0] < 2e-4 < x['interval'][1] and x['interval'][0] > 0.0
    assert entry['interval_excludes_zero'] and doc['verdict'] == 'explained'


def _found(**given):
    return {k: intervals.Estimate(v, s, (v - 2.4 * s, v + 2.4 * s), 'jackknife')
            for k, (v, s) in given.items()}


def test_the_size_rule_needs_one_component_beyond_two_sigma():
    g = generic.effect('g_sensitivity')
    names = [p.name for p in g.params]
    within = _found(**{names[0]: (1.5e-5, 1.0e-5), names[1]: (-1.0e-5, 0.7e-5),
                       names[2]: (1.6e-5, 1.1e-5)})
    assert not intervals.clear_of_zero(g, within, None, 1.0, 0.9, 100.0, 2.0)
    beyond = dict(within, **_found(**{names[2]: (3.0e-5, 1.1e-5)}))
    assert intervals.clear_of_zero(g, beyond, None, 1.0, 0.9, 100.0, 2.0)
    # the 95 % interval (t_7: 2.36 sigma) is the stricter rule that explained needs
    assert not intervals.interval_clear_of_zero(
        g, dict(within, **_found(**{names[2]: (2.2e-5, 1.0e-5)})), None, 1.0, 0.9, 100.0)


def _polynomial_folds(rng, slope, folds=8, n=400):
    """Fit [1, dT, dT^2] through two cycles; return (theta, the delete-a-fold thetas)."""
    d_t = 40.0 * np.sin(2.0 * np.pi * 2.0 * np.linspace(0.0, 1.0, n)) ** 2 - 10.0
    x = np.column_stack([np.ones(n), d_t, d_t ** 2])
    y = slope * d_t + rng.standard_normal(n)
    keep = [np.setdiff1d(np.arange(n), f) for f in np.array_split(np.arange(n), folds)]
    per_fold = np.array([np.linalg.lstsq(x[k], y[k], rcond=None)[0][1:] for k in keep])
    return np.linalg.lstsq(x, y, rcond=None)[0][1:], per_fold


def test_the_joint_size_rule_holds_its_level_and_sees_a_correlated_pair():
    # dT and dT^2 through cycles from 15 to 55 C about T_ref 25 C: r = 0.89.
    # Hotelling's T^2 on the folds' jackknife covariance at the level of one
    # coefficient at 2 sigma on 8 folds, 2 P(t_7 > 2) = 0.086: with no effect
    # it rejects at that level (2000 draws: binomial sd 0.0063, 4 sd allowed),
    # and on a linear tempco it finds what neither coefficient alone shows.
    rng = np.random.default_rng(20261129)
    level = 2.0 * stats.t.sf(2.0, 7)
    null = [intervals.hotelling_p(*_polynomial_folds(rng, 0.0)) < level for _ in range(2000)]
    assert abs(np.mean(null) - level) < 4.0 * math.sqrt(level * (1.0 - level) / 2000)
    # paired over 400 draws (McNemar): the draws only the joint rule finds
    # outnumber those only one coefficient finds by 4 sd of their difference
    only_joint = only_alone = 0
    for _ in range(400):
        theta, per_fold = _polynomial_folds(rng, 0.01)
        sigma = np.sqrt(7.0 / 8.0 * np.sum((per_fold - per_fold.mean(axis=0)) ** 2, axis=0))
        joint = intervals.hotelling_p(theta, per_fold) < level
        alone = bool(np.any(np.abs(theta) > 2.0 * sigma))
        only_joint += joint and not alone
        only_alone += alone and not joint
    assert only_joint - only_alone > 4.0 * math.sqrt(only_joint + only_alone)


def test_the_joint_rule_gives_no_verdict_where_the_folds_cannot():
    assert intervals.hotelling_p([1.0, 2.0], np.ones((8, 2))) == 1.0     # no spread
    assert intervals.hotelling_p([1.0, 2.0, 3.0], np.zeros((3, 3))) == 1.0   # K - p < 1
    collinear = np.outer(np.arange(8.0), [1.0, 2.0])
    assert intervals.hotelling_p([1.0, 2.0], collinear) == 1.0


def test_a_cause_without_coefficients_is_judged_on_its_profile_at_no_effect():
    delay = generic.effect('time_delay')
    ctx = type('Ctx', (), {})()
    # SSE 100 -> 90 on 50 effective bins: 10 > 4 x 90 / 50 = 7.2 (2 sigma) but < 3.84 x 1.8
    assert intervals.clear_of_zero(delay, {}, ctx, 100.0, 90.0, 50.0, 2.0)
    assert intervals.clear_of_zero(delay, {}, ctx, 100.0, 95.0, 50.0, 2.0) is False


def test_the_sutherland_law_is_judged_on_its_share():
    # share 0 is the baseline's constant viscosity: the law is judged as any
    # coefficient is, on its share's jackknife sigma, not waved through
    visc = generic.effect('viscosity_temperature')
    assert visc.n_columns == 1 and visc.params[1].name == 'sutherland_share'
    near = _found(sutherland_share=(0.01, 0.008))
    assert not intervals.clear_of_zero(visc, near, None, 1.0, 1.0, 50.0, 2.0)
    assert not intervals.interval_clear_of_zero(visc, near, None, 1.0, 1.0, 50.0)
    law = _found(sutherland_share=(1.0, 0.01))
    assert intervals.clear_of_zero(visc, law, None, 1.0, 0.5, 50.0, 2.0)
    assert intervals.interval_clear_of_zero(visc, law, None, 1.0, 0.5, 50.0)


def test_bounds_are_in_datasheet_units():
    deg = math.pi / 180.0
    found = _found(bias_temp_coeff_rad_s_k=(1e-5 * deg, 2e-4 * deg),
                   bias_temp_coeff2_rad_s_k2=(0.0, 1e-6))
    [(quantity, upper, unit)] = ruled_out.bounds_of('bias_temperature', found, {})
    assert quantity == 'bias tempco' and unit == 'deg/s/K'
    assert upper == pytest.approx(1e-5 + 2.4 * 2e-4)
    sf = _found(sf_temp_coeff_per_k=(-5e-6, 10e-6), sf_temp_coeff2_per_k2=(0.0, 1e-7))
    assert ruled_out.bounds_of('scale_factor_temperature', sf, {})[0] == pytest.approx(
        ('SF tempco', 5 + 24.0, 'ppm/K'))
    # every cause has a zero, the Sutherland law at share 0 too: each gets a bound
    assert set(ruled_out.BOUNDS) == set(generic.CANDIDATE_IDS)
    share = _found(sutherland_share=(0.01, 0.02))
    assert ruled_out.bounds_of('viscosity_temperature', share, {})[0] == pytest.approx(
        ('share of the Sutherland law', 100 * (0.01 + 2.4 * 0.02), '%'))


def test_a_nonlinearity_is_measured_only_beside_more_than_one_rate_magnitude():
    # a bias and a scale factor are calibrated: on one magnitude the deviation at the
    # largest rate is a scale factor, and no bound on it holds
    levels = np.repeat([0.0, 0.5, 0.0, 0.5, 0.0], 100)
    assert not ruled_out.nonlinearity_measured(levels)              # rate^2 = 0.5 rate
    assert not ruled_out.nonlinearity_measured(np.r_[levels, -levels])   # rate^3 = 0.25 rate
    assert not ruled_out.nonlinearity_measured(np.zeros(50))
    assert ruled_out.nonlinearity_measured(np.r_[levels, -levels, 0.5 * levels])
    found = _found(nonlinearity_quadratic_s_rad=(0.0, 1e-4),
                   nonlinearity_cubic_s2_rad2=(0.0, 1e-4))
    info = {'max_rate_rad_s': 0.5}
    assert ruled_out.bounds_of('scale_factor_nonlinearity', found, info)
    info['nonlinearity_measured'] = False
    assert ruled_out.bounds_of('scale_factor_nonlinearity', found, info) == []


def test_an_interval_open_at_the_searched_range_bounds_nothing():
    # a delay still admissible at the grid's end (300 ms): the search stopped there,
    # the data did not
    closed = {'delay_s': intervals.Estimate(0.0, 1e-3, (-2e-3, 2e-3), 'profile likelihood')}
    assert ruled_out.bounds_of('time_delay', closed, {}) == [('delay', 2.0, 'ms')]
    for low, high in ((False, True), (True, True)):
        edge = {'delay_s': intervals.Estimate(0.0, 0.1, (-0.05, 0.3), 'profile likelihood',
                                              low, high)}
        assert ruled_out.bounds_of('time_delay', edge, {}) == []
    near_open = {'delay_s': intervals.Estimate(0.0, 0.1, (-0.05, 0.01), 'profile likelihood',
                                               True, False)}
    assert ruled_out.bounds_of('time_delay', near_open, {}) == []
    lag = {'thermal_time_constant_s': intervals.Estimate(0.0, 90.0, (0.0, 181.0), 'profile '
                                                         'likelihood', True, True)}
    assert ruled_out.bounds_of('thermal_lag', lag, {}) == []


def test_a_record_whose_rate_never_changes_bounds_no_delay():
    # a delay of the output behind a constant rate changes nothing: 'delay above 300 ms'
    # (the end of the searched range) was stated as ruled out
    rng = np.random.default_rng(3)
    t = np.arange(20_000) * 0.01
    rate = np.full(len(t), 0.5)
    gyro = rate + 1e-3 * rng.standard_normal(len(t))
    doc = to_json(diagnose(MeasuredData(t, rate, np.full(len(t), 25.0), gyro, source='hold'),
                           effects=('time_delay', 'bias_step')))
    assert 'time_delay' in doc['residual']['causes_tested']
    assert 'time_delay' not in {b['effect'] for b in doc['ruled_out']}
    assert 'delay above' not in doc['residual']['message']


def test_a_one_magnitude_record_rules_out_no_nonlinearity_it_holds():
    # 1 % at 0.5 rad/s, rates 0 and 0.5 rad/s only: the bound stated was 0.0002 %
    rng = np.random.default_rng(0)
    t = np.arange(20_000) * 0.01
    rate = np.repeat(rng.choice([0.0, 0.5], 20), 1000)
    gyro = rate * (1.0 + 0.02 * rate) + 1e-3 * rng.standard_normal(len(t))
    doc = to_json(diagnose(MeasuredData(t, rate, np.full(len(t), 25.0), gyro, source='nl'),
                           effects=('scale_factor_nonlinearity', 'bias_step')))
    assert 'scale_factor_nonlinearity' in doc['residual']['causes_tested']
    assert 'scale_factor_nonlinearity' not in {b['effect'] for b in doc['ruled_out']}
    assert 'SF nonlinearity' not in doc['residual']['message']


@pytest.mark.parametrize('seed', (1, 2))
def test_no_mismatch_states_what_the_data_rule_out(seed):
    record, _ = make_truth('none', seed, profile='static', duration_s=900.0,
                           sample_rate_hz=2.0)
    doc = to_json(diagnose(record))
    assert doc['verdict'] == 'no_mismatch'
    tested = set(doc['residual']['causes_tested'])
    assert {b['effect'] for b in doc['ruled_out']} == tested
    message = doc['residual']['message']
    assert 'The data rule out (95 %)' in message and 'explains what could be tested' not in message
    assert all(f"{b['quantity']} above" in message for b in doc['ruled_out'])


def _c1(own_ppm, sigma_ppm):
    physics = 545e-6
    value = own_ppm * 1e-6 - physics
    half = 2.365 * sigma_ppm * 1e-6
    return Parameter(value=value, sigma=sigma_ppm * 1e-6, unit='1/K', meaning='',
                     interval=(value - half, value + half), method='jackknife')


@pytest.mark.parametrize('own_ppm,sigma_ppm,compensated', [
    (0.2, 0.5, True), (-40.6, 1.7, True), (13.4, 1.1, True),
    (-148.0, 1.7, False), (50.0, 0.64, False)])
def test_compensated_follows_the_parts_interval_against_a_named_figure(own_ppm, sigma_ppm,
                                                                       compensated):
    class Phys:
        ref_temp_c = 25.0

        @staticmethod
        def ratio(temp):
            return 1.0 + 545e-6 * (temp - 25.0)

    own = document.own_tempco(_c1(own_ppm, sigma_ppm), Phys)
    assert own.compensated is compensated
    assert own.datasheet_per_k == 40e-6 and '40 ppm/K' in own.datasheet
    assert own.interval[0] < own.value < own.interval[1]


def _groups(n=240, count=100, dt=0.1):
    cnt = np.full(n, float(count))
    return statespace.Groups(cnt, cnt * dt, (np.arange(n) + 0.5) * count * dt)


def test_the_known_noise_likelihood_ratio_is_chi2_on_the_null_and_finds_an_effect():
    ref = reference.ReferenceNoise('ref', 1e4, 2e-3, 3e-4, 2e-6, 1e3)
    g = _groups()
    known = reference.KnownNoise(ref, g, 0.1)
    chol = np.tril(known._chol[0])                  # the differences' covariance factor
    rng = np.random.default_rng(11)
    x = np.interp(np.arange(240), [0, 60, 120, 180, 239], [0, 1, 0, 1, 0])[:, None]
    ps = []
    for _ in range(300):
        y = np.r_[0.0, np.cumsum(chol @ rng.standard_normal(239))]
        ps.append(known.lr_test(y, np.zeros((240, 0)), x).p_value)
    share = np.mean(np.array(ps) < 0.05)
    assert stats.binom.cdf(share * 300, 300, 0.05) > 0.005
    assert stats.binom.sf(share * 300 - 1, 300, 0.05) > 0.005
    y = np.r_[0.0, np.cumsum(chol @ rng.standard_normal(239))] + 2e-3 * x[:, 0]
    assert known.lr_test(y, np.zeros((240, 0)), x).p_value < 1e-3


def test_flicker_covariance_is_that_of_window_means_of_the_gauss_markov_terms():
    from gyro_emulator.sensor import noise as sensor_noise
    g = _groups(n=40, count=100, dt=0.1)
    cov = reference.flicker_covariance(g, 1e-3)
    # the same terms simulated exactly at the samples, then averaged per group
    taus = sensor_noise.flicker_corr_times_s((10.0, 10.0 * float(g.time_s[-1] - g.time_s[0])))
    var = sensor_noise.flicker_unit_variance(taus) * 1e-6
    rng = np.random.default_rng(3)
    reps, n = 1500, 4000
    total = np.zeros((n, reps))
    for tau, q in zip(taus, var):
        phi = math.exp(-0.1 / tau)
        x = math.sqrt(q) * rng.standard_normal(reps)
        for i in range(n):
            x = phi * x + math.sqrt(q * (1 - phi * phi)) * rng.standard_normal(reps)
            total[i] += x
    means = total.reshape(40, 100, reps).mean(axis=1)
    for i, j in ((20, 20), (20, 21), (5, 30)):
        assert np.mean(means[i] * means[j]) == pytest.approx(cov[i, j], rel=0.12), (i, j)


def test_reference_noise_reads_a_static_record():
    rng = np.random.default_rng(4)
    n, dt = 200_000, 0.01
    t = np.arange(n) * dt
    y = 2e-3 * rng.standard_normal(n) + np.cumsum(rng.standard_normal(n)) * 2e-5 * math.sqrt(dt)
    ref = reference.reference_noise(MeasuredData(t, np.zeros(n), None, y, source='s'))
    assert ref.arw_rad_s_sqrt_hz == pytest.approx(2e-3 * math.sqrt(dt), rel=0.1)
    assert ref.rrw_rad_s_sqrt_s == pytest.approx(2e-5, rel=0.5)
    with pytest.raises(ValueError, match='reference'):
        reference.reference_noise(MeasuredData(t[:20], np.zeros(20), None, np.zeros(20),
                                               source='flat'))


def test_a_reference_shorter_than_the_record_is_a_one_line_error():
    # its slow noise is not measured at the record's scales (its fit gives zero there)
    record, _ = make_truth('none', 1, profile='static', duration_s=900.0, sample_rate_hz=2.0)
    rng = np.random.default_rng(6)
    t = np.arange(0.0, 400.0, 0.5)
    short = MeasuredData(t, np.zeros(len(t)), None, 1e-3 * rng.standard_normal(len(t)),
                         source='short')
    with pytest.raises(ValueError, match=r"reference 'short' lasts 400 s, shorter than the "
                                         r'record \(900 s\)') as err:
        diagnose(record, reference=short)
    assert '\n' not in str(err.value)


def _static_record(n, seed, dt=0.5, source='ref'):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    y = np.round(1e-3 * rng.standard_normal(n) / 1e-4) * 1e-4   # quantised, 3.3 LSB rms
    return MeasuredData(t, np.zeros(n), None, y, source=source)


@pytest.mark.parametrize('how', ['itself', 'a copy', 'a log that holds it'])
def test_a_reference_that_holds_the_record_is_a_one_line_error(how):
    # its noise would be the record's own wander, effect included: the null too tight
    long = _static_record(2400, 8, source='long')
    record = MeasuredData(long.time_s[:1800], long.rate_cmd_rad_s[:1800], None,
                          long.gyro_rad_s[:1800], source='record')
    ref = {'itself': record,
           'a copy': MeasuredData(record.time_s, record.rate_cmd_rad_s, None,
                                  record.gyro_rad_s.copy(), source='copy'),
           'a log that holds it': MeasuredData(long.time_s, long.rate_cmd_rad_s, None,
                                               long.gyro_rad_s - 0.0, source='long')}[how]
    with pytest.raises(ValueError, match=r'holds 100 % of the record.s output samples .*'
                                         r'not measured independently') as err:
        diagnose(record, reference=ref)
    assert '\n' not in str(err.value)


def test_a_separate_reference_of_the_same_part_shares_no_samples():
    # two quantised static records of one part: far below the 1 % the check allows,
    # down to an output whose noise is a fifth of its LSB; a copy is found there too
    rng = np.random.default_rng(2)
    for sigma_lsb in (3.0, 1.0, 0.5, 0.2):
        a, b = (np.round(sigma_lsb * rng.standard_normal(100_000)) for _ in range(2))
        assert reference.shared_share(a, b) < 1e-3 < reference.MAX_SHARED_SHARE
        assert reference.shared_share(a[500:60_000], np.r_[b[:7], a]) > \
            reference.MAX_SHARED_SHARE
    record, ref = _static_record(1800, 8), _static_record(1800, 9)
    assert reference.shared_share(record.gyro_rad_s, ref.gyro_rad_s) == 0.0


def test_a_moving_reference_is_a_one_line_error():
    # its output holds the motion: the noise held fixed would be far too loose
    ref = _static_record(1800, 9)
    moving = MeasuredData(ref.time_s, 0.5 * np.sin(ref.time_s), None,
                          ref.gyro_rad_s + 0.5 * np.sin(ref.time_s), source='moving')
    with pytest.raises(ValueError, match=r"reference 'moving' is not static: its applied "
                                         r'rate is 0.35[0-9] rad/s rms: allowed: below 0.001 '
                                         r'rad/s rms'):
        reference.reference_noise(moving)


def test_a_reference_with_a_gap_lasts_the_time_it_covers():
    # two 300 s stretches 1300 s apart measured no slow noise over 1800 s
    record, _ = make_truth('none', 1, profile='static', duration_s=900.0, sample_rate_hz=2.0)
    whole = _static_record(3800, 9)
    keep = (whole.time_s < 300.0) | (whole.time_s >= 1600.0)
    gappy = MeasuredData(whole.time_s[keep], whole.rate_cmd_rad_s[keep], None,
                         whole.gyro_rad_s[keep], source='gappy')
    assert reference.covered_s(gappy.time_s, 0.5) == pytest.approx(600.0)
    assert reference.covered_s(whole.time_s, 0.5) == 1900.0
    with pytest.raises(ValueError, match=r"reference 'gappy' lasts 600 s \(its logging gaps "
                                         r'left out\), shorter than the record \(900 s\)'):
        diagnose(record, reference=gappy)


def test_effective_tests_of_a_grid():
    x = np.random.default_rng(0).standard_normal((500, 1))
    assert selection.effective_tests(np.repeat(x, 20, axis=1)) == pytest.approx(1.0)
    eye = np.random.default_rng(1).standard_normal((5000, 6))
    assert selection.effective_tests(eye) == pytest.approx(6.0, abs=0.3)


def test_the_injection_profile_is_a_sampled_profile_with_its_rate_knots():
    t = np.arange(0.0, 100.0, 0.01)
    prof = inj.profile('ramp+rate_steps', t, np.random.default_rng(0))
    assert isinstance(prof, profiles.SampledProfile) and isinstance(prof, profiles.Profile)
    kt, kr = prof.rate_knots
    np.testing.assert_array_equal(prof.rate_rad_s[:, 2],
                                  np.interp(t, kt, kr[:, 2], left=0.0, right=0.0))
    # the rate between samples, exactly: a delay reads it
    mid = t[:-1] + 0.003
    np.testing.assert_array_equal(prof.rate_at(mid)[:, 2],
                                  np.interp(mid, kt, kr[:, 2], left=0.0, right=0.0))
    # a one-way ramp is the shared chamber-program idea: 15 -> 55 C, linear
    np.testing.assert_allclose(prof.temp_c, 15.0 + 40.0 * t / t[-1], rtol=0, atol=1e-12)
    still = inj.profile('cycles', t, np.random.default_rng(0))
    assert still.rate_knots is None and not np.any(inj.sensed_rate(still, t))
