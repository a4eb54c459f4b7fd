"""Datasheet unit conversions (gyro_emulator.units): known values, both ways."""

import math

from gyro_emulator import units
import numpy as np
import pytest

DEG = math.pi / 180.0

# (forward, inverse, datasheet value, SI value computed by hand here)
PAIRS = [
    # 1 deg/sqrt(h) = 1 deg / sqrt(3600 s) = (1/60) deg/sqrt(s)
    (units.arw_deg_sqrt_h_to_rad_s_sqrt_hz, units.rad_s_sqrt_hz_to_arw_deg_sqrt_h,
     1.0, DEG / 60.0),
    (units.deg_s_sqrt_hz_to_rad_s_sqrt_hz, units.rad_s_sqrt_hz_to_deg_s_sqrt_hz,
     0.005, 0.005 * DEG),
    # 3600 deg/h = 1 deg/s
    (units.deg_h_to_rad_s, units.rad_s_to_deg_h, 3600.0, DEG),
    # 1 deg/h/sqrt(h) = (1/3600) deg/s / (60 sqrt(s))
    (units.rrw_deg_h_sqrt_h_to_rad_s_sqrt_s, units.rad_s_sqrt_s_to_rrw_deg_h_sqrt_h,
     1.0, DEG / 3600.0 / 60.0),
    (units.g_to_m_s2, units.m_s2_to_g, 2.0, 2.0 * 9.80665),
    (units.deg_s_per_g_to_rad_s_per_m_s2, units.rad_s_per_m_s2_to_deg_s_per_g,
     0.1, 0.1 * DEG / 9.80665),
    (units.ppm_to_ratio, units.ratio_to_ppm, 500.0, 5e-4),
    (units.two_sided_to_one_sided_density, units.one_sided_to_two_sided_density,
     1.0, math.sqrt(2.0)),
]


@pytest.mark.parametrize('forward,inverse,value,expected', PAIRS,
                         ids=[p[0].__name__ for p in PAIRS])
def test_known_value_and_round_trip(forward, inverse, value, expected):
    assert forward(value) == pytest.approx(expected, rel=1e-12)
    assert inverse(expected) == pytest.approx(value, rel=1e-12)
    values = np.array([0.0, 1e-6, 3.7, -2.5])
    np.testing.assert_allclose(inverse(forward(values)), values, rtol=1e-12, atol=0)


def test_datasheet_density_equals_arw_times_sixty():
    """MPU-6050: 0.005 deg/s/sqrt(Hz) is N = 0.3 deg/sqrt(h) (1 sqrt(h) = 60 sqrt(s))."""
    n = units.deg_s_sqrt_hz_to_rad_s_sqrt_hz(0.005)
    assert units.rad_s_sqrt_hz_to_arw_deg_sqrt_h(n) == pytest.approx(0.3, rel=1e-12)


def test_one_sided_psd_is_twice_two_sided():
    """S_one(f) = 2 S_two(f): the squared amplitude densities differ by 2."""
    two = 3e-4
    one = units.two_sided_to_one_sided_density(two)
    assert one ** 2 == pytest.approx(2.0 * two ** 2, rel=1e-12)


def test_sample_sigma_both_ways():
    # sigma = N sqrt(fs): N = 1e-3 rad/s/sqrt(Hz) at 100 Hz -> 1e-2 rad/s
    assert units.density_to_sample_sigma(1e-3, 100.0) == pytest.approx(1e-2, rel=1e-12)
    assert units.sample_sigma_to_density(1e-2, 100.0) == pytest.approx(1e-3, rel=1e-12)
    # K sqrt(dt): K = 2e-5 rad/s/sqrt(s) at 400 Hz -> 1e-6 rad/s per step
    assert units.rrw_to_step_sigma(2e-5, 400.0) == pytest.approx(1e-6, rel=1e-12)


def test_sample_sigma_gives_the_density_back_statistically():
    """White noise drawn with sigma = N sqrt(fs) has the Allan deviation N/sqrt(tau)."""
    rng = np.random.default_rng(5)
    fs, density = 200.0, 2e-3
    x = rng.standard_normal(400_000) * units.density_to_sample_sigma(density, fs)
    # mean of 1 s blocks has standard deviation N / sqrt(1 s)
    means = x.reshape(-1, int(fs)).mean(axis=1)
    # 2000 blocks: the sample std has a relative standard error of 1/sqrt(2*2000)
    assert means.std(ddof=1) == pytest.approx(density, rel=5.0 / math.sqrt(4000))


def test_flicker_floor_constant():
    assert units.FLICKER_FLOOR_PER_B == pytest.approx(
        math.sqrt(2.0 * math.log(2.0) / math.pi), rel=1e-15)
    assert units.FLICKER_FLOOR_PER_B == pytest.approx(0.664, abs=5e-4)
