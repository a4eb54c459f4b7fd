"""
Noise generators of the gyro error model, exactly discretised.

The coefficients of the generators, exactly discretised. The compiled kernel
(:mod:`gyro_emulator.sensor.kernel`) runs the recursions sample by sample
on the standard normals of the injected ``numpy.random.Generator``; it takes
its coefficients from :func:`gauss_markov_phi`, :func:`flicker_plan` and
:func:`flicker_initial_state`. Plain block versions of the same recursions
and the flicker generator's Allan variance live with the tests
(test/noise_reference.py), which check the kernel against them.

Exact discretisation at the sample period dt (no Euler steps):

* white rate noise of two-sided density N: sigma = N / sqrt(dt);
* first-order Gauss-Markov process of variance q and correlation time T:
  x[n] = phi x[n-1] + sqrt(q (1 - phi^2)) w[n], phi = exp(-dt / T);
* rate random walk K: b[n] = b[n-1] + K sqrt(dt) w[n];
* bias instability (flicker, 1/f): a sum of Gauss-Markov processes with
  correlation times one decade apart (the standard rational approximation of
  1/f noise; IEEE Std 952 Annex C, Keshner 1982), generated from ONE normal per
  sample and axis through an exact single-input representation (see
  :func:`flicker_plan`).

The mechanical-thermal (Brownian) noise of the sense mode sets the physical
floor of the angle random walk (:func:`brownian_arw_rad_s_sqrt_hz`) and that
of the proof mass the floor of the accelerometer's velocity random walk
(:func:`brownian_vrw_m_s2_sqrt_hz`).
"""

from dataclasses import dataclass

from gyro_emulator.physics import first_order
from gyro_emulator.units import (BOLTZMANN_J_K, celsius_to_kelvin, FLICKER_FLOOR_PER_B,
                                 one_sided_to_two_sided_density)
import numpy as np


def gauss_markov_phi(corr_time_s, dt_s):
    """Exact AR(1) coefficient phi = exp(-dt / T) of a Gauss-Markov process."""
    return np.exp(-np.asarray(dt_s, dtype=float) / np.asarray(corr_time_s, dtype=float))


def gauss_markov_avar(variance, corr_time_s, tau_s):
    """
    Allan variance of a first-order Gauss-Markov rate process.

    sigma^2(tau) = q (T/tau)^2 (2 tau/T - 3 + 4 e^(-tau/T) - e^(-2 tau/T))
    for steady-state variance q and correlation time T (IEEE Std 952 Annex C).
    """
    q = np.asarray(variance, dtype=float)
    t = np.asarray(corr_time_s, dtype=float)
    x = np.asarray(tau_s, dtype=float) / t
    # Series for small x avoids cancellation: (2x - 3 + 4e^-x - e^-2x)/x^2
    # = x/3 - x^2/4 + 7 x^3/60 - ...
    small = x < 1e-3
    xs = np.where(small, 1.0, x)
    exact = (2.0 * xs - 3.0 + 4.0 * np.exp(-xs) - np.exp(-2.0 * xs)) / xs ** 2
    series = x / 3.0 - x ** 2 / 4.0 + 7.0 * x ** 3 / 60.0
    return q * np.where(small, series, exact)


@dataclass(frozen=True)
class FlickerPlan:
    """
    Coefficients of the bias-instability (flicker) generator for B = 1 rad/s.

    ``corr_times_s`` are the K Gauss-Markov correlation times, ``phi`` their
    exact poles exp(-dt/T_k), ``variances`` their steady-state variances,
    ``gains`` the single-input gains c_k and ``stationary_factor`` a K x K
    matrix L with L L^T the stationary state covariance (all for B = 1).
    """

    dt_s: float
    corr_times_s: np.ndarray
    phi: np.ndarray
    variances: np.ndarray
    gains: np.ndarray
    stationary_factor: np.ndarray


def flicker_corr_times_s(band_s, per_decade=1.0):
    """
    Correlation times of the Gauss-Markov sum, log-spaced across ``band_s``.

    T_k = T_min r^k with r = 10^(1/per_decade), K = round(log_r(T_max/T_min)) + 1.
    One per decade keeps the Allan floor within a few percent of flat.
    """
    t_min, t_max = float(band_s[0]), float(band_s[1])
    ratio = 10.0 ** (1.0 / float(per_decade))
    count = int(round(np.log(t_max / t_min) / np.log(ratio))) + 1
    return t_min * ratio ** np.arange(count)


def flicker_unit_variance(corr_times_s):
    """
    Steady-state variance of each Gauss-Markov term for B = 1.

    Equal variances q on log-spaced T_k give a 1/f spectrum. q is set so the
    theoretical Allan deviation, averaged in log over the flat part
    [2 T_min, T_max / 2] (the centre for one or two terms), equals the flicker
    floor sqrt(2 ln 2 / pi) B = 0.664 B (IEEE Std 952 Annex C).
    """
    t = np.asarray(corr_times_s, dtype=float)
    lo, hi = 2.0 * t[0], 0.5 * t[-1]
    if hi <= lo:
        taus = np.array([1.89 * np.sqrt(t[0] * t[-1])])
    else:
        taus = np.logspace(np.log10(lo), np.log10(hi), 41)
    unit = sum(gauss_markov_avar(1.0, tk, taus) for tk in t)
    mean_log = np.exp(np.mean(np.log(unit)))
    return np.full(t.shape, FLICKER_FLOOR_PER_B ** 2 / mean_log)


def _single_input_gains(phi, variances, one_minus_phiphi):
    """
    Solve c_k (G c)_k = q_k with G_kj = 1 / (1 - phi_k phi_j) (Newton).

    With these gains, x_k[n] = phi_k x_k[n-1] + c_k w[n] driven by ONE white
    sequence w has sum_k x_k with autocovariance sum_k q_k phi_k^|m| at every
    lag m: the same Gaussian law as the sampled sum of independent
    Gauss-Markov processes.
    """
    g = 1.0 / one_minus_phiphi
    q = np.asarray(variances, dtype=float)
    scale = np.sqrt(q * np.diag(one_minus_phiphi))
    u = np.full(q.shape, 0.5)

    def residual(v):
        c = v * scale
        return c * (g @ c) / q - 1.0

    for _ in range(200):
        f = residual(u)
        if np.max(np.abs(f)) < 1e-14:
            break
        c = u * scale
        jac = (np.diag(g @ c) + c[:, np.newaxis] * g) * scale[np.newaxis, :] \
            / q[:, np.newaxis]
        step = np.linalg.solve(jac, -f)
        lam = 1.0
        while lam > 1e-6 and np.max(np.abs(residual(u + lam * step))) >= np.max(
                np.abs(f)):
            lam *= 0.5
        u = u + lam * step
    if np.max(np.abs(residual(u))) > 1e-10:
        raise RuntimeError('flicker gains did not converge')
    return u * scale


def flicker_plan(band_s, dt_s, per_decade=1.0):
    """
    Build the exact single-input flicker generator for B = 1 rad/s.

    The bias instability is the sum of K Gauss-Markov processes with
    correlation times across ``band_s`` (:func:`flicker_corr_times_s`) and
    equal variances (:func:`flicker_unit_variance`). Its exact sampled law is
    reproduced by K first-order recursions x_k[n] = phi_k x_k[n-1] + c_k w[n]
    that share one standard normal w[n] per sample (gains from
    :func:`_single_input_gains`): one random number per sample and axis
    instead of K.

    Parameters
    ----------
    band_s : sequence of float
        (T_min, T_max) correlation-time band, s.
    dt_s : float
        Sample period, s.
    per_decade : float
        Gauss-Markov terms per decade of correlation time.

    Returns
    -------
    FlickerPlan

    """
    t = flicker_corr_times_s(band_s, per_decade)
    q = flicker_unit_variance(t)
    rates = 1.0 / t
    one_minus_phiphi = -np.expm1(-dt_s * (rates[:, np.newaxis] + rates[np.newaxis, :]))
    c = _single_input_gains(np.exp(-dt_s * rates), q, one_minus_phiphi)
    cov = c[:, np.newaxis] * c[np.newaxis, :] / one_minus_phiphi
    vals, vecs = np.linalg.eigh(cov)
    factor = vecs * np.sqrt(np.clip(vals, 0.0, None))[np.newaxis, :]
    return FlickerPlan(dt_s=float(dt_s), corr_times_s=t, phi=np.exp(-dt_s * rates),
                       variances=q, gains=c, stationary_factor=factor)


def flicker_initial_state(plan, bias_instability_rad_s, z):
    """
    Draw the K flicker states from their stationary distribution.

    Parameters
    ----------
    plan : FlickerPlan
        The generator.
    bias_instability_rad_s : numpy.ndarray
        B per axis, rad/s, shape (axes,).
    z : numpy.ndarray
        Standard normals, shape (K, axes).

    Returns
    -------
    numpy.ndarray
        States x_k, shape (K, axes), rad/s.

    """
    return (plan.stationary_factor @ z) * np.asarray(bias_instability_rad_s, dtype=float)


def brownian_arw_rad_s_sqrt_hz(device, temp_c=25.0):
    """
    Angle random walk N from the mechanical-thermal noise of the sense mode.

    The sense damping C_sense carries a Brownian force of ONE-sided density
    sqrt(4 k_B T C_sense) N/sqrt(Hz) (Nyquist). The Coriolis force per unit
    rate is F_c / Omega = 2 M V_drive (Eq 17). Both act on the same sense mode
    at the drive frequency, so the mode's response cancels. Synchronous
    demodulation keeps the in-phase part of the force noise, whose baseband
    one-sided PSD is twice the force PSD: 8 k_B T C. Referred to rate, the
    one-sided PSD is 8 k_B T C / (2 M V_drive)^2, i.e. a TWO-sided density

        N = sqrt(4 k_B T C_sense) / (2 M V_drive)   rad/s/sqrt(Hz),

    which is the IEEE Std 952 angle random walk coefficient (Allan deviation
    N / sqrt(tau)). First-order (matched-mode) physics, Eq 5-17.

    Parameters
    ----------
    device : gyro_emulator.physics.params.Device
        The device.
    temp_c : float or array_like
        Die temperature, deg C.

    Returns
    -------
    numpy.ndarray
        N, rad/s/sqrt(Hz).

    """
    return brownian_arw_from_response(first_order.first_order_response(device, 1.0, temp_c),
                                      temp_c)


def brownian_arw_from_response(response, temp_c):
    """
    Brownian angle random walk N from a first-order response already computed.

    N = sqrt(4 k_B T C_sense) / (2 M V_drive), rad/s/sqrt(Hz) (see
    :func:`brownian_arw_rad_s_sqrt_hz`), for the
    :class:`~gyro_emulator.physics.first_order.FirstOrderResponse` of the
    device at ``temp_c`` (deg C): a fleet evaluates the response once and
    reads its scale factor and its noise from it.
    """
    p = response.params
    force = np.sqrt(4.0 * BOLTZMANN_J_K * celsius_to_kelvin(temp_c)
                    * p.damping_sense_n_s_m)
    return force / (2.0 * p.mass_kg * response.drive_velocity_m_s)


def brownian_vrw_m_s2_sqrt_hz(device, temp_c=25.0):
    """
    Velocity random walk N from the Brownian acceleration noise of the proof mass.

    The damping c of the proof mass carries a Brownian force of ONE-sided
    density sqrt(4 k_B T c) N/sqrt(Hz) (Nyquist), so a proof mass m read at
    baseband (an accelerometer: no demodulation, unlike the gyro's sense
    mode) has the one-sided acceleration density (Gabrielson, IEEE Trans.
    Electron Devices 40(5), 1993)

        a_n = sqrt(4 k_B T c) / m        m/s^2/sqrt(Hz), one-sided,

    and, in the convention of :mod:`gyro_emulator.units` and the gyro's N
    (IEEE Std 952: S(f) = N^2 two-sided, Allan deviation N / sqrt(tau)),

        N = a_n / sqrt(2) = sqrt(2 k_B T c) / m.

    m is the device's proof mass (Eq 5) and c its sense-mode damping
    (slide-film under the plate plus the sense comb, Eq 9-11), so N moves
    with T and with the gas (viscosity law, pressure, a sealed cavity). The
    physics has the in-plane damping only: every axis gets this figure.

    Parameters
    ----------
    device : gyro_emulator.physics.params.Device
        The device.
    temp_c : float or array_like
        Die temperature, deg C.

    Returns
    -------
    numpy.ndarray
        N, m/s^2/sqrt(Hz) (two-sided).

    """
    p = first_order.lumped_parameters(device, temp_c)
    one_sided = np.sqrt(4.0 * BOLTZMANN_J_K * celsius_to_kelvin(temp_c)
                        * p.damping_sense_n_s_m) / p.mass_kg
    return one_sided_to_two_sided_density(one_sided)
