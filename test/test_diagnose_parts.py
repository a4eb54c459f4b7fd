"""The building blocks of diagnose v2: screening, steps, hysteresis, noise, tests."""

import math

from gyro_emulator.analysis import allan
from gyro_emulator.analysis.diagnose import cv as cvmod
from gyro_emulator.analysis.diagnose import generic, models, noise_model, screening
from gyro_emulator.analysis.diagnose.baseline import DevicePhysics
from gyro_emulator.analysis.diagnose.data import MeasuredData, Prepared
from gyro_emulator.analysis.diagnose.effects import Context
from gyro_emulator.physics.presets import physics_preset
import numpy as np
import pytest


def _static(n=20000, dt=0.1, seed=0, sigma=1e-3, walk=0.0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    gyro = 0.01 + sigma * rng.standard_normal(n) + walk * np.cumsum(rng.standard_normal(n))
    return MeasuredData(time_s=t, rate_cmd_rad_s=np.zeros(n), temp_c=None, gyro_rad_s=gyro)


def _ratio(temp):
    return np.ones_like(np.asarray(temp, dtype=float))


def test_screening_sets_aside_spikes_and_motion_and_nothing_else():
    rec = _static()
    gyro = rec.gyro_rad_s.copy()
    spikes = [500, 7001, 15000]
    gyro[spikes] += [0.05, -0.02, 0.5]
    rng = np.random.default_rng(1)
    motion = slice(9000, 9300)                       # 30 s of handling
    gyro[motion] += 0.2 * np.sin(np.arange(300) * 0.3) * rng.uniform(0.5, 1.0, 300)
    bad = MeasuredData(time_s=rec.time_s, rate_cmd_rad_s=rec.rate_cmd_rad_s, temp_c=None,
                       gyro_rad_s=gyro)
    found = screening.screen(bad, _ratio)
    dropped = np.flatnonzero(~found['keep'])
    assert set(spikes) <= set(dropped)
    assert set(range(9000, 9300)) <= set(dropped)
    # only the motion's settling margin (1 s each side) beyond the outliers
    assert found['count'] <= len(spikes) + 300 + 2 * 11
    assert screening.screen(rec, _ratio)['count'] == 0
    assert screening.screen(bad, _ratio, threshold=math.inf)['count'] == 0


def test_change_point_is_the_exact_least_squares_step():
    rng = np.random.default_rng(3)
    n = 600
    t = np.arange(n) * 1.0
    gyro = 0.002 * rng.standard_normal(n) + np.where(t >= 377.0, 0.01, 0.0)
    rec = MeasuredData(time_s=t, rate_cmd_rad_s=np.zeros(n), temp_c=np.full(n, 25.0),
                       gyro_rad_s=gyro)
    prep = Prepared(rec, max_bins=n)
    ctx = Context(phys=DevicePhysics(physics_preset('paper'), 25.0, 25.0, 25.0),
                  ref_temp_c=25.0, time_span_s=(0.0, t[-1]), duration_s=prep.duration_s)
    step = generic.effect('bias_step')
    fit = models.fit_model(models.Model((step,)), ctx, prep.binned)
    brute = []
    for t0 in t[12:-12]:
        cols = [np.ones(n), np.zeros(n), (t >= t0).astype(float)]
        brute.append((models.wls(cols, gyro, np.ones(n))[1], t0))
    assert fit.phis[0][0] == min(brute)[1] == 377.0
    assert fit.beta[2] == pytest.approx(0.01, abs=0.001)


def test_play_operator_keeps_its_branch_through_a_soak():
    temp = np.r_[np.linspace(20, 30, 11), np.full(5, 30.0), np.linspace(30, 20, 11)]
    p = generic.play(temp, 2.0)
    np.testing.assert_allclose(p[:11], np.maximum(20.0, temp[:11] - 2.0))
    np.testing.assert_allclose(p[11:16], 28.0)     # heated: the lower branch holds
    assert p[-1] == pytest.approx(22.0)             # cooled: the upper branch


def test_robust_allan_matches_the_plain_one_on_noise_and_ignores_a_step():
    rng = np.random.default_rng(5)
    x = 1e-3 * rng.standard_normal(40000)
    plain = allan.overlapping_adev(x, 10.0)
    robust = noise_model.robust_adev([x], 10.0)
    np.testing.assert_allclose(robust.adev[:12], plain.adev[:12], rtol=0.05)
    stepped = x + np.where(np.arange(40000) > 20000, 5e-3, 0.0)
    plain_s = allan.overlapping_adev(stepped, 10.0)
    robust_s = noise_model.robust_adev([stepped], 10.0)
    # up to a fortieth of the record few windows straddle the step
    mid = (plain.taus_s > 10.0) & (plain.taus_s <= 100.0)
    assert np.all(plain_s.adev[mid] > 1.5 * plain.adev[mid])
    np.testing.assert_allclose(robust_s.adev[mid], plain.adev[mid], rtol=0.2)


def test_short_term_sigma_reads_filtered_noise_per_sample():
    rng = np.random.default_rng(7)
    w = rng.standard_normal(200001)
    filtered = (w[1:] + w[:-1]) / math.sqrt(2.0)    # lag-1 correlation 0.5, variance 1
    sigma = noise_model._short_term_sigma([filtered], 0.01)
    assert sigma == pytest.approx(1.0, rel=0.02)
    naive = math.sqrt(0.5 * np.mean(np.diff(filtered) ** 2))
    assert naive == pytest.approx(math.sqrt(0.5), rel=0.02)


def test_simulated_noise_has_the_fitted_allan_deviation():
    noise = noise_model.NoiseModel(white_sigma_rad_s=1e-3, arw_rad_s_sqrt_hz=1e-4,
                                   bias_instability_rad_s=2e-5, rrw_rad_s_sqrt_s=3e-7,
                                   tau_max_s=1e3)

    class Groups:
        time_s = np.arange(4000) * 5.0
        weight = np.full(4000, 50.0)
        dt_s = 0.1

    sims = noise_model.draw_noise_records(noise, Groups, 8, np.random.default_rng(2))
    taus = np.array([50.0, 500.0, 2000.0])
    got = np.sqrt(np.mean([allan.overlapping_adev(sims[:, j], 0.2, taus).adev ** 2
                           for j in range(8)], axis=0))
    want = allan.model_adev(taus, 1e-4, 2e-5, 3e-7)
    np.testing.assert_allclose(got, want, rtol=0.25)


def test_fold_test_and_tail_bound():
    ref = np.full(8, 10.0)
    assert cvmod.fold_test(ref, ref - np.linspace(0.5, 1.5, 8)) < 1e-3
    assert cvmod.fold_test(ref, ref + 1.0) > 0.99
    # a reduction noise alone gives is not evidence
    assert cvmod.fold_test(ref, ref - 1.0, np.full(8, 1.0)) == 1.0
    null = np.random.default_rng(0).standard_normal(2000)
    for k in (3.0, 10.0, 30.0):
        bound = cvmod.tail_bound(np.median(null) + k, null)
        assert bound >= np.mean(null >= np.median(null) + k)
    assert cvmod.tail_bound(-5.0, null) == 1.0


def test_effective_bins_counts_correlated_bins_once():
    rng = np.random.default_rng(4)
    white = rng.standard_normal(5000)
    assert cvmod.effective_bins(white, np.ones(5000)) == pytest.approx(5000, rel=0.1)
    smooth = np.repeat(rng.standard_normal(100), 50)
    assert cvmod.effective_bins(smooth, np.ones(5000)) < 100
