"""
Reference implementations of the noise processes, for the tests only.

Plain numpy/scipy block versions of the recursions that the compiled
kernel (gyro_emulator.sensor.kernel) runs per sample, and the theoretical
Allan variance of the flicker generator. The tests check the kernel and the
generators against these; the product does not use them.
"""

from gyro_emulator.sensor.noise import gauss_markov_avar
import numpy as np
from scipy.signal import lfilter


def gauss_markov_drive_sigma(sigma, corr_time_s, dt_s):
    """
    Exact per-sample innovation sigma of a Gauss-Markov process.

    sigma_d = sigma sqrt(1 - phi^2) with phi = exp(-dt/T), written with expm1
    so that it stays accurate for T >> dt. ``sigma`` is the steady-state
    standard deviation (any unit; the result has the same unit).
    """
    one_minus_phi2 = -np.expm1(-2.0 * np.asarray(dt_s, dtype=float)
                               / np.asarray(corr_time_s, dtype=float))
    return np.asarray(sigma, dtype=float) * np.sqrt(one_minus_phi2)


def first_order_filter(u, phi, gain, last):
    """
    Run y[n] = phi y[n-1] + gain u[n] over a block, along axis 0.

    The exact discretisation of a first-order lag (or Gauss-Markov process
    when ``u`` is white) with phi = exp(-dt / T). ``last`` is y[-1] (shape of
    one sample); the block result does not depend on how a record is split
    into blocks.

    Parameters
    ----------
    u : numpy.ndarray
        Input block, shape (n, ...).
    phi : float
        Pole, 0 <= phi < 1.
    gain : float
        Input gain.
    last : numpy.ndarray or float
        Previous output y[-1], shape ``u.shape[1:]``.

    Returns
    -------
    y : numpy.ndarray
        Output block, same shape as ``u``.
    last : numpy.ndarray
        y[n-1] of the block, to pass to the next call.

    """
    u = np.asarray(u, dtype=float)
    zi = (phi * np.asarray(last, dtype=float))[np.newaxis, ...]
    y, _ = lfilter([gain], [1.0, -phi], u, axis=0, zi=zi)
    return y, y[-1].copy()


def random_walk(z, step_sigma, last):
    """
    Random walk b[n] = b[n-1] + step_sigma w[n] over a block (axis 0).

    ``step_sigma`` = K sqrt(dt) is the exact increment sigma of a Wiener
    process of intensity K (rad/s/sqrt(s) for a rate random walk). The sum
    runs sequentially, so splitting a record into blocks changes nothing.

    Parameters
    ----------
    z : numpy.ndarray
        Standard normals, shape (n, ...).
    step_sigma : float or numpy.ndarray
        Increment sigma, broadcast against ``z[0]``.
    last : numpy.ndarray
        b[-1], shape ``z.shape[1:]``.

    Returns
    -------
    b : numpy.ndarray
        The walk over the block.
    last : numpy.ndarray
        The final value.

    """
    inc = np.asarray(z, dtype=float) * step_sigma
    inc[0] += last
    np.cumsum(inc, axis=0, out=inc)
    return inc, inc[-1].copy()


def flicker(z, plan, bias_instability_rad_s, states):
    """
    Bias instability over a block: sum_k x_k, x_k[n] = phi_k x_k[n-1] + c_k B w[n].

    Parameters
    ----------
    z : numpy.ndarray
        Standard normals w, shape (n, axes).
    plan : FlickerPlan
        The generator.
    bias_instability_rad_s : numpy.ndarray
        B per axis, rad/s.
    states : numpy.ndarray
        x_k[-1], shape (K, axes).

    Returns
    -------
    b : numpy.ndarray
        Flicker bias, shape (n, axes), rad/s.
    states : numpy.ndarray
        The new states.

    """
    u = np.asarray(z, dtype=float) * np.asarray(bias_instability_rad_s, dtype=float)
    out = None
    new = np.empty_like(states)
    for k in range(len(plan.phi)):
        xk, new[k] = first_order_filter(u, plan.phi[k], plan.gains[k], states[k])
        out = xk if out is None else out + xk
    return out, new


def flicker_autocovariance(plan, lag_samples):
    """Autocovariance sum_k q_k phi_k^|m| of the flicker process for B = 1, (rad/s)^2."""
    m = np.abs(np.asarray(lag_samples, dtype=float))[..., np.newaxis]
    return np.sum(plan.variances * plan.phi ** m, axis=-1)


def flicker_avar(plan, bias_instability_rad_s, tau_s):
    """Theoretical Allan variance of the flicker generator, (rad/s)^2."""
    b2 = np.asarray(bias_instability_rad_s, dtype=float) ** 2
    return b2 * sum(gauss_markov_avar(q, t, tau_s)
                    for q, t in zip(plan.variances, plan.corr_times_s))
