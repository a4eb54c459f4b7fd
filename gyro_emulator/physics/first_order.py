"""
Lumped parameters and first-order response of the vibratory gyroscope.

Equations are those of Patel & McCluskey, "Modeling and Simulation of the MEMS
Vibratory Gyroscope" (Eq 5-22), as reconstructed in ``docs/physics.md``.
Every function is vectorised: device fields, rates and temperatures broadcast
against each other with numpy rules. All quantities are SI; temperatures are
degrees Celsius at the interface and kelvin inside the gas laws.

The model of motion (Eq 3-4, rotating frame)::

    M x'' + C_d x' + k_x x = F_d sin(w_x t) + 2 M Omega y'
    M y'' + C_s y' + k_y y =                - 2 M Omega x'

is solved here to first order: drive at resonance, Coriolis force at the sense
resonance. ``gyro_emulator.physics.dynamics`` solves it exactly.
"""

from dataclasses import dataclass

from gyro_emulator.physics.params import SILICON_YOUNGS_TEMP_COEFF_PER_K
from gyro_emulator.units import (AVOGADRO_1_MOL, celsius_to_kelvin,
                                 GAS_CONSTANT_J_MOL_K, VACUUM_PERMITTIVITY_F_M)
from gyro_emulator.validation import check_temperature_c
import numpy as np


def _a(x):
    return np.asarray(x, dtype=float)


# --- Eq 5: mass ------------------------------------------------------------

def plate_area_m2(geometry):
    """
    Area of the proof-mass plate and its frames, m^2 (A_plate, Eq 5, 9).

    The plate of side s is surrounded by ``frame_count`` frames of width w,
    each after a clearance c: frame i spans from d_i + 2c to d_i + 2c + 2w.
    """
    g = geometry
    side = _a(g.plate_side_m)
    area = side ** 2
    inner = side
    for i in range(int(np.max(g.frame_count))):
        opening = inner + 2.0 * _a(g.clearance_m)
        outer = opening + 2.0 * _a(g.frame_width_m)
        area = area + np.where(i < _a(g.frame_count), outer ** 2 - opening ** 2,
                               0.0)
        inner = np.where(i < _a(g.frame_count), outer, inner)
    return area


def structure_area_m2(geometry):
    """
    Net area of the moving structure, m^2 (Eq 5's bracket).

    A_plate + A_beams + A_fingers - A_holes, with 4 + 4 suspension beams and
    the moving fingers of the drive and sense combs.
    """
    g = geometry
    beams = 4.0 * (_a(g.beam1_width_m) * _a(g.beam1_length_m)
                   + _a(g.beam2_width_m) * _a(g.beam2_length_m))
    fingers = _a(g.finger_width_m) * (
        _a(g.drive_finger_count) * _a(g.drive_finger_length_m)
        + _a(g.sense_finger_count) * _a(g.sense_finger_length_m))
    holes = _a(g.hole_count) * _a(g.hole_side_m) ** 2
    return plate_area_m2(g) + beams + fingers - holes


def mass_kg(geometry, material):
    """Suspended mass M = rho t (A_plate + A_beams + A_fingers - A_holes), kg (Eq 5)."""
    return _a(material.density_kg_m3) * _a(geometry.thickness_m) * \
        structure_area_m2(geometry)


# --- Eq 6, 7, 22: stiffness and frequency ----------------------------------

def youngs_modulus_pa(material, temp_c):
    """
    Young's modulus E(T), Pa.

    ``paper``: E(T) = E_s + dE/dT (T - T_s) (Eq 22); ``silicon``: E(T) =
    E_s (1 + a (T - T_s)), a = -60 ppm/K (single-crystal silicon; see
    :class:`gyro_emulator.physics.params.Material`).
    """
    if material.youngs_modulus_law == 'silicon':
        return _a(material.youngs_modulus_pa) * (1.0 + SILICON_YOUNGS_TEMP_COEFF_PER_K * (
            _a(temp_c) - _a(material.youngs_ref_temp_c)))
    return _a(material.youngs_modulus_pa) + _a(material.youngs_temp_coeff_pa_k) * (
        _a(temp_c) - _a(material.youngs_ref_temp_c))


def stiffness_n_m(geometry, material, temp_c):
    """
    Suspension stiffness K, N/m (Eq 6, with E(T) from Eq 22).

    1/K = l1^3 / (4 E t w1^3) + l2^3 / (4 E t w2^3): four beams of type 1 in
    series with four of type 2. The drive and sense suspensions are the same
    beams, so k_x = k_y.
    """
    e_t = 4.0 * youngs_modulus_pa(material, temp_c) * _a(geometry.thickness_m)
    compliance = (_a(geometry.beam1_length_m) ** 3
                  / (e_t * _a(geometry.beam1_width_m) ** 3)
                  + _a(geometry.beam2_length_m) ** 3
                  / (e_t * _a(geometry.beam2_width_m) ** 3))
    return 1.0 / compliance


def resonant_frequency_hz(stiffness, mass):
    """Natural frequency f = sqrt(K/M) / (2 pi), Hz (Eq 7)."""
    return np.sqrt(_a(stiffness) / _a(mass)) / (2.0 * np.pi)


# --- Eq 8-11: gas and damping ----------------------------------------------

def gas_pressure_pa(gas, temp_c):
    """
    Cavity pressure at ``temp_c``, Pa.

    A vented cavity holds ``pressure_pa``; a sealed cavity keeps its number
    density, so P = P_ref T / T_ref (ideal gas).
    """
    p_ref = _a(gas.pressure_pa)
    if gas.cavity == 'sealed':
        return p_ref * celsius_to_kelvin(temp_c) / celsius_to_kelvin(
            gas.pressure_ref_temp_c)
    return p_ref * np.ones_like(_a(temp_c))


def mean_free_path_m(gas, temp_c):
    """Mean free path lambda = R T / (sqrt(2) pi D^2 N_A P), m (Eq 8)."""
    temp_k = celsius_to_kelvin(temp_c)
    return GAS_CONSTANT_J_MOL_K * temp_k / (
        np.sqrt(2.0) * np.pi * _a(gas.molecule_diameter_m) ** 2
        * AVOGADRO_1_MOL * gas_pressure_pa(gas, temp_c))


def knudsen_number(geometry, gas, temp_c):
    """Knudsen number Kn = lambda / L_c (Eq 8)."""
    return mean_free_path_m(gas, temp_c) / _a(geometry.flow_length_m)


def viscosity_pa_s(gas, temp_c):
    """
    Dynamic viscosity of the gas, Pa s.

    ``constant``: mu = mu_ref at any temperature (the paper's assumption).
    ``sutherland``: mu = mu_ref (T/T_ref)^1.5 (T_ref + S) / (T + S), with
    S = ``sutherland_constant_k`` (110.4 K for air; White, Viscous Fluid Flow).
    """
    mu_ref = _a(gas.viscosity_pa_s)
    if gas.viscosity_law == 'constant':
        return mu_ref * np.ones_like(_a(temp_c))
    temp_k = celsius_to_kelvin(temp_c)
    ref_k = celsius_to_kelvin(gas.viscosity_ref_temp_c)
    s_k = _a(gas.sutherland_constant_k)
    return mu_ref * (temp_k / ref_k) ** 1.5 * (ref_k + s_k) / (temp_k + s_k)


def proof_mass_damping_n_s_m(geometry, gas, temp_c, knudsen=None, viscosity=None):
    """
    Slide-film damping under the plate, C = mu A / (h (1 + 2 Kn)), N s/m (Eq 9).

    ``knudsen`` and ``viscosity``, when given, are Kn and mu already computed
    for the same geometry, gas and temperature (they are not recomputed).
    """
    kn = knudsen_number(geometry, gas, temp_c) if knudsen is None else knudsen
    mu = viscosity_pa_s(gas, temp_c) if viscosity is None else viscosity
    return mu * plate_area_m2(geometry) / (
        _a(geometry.substrate_gap_m) * (1.0 + 2.0 * kn))


def comb_damping_n_s_m(geometry, gas, temp_c, capacitor_count, overlap_m,
                       mean_free_path=None, viscosity=None):
    """
    Comb slide-film damping C = mu N l t / (g_c + 2 lambda), N s/m (Eq 10).

    ``mean_free_path`` and ``viscosity``, when given, are lambda and mu
    already computed for the same gas and temperature.
    """
    lam = mean_free_path_m(gas, temp_c) if mean_free_path is None else mean_free_path
    mu = viscosity_pa_s(gas, temp_c) if viscosity is None else viscosity
    return mu * _a(capacitor_count) * _a(overlap_m) \
        * _a(geometry.thickness_m) / (_a(geometry.comb_gap_m) + 2.0 * lam)


def drive_damping_n_s_m(geometry, gas, temp_c):
    """Drive-mode damping C_drive = C_proof + C_comb,drive, N s/m (Eq 11)."""
    return proof_mass_damping_n_s_m(geometry, gas, temp_c) + comb_damping_n_s_m(
        geometry, gas, temp_c, geometry.drive_capacitor_count,
        geometry.drive_overlap_m)


def sense_damping_n_s_m(geometry, gas, temp_c):
    """
    Sense-mode damping C_sense = C_proof + C_comb,sense, N s/m (Eq 11).

    The printed Eq 11 sets C_sense = C_drive, but Table 1's C_sense (7.94e-6)
    needs the sense comb's own slide-film damping; see docs/physics.md.
    """
    return proof_mass_damping_n_s_m(geometry, gas, temp_c) + comb_damping_n_s_m(
        geometry, gas, temp_c, geometry.sense_capacitor_count,
        geometry.sense_overlap_m)


def permittivity_f_m(gas):
    """Permittivity of the cavity gas eps = eps_r eps_0, F/m."""
    return _a(gas.relative_permittivity) * VACUUM_PERMITTIVITY_F_M


# --- Eq 12: drive force ----------------------------------------------------

def comb_drive_force_n(geometry, gas, drive):
    """Comb-drive force F_d = 2.28 N eps t V_dc V_ac / g_c, N (Eq 12)."""
    return _a(drive.comb_force_factor) * _a(geometry.drive_capacitor_count) \
        * permittivity_f_m(gas) * _a(geometry.thickness_m) \
        * _a(drive.dc_voltage_v) * _a(drive.ac_voltage_v) / _a(geometry.comb_gap_m)


def quality_factor(stiffness, mass, damping):
    """Quality factor Q = sqrt(K M) / C (Eq 14, 19)."""
    return np.sqrt(_a(stiffness) * _a(mass)) / _a(damping)


def differential_capacitance_f(geometry, gas, displacement_m):
    """Capacitance change dC = 2 eps l_pc t y / g_c^2, F (Eq 21)."""
    return 2.0 * permittivity_f_m(gas) * _a(geometry.sense_overlap_m) \
        * _a(geometry.thickness_m) * _a(displacement_m) / _a(geometry.comb_gap_m) ** 2


# --- Eq 13-21: the first-order response ------------------------------------

@dataclass(frozen=True)
class LumpedParameters:
    """Lumped parameters of a device at one temperature (Eq 5-12), SI units."""

    mass_kg: np.ndarray
    stiffness_x_n_m: np.ndarray
    stiffness_y_n_m: np.ndarray
    freq_x_hz: np.ndarray
    freq_y_hz: np.ndarray
    mean_free_path_m: np.ndarray
    knudsen: np.ndarray
    viscosity_pa_s: np.ndarray
    damping_proof_n_s_m: np.ndarray
    damping_comb_drive_n_s_m: np.ndarray
    damping_comb_sense_n_s_m: np.ndarray
    damping_drive_n_s_m: np.ndarray
    damping_sense_n_s_m: np.ndarray
    drive_force_n: np.ndarray
    q_drive: np.ndarray
    q_sense: np.ndarray


def lumped_parameters(device, temp_c=25.0):
    """
    Evaluate Eq 5-12, 14 and 19 for ``device`` at die temperature ``temp_c``.

    Parameters
    ----------
    device : gyro_emulator.physics.params.Device
        The device (fields may be arrays).
    temp_c : float or array_like
        Die temperature, deg C; must lie in ``MODEL_TEMP_RANGE_C``.

    Returns
    -------
    LumpedParameters

    """
    check_temperature_c(temp_c, 'lumped_parameters')
    g, m, gas = device.geometry, device.material, device.gas
    mass = mass_kg(g, m)
    k = stiffness_n_m(g, m, temp_c)
    lam = mean_free_path_m(gas, temp_c)         # once: every damping term uses it
    mu = viscosity_pa_s(gas, temp_c)
    kn = lam / _a(g.flow_length_m)
    c_proof = proof_mass_damping_n_s_m(g, gas, temp_c, kn, mu)
    c_comb_d = comb_damping_n_s_m(g, gas, temp_c, g.drive_capacitor_count,
                                  g.drive_overlap_m, lam, mu)
    c_comb_s = comb_damping_n_s_m(g, gas, temp_c, g.sense_capacitor_count,
                                  g.sense_overlap_m, lam, mu)
    c_d = c_proof + c_comb_d
    c_s = c_proof + c_comb_s
    f = resonant_frequency_hz(k, mass)
    return LumpedParameters(
        mass_kg=mass, stiffness_x_n_m=k, stiffness_y_n_m=k, freq_x_hz=f,
        freq_y_hz=f, mean_free_path_m=lam, knudsen=kn, viscosity_pa_s=mu,
        damping_proof_n_s_m=c_proof, damping_comb_drive_n_s_m=c_comb_d,
        damping_comb_sense_n_s_m=c_comb_s, damping_drive_n_s_m=c_d,
        damping_sense_n_s_m=c_s,
        drive_force_n=comb_drive_force_n(g, gas, device.drive),
        q_drive=quality_factor(k, mass, c_d), q_sense=quality_factor(k, mass, c_s))


@dataclass(frozen=True)
class FirstOrderResponse:
    """First-order drive and sense response (Eq 13-21), SI units."""

    params: LumpedParameters
    rate_rad_s: np.ndarray
    drive_static_m: np.ndarray
    drive_amplitude_m: np.ndarray
    drive_velocity_m_s: np.ndarray
    coriolis_force_n: np.ndarray
    sense_static_m: np.ndarray
    sense_amplitude_m: np.ndarray
    capacitance_change_f: np.ndarray


def first_order_response(device, rate_rad_s, temp_c=25.0):
    """
    First-order solution of Eq 3-4 for a rate and a die temperature.

    X_static = F_d / k_x, X_drive = X_static Q_d (Eq 13-15);
    V_drive = 2 pi f_x X_drive (Eq 16); F_c = 2 M Omega V_drive (Eq 17);
    Y_static = F_c / k_y, Y_sense = Y_static Q_s (Eq 18-20); dC (Eq 21).
    Signs follow the rate: a negative rate gives a negative Y_sense and dC.

    Parameters
    ----------
    device : gyro_emulator.physics.params.Device
        The device (fields may be arrays).
    rate_rad_s : float or array_like
        True angular rate about the sense axis, rad/s.
    temp_c : float or array_like
        Die temperature, deg C.

    Returns
    -------
    FirstOrderResponse

    """
    p = lumped_parameters(device, temp_c)
    rate = _a(rate_rad_s)
    x_static = p.drive_force_n / p.stiffness_x_n_m
    x_drive = x_static * p.q_drive
    v_drive = x_drive * 2.0 * np.pi * p.freq_x_hz
    f_c = 2.0 * p.mass_kg * rate * v_drive
    y_static = f_c / p.stiffness_y_n_m
    y_sense = y_static * p.q_sense
    return FirstOrderResponse(
        params=p, rate_rad_s=rate, drive_static_m=x_static,
        drive_amplitude_m=x_drive, drive_velocity_m_s=v_drive,
        coriolis_force_n=f_c, sense_static_m=y_static,
        sense_amplitude_m=y_sense,
        capacitance_change_f=differential_capacitance_f(
            device.geometry, device.gas, y_sense))


def sense_scale_factor_m_per_rad_s(device, temp_c=25.0):
    """
    First-order scale factor Y_sense / Omega, m per rad/s.

    Equal to 2 M^1.5 F_d / (C_drive C_sense sqrt(k_y)) (from Eq 13-20).
    """
    return first_order_response(device, 1.0, temp_c).sense_amplitude_m


def scale_factor_ratio(device, temp_c, calibration_temp_c=None):
    """
    Scale factor at ``temp_c`` relative to the calibration temperature.

    This is the apparent-rate gain of a part calibrated at
    ``calibration_temp_c`` (default ``device.calibration_temp_c``) and
    operated at ``temp_c`` (the quantity plotted in the paper's Fig 6).
    """
    cal = device.calibration_temp_c if calibration_temp_c is None \
        else calibration_temp_c
    return sense_scale_factor_m_per_rad_s(device, temp_c) / \
        sense_scale_factor_m_per_rad_s(device, cal)


def apparent_rate_rad_s(device, rate_rad_s, temp_c, calibration_temp_c=None):
    """
    Rate a part calibrated at ``calibration_temp_c`` reports at ``temp_c``.

    Omega_apparent = Omega Y_sense(T) / Y_sense(T_cal) (Fig 6).
    """
    return _a(rate_rad_s) * scale_factor_ratio(device, temp_c,
                                               calibration_temp_c)
