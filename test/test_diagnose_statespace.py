"""The joint noise + effect likelihood test of diagnose (analysis.diagnose.statespace)."""

import math
import warnings

from gyro_emulator.analysis.diagnose import noise_model, statespace as ss
import numpy as np
import pytest


def _groups(n=300, count=100, dt=0.01):
    cnt = np.full(n, float(count))
    return ss.Groups(cnt, cnt * dt, (np.arange(n) + 0.5) * count * dt)


def _null_record(rng, groups, sigma=1e-3, k=2e-5):
    """White noise of per-sample sigma averaged per group plus a walk of intensity k."""
    fit = ss.LevelFit(0.0, sigma ** 2, k ** 2, np.zeros(0), False)
    return np.r_[0.0, np.cumsum(ss.simulate_differences(fit, groups, 1, rng)[:, 0])]


def test_loglike_matches_statsmodels_local_level():
    sm = pytest.importorskip('statsmodels.tsa.statespace.structural')
    rng = np.random.default_rng(1)
    g = _groups()
    y = _null_record(rng, g)
    x = np.sin(np.arange(len(y)) / 40.0)[:, None]
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        ref0 = sm.UnobservedComponents(y * 1e3, 'llevel').fit(disp=False).llf
        ref1 = sm.UnobservedComponents(y * 1e3, 'llevel', exog=x).fit(disp=False).llf
    # the same model family on equal groups: the same maximum, up to the units of y
    shift = (len(y) - 1) * math.log(1e3)
    assert ss.fit_level(y, np.zeros((len(y), 0)), g).loglike - shift == \
        pytest.approx(ref0, abs=1e-3)
    assert ss.fit_level(y, x, g).loglike - shift == pytest.approx(ref1, abs=1e-3)


def test_fit_recovers_white_and_walk():
    rng = np.random.default_rng(2)
    g = _groups(n=2000)
    fit = ss.fit_level(_null_record(rng, g), np.zeros((2000, 0)), g)
    assert math.sqrt(fit.white_var_rad2_s2) == pytest.approx(1e-3, rel=0.1)
    assert math.sqrt(fit.rw_var_rad2_s3) == pytest.approx(2e-5, rel=0.25)


def test_cap_binds_and_is_reported():
    rng = np.random.default_rng(3)
    g = _groups()
    fit = ss.fit_level(_null_record(rng, g), np.zeros((300, 0)), g, rw_cap=(5e-6) ** 2)
    assert fit.capped and fit.rw_var_rad2_s3 == pytest.approx(25e-12)


def test_asymptotic_level_on_the_null():
    """A column with no effect: LR ~ chi^2_1, about 5 % of p-values below 0.05."""
    rng = np.random.default_rng(4)
    g = _groups(n=200)
    x = np.interp(np.arange(200), [0, 50, 100, 150, 199], [0, 1, 0, 1, 0])[:, None]
    p = [ss.lr_test(_null_record(rng, g), np.zeros((200, 0)), x, g, rng, n_boot=0).p_value
         for _ in range(200)]
    assert 0.01 <= np.mean(np.array(p) < 0.05) <= 0.11


def test_bootstrap_bartlett_factor_and_detection():
    """A cycle-shaped effect of 3x the walk's excursion is found; the factor is near 1."""
    rng = np.random.default_rng(5)
    g = _groups()
    x = np.interp(np.arange(300), [0, 75, 150, 225, 299], [0, 1, 0, 1, 0])[:, None]
    y = _null_record(rng, g) + 3.0 * 2e-5 * math.sqrt(300.0) * x[:, 0]
    res = ss.lr_test(y, np.zeros((300, 0)), x, g, rng)
    assert res.bootstrapped and 0.5 < res.bartlett < 2.0
    assert res.p_value < 1e-4 and res.alt.beta[0] > 0.0
    assert 0.0 < res.gain_predictive < 1.0


def test_bootstrap_skipped_where_it_cannot_change_the_answer():
    rng = np.random.default_rng(6)
    g = _groups()
    x = np.arange(300.0)[:, None]
    res = ss.lr_test(_null_record(rng, g), np.zeros((300, 0)), np.sin(x / 7.0), g, rng,
                     decide_at=1e-12)
    assert not res.bootstrapped


def test_groups_validated():
    with pytest.raises(ValueError, match='count'):
        ss.Groups(np.zeros(10), np.ones(10), np.arange(10.0))
    with pytest.raises(ValueError, match='time_s'):
        ss.Groups(np.ones(10), np.ones(10), np.zeros(10))


def test_random_walk_cap_bounds_the_walk_and_ignores_a_slow_cycle():
    rng = np.random.default_rng(7)
    dt, n, k = 0.01, 360_000, 1e-5
    t = np.arange(n) * dt
    noise = rng.normal(0.0, 3e-3, n) + np.cumsum(rng.normal(0.0, k * math.sqrt(dt), n))
    cap = noise_model.random_walk_cap(noise, t, dt, n * dt)
    assert cap >= k ** 2
    # a tempco over two chamber cycles: its walk-like look at long averaging times
    # does not reach the cap, set at averaging times up to 100 s
    cycle = 2e-4 * np.interp(t % 1800.0, [0, 270, 630, 1170, 1530, 1800], [0, 0, 1, 1, 0, 0])
    assert noise_model.random_walk_cap(noise + cycle, t, dt, n * dt) < 4.0 * cap
