"""
Reference integration of Eq 3-4 in time, for the tests and the benchmark only.

scipy's ``solve_ivp`` (DOP853, an adaptive 8th-order Runge-Kutta) of the
two-mode equations from rest, with tight tolerances: an independent check
of the exact per-cycle map of ``gyro_emulator.physics.time_domain``. The
product does not use it.
"""

import math

from gyro_emulator.physics import time_domain
import numpy as np
from scipy.integrate import solve_ivp


def simulate_reference(device, duration_s, rate_rad_s=0.0, temp_c=25.0, split_hz=0.0,
                       rtol=1e-12):
    """
    Integrate Eq 3-4 from rest with DOP853 (Hairer, Norsett and Wanner 1993).

    Open-loop drive F_d sin(w_x t), constant rate and temperature:
    x'' = F_d/M sin(w_x t) - C_d/M x' - K_x/M x + 2 Omega y',
    y'' = -C_s/M y' - K_y/M y - 2 Omega x'.

    Parameters
    ----------
    device : gyro_emulator.physics.params.Device
        The device (scalar fields).
    duration_s : float
        Simulated time, s (whole drive cycles).
    rate_rad_s : float
        True rate, rad/s.
    temp_c : float
        Die temperature, deg C.
    split_hz : float
        Drive-sense split f_y - f_x, Hz.
    rtol : float
        Relative tolerance of the integrator; the absolute tolerance is
        ``rtol`` times the drive's resonant amplitude F_d / (C_d w_x) (and
        w_x times it for the velocities).

    Returns
    -------
    numpy.ndarray
        (x, x', y, y') at the start of each drive cycle, shape (n_cycles + 1, 4).

    """
    mech = time_domain._mechanics(device, temp_c, split_hz, None)
    w = 2.0 * np.pi * mech.drive_freq_hz
    cycles = max(1, int(math.ceil(duration_s * mech.drive_freq_hz - 1e-9)))
    inv_m = 1.0 / mech.mass
    kx, ky, cd, cs = (mech.k_x * inv_m, mech.k_y * inv_m, mech.c_d * inv_m,
                      mech.c_s * inv_m)
    fm = mech.force * inv_m
    two_r = 2.0 * float(rate_rad_s)

    def deriv(t, s):
        x, vx, y, vy = s
        return (vx, fm * math.sin(w * t) - cd * vx - kx * x + two_r * vy,
                vy, -cs * vy - ky * y - two_r * vx)

    times = np.arange(cycles + 1) / mech.drive_freq_hz
    amplitude = fm / (cd * w)
    atol = rtol * amplitude * np.array([1.0, w, 1.0, w])
    sol = solve_ivp(deriv, (0.0, times[-1]), np.zeros(4), method='DOP853',
                    t_eval=times, rtol=rtol, atol=atol)
    if not sol.success:
        raise RuntimeError(f'simulate_reference: {sol.message}')
    return sol.y.T
