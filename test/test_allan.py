"""Overlapping Allan deviation, confidence intervals, the N/B/K fit and the self-check."""

from dataclasses import replace
import math
import os

import allantools
from gyro_emulator import units
from gyro_emulator.analysis import allan
from gyro_emulator.recording.record import load_record
from gyro_emulator.sensor import noise
from gyro_emulator.sensor.config import SensorConfig
from gyro_emulator.sensor.model import GyroModel
import noise_reference
import numpy as np
import pytest
from scipy import signal


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


@pytest.mark.parametrize('q,r', [(0.0, 0.0), (2e-5, 0.0), (0.0, 3e-7)])
def test_fit_recovers_an_exact_model_curve(q, r):
    """All five IEEE Std 952 terms from a noise-free curve (huge record: no chi^2 bias)."""
    n, b, k = 3e-4, 2e-5, 4e-6
    taus = np.logspace(-2, 3, 40)
    adev = allan.model_adev(taus, n, b, k, q, r)
    res = allan.AllanResult(taus_s=taus, adev=adev, adev_lo=adev, adev_hi=adev,
                            edf=np.full(40, 1e9), alpha=np.zeros(40), n_terms=np.ones(40),
                            rate_hz=100.0, n_samples=10 ** 13, ci=0.683)
    fit = allan.fit_noise_terms(res)
    got = (fit.quantization_rad, fit.arw_rad_s_sqrt_hz, fit.bias_instability_rad_s,
           fit.rrw_rad_s_sqrt_s, fit.rate_ramp_rad_s2)
    np.testing.assert_allclose(got, (q, n, b, k, r), rtol=1e-4, atol=1e-12)
    assert fit.arw_deg_sqrt_h == pytest.approx(units.rad_s_sqrt_hz_to_arw_deg_sqrt_h(n))
    assert fit.misfit == pytest.approx(0.0, abs=1e-6)


def test_a_fit_restricted_to_some_terms_holds_the_others_at_zero():
    """``terms``: a curve with a rate ramp fitted with N, B, K only puts nothing in R."""
    n, b, k, r = 3e-4, 2e-5, 4e-6, 3e-7
    taus = np.logspace(-2, 3, 40)
    adev = allan.model_adev(taus, n, b, k, 0.0, r)
    res = allan.AllanResult(taus_s=taus, adev=adev, adev_lo=adev, adev_hi=adev,
                            edf=np.full(40, 1e9), alpha=np.zeros(40), n_terms=np.ones(40),
                            rate_hz=100.0, n_samples=10 ** 13, ci=0.683)
    full = allan.fit_noise_terms(res)
    nbk = allan.fit_noise_terms(res, terms=('arw', 'bias_instability', 'rrw'))
    assert full.rate_ramp_rad_s2 == pytest.approx(r, rel=1e-4)
    assert nbk.rate_ramp_rad_s2 == 0.0 and nbk.quantization_rad == 0.0
    # the ramp's rise has to go somewhere: the random walk takes it
    assert nbk.rrw_rad_s_sqrt_s > 1.5 * k
    with pytest.raises(ValueError, match="terms = .*'drift'.* is not allowed"):
        allan.fit_noise_terms(res, terms=('arw', 'drift'))


def test_self_check_two_hours_at_200_hz():
    """
    Simulate 2 h at 200 Hz with configured N, B, K; the Allan fit recovers them.

    N = 0.3 deg/sqrt(h), B = 10 deg/h, K = 100 deg/h/sqrt(h) (white noise
    crosses the 0.664 B floor near 7 s, rate random walk near 50 s). The
    issue's tolerances (N 10 %, B 25 %, K 25 %) are checked on every axis.
    Over 18 seeds (6 x 3 axes) the per-axis estimates scattered by 0.1 % (N),
    3.5 % (B) and 13 % (K): a 2 h record holds few independent samples of a
    random walk at tau > 50 s, so about 1 axis in 20 misses 25 % on K. This
    seed's axes give K = 93, 117 and 94; the mean of the three independent
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


# --- IEEE Std 952 identification: band limit, five terms, intervals, read-offs ---

REAL = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), '..',
                    'shared', 'data', 'real')


def test_filtered_white_noise_region_is_found_from_the_psd_and_dropped():
    """A 20 Hz Butterworth at 100 Hz: the short taus are dropped and N is unbiased."""
    rng = np.random.default_rng(4)
    rate = 100.0
    b, a = signal.butter(2, 20.0, fs=rate)
    data = signal.lfilter(b, a, rng.standard_normal(200_000))
    truth = float(units.sample_sigma_to_density(1.0, rate))     # DC gain 1: N unchanged
    res, fit = allan.identify([data], rate)
    assert fit.band.method == 'psd' and fit.band.tau_min_s > 0.1
    assert fit.arw_rad_s_sqrt_hz == pytest.approx(truth, rel=0.03)
    low, high = fit.intervals['arw'].low, fit.intervals['arw'].high
    assert low <= truth <= high
    # the failure mode the drop removes: fitting the filtered taus biases N low
    naive = allan.fit_noise_terms(res)
    assert naive.arw_rad_s_sqrt_hz < 0.96 * truth


def _noise_config(n_deg_sqrt_h, b_deg_h, k_deg_h_sqrt_h, band=(0.1, 1000.0), per_decade=1.0):
    config = SensorConfig.ideal().with_terms(
        electronics_noise=True, bias_instability=True, rate_random_walk=True)
    return replace(
        config,
        electronics_noise_rad_s_sqrt_hz=float(units.arw_deg_sqrt_h_to_rad_s_sqrt_hz(
            n_deg_sqrt_h)),
        bias_instability_rad_s=float(units.deg_h_to_rad_s(b_deg_h)),
        rate_random_walk_rad_s_sqrt_s=float(units.rrw_deg_h_sqrt_h_to_rad_s_sqrt_s(
            k_deg_h_sqrt_h)),
        bias_instability_band_s=band, bias_instability_per_decade=per_decade)


@pytest.fixture(scope='module')
def population():
    """36 independent 1 h axes at 100 Hz of N 0.3, B 10 (flat over 0.03 .. 3e4 s), K 100."""
    config = _noise_config(0.3, 10.0, 100.0, band=(0.01, 1e5), per_decade=2.0)
    fits = []
    for seed in range(12):
        out = GyroModel(config, 100.0, np.random.default_rng(seed)).run(
            np.zeros((360_000, 3)), 25.0).gyro_rad_s
        fits += [allan.identify([out[:, axis]], 100.0) for axis in range(3)]
    return fits


def test_term_intervals_cover_the_truth(population):
    """
    95 % intervals of N, B and K hold the configured values on >= 31 of 36 axes.

    Coverage is a property of many records, not of one: at the nominal 95 %
    about 34 of 36 would hold; 31 allows for the flicker generator, whose
    floor is flat within a few percent only.
    """
    truth = {'arw': units.arw_deg_sqrt_h_to_rad_s_sqrt_hz(0.3),
             'bias_instability': units.deg_h_to_rad_s(10.0),
             'rrw': units.rrw_deg_h_sqrt_h_to_rad_s_sqrt_s(100.0)}
    for term, value in truth.items():
        inside = sum(f.intervals[term].low <= value <= f.intervals[term].high
                     for _, f in population)
        assert inside >= 31, (term, inside)


def test_no_false_alarms_on_plain_noise(population):
    """No band limit, no Q or R and no read-off warning on unfiltered N + B + K noise."""
    assert all(res.taus_s[0] == f.band.tau_min_s for res, f in population)
    assert all(f.quantization_rad == 0.0 and f.rate_ramp_rad_s2 == 0.0 for _, f in population)
    assert sum(bool(f.warnings) for _, f in population) <= 1


def test_no_random_walk_is_claimed_where_there_is_none():
    """
    1 h axes of N 0.3 and B 10 only: K stays an upper bound whose interval holds 0.

    An adversarial review found K resolved (lower bound above 0) on 8 of 48
    such axes (and the project's own generator on 4 of 36): the long end of
    a flicker curve rises and falls by chance. With K resolved only from
    taus up to T/10 and only when its removal costs the fit
    RRW_LIKELIHOOD_RATIO, none of 84 calibration axes claimed it. These 36
    axes use other seeds: the former rule claimed K on 7 of them, this one
    on 1; two are allowed.
    """
    config = replace(_noise_config(0.3, 10.0, 100.0, band=(0.01, 1e5), per_decade=2.0),
                     rate_random_walk_rad_s_sqrt_s=0.0)
    fits = []
    for seed in range(300, 312):
        out = GyroModel(config, 100.0, np.random.default_rng(seed)).run(
            np.zeros((360_000, 3)), 25.0).gyro_rad_s
        fits += [allan.identify([out[:, axis]], 100.0)[1] for axis in range(3)]
    assert sum(f.resolved('rrw') for f in fits) <= 2
    assert sum(f.intervals['rrw'].low == 0.0 for f in fits) >= 34


@pytest.mark.parametrize('fs,fc', [(1000.0, 30.0), (400.0, 10.0), (200.0, 50.0)])
def test_a_low_pass_output_drops_only_its_own_short_taus(fs, fc):
    """
    A 2nd-order output filter: the dropped region ends near 20 / fc, not at long taus.

    Before, the Welch grid sampled the Allan kernel's ripple at long taus
    (on its zeros when tau df was whole) and a few isolated long taus
    dropped almost the whole curve: N was exported as 0.
    """
    rng = np.random.default_rng(1)
    n = int(1800 * fs)
    n_true = float(units.arw_deg_sqrt_h_to_rad_s_sqrt_hz(0.5))
    y = rng.standard_normal(n) * n_true * math.sqrt(fs)
    y += np.cumsum(rng.standard_normal(n)) * 1.6e-6 / math.sqrt(fs)     # K 20 deg/h/sqrt(h)
    b, a = signal.butter(2, fc / (fs / 2))
    y = signal.lfilter(b, a, y)
    res, fit = allan.identify([y], fs)
    assert fit.band.method in ('psd', 'slope')
    assert 2.0 / fc <= fit.band.tau_min_s <= 25.0 / fc
    # the band rule allows 1 % in variance (0.5 % in deviation) at the edge
    low, high = fit.intervals['arw'].low, fit.intervals['arw'].high
    assert low * 0.99 <= n_true <= high * 1.01


def test_white_noise_has_no_band_limit_over_seeds():
    rng = np.random.default_rng(12)
    flagged = 0
    for _ in range(20):
        res, fit = allan.identify([rng.standard_normal(60_000)], 100.0)
        flagged += fit.band.tau_min_s > res.taus_s[0]
    assert flagged <= 1


def test_quantisation_and_rate_ramp_are_recovered():
    """Angle quantisation (tau^-1) and a rate ramp (tau^+1), IEEE Std 952 Table C.1."""
    rng = np.random.default_rng(5)
    rate, n = 100.0, 400_000
    density = float(units.arw_deg_sqrt_h_to_rad_s_sqrt_hz(0.5))
    white = rng.standard_normal(n) * density * np.sqrt(rate)
    step = 2e-5                                          # angle LSB, rad: Q = step / sqrt(12)
    angle = np.concatenate(([0.0], np.cumsum(white / rate))) + rng.uniform(0.0, step)
    quantised = np.diff(np.round(angle / step) * step) * rate
    res, fit = allan.identify([quantised], rate)
    assert fit.band.quantisation
    assert fit.quantization_rad == pytest.approx(step / np.sqrt(12.0), rel=0.15)
    assert fit.arw_rad_s_sqrt_hz == pytest.approx(density, rel=0.03)
    ramp = 1e-6
    drifting = white + ramp * np.arange(n) / rate
    _, fit = allan.identify([drifting], rate)
    assert fit.rate_ramp_rad_s2 == pytest.approx(ramp, rel=0.15)
    assert fit.intervals['rate_ramp'].low <= ramp <= fit.intervals['rate_ramp'].high


def test_read_offs_are_upper_bounds_and_a_bump_is_warned():
    taus = np.logspace(-1, 3, 41)
    n, b, k = 3e-4, 2e-5, 4e-6
    clean = allan.model_adev(taus, n, b, k)
    found = allan.readings(taus, clean)
    assert found['arw'].value >= n and found['arw'].value == pytest.approx(n, rel=0.05)
    assert found['bias_instability'].value >= b
    res = allan.AllanResult(taus_s=taus, adev=clean, adev_lo=clean, adev_hi=clean,
                            edf=np.full(41, 1e4), alpha=np.zeros(41), n_terms=np.ones(41),
                            rate_hz=100.0, n_samples=10 ** 9, ci=0.683)
    fit = allan.fit_noise_terms(res)
    assert allan.compare_readings(fit, res, found) == []
    # a dip of 35 % about the curve's minimum, which five smooth terms cannot follow
    bumped = clean * (1.0 - 0.35 * np.exp(-0.5 * (np.log10(taus / 80.0) / 0.2) ** 2))
    res = replace(res, adev=bumped)
    fit = allan.fit_noise_terms(res)
    warnings = list(fit.warnings) + allan.compare_readings(fit, res, allan.readings(taus, bumped))
    assert any('departs from the IEEE Std 952 terms' in w for w in warnings)
    # a fit that does not belong to the curve: every identified read-off disagrees
    other = replace(res, adev=1.3 * clean)
    warnings = allan.compare_readings(allan.fit_noise_terms(replace(res, adev=clean)), other,
                                      allan.readings(taus, 1.3 * clean))
    assert any('for rrw' in w for w in warnings)


def test_edf_at_the_noisy_long_end_is_never_white_phase():
    """A slope of -1 at the last taus (noise) must not claim white-PM degrees of freedom."""
    taus = np.logspace(-2, 2, 30)
    adev = 1e-3 / np.sqrt(taus)
    adev[-3:] = adev[-4] * (taus[-4] / taus[-3:])          # slope -1 at the end
    m = np.round(taus * 100.0)
    alpha, edf = allan.adev.conservative_edf((40_000,), m, taus, adev)
    assert np.all(edf[-3:] < 100.0)
    assert alpha[0] == 0


@pytest.mark.skipif(not os.path.isdir(REAL), reason='shared real data not present')
def test_adis16405_z_has_a_bias_instability():
    """The issue's symptom: z got B = 0; the floor is there, below the min/0.664 read-off."""
    path = os.path.join(REAL, 'adis16405_static', 'adis16405_run1_100hz.csv.gz')
    info, _, fit = allan.analyse_record(load_record(path), 'z')
    assert fit.resolved('bias_instability')
    read = info['bias_instability_min_deg_h']
    assert 0.3 * read < fit.bias_instability_deg_h < read
    assert fit.band.tau_min_s > 0.1                       # its spectral line and roll-off


def test_a_log_with_some_axes_is_read_by_axis(tmp_path):
    """A CSV with only gyro_y_rad_s and gyro_z_rad_s: the axes it has, and a clear error."""
    from gyro_emulator.recording import csvio

    rng = np.random.default_rng(5)
    path = tmp_path / 'yz.csv'
    y, z = rng.standard_normal((2, 400)) * 1e-3
    csvio.write_csv(path, {'time_s': np.arange(400) / 100.0, 'gyro_y_rad_s': y,
                           'gyro_z_rad_s': z})
    record = load_record(str(path))
    assert set(record.gyro) == {'y', 'z'}
    rate, column = record.gyro_axis('z')
    assert column == 'gyro_z_rad_s'
    np.testing.assert_allclose(rate, z, rtol=1e-9)
    assert record.gyro_axis(None)[1] == 'gyro_y_rad_s'
    with pytest.raises(ValueError, match="no gyro column for axis 'x'; the file has "
                                         'gyro_y_rad_s, gyro_z_rad_s'):
        record.gyro_axis('x')


def _white_and_walk(seed, n, rate_hz):
    """N 0.3 deg/sqrt(h) and K 100 deg/h/sqrt(h): at 1 Hz the white region is 1 .. 20 s."""
    rng = np.random.default_rng(seed)
    n_true = float(units.arw_deg_sqrt_h_to_rad_s_sqrt_hz(0.3))
    k_true = float(units.rrw_deg_h_sqrt_h_to_rad_s_sqrt_s(100.0))
    return (rng.standard_normal(n) * n_true * math.sqrt(rate_hz)
            + np.cumsum(rng.standard_normal(n)) * k_true / math.sqrt(rate_hz))


def test_a_1hz_log_without_a_filter_is_not_given_one():
    """
    A 2 h log at 1 Hz of white noise and a random walk has no output filter.

    Its PSD is too coarse for a white run, so the band limit falls back on
    the Allan slope. Before, a slope lifted 0.02 above -1/2 by the random
    walk read as a filter (tau < 2-3 s dropped on 4 of these 40 logs), and once a
    slope of -1/2 at the noisy long end, past the curve's minimum, dropped
    every tau below 1800 s and the log was refused as too short.
    """
    flagged = 0
    for seed in range(1000, 1040):
        y = _white_and_walk(seed, 7200, 1.0)
        res = allan.overlapping_adev(y, 1.0, taus=allan.tau_multiples(7200, 10, 0.25))
        limit = allan.band.band_limit([y], 1.0, res.taus_s, res.adev)
        flagged += limit.tau_min_s > res.taus_s[0]
    assert flagged <= 1


def test_the_slope_fallback_stops_at_the_curves_minimum():
    """A white region comes before the minimum: a -1/2 slope after it is no anchor."""
    taus = np.logspace(0.0, 3.0, 31)
    adev = 1e-4 / np.sqrt(taus) + 1e-6 * np.sqrt(taus)
    slopes = np.full(len(taus), -0.45)
    slopes[np.argmin(adev) + 1:] = 0.4
    slopes[-3] = -0.5                                    # a noisy dip at the long end
    limit = allan.band.slope_band_limit(taus, adev, slopes=slopes)
    assert limit.method == 'none' and limit.tau_min_s == taus[0]


def test_the_slope_fallback_still_finds_a_filter():
    """Filtered white noise (2nd order at 30 Hz, 1 kHz): the slope region ends near 1 / fc."""
    rng = np.random.default_rng(4)
    fs, fc = 1000.0, 30.0
    b, a = signal.butter(2, fc / (fs / 2))
    y = signal.lfilter(b, a, rng.standard_normal(600_000))
    res = allan.overlapping_adev(y, fs, taus=allan.tau_multiples(len(y), 10, 0.25) / fs)
    limit = allan.band.slope_band_limit(res.taus_s, res.adev)
    assert limit.method == 'slope'
    assert 2.0 / fc <= limit.tau_min_s <= 25.0 / fc
