"""
The rate channel's envelope (reduced-order) model of Eq 4.

The demodulated sense envelope is one complex pole p = -sigma + j delta
(:func:`rate_channel_poles`), cheap enough to run per output sample in a
node: continuous state space with DC gain 1, its exact discretisation at
the output's sample instants (no delay of the samples), per-sample and
batch filters, frequency and step responses and the bandwidth. Every
function takes the device, the die temperature ``temp_c`` (deg C), the
drive-sense split ``split_hz`` (f_y - f_x, Hz) and optionally the drive
frequency ``drive_freq_hz`` (Hz, default f_x), as :func:`rate_channel_poles`
documents.
"""

from dataclasses import dataclass
import math

from gyro_emulator.physics import first_order
from gyro_emulator.physics.exact import as_float, sense_frequency_hz
from gyro_emulator.validation import check_range
import numpy as np


@dataclass(frozen=True)
class RateChannelPoles:
    """Slow sense pole -sigma + j delta of the demodulated frame, 1/s."""

    sigma_1_s: float
    delta_rad_s: float
    drive_freq_hz: float
    sense_freq_hz: float


def rate_channel_poles(device, temp_c=25.0, split_hz=0.0, drive_freq_hz=None):
    """
    Pole of the sense envelope seen through the demodulator, 1/s.

    The sense mode's poles are -sigma +- j w_d with sigma = C_s / (2 M) and
    w_d = sqrt(w_y^2 - sigma^2) (Eq 4). Demodulating at the drive frequency w
    shifts the slow one to -sigma + j delta, delta = w_d - w; the image near
    -2 j w is filtered out by the demodulator and dropped. Matched modes give
    delta ~ 0 (a first-order lag, tau = 1/sigma = 2 Q_s / w_y); a split gives
    delta ~ 2 pi split_hz (a complex pole pair in the real I/Q frame).

    Parameters
    ----------
    device : gyro_emulator.physics.params.Device
        The device (scalar fields).
    temp_c : float
        Die temperature, deg C.
    split_hz : float
        Drive-sense split f_y - f_x, Hz.
    drive_freq_hz : float, optional
        Drive frequency, Hz; default f_x.

    Returns
    -------
    RateChannelPoles

    """
    owner = 'rate_channel'
    if np.ndim(temp_c) or np.ndim(split_hz):
        raise ValueError(f'{owner}: temp_c = {temp_c!r} and split_hz = '
                         f'{split_hz!r} must be scalars')
    p = first_order.lumped_parameters(device, temp_c)
    if np.ndim(p.mass_kg):
        raise ValueError(f'{owner}: device fields must be scalars, not arrays')
    _, f_y = sense_frequency_hz(owner, p, split_hz)
    f_d = float(p.freq_x_hz) if drive_freq_hz is None else float(
        check_range(owner, 'drive_freq_hz', drive_freq_hz, 0.0, None, 'Hz'))
    sigma = float(p.damping_sense_n_s_m / (2.0 * p.mass_kg))
    w_y = 2.0 * np.pi * float(f_y)
    if w_y <= sigma:
        raise ValueError(f'{owner}.split_hz = {split_hz!r} leaves an overdamped '
                         'sense mode: allowed f_y > sigma / (2 pi)')
    delta = math.sqrt(w_y ** 2 - sigma ** 2) - 2.0 * np.pi * f_d
    return RateChannelPoles(sigma, delta, f_d, float(f_y))


def rate_channel_state_space(device, temp_c=25.0, split_hz=0.0,
                             drive_freq_hz=None):
    """
    Continuous envelope model of the rate channel, DC gain exactly 1.

    States are the demodulated sense envelope (a, b) = (Re, Im) of the slowly
    varying complex amplitude; with p = -sigma + j delta from
    :func:`rate_channel_poles`::

        d/dt [a]   [-sigma  -delta] [a]   [sigma]
             [b] = [ delta  -sigma] [b] + [  0  ] Omega,   out = g a

    g = (sigma^2 + delta^2) / sigma^2 makes the DC gain 1, so the output is
    the rate the in-phase channel reports (rad/s) with its scale factor
    removed; the transfer function is
    H(s) = (sigma^2 + delta^2)(s + sigma) / (sigma ((s + sigma)^2 + delta^2)).
    Derived from Eq 4 with the drive velocity as carrier (slowly varying
    envelope, image pole dropped); matches :func:`simulate_time_domain`
    within 2 % (test/test_dynamics.py).

    Parameters
    ----------
    device, temp_c, split_hz, drive_freq_hz
        The device and its operating point, as in :func:`rate_channel_poles`.

    Returns
    -------
    tuple of numpy.ndarray
        ``(A, B, C, D)`` with shapes (2, 2), (2, 1), (1, 2), (1, 1).

    """
    poles = rate_channel_poles(device, temp_c, split_hz, drive_freq_hz)
    s, d = poles.sigma_1_s, poles.delta_rad_s
    a = np.array([[-s, -d], [d, -s]])
    b = np.array([[s], [0.0]])
    c = np.array([[(s * s + d * d) / (s * s), 0.0]])
    return a, b, c, np.zeros((1, 1))


def rate_channel_discrete(device, sample_rate_hz, temp_c=25.0, split_hz=0.0,
                          drive_freq_hz=None):
    """
    Exact discretisation of the rate-channel envelope model, sampled at its output instants.

    Sample n is the output at its instant t_n = n dt, dt = 1 / ``sample_rate_hz``,
    and the rate ``u[n]`` is the one applied over the period that ends there,
    (t_{n-1}, t_n] (the convention of the die-temperature lag and of every
    other term of the sensor model: a sample reflects the input at its own
    instant). The state is the envelope one sample earlier,
    ``x[n] = x(t_{n-1})``, and integrating the model exactly over the period::

        x(t_n) = Ad x(t_{n-1}) + Bd u[n],   Ad = e^{A dt},  Bd = int_0^dt e^{A s} ds B
        y[n]   = C x(t_n) = (C Ad) x[n] + (C Bd) u[n]

    so the discrete system is ``(Ad, Bd, Cd, Dd) = (Ad, Bd, C Ad, C Bd)``: the
    zero-order-hold state update with the output read after it (direct
    feedthrough ``C Bd``). Its DC gain is that of the continuous model,
    C Ad (I - Ad)^-1 Bd + C Bd = C (I - Ad)^-1 Bd = -C A^-1 B = 1, and its step
    response at the sample instants is the continuous one,
    y[n] = s((n + 1) dt) for a rate applied from t_{-1} on. Reading the output
    before the update (``Cd = C``, ``Dd = 0``) would make y[n] answer
    u[n - 1]: a one-sample delay of the output that no part has.

    The model is one complex pole p = -sigma + j delta, so Ad and Bd have a
    closed form: Ad = e^{-sigma dt} [[cos, -sin], [sin, cos]](delta dt) and
    Bd = (Re, Im) of sigma (e^{p dt} - 1) / p (what
    ``scipy.signal.cont2discrete(..., 'zoh')`` returns for them). Run it per
    sample as ``y = Cd @ x + Dd u; x = Ad @ x + Bd[:, 0] * u``
    (:func:`rate_channel_step`) or over a batch with :func:`rate_channel_filter`.

    Parameters
    ----------
    device : gyro_emulator.physics.params.Device
        The device (scalar fields).
    sample_rate_hz : float
        Output sample rate, Hz.
    temp_c, split_hz, drive_freq_hz
        The operating point, as in :func:`rate_channel_poles`.

    Returns
    -------
    tuple of numpy.ndarray
        ``(Ad, Bd, Cd, Dd)`` with shapes (2, 2), (2, 1), (1, 2), (1, 1).

    """
    rate_hz = check_range('rate_channel_discrete', 'sample_rate_hz',
                          sample_rate_hz, 0.0, 1e9, 'Hz')
    a, b, c, _ = rate_channel_state_space(device, temp_c, split_hz, drive_freq_hz)
    p = complex(a[0, 0], a[1, 0])
    lam = np.exp(p / rate_hz)
    beta = b[0, 0] * (lam - 1.0) / p
    ad = np.array([[lam.real, -lam.imag], [lam.imag, lam.real]])
    bd = np.array([[beta.real], [beta.imag]])
    return ad, bd, c @ ad, c @ bd


def rate_channel_step(discrete, state, rate_rad_s):
    """
    Advance the discrete rate channel by one sample (pure function).

    Parameters
    ----------
    discrete : tuple
        ``(Ad, Bd, Cd, Dd)`` from :func:`rate_channel_discrete`.
    state : numpy.ndarray
        Envelope state, shape (2,).
    rate_rad_s : float
        True rate over the sample's period (the one that ends at its instant), rad/s.

    Returns
    -------
    tuple
        ``(new_state, output_rad_s)``: y_k = Cd x_k + Dd u_k, then
        x_{k+1} = Ad x_k + Bd u_k (with :func:`rate_channel_discrete`'s
        matrices, y_k is the envelope at the sample's instant, C x_{k+1}).

    """
    ad, bd, cd, dd = discrete
    x = np.asarray(state, dtype=float)
    out = float(cd[0] @ x + dd[0, 0] * rate_rad_s)
    return ad @ x + bd[:, 0] * rate_rad_s, out


def rate_channel_filter(discrete, rate_rad_s, state=None):
    """
    Run the discrete rate channel over a batch of samples (vectorised).

    The 2-state model is one complex pole, so the batch runs as a complex
    first-order IIR filter (``scipy.signal.lfilter``), identical to repeated
    :func:`rate_channel_step` calls.

    Parameters
    ----------
    discrete : tuple
        ``(Ad, Bd, Cd, Dd)`` from :func:`rate_channel_discrete`.
    rate_rad_s : array_like
        True rate per sample, rad/s, shape (n,).
    state : numpy.ndarray, optional
        Initial envelope state, shape (2,); default zeros.

    Returns
    -------
    tuple
        ``(output_rad_s, final_state)``.

    """
    # scipy.signal costs 1 s: `gyro-emulator dynamics` imports this module and never filters.
    from scipy import signal

    ad, bd, cd, dd = discrete
    u = np.asarray(rate_rad_s, dtype=float)
    x0 = np.zeros(2) if state is None else np.asarray(state, dtype=float)
    lam = complex(ad[0, 0], ad[1, 0])
    beta = complex(bd[0, 0], bd[1, 0])
    if u.size == 0:
        return np.zeros(0), x0.copy()
    z0 = complex(x0[0], x0[1])
    # zeta_{k+1} = lam zeta_k + beta u_k; lfilter gives zeta_{k+1} for each k.
    nxt, _ = signal.lfilter([beta], [1.0, -lam], u.astype(complex),
                            zi=[lam * z0])
    zeta = np.concatenate(([z0], nxt[:-1]))
    out = cd[0, 0] * zeta.real + cd[0, 1] * zeta.imag + dd[0, 0] * u
    return out, np.array([nxt[-1].real, nxt[-1].imag])


def rate_channel_frequency_response(device, freq_hz, temp_c=25.0, split_hz=0.0,
                                    drive_freq_hz=None):
    """
    Complex frequency response H(j 2 pi f) of the envelope model (DC = 1).

    Parameters
    ----------
    device : gyro_emulator.physics.params.Device
        The device (scalar fields).
    freq_hz : float or array_like
        Rate-input frequency, Hz.
    temp_c, split_hz, drive_freq_hz
        The operating point, as in :func:`rate_channel_poles`.

    Returns
    -------
    numpy.ndarray
        Complex response, same shape as ``freq_hz``.

    """
    poles = rate_channel_poles(device, temp_c, split_hz, drive_freq_hz)
    s, d = poles.sigma_1_s, poles.delta_rad_s
    jw = 2j * np.pi * as_float(freq_hz)
    return (s * s + d * d) * (jw + s) / (s * ((jw + s) ** 2 + d * d))


def rate_channel_step_response(device, time_s, temp_c=25.0, split_hz=0.0,
                               drive_freq_hz=None):
    """
    Return the unit step response of the envelope model (final value 1).

    Closed form: with p = -sigma + j delta, the envelope is
    (sigma / -p)(1 - e^{p t}) and the output g Re(.) of it.

    Parameters
    ----------
    device : gyro_emulator.physics.params.Device
        The device (scalar fields).
    time_s : array_like
        Times after the step, s (negative times give 0).
    temp_c, split_hz, drive_freq_hz
        The operating point, as in :func:`rate_channel_poles`.

    Returns
    -------
    numpy.ndarray

    """
    poles = rate_channel_poles(device, temp_c, split_hz, drive_freq_hz)
    s, d = poles.sigma_1_s, poles.delta_rad_s
    p = complex(-s, d)
    t = as_float(time_s)
    env = (s / -p) * (1.0 - np.exp(p * np.maximum(t, 0.0)))
    return np.where(t > 0.0, (s * s + d * d) / (s * s) * env.real, 0.0)


def rate_channel_bandwidth_hz(device, temp_c=25.0, split_hz=0.0,
                              drive_freq_hz=None):
    """
    -3 dB bandwidth of the rate channel, Hz (highest f with |H| >= 1/sqrt 2).

    From |H(jw)|^2 = 1/2 with u = w^2, S = sigma^2 + delta^2, K = S / sigma:
    u^2 + (4 sigma^2 - 2 S - 2 K^2) u + S^2 - 2 K^2 sigma^2 = 0, which has
    exactly one positive root. Matched modes give sigma / (2 pi) =
    f_y / (2 Q_s). The arguments are those of :func:`rate_channel_poles`;
    returns the bandwidth as a float, Hz.

    """
    poles = rate_channel_poles(device, temp_c, split_hz, drive_freq_hz)
    s, d = poles.sigma_1_s, poles.delta_rad_s
    big_s = s * s + d * d
    k2 = (big_s / s) ** 2
    b = 4.0 * s * s - 2.0 * big_s - 2.0 * k2
    c = big_s ** 2 - 2.0 * k2 * s * s
    u = (-b + math.sqrt(b * b - 4.0 * c)) / 2.0
    return math.sqrt(u) / (2.0 * np.pi)
