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
