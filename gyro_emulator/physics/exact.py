"""
Exact steady state of the paper's 2-DOF equations of motion (Eq 3-4).

Harmonic balance of::

    M x'' + C_d x' + k_x x = F sin(w t) + 2 M Omega y'          (Eq 3)
    M y'' + C_s y' + k_y y =            - 2 M Omega x'          (Eq 4)

including the Coriolis back-action on the drive: a complex 2x2 solve per
frequency, with the lumped parameters of
:func:`gyro_emulator.physics.first_order.lumped_parameters` (Eq 5-12). A
drive-sense split keeps ``k_x`` and sets ``k_y = M (2 pi (f_x + split_hz))^2``
(:func:`sense_frequency_hz`). Demodulation convention: see
:mod:`gyro_emulator.physics.dynamics`.
"""

from dataclasses import dataclass

from gyro_emulator.physics import first_order
from gyro_emulator.validation import check_range
import numpy as np


def as_float(x):
    """Return ``x`` as a float array."""
    return np.asarray(x, dtype=float)


def sense_frequency_hz(owner, params, split_hz):
    """Validate ``split_hz`` against f_x and return ``(split, f_y)``, Hz."""
    split = as_float(split_hz)
    low = float(-np.min(params.freq_x_hz))
    check_range(owner, 'split_hz', split, low, None, 'Hz')
    return split, params.freq_x_hz + split


@dataclass(frozen=True)
class ExactSteadyState:
    """
    Harmonic steady state of Eq 3-4 (SI units; arrays broadcast).

    ``sense_amplitude_m`` is |Y| signed by the rate (like Eq 20's Y_sense);
    ``sense_phase_rad`` is the phase of the sense motion relative to the drive
    velocity with the rate's sign removed (+pi/2 for matched modes).
    ``sense_in_phase_m`` / ``sense_quadrature_m`` are what a synchronous
    demodulator referenced to the drive force reads (module docstring).
    """

    params: first_order.LumpedParameters
    rate_rad_s: np.ndarray
    split_hz: np.ndarray
    drive_freq_hz: np.ndarray
    sense_freq_hz: np.ndarray
    stiffness_y_n_m: np.ndarray
    drive_force_n: np.ndarray
    drive_amplitude_m: np.ndarray
    drive_phase_rad: np.ndarray
    drive_velocity_m_s: np.ndarray
    sense_amplitude_m: np.ndarray
    sense_phase_rad: np.ndarray
    sense_in_phase_m: np.ndarray
    sense_quadrature_m: np.ndarray
    first_order_m: np.ndarray
    ratio_to_first_order: np.ndarray


def exact_steady_state(device, rate_rad_s, temp_c=25.0, split_hz=0.0,
                       drive_freq_hz=None, drive_force_n=None):
    """
    Exact harmonic steady state of Eq 3-4 with a drive-sense split.

    With x = Re(X e^{jwt}), y = Re(Y e^{jwt}) and the force F sin(wt)
    (phasor -jF), Eq 3-4 become the complex linear system::

        [k_x - M w^2 + j w C_d    -2 M Omega j w      ] [X]   [-j F]
        [ 2 M Omega j w            k_y - M w^2 + j w C_s] [Y] = [ 0  ]

    solved in closed form (Cramer), so the Coriolis back-action on the drive
    is included. For matched modes at w = w_x this reduces to Eq 13-20 up to
    a factor 1 / (1 + (2 M Omega)^2 / (C_d C_s)) (about 1e-6 at 60 deg/s).

    Parameters
    ----------
    device : gyro_emulator.physics.params.Device
        The device (fields may be arrays).
    rate_rad_s : float or array_like
        True angular rate Omega, rad/s.
    temp_c : float or array_like
        Die temperature, deg C (sets the lumped parameters, Eq 5-12, 22).
    split_hz : float or array_like
        Drive-sense split f_y - f_x, Hz; must keep f_y > 0.
    drive_freq_hz : float or array_like, optional
        Drive frequency, Hz; default f_x (the drive resonance at ``temp_c``).
    drive_force_n : float or array_like, optional
        Drive force amplitude F, N; default Eq 12's F_d.

    Returns
    -------
    ExactSteadyState

    """
    owner = 'exact_steady_state'
    p = first_order.lumped_parameters(device, temp_c)
    rate = as_float(rate_rad_s)
    check_range(owner, 'rate_rad_s', rate, None, None, 'rad/s')
    split, f_y = sense_frequency_hz(owner, p, split_hz)
    if drive_freq_hz is None:
        f_d = p.freq_x_hz
    else:
        f_d = as_float(check_range(owner, 'drive_freq_hz', drive_freq_hz, 0.0, None, 'Hz'))
    force = p.drive_force_n if drive_force_n is None else as_float(
        check_range(owner, 'drive_force_n', drive_force_n, 0.0, None, 'N', False))
    m = p.mass_kg
    w = 2.0 * np.pi * f_d
    k_y = m * (2.0 * np.pi * f_y) ** 2
    z_x = p.stiffness_x_n_m - m * w ** 2 + 1j * w * p.damping_drive_n_s_m
    z_y = k_y - m * w ** 2 + 1j * w * p.damping_sense_n_s_m
    cor = 2j * m * rate * w
    x_ph = -1j * force * z_y / (z_x * z_y + cor ** 2)
    y_ph = -cor * x_ph / z_y
    first = first_order.first_order_response(device, rate, temp_c).sense_amplitude_m
    # |Y / Omega| (well defined at Omega = 0) over the first-order Eq 20 slope.
    y_per_rate = np.abs(2.0 * m * w * x_ph / z_y)
    ratio = y_per_rate / np.abs(first_order.sense_scale_factor_m_per_rad_s(device, temp_c))
    amp = np.sign(rate) * np.abs(y_ph)
    return ExactSteadyState(
        params=p, rate_rad_s=rate, split_hz=split, drive_freq_hz=f_d,
        sense_freq_hz=f_y, stiffness_y_n_m=k_y, drive_force_n=force,
        drive_amplitude_m=np.abs(x_ph),
        drive_phase_rad=np.angle(1j * x_ph),
        drive_velocity_m_s=w * np.abs(x_ph), sense_amplitude_m=amp,
        sense_phase_rad=np.broadcast_to(np.angle(-2.0 * m / z_y), y_ph.shape).copy(),
        sense_in_phase_m=y_ph.real, sense_quadrature_m=-y_ph.imag,
        first_order_m=first, ratio_to_first_order=ratio)
