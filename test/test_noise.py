"""Noise generators: exact discretisation, block invariance, flicker, Brownian ARW."""

import math

from gyro_emulator.physics import first_order
from gyro_emulator.physics.presets import PAPER_DEVICE
from gyro_emulator.sensor import noise
from gyro_emulator.units import BOLTZMANN_J_K, FLICKER_FLOOR_PER_B
import noise_reference
import numpy as np
import pytest
from scipy import integrate


def _split(n, rng):
    cuts = np.sort(rng.choice(np.arange(1, n), size=7, replace=False))
    return np.split(np.arange(n), cuts)


def test_gauss_markov_exact_variance_and_correlation():
    """x[n] = phi x[n-1] + sigma sqrt(1-phi^2) w has variance sigma^2 and lag-1 corr phi."""
    rng = np.random.default_rng(1)
    dt, corr_time, sigma = 0.01, 0.05, 2.0
    phi = noise.gauss_markov_phi(corr_time, dt)
    drive = noise_reference.gauss_markov_drive_sigma(sigma, corr_time, dt)
    z = rng.standard_normal((400_000, 1))
    x, _ = noise_reference.first_order_filter(z, phi, drive, np.array([0.3 * sigma]))
    x = x[1000:, 0]
    # effective sample size ~ n (1 - phi) / (1 + phi); 5 standard errors
    n_eff = len(x) * (1 - phi) / (1 + phi)
    assert x.var() == pytest.approx(sigma ** 2, rel=5 * math.sqrt(2 / n_eff))
    lag1 = np.corrcoef(x[:-1], x[1:])[0, 1]
    assert lag1 == pytest.approx(phi, abs=5 * (1 - phi ** 2) / math.sqrt(n_eff))


def test_gauss_markov_drive_sigma_is_accurate_for_long_times():
    """The innovation sigma sqrt(1 - exp(-2 dt/T)) matches the series for T >> dt."""
    dt, t = 1e-3, 1e7
    eps = 2 * dt / t
    series = math.sqrt(eps - eps ** 2 / 2)
    assert noise_reference.gauss_markov_drive_sigma(1.0, t, dt) == pytest.approx(series, rel=1e-12)


def test_gauss_markov_avar_matches_psd_integral():
    """AVAR = 2 int S(f) sin^4(pi f tau) / (pi f tau)^2 df with S = 4 q T / (1 + (2 pi f T)^2)."""
    q, t = 1.7, 2.0
    for tau in (0.1, 3.0, 40.0):
        def integrand(f):
            return 4 * q * t / (1 + (2 * math.pi * f * t) ** 2) * math.sin(
                math.pi * f * tau) ** 4 / (math.pi * f * tau) ** 2
        num = 2 * integrate.quad(integrand, 0, np.inf, limit=1000)[0]
        assert noise.gauss_markov_avar(q, t, tau) == pytest.approx(num, rel=1e-6)


def test_random_walk_increments_and_blocks():
    rng = np.random.default_rng(2)
    z = rng.standard_normal((50_000, 3))
    walk, last = noise_reference.random_walk(z, 0.01, np.zeros(3))
    np.testing.assert_array_equal(last, walk[-1])
    inc = np.diff(walk, axis=0)
    assert inc.std() == pytest.approx(0.01, rel=0.02)
    parts, state = [], np.zeros(3)
    for idx in _split(len(z), rng):
        out, state = noise_reference.random_walk(z[idx], 0.01, state)
        parts.append(out)
    assert np.array_equal(np.concatenate(parts), walk)


def test_first_order_filter_block_invariance():
    rng = np.random.default_rng(3)
    u = rng.standard_normal((5000, 3))
    whole, _ = noise_reference.first_order_filter(u, 0.97, 0.03, np.ones(3))
    parts, last = [], np.ones(3)
    for idx in _split(len(u), rng):
        out, last = noise_reference.first_order_filter(u[idx], 0.97, 0.03, last)
        parts.append(out)
    assert np.array_equal(np.concatenate(parts), whole)


def test_flicker_single_input_gains_reproduce_the_gauss_markov_sum():
    """With shared input, sum_k x_k has autocovariance sum_k q_k phi_k^m (checked by h*h)."""
    dt = 1.0
    plan = noise.flicker_plan((2.0, 200.0), dt)
    # impulse response of the parallel sections, summed long enough to converge
    n = np.arange(20000)
    h = np.sum(plan.gains[:, np.newaxis] * plan.phi[:, np.newaxis] ** n, axis=0)
    for lag in (0, 1, 7, 50, 300):
        r = np.dot(h[:len(h) - lag], h[lag:])
        expect = noise_reference.flicker_autocovariance(plan, lag)
        assert r == pytest.approx(expect, rel=1e-9)


def test_flicker_stationary_start_has_the_stationary_variance():
    plan = noise.flicker_plan((0.01, 1.0), 1e-3)
    cov = plan.stationary_factor @ plan.stationary_factor.T
    total = np.sum(cov)              # variance of sum_k x_k
    assert total == pytest.approx(np.sum(plan.variances), rel=1e-9)


def test_flicker_allan_floor_is_flat_and_equals_0664_b():
    plan = noise.flicker_plan((0.1, 1000.0), 0.005)
    b = 3e-5
    floor = FLICKER_FLOOR_PER_B * b
    # normalised over [2 T_min, T_max / 2]: log-mean equals the floor
    taus = np.logspace(np.log10(0.2), np.log10(500.0), 41)
    adev = np.sqrt(noise_reference.flicker_avar(plan, b, taus))
    assert np.exp(np.mean(np.log(adev))) == pytest.approx(floor, rel=1e-9)
    # one term per decade: within 5 % of flat over [3 T_min, T_max / 3]
    taus = np.logspace(np.log10(0.3), np.log10(333.0), 30)
    adev = np.sqrt(noise_reference.flicker_avar(plan, b, taus))
    assert np.max(np.abs(adev / floor - 1)) < 0.05


def test_flicker_simulation_variance_and_blocks():
    rng = np.random.default_rng(4)
    plan = noise.flicker_plan((0.01, 0.1), 1e-3)
    b = np.array([1.0, 2.0, 3.0])
    state = noise.flicker_initial_state(plan, b, rng.standard_normal((len(plan.phi), 3)))
    z = rng.standard_normal((200_000, 3))
    whole, _ = noise_reference.flicker(z, plan, b, state)
    # each axis: variance sum_k q_k B^2; longest correlation 0.1 s = 100 samples
    n_eff = len(z) / (2 * 100)
    np.testing.assert_allclose(whole.var(axis=0), np.sum(plan.variances) * b ** 2,
                               rtol=5 * math.sqrt(2 / n_eff))
    parts, st = [], state
    for idx in _split(len(z), rng):
        out, st = noise_reference.flicker(z[idx], plan, b, st)
        parts.append(out)
    assert np.array_equal(np.concatenate(parts), whole)


def test_brownian_arw_from_table1_numbers():
    """N = sqrt(4 k_B T C_sense) / (2 M V_drive) with the paper's Table 1 values (25 C)."""
    c_sense, mass, x_drive, f = 7.94e-6, 4.0e-9, 6.39e-6, 14000.0
    expect = math.sqrt(4 * BOLTZMANN_J_K * 298.15 * c_sense) / (
        2 * mass * x_drive * 2 * math.pi * f)
    got = float(noise.brownian_arw_rad_s_sqrt_hz(PAPER_DEVICE, 25.0))
    assert got == pytest.approx(expect, rel=0.01)     # Table 1 is rounded to 3 digits


def test_brownian_arw_temperature_dependence_follows_the_physics():
    temps = np.array([-40.0, 25.0, 85.0])
    got = noise.brownian_arw_rad_s_sqrt_hz(PAPER_DEVICE, temps)
    r = first_order.first_order_response(PAPER_DEVICE, 1.0, temps)
    kelvin = temps + 273.15
    expect = np.sqrt(kelvin * r.params.damping_sense_n_s_m) / (
        r.params.mass_kg * r.drive_velocity_m_s)
    np.testing.assert_allclose(got / got[1], expect / expect[1], rtol=1e-12)
