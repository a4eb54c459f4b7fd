"""Overlapping Allan deviation, confidence intervals, the N/B/K fit and the self-check."""

from dataclasses import replace
import math

import allantools
from gyro_emulator import units
from gyro_emulator.analysis import allan
from gyro_emulator.sensor import noise
from gyro_emulator.sensor.config import SensorConfig
from gyro_emulator.sensor.model import GyroModel
import noise_reference
import numpy as np
import pytest


def _noise_config(n_deg_sqrt_h, b_deg_h, k_deg_h_sqrt_h, band=(0.1, 1000.0)):
    config = SensorConfig.ideal().with_terms(
        electronics_noise=True, bias_instability=True, rate_random_walk=True)
    return replace(
        config,
        electronics_noise_rad_s_sqrt_hz=float(units.arw_deg_sqrt_h_to_rad_s_sqrt_hz(
            n_deg_sqrt_h)),
        bias_instability_rad_s=float(units.deg_h_to_rad_s(b_deg_h)),
        rate_random_walk_rad_s_sqrt_s=float(units.rrw_deg_h_sqrt_h_to_rad_s_sqrt_s(
            k_deg_h_sqrt_h)),
        bias_instability_band_s=band)


@pytest.fixture(scope='module')
def record():
    """20 min at 100 Hz of white + flicker + random-walk rate noise (3 axes)."""
    model = GyroModel(_noise_config(0.5, 20.0, 60.0), 100.0, np.random.default_rng(11))
    return model.run(np.zeros((120_000, 3)), 25.0).gyro_rad_s


@pytest.mark.parametrize('taus', ['decade', 'octave', 'explicit'])
def test_agrees_with_allantools(record, taus):
    data = record[:, 0]
    arg = np.array([0.01, 0.05, 0.3, 1.0, 7.5, 60.0, 250.0]) if taus == 'explicit' else taus
    ours = allan.overlapping_adev(data, 100.0, taus=arg)
    ref_taus, ref_adev, _, ref_n = allantools.oadev(data, rate=100.0, data_type='freq',
                                                    taus=ours.taus_s)
    np.testing.assert_allclose(ref_taus, ours.taus_s, rtol=1e-12)
    np.testing.assert_allclose(ours.adev, ref_adev, rtol=0.01)
    np.testing.assert_array_equal(ours.n_terms, ref_n)


@pytest.mark.parametrize('alpha', [0, -1, -2])
def test_edf_matches_allantools_simple_table(alpha):
    """NIST SP 1065 Table 5, checked against allantools.edf_simple."""
    for n_phase, m in ((1001, 1), (1001, 10), (100001, 333), (5000, 1200)):
        if alpha == -1 and m == 1:
            continue
        ours = allan.edf_overlapping(n_phase, m, alpha)
        assert ours == pytest.approx(allantools.edf_simple(n_phase, m, alpha), rel=1e-9)


def test_edf_flicker_fm_at_m1_uses_the_squared_table_entry():
    """
    NIST SP 1065 Table 5, flicker FM, m = 1: 2 (N - 2)^2 / (2.3 N - 4.9).

    allantools 2024.6 drops the square (0.87 dof for 1001 points); the entry
    must grow like N, and continue smoothly into the m >= 2 formula.
    """
    n_phase = 1001
    assert allan.edf_overlapping(n_phase, 1, -1) == pytest.approx(
        2 * (n_phase - 2) ** 2 / (2.3 * n_phase - 4.9), rel=1e-12)
    assert 0.5 < allan.edf_overlapping(n_phase, 1, -1) / allan.edf_overlapping(
        n_phase, 2, -1) < 2.0


def test_confidence_interval_brackets_and_matches_chi2(record):
    res = allan.overlapping_adev(record[:, 1], 100.0)
    assert np.all(res.adev_lo < res.adev) and np.all(res.adev < res.adev_hi)
    ref = np.array([allantools.confidence_interval(d, e, ci=0.683)
                    for d, e in zip(res.adev, res.edf)])
    np.testing.assert_allclose(res.adev_lo, ref[:, 0], rtol=1e-6)
    np.testing.assert_allclose(res.adev_hi, ref[:, 1], rtol=1e-6)
    # wider intervals where fewer degrees of freedom remain
    assert (res.adev_hi / res.adev_lo)[-1] > (res.adev_hi / res.adev_lo)[0]


def test_pooled_segments(record):
    data = record[:, 2]
    whole = allan.overlapping_adev(data, 100.0)
    one = allan.overlapping_adev([data], 100.0)
    np.testing.assert_array_equal(whole.adev, one.adev)
    # two halves pooled: same sum of second differences except across the cut
    taus = np.array([0.01, 0.1, 1.0])
    halves = allan.overlapping_adev([data[:60_000], data[60_000:]], 100.0, taus=taus)
    full = allan.overlapping_adev(data, 100.0, taus=taus)
    np.testing.assert_allclose(halves.adev, full.adev, rtol=0.01)
    assert halves.segment_lengths == (60_000, 60_000)


def test_white_noise_adev_is_n_over_sqrt_tau():
    rng = np.random.default_rng(3)
    density, rate = 1e-3, 50.0
    data = rng.standard_normal(200_000) * units.density_to_sample_sigma(density, rate)
    res = allan.overlapping_adev(data, rate, taus=[0.1, 1.0, 10.0])
    expect = density / np.sqrt(res.taus_s)
    assert np.all((res.adev_lo < expect) | np.isclose(res.adev_lo, expect, rtol=0.05))
    assert np.all(np.abs(res.adev / expect - 1) < 5 / np.sqrt(res.edf))


def test_fit_recovers_an_exact_model_curve():
    n, b, k = 3e-4, 2e-5, 4e-6
    taus = np.logspace(-2, 3, 40)
    adev = allan.model_adev(taus, n, b, k)
    res = allan.AllanResult(taus_s=taus, adev=adev, adev_lo=adev, adev_hi=adev,
                            edf=np.ones(40), alpha=np.zeros(40), n_terms=np.ones(40),
                            rate_hz=100.0, n_samples=10_000_000, ci=0.683)
    fit = allan.fit_noise_terms(res)
    assert (fit.arw_rad_s_sqrt_hz, fit.bias_instability_rad_s, fit.rrw_rad_s_sqrt_s) == \
        pytest.approx((n, b, k), rel=1e-6)
    assert fit.arw_deg_sqrt_h == pytest.approx(units.rad_s_sqrt_hz_to_arw_deg_sqrt_h(n))


def test_self_check_two_hours_at_200_hz():
    """
    Simulate 2 h at 200 Hz with configured N, B, K; the Allan fit recovers them.

    N = 0.3 deg/sqrt(h), B = 10 deg/h, K = 100 deg/h/sqrt(h) (white noise
    crosses the 0.664 B floor near 7 s, rate random walk near 50 s). The
    issue's tolerances (N 10 %, B 25 %, K 25 %) are checked on every axis.
    Over 18 seeds (6 x 3 axes) the per-axis estimates scattered by 0.1 % (N),
    3.5 % (B) and 13 % (K): a 2 h record holds few independent samples of a
    random walk at tau > 50 s, so about 1 axis in 20 misses 25 % on K. This
    seed's axes give K = 92, 115 and 93; the mean of the three independent
    records is also held to 25 % (about 3 standard deviations).
    """
    config = _noise_config(0.3, 10.0, 100.0)
    out = GyroModel(config, 200.0, np.random.default_rng(2026)).run(
        np.zeros((2 * 3600 * 200, 3)), 25.0)
    fits = []
    for axis in range(3):
        res = allan.overlapping_adev(out.gyro_rad_s[:, axis], 200.0)
        fits.append(allan.fit_noise_terms(res))
    for fit in fits:
        assert fit.arw_deg_sqrt_h == pytest.approx(0.3, rel=0.10)
        assert fit.bias_instability_deg_h == pytest.approx(10.0, rel=0.25)
        assert fit.rrw_deg_h_sqrt_h == pytest.approx(100.0, rel=0.25)
    assert np.mean([f.rrw_deg_h_sqrt_h for f in fits]) == pytest.approx(100.0, rel=0.25)


def test_theory_of_the_generators_matches_the_fit_model():
    """The flicker generator's Allan floor and the fit's B term agree within 5 %."""
    plan = noise.flicker_plan((0.1, 1000.0), 0.005)
    b = units.deg_h_to_rad_s(10.0)
    taus = np.logspace(0, 2, 9)
    adev = np.sqrt(noise_reference.flicker_avar(plan, b, taus))
    np.testing.assert_allclose(adev, allan.model_adev(taus, 0.0, b, 0.0), rtol=0.05)


def test_bad_inputs():
    with pytest.raises(ValueError, match='rate_hz'):
        allan.overlapping_adev(np.zeros(10), 0.0)
    with pytest.raises(ValueError, match='non-finite'):
        allan.overlapping_adev(np.array([0.0, math.nan, 1.0, 2.0]), 1.0)
    with pytest.raises(ValueError, match='taus'):
        allan.overlapping_adev(np.zeros(100), 1.0, taus='weekly')
