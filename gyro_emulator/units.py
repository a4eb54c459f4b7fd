"""
Physical constants and unit conversions, in one place.

Everything inside gyro_emulator is SI (rad/s for rates, as sensor_msgs/Imu
requires; degrees Celsius for temperatures, as sensor_msgs/Temperature does).
Datasheet units enter and leave only through the functions here.
"""

import numpy as np

#: Molar gas constant, J/(mol K) (CODATA 2018, exact).
GAS_CONSTANT_J_MOL_K = 8.314462618
#: Avogadro constant, 1/mol (SI 2019, exact).
AVOGADRO_1_MOL = 6.02214076e23
#: Boltzmann constant, J/K (SI 2019, exact).
BOLTZMANN_J_K = 1.380649e-23
#: Vacuum permittivity, F/m (CODATA 2018).
VACUUM_PERMITTIVITY_F_M = 8.8541878128e-12
#: Offset between the Celsius and Kelvin scales, K.
ZERO_CELSIUS_K = 273.15
#: Standard gravity, m/s^2 (CGPM 1901).
STANDARD_GRAVITY_M_S2 = 9.80665
#: One standard atmosphere, Pa.
STANDARD_ATMOSPHERE_PA = 101325.0

SECONDS_PER_HOUR = 3600.0
#: The sensor frame's axes, in the order of every 3-vector (REP 103: x forward, y left, z up).
AXES = ('x', 'y', 'z')
#: Nanoseconds per second: ROS and MCAP stamps are integer nanoseconds.
NS_PER_S = 1_000_000_000


def celsius_to_kelvin(temp_c):
    """Return the absolute temperature in K of ``temp_c`` degrees Celsius."""
    return np.asarray(temp_c, dtype=float) + ZERO_CELSIUS_K


def kelvin_to_celsius(temp_k):
    """Return degrees Celsius of the absolute temperature ``temp_k`` (K)."""
    return np.asarray(temp_k, dtype=float) - ZERO_CELSIUS_K


def deg_s_to_rad_s(rate_deg_s):
    """Convert an angular rate from deg/s to rad/s."""
    return np.deg2rad(rate_deg_s)


def rad_s_to_deg_s(rate_rad_s):
    """Convert an angular rate from rad/s to deg/s."""
    return np.rad2deg(rate_rad_s)


def rpm_to_rad_s(rate_rpm):
    """Convert revolutions per minute to rad/s (1 RPM = 2 pi / 60 rad/s)."""
    return np.asarray(rate_rpm, dtype=float) * (2.0 * np.pi / 60.0)


def rad_s_to_rpm(rate_rad_s):
    """Convert rad/s to revolutions per minute."""
    return np.asarray(rate_rad_s, dtype=float) * (60.0 / (2.0 * np.pi))


def rpm_to_deg_s(rate_rpm):
    """Convert revolutions per minute to deg/s (1 RPM = 6 deg/s)."""
    return np.asarray(rate_rpm, dtype=float) * 6.0


# --- Datasheet units of gyro errors ----------------------------------------
#
# Conventions (IEEE Std 952-1997, Annex C; NIST SP 1065):
#
# * The angle random walk coefficient N is the square root of the TWO-SIDED
#   power spectral density of the white rate noise, S(f) = N^2 for all f.
#   Its SI unit is rad/s/sqrt(Hz) (= rad/sqrt(s)); the Allan deviation of white
#   rate noise is N / sqrt(tau). Datasheets give N in deg/sqrt(h) or as a
#   "rate noise density" in deg/s/sqrt(Hz); 1 deg/sqrt(h) = 1/60 deg/s/sqrt(Hz).
# * A ONE-SIDED density (f >= 0 only, S1 = 2 S) is sqrt(2) times larger.
# * Sampled at f_s = 1/dt, white noise of two-sided density N has the exact
#   per-sample standard deviation sigma = N sqrt(f_s) = N / sqrt(dt).
# * Bias instability B is in rad/s (datasheets: deg/h); the flicker floor of
#   the Allan deviation is B sqrt(2 ln 2 / pi) = 0.664 B.
# * The rate random walk coefficient K is in rad/s/sqrt(s) (datasheets:
#   deg/h/sqrt(h)); its Allan deviation is K sqrt(tau / 3) and its exact
#   per-sample increment has standard deviation K sqrt(dt).

#: sqrt(2 ln 2 / pi): Allan deviation floor of flicker noise per unit B.
FLICKER_FLOOR_PER_B = float(np.sqrt(2.0 * np.log(2.0) / np.pi))

_DEG = np.pi / 180.0


def arw_deg_sqrt_h_to_rad_s_sqrt_hz(arw_deg_sqrt_h):
    """Convert an angle random walk N from deg/sqrt(h) to rad/s/sqrt(Hz)."""
    return np.asarray(arw_deg_sqrt_h, dtype=float) * (_DEG / 60.0)


def rad_s_sqrt_hz_to_arw_deg_sqrt_h(density_rad_s_sqrt_hz):
    """Convert a (two-sided) rate noise density rad/s/sqrt(Hz) to N in deg/sqrt(h)."""
    return np.asarray(density_rad_s_sqrt_hz, dtype=float) * (60.0 / _DEG)


def deg_s_sqrt_hz_to_rad_s_sqrt_hz(density_deg_s_sqrt_hz):
    """Convert a rate noise density from deg/s/sqrt(Hz) to rad/s/sqrt(Hz)."""
    return np.asarray(density_deg_s_sqrt_hz, dtype=float) * _DEG


def rad_s_sqrt_hz_to_deg_s_sqrt_hz(density_rad_s_sqrt_hz):
    """Convert a rate noise density from rad/s/sqrt(Hz) to deg/s/sqrt(Hz)."""
    return np.asarray(density_rad_s_sqrt_hz, dtype=float) / _DEG


def deg_h_to_rad_s(rate_deg_h):
    """Convert a rate (e.g. bias instability B) from deg/h to rad/s."""
    return np.asarray(rate_deg_h, dtype=float) * (_DEG / SECONDS_PER_HOUR)


def rad_s_to_deg_h(rate_rad_s):
    """Convert a rate from rad/s to deg/h."""
    return np.asarray(rate_rad_s, dtype=float) * (SECONDS_PER_HOUR / _DEG)


def rrw_deg_h_sqrt_h_to_rad_s_sqrt_s(rrw_deg_h_sqrt_h):
    """Convert a rate random walk K from deg/h/sqrt(h) to rad/s/sqrt(s)."""
    return np.asarray(rrw_deg_h_sqrt_h, dtype=float) * (
        _DEG / SECONDS_PER_HOUR / 60.0)


def rad_s_sqrt_s_to_rrw_deg_h_sqrt_h(rrw_rad_s_sqrt_s):
    """Convert a rate random walk K from rad/s/sqrt(s) to deg/h/sqrt(h)."""
    return np.asarray(rrw_rad_s_sqrt_s, dtype=float) * (
        SECONDS_PER_HOUR * 60.0 / _DEG)


def one_sided_to_two_sided_density(density_one_sided):
    """
    Convert an amplitude density from one-sided to two-sided convention.

    S_one(f) = 2 S_two(f) for f >= 0, so the amplitude density (the square
    root of the PSD, e.g. rad/s/sqrt(Hz)) is divided by sqrt(2).
    """
    return np.asarray(density_one_sided, dtype=float) / np.sqrt(2.0)


def two_sided_to_one_sided_density(density_two_sided):
    """Convert an amplitude density from two-sided to one-sided convention (x sqrt(2))."""
    return np.asarray(density_two_sided, dtype=float) * np.sqrt(2.0)


def density_to_sample_sigma(density_two_sided, sample_rate_hz):
    """
    Per-sample standard deviation of white noise of a given density.

    sigma = N sqrt(f_s) = N / sqrt(dt): the exact discretisation of white
    noise of two-sided density N (the average of the continuous noise over
    one sample period has this variance). Units follow the density: rad/s
    for a density in rad/s/sqrt(Hz).
    """
    return np.asarray(density_two_sided, dtype=float) * np.sqrt(
        np.asarray(sample_rate_hz, dtype=float))


def sample_sigma_to_density(sigma, sample_rate_hz):
    """Two-sided white-noise density of a per-sample sigma: N = sigma / sqrt(f_s)."""
    return np.asarray(sigma, dtype=float) / np.sqrt(
        np.asarray(sample_rate_hz, dtype=float))


def rrw_to_step_sigma(rrw_rad_s_sqrt_s, sample_rate_hz):
    """
    Per-sample increment sigma of a rate random walk: K sqrt(dt) = K / sqrt(f_s).

    Exact: a Wiener process of intensity K sampled every dt has independent
    Gaussian increments of variance K^2 dt.
    """
    return np.asarray(rrw_rad_s_sqrt_s, dtype=float) / np.sqrt(
        np.asarray(sample_rate_hz, dtype=float))


def g_to_m_s2(accel_g):
    """Convert an acceleration from standard gravities to m/s^2."""
    return np.asarray(accel_g, dtype=float) * STANDARD_GRAVITY_M_S2


def m_s2_to_g(accel_m_s2):
    """Convert an acceleration from m/s^2 to standard gravities."""
    return np.asarray(accel_m_s2, dtype=float) / STANDARD_GRAVITY_M_S2


def deg_s_per_g_to_rad_s_per_m_s2(sens_deg_s_g):
    """Convert a g-sensitivity from deg/s per g to rad/s per m/s^2."""
    return np.asarray(sens_deg_s_g, dtype=float) * (_DEG / STANDARD_GRAVITY_M_S2)


def rad_s_per_m_s2_to_deg_s_per_g(sens_rad_s_m_s2):
    """Convert a g-sensitivity from rad/s per m/s^2 to deg/s per g."""
    return np.asarray(sens_rad_s_m_s2, dtype=float) * (STANDARD_GRAVITY_M_S2 / _DEG)


def ppm_to_ratio(value_ppm):
    """Convert parts per million to a plain ratio (1 ppm = 1e-6)."""
    return np.asarray(value_ppm, dtype=float) * 1e-6


def ratio_to_ppm(ratio):
    """Convert a plain ratio to parts per million."""
    return np.asarray(ratio, dtype=float) * 1e6


def percent_to_ratio(value_pct):
    """Convert a percentage to a plain ratio (1 % = 0.01)."""
    return np.asarray(value_pct, dtype=float) * 0.01


def ratio_to_percent(ratio):
    """Convert a plain ratio to a percentage."""
    return np.asarray(ratio, dtype=float) * 100.0


# --- Datasheet units of accelerometer errors -------------------------------
#
# The same conventions as the gyro's (IEEE Std 952 terms carried over to
# specific force): the velocity random walk N is the square root of the
# TWO-SIDED power spectral density of the white acceleration noise, in
# m/s^2/sqrt(Hz) (= m/s/sqrt(s)); datasheets give it as a noise density in
# ug/sqrt(Hz) or as a VRW in m/s/sqrt(h) (1 m/s/sqrt(h) = 1/60 m/s^2/sqrt(Hz)).
# The acceleration random walk K is in m/s^3/sqrt(Hz) (= m/s^2/sqrt(s)), the
# bias instability B in m/s^2 (datasheets: mg or ug). 1 g is
# STANDARD_GRAVITY_M_S2.

def mg_to_m_s2(accel_mg):
    """Convert an acceleration (or an acceleration per K) from milli-g to m/s^2."""
    return np.asarray(accel_mg, dtype=float) * (STANDARD_GRAVITY_M_S2 * 1e-3)


def m_s2_to_mg(accel_m_s2):
    """Convert an acceleration (or an acceleration per K) from m/s^2 to milli-g."""
    return np.asarray(accel_m_s2, dtype=float) / (STANDARD_GRAVITY_M_S2 * 1e-3)


def ug_sqrt_hz_to_m_s2_sqrt_hz(density_ug_sqrt_hz):
    """Convert an acceleration noise density from micro-g/sqrt(Hz) to m/s^2/sqrt(Hz)."""
    return np.asarray(density_ug_sqrt_hz, dtype=float) * (STANDARD_GRAVITY_M_S2 * 1e-6)


def m_s2_sqrt_hz_to_ug_sqrt_hz(density_m_s2_sqrt_hz):
    """Convert an acceleration noise density from m/s^2/sqrt(Hz) to micro-g/sqrt(Hz)."""
    return np.asarray(density_m_s2_sqrt_hz, dtype=float) / (STANDARD_GRAVITY_M_S2 * 1e-6)


def vrw_m_s_sqrt_h_to_m_s2_sqrt_hz(vrw_m_s_sqrt_h):
    """Convert a velocity random walk from m/s/sqrt(h) to m/s^2/sqrt(Hz) (divide by 60)."""
    return np.asarray(vrw_m_s_sqrt_h, dtype=float) / 60.0


def m_s2_sqrt_hz_to_vrw_m_s_sqrt_h(density_m_s2_sqrt_hz):
    """Convert a (two-sided) acceleration noise density m/s^2/sqrt(Hz) to a VRW in m/s/sqrt(h)."""
    return np.asarray(density_m_s2_sqrt_hz, dtype=float) * 60.0
