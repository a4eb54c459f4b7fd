"""
Kinematics of the part: its attitude, and the specific force an accelerometer senses.

Conventions (REP 103): the world frame is ENU with z up; the body (sensor)
frame is x forward, y left, z up. An attitude is a unit quaternion
q = (w, x, y, z) (Hamilton product, w first) that rotates body vectors into
the world frame: v_world = R(q) v_body. Level is q = (1, 0, 0, 0).

* Attitude propagation: the body rate omega (rad/s, body frame) held over
  each step dt is integrated exactly (a zero-order hold),
  q_{k+1} = q_k (x) exp(omega_k dt_k / 2), with exp of the rotation vector
  phi = omega dt in closed form, (cos(|phi|/2), sin(|phi|/2) phi / |phi|),
  and q renormalised after every step (Savage, "Strapdown Analytics",
  Sec 7.1.2; Sola, "Quaternion kinematics for the error-state Kalman
  filter", Eq 101 and 214). :func:`propagate` is the batch form,
  :class:`AttitudeTrack` the stateful form on sample times; both run the
  same compiled loop, so they agree bit for bit however a record is split.
* Specific force: what an accelerometer at rest in the body frame senses,
  f = a_body - R(q)^T g_world with g_world = (0, 0, -g), i.e.
  f = a_body + g R(q)^T e_z: a level part at rest reads +g on z
  (:func:`specific_force`).

Imports numpy and numba (the sequential attitude loop is compiled).
"""

import math

from gyro_emulator.units import STANDARD_GRAVITY_M_S2
import numba
import numpy as np

#: The level attitude (body axes on the world axes), (w, x, y, z).
LEVEL_WXYZ = (1.0, 0.0, 0.0, 0.0)
#: Largest gravity accepted, m/s^2 (ten times the Earth's: beyond any planet a robot works on).
MAX_GRAVITY_M_S2 = 100.0
#: How far from 1 the norm of a given attitude may be before it is refused.
NORM_TOLERANCE = 1e-6


def check_gravity(gravity_m_s2, owner='kinematics'):
    """Return ``gravity_m_s2`` as a float in (0, 100] m/s^2, or raise a one-line ValueError."""
    number = isinstance(gravity_m_s2, (int, float, np.integer, np.floating)) \
        and not isinstance(gravity_m_s2, bool)
    value = float(gravity_m_s2) if number else math.nan
    if not (math.isfinite(value) and 0.0 < value <= MAX_GRAVITY_M_S2):
        raise ValueError(f'{owner}.gravity_m_s2 = {gravity_m_s2!r} is out of range: allowed '
                         f'(0, {MAX_GRAVITY_M_S2:g}] m/s^2')
    return value


def check_attitude(attitude_wxyz, owner='kinematics'):
    """
    Return an attitude (w, x, y, z) as a unit float array (4,), or raise a one-line ValueError.

    The four numbers must be finite with a norm within :data:`NORM_TOLERANCE`
    of 1 (a quaternion a user wrote with a few digits is renormalised; a zero
    or far-off one is refused).
    """
    try:
        q = np.array(attitude_wxyz, dtype=float)
    except (TypeError, ValueError):
        q = np.full(1, math.nan)
    norm = float(np.sqrt(np.sum(q * q))) if q.shape == (4,) else math.nan
    if not (math.isfinite(norm) and abs(norm - 1.0) <= NORM_TOLERANCE):
        raise ValueError(f'{owner}.attitude_wxyz = {attitude_wxyz!r} is not allowed: expected '
                         f'4 finite numbers (w, x, y, z) of norm 1 (within {NORM_TOLERANCE:g})')
    return q / norm


def from_roll_pitch_yaw(roll_rad, pitch_rad, yaw_rad):
    """
    Return the attitude (w, x, y, z) of roll, pitch and yaw, rad (REP 103: fixed axes x, y, z).

    R = Rz(yaw) Ry(pitch) Rx(roll): the body is rolled about x, then pitched
    about y, then yawed about z.
    """
    cr, sr = math.cos(0.5 * roll_rad), math.sin(0.5 * roll_rad)
    cp, sp = math.cos(0.5 * pitch_rad), math.sin(0.5 * pitch_rad)
    cy, sy = math.cos(0.5 * yaw_rad), math.sin(0.5 * yaw_rad)
    return np.array([cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                     cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy])


def rotate_to_world(attitude_wxyz, vector_body):
    """Return R(q) v for attitudes (N, 4) or (4,) and body vectors (N, 3) or (3,)."""
    q = np.asarray(attitude_wxyz, dtype=float)
    v = np.asarray(vector_body, dtype=float)
    w, u = q[..., :1], q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def gravity_up_in_body(attitude_wxyz):
    """
    Return R(q)^T e_z, the world's up in the body frame, for attitudes (N, 4) or (4,).

    The third row of R(q): (2 (x z - w y), 2 (y z + w x), 1 - 2 (x^2 + y^2)).
    """
    q = np.asarray(attitude_wxyz, dtype=float)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([2.0 * (x * z - w * y), 2.0 * (y * z + w * x),
                     1.0 - 2.0 * (x * x + y * y)], axis=-1)


def specific_force(attitude_wxyz, linear_accel_m_s2=None, gravity_m_s2=STANDARD_GRAVITY_M_S2):
    """
    Return the specific force f = a_body - R(q)^T (0, 0, -g), m/s^2 (module docstring).

    Parameters
    ----------
    attitude_wxyz : array_like
        Attitudes (N, 4) or (4,), body to world.
    linear_accel_m_s2 : array_like, optional
        Applied linear acceleration in the body frame, (N, 3) or (3,), m/s^2
        (None: at rest).
    gravity_m_s2 : float
        Magnitude of gravity, (0, 100] m/s^2.

    Returns
    -------
    numpy.ndarray
        (N, 3) or (3,): a level part at rest reads (0, 0, +g). Zeros are +0.

    """
    g = check_gravity(gravity_m_s2)
    force = g * gravity_up_in_body(attitude_wxyz)
    if linear_accel_m_s2 is not None:
        force = np.asarray(linear_accel_m_s2, dtype=float) + force
    return force + 0.0       # -0.0 -> +0.0: a level part reads exactly (0, 0, g)


def specific_force_one(attitude_wxyz, linear_accel_m_s2, gravity_m_s2):
    """
    Return :func:`specific_force` of one sample as a tuple, on Python floats (the hot path).

    The same expressions in the same order as :func:`gravity_up_in_body` and
    :func:`specific_force`, so the same bits; ``gravity_m_s2`` must be
    checked already (:func:`check_gravity`).
    """
    w, x, y, z = attitude_wxyz
    ax, ay, az = linear_accel_m_s2
    g = gravity_m_s2
    return (ax + g * (2.0 * (x * z - w * y)) + 0.0, ay + g * (2.0 * (y * z + w * x)) + 0.0,
            az + g * (1.0 - 2.0 * (x * x + y * y)) + 0.0)


def step(attitude_wxyz, rate_rad_s, dt_s):
    """
    Return the attitude (4,) after one step of ``rate_rad_s`` held for ``dt_s`` (the hot path).

    :func:`propagate` on a record of one, on the same compiled loop, without
    its input checks: ``attitude_wxyz`` a unit float array (4,), the rate
    three finite numbers, ``dt_s`` finite and >= 0 (the caller checked).
    """
    out = np.empty((1, 4))
    return _propagate(attitude_wxyz, np.array((rate_rad_s,), dtype=float),
                      np.array((dt_s,), dtype=float), out)


def steps_held(attitude_wxyz, rate_rad_s, dt_s):
    """
    Return the attitudes (N, 4) after each of N steps of one rate held (the hot path).

    :func:`step` applied N times in one call: row k is the attitude after
    step k of ``dt_s[k]``, on the same compiled loop and so the same bits
    as N calls of :func:`step`. ``attitude_wxyz`` a unit float array (4,),
    the rate three finite numbers, ``dt_s`` (N,) finite and >= 0 (the caller
    checked).
    """
    dt = np.ascontiguousarray(dt_s, dtype=float)
    rate = np.empty((len(dt), 3))
    rate[:] = rate_rad_s
    out = np.empty((len(dt), 4))
    if not len(dt):
        return out
    after = _propagate(attitude_wxyz, rate, dt, out)
    out[:-1] = out[1:]
    out[-1] = after
    return out


@numba.njit(cache=True, error_model='numpy')
def _propagate(q, rate, dt, out):
    """
    Write q_k for k = 0..N-1 into ``out`` (N, 4) and return q_N (module docstring).

    q_{k+1} = q_k (x) (cos(h), s omega_x, s omega_y, s omega_z) with
    h = |omega| dt / 2 and s = sin(h) / |omega| (s = dt / 2 for omega = 0),
    renormalised.
    """
    w, x, y, z = q[0], q[1], q[2], q[3]
    for k in range(rate.shape[0]):
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = w, x, y, z
        ox, oy, oz = rate[k, 0], rate[k, 1], rate[k, 2]
        speed = math.sqrt(ox * ox + oy * oy + oz * oz)
        half = 0.5 * speed * dt[k]
        c = math.cos(half)
        s = math.sin(half) / speed if speed > 0.0 else 0.5 * dt[k]
        px, py, pz = s * ox, s * oy, s * oz
        w, x, y, z = (w * c - x * px - y * py - z * pz, w * px + x * c + y * pz - z * py,
                      w * py - x * pz + y * c + z * px, w * pz + x * py - y * px + z * c)
        norm = math.sqrt(w * w + x * x + y * y + z * z)
        w, x, y, z = w / norm, x / norm, y / norm, z / norm
    result = np.empty(4)
    result[0], result[1], result[2], result[3] = w, x, y, z
    return result


def propagate(attitude_wxyz, rate_rad_s, dt_s):
    """
    Integrate body rates held over each step (batch form; module docstring).

    Parameters
    ----------
    attitude_wxyz : array_like
        Attitude at the first sample, (4,), unit.
    rate_rad_s : array_like
        Body rate of each sample, held until the next, (N, 3), rad/s.
    dt_s : array_like or float
        Time from each sample to the next, (N,) or one for all, s (>= 0).

    Returns
    -------
    attitudes : numpy.ndarray
        The attitude at each sample, (N, 4) (the first is ``attitude_wxyz``).
    after : numpy.ndarray
        The attitude after the last step, (4,).

    """
    return _steps(check_attitude(attitude_wxyz, 'propagate'), rate_rad_s, dt_s)


def _steps(q, rate_rad_s, dt_s):
    """:func:`propagate` from a unit attitude ``q`` as it is (no renormalisation first)."""
    rate = np.ascontiguousarray(rate_rad_s, dtype=float)
    if rate.ndim != 2 or rate.shape[1] != 3 or not np.all(np.isfinite(rate)):
        raise ValueError(f'propagate: rate_rad_s has shape {rate.shape} or values that are not '
                         'finite: expected finite (N, 3)')
    dt = np.ascontiguousarray(np.broadcast_to(np.asarray(dt_s, dtype=float), (len(rate),)))
    if not np.all((dt >= 0.0) & np.isfinite(dt)):
        raise ValueError('propagate: dt_s has values that are negative or not finite: '
                         'allowed finite >= 0 s')
    out = np.empty((len(rate), 4))
    return out, _propagate(q, rate, dt, out)


class AttitudeTrack:
    """
    The attitude on a sequence of sample times, the rate held from each sample to the next.

    :meth:`at` takes the samples of a record in order, in calls of any size;
    the attitude at a sample is the previous attitude advanced by the
    previous sample's rate over the time between them (exactly, as
    :func:`propagate`, which it runs). Bit for bit the same however the
    samples are split into calls.

    Parameters
    ----------
    attitude_wxyz : array_like
        Attitude at the first sample (default level), body to world.

    """

    def __init__(self, attitude_wxyz=LEVEL_WXYZ):
        self._q = check_attitude(attitude_wxyz, 'AttitudeTrack')
        self._last_time_s = None
        self._last_rate = None

    @property
    def attitude_wxyz(self):
        """Return the attitude at the last sample given (the initial one before any)."""
        return self._q.copy()

    def at(self, time_s, rate_rad_s):
        """
        Return the attitudes (N, 4) at the sample times ``time_s`` (N,), s, non-decreasing.

        ``rate_rad_s`` (N, 3) is each sample's body rate, held until the next sample.
        """
        t = np.asarray(time_s, dtype=float)
        rate = np.asarray(rate_rad_s, dtype=float)
        if t.ndim != 1 or rate.shape != (len(t), 3):
            raise ValueError(f'AttitudeTrack.at: time_s {t.shape} and rate_rad_s {rate.shape} '
                             'must be (N,) and (N, 3)')
        if not len(t):
            return np.empty((0, 4))
        first = self._last_time_s is None
        if first:       # the first sample is at the initial attitude
            rates, dts = rate[:-1], np.diff(t)
        else:           # the last sample's rate, held until this call's first sample
            rates = np.vstack([self._last_rate, rate[:-1]])
            dts = np.diff(np.concatenate(([self._last_time_s], t)))
        path, after = _steps(self._q, rates, dts)
        attitudes = np.vstack([path if first else path[1:], after])
        self._q, self._last_time_s, self._last_rate = after, float(t[-1]), rate[-1].copy()
        return attitudes

    def step(self, time_s, rate_rad_s):
        """Return the attitude (4,) at one more sample (:meth:`at` on a record of one)."""
        return self.at(np.array([float(time_s)]), np.asarray(rate_rad_s, dtype=float)[None])[0]
