"""
The part's attitude and the specific force it senses, sample by sample (no ROS imports).

:class:`AttitudeState` keeps the attitude q (w, x, y, z), body to the ENU
world (REP 103), from the node's ``initial_attitude_rpy_rad``. At each
sample it advances q by the previous sample's true rate held over the time
between the two samples, with the exact zero-order-hold step and the
renormalisation of :func:`gyro_emulator.physics.kinematics.propagate` (its
one-step form :func:`~gyro_emulator.physics.kinematics.step`)
(Savage, "Strapdown Analytics", Sec 7.1.2), and gives the specific force

    f = a_body - R(q)^T (0, 0, -g)        (:func:`kinematics.specific_force`)

with a_body the applied linear acceleration (``cmd/linear_acceleration``).
A level part at rest reads (0, 0, +g). Behind a simulator
(``input_source: imu``) the simulator's acceleration is the specific force
itself; the attitude is still integrated from its rates, for the truth.

The hot path is cheap: while the rate is zero the attitude does not move,
and while neither the attitude nor the applied acceleration changes the
specific force is the previous tuple (the same object, so the model's
block stepper keeps its block). While the rate and the applied
acceleration hold, the attitudes and forces of the next samples are known
ahead: :meth:`AttitudeState.forces` integrates them in one call
(:func:`kinematics.steps_held`, the same compiled loop and so the same
bits as a step per sample) on the instants the sample clock will hand out,
so the model can run them as one block while gravity turns. Each sample
checks that its instant, the rate held since the previous one and the
acceleration are those of the forecast, bit for bit; any other sample
drops it and steps alone, as without a forecast.
"""

import math

from gyro_emulator.physics import kinematics
from gyro_emulator.units import NS_PER_S
import numpy as np


def initial_attitude(roll_pitch_yaw_rad, owner='initial_attitude_rpy_rad'):
    """
    Return the unit attitude (w, x, y, z) of (roll, pitch, yaw), rad, or raise ValueError.

    The three angles must be finite (REP 103 fixed axes: roll about x, pitch
    about y, yaw about z); the message names the field, the value and the range.
    """
    angles = tuple(roll_pitch_yaw_rad)
    if len(angles) != 3 or not all(isinstance(a, (int, float)) and not isinstance(a, bool)
                                   and math.isfinite(a) for a in angles):
        raise ValueError(f'{owner} = {roll_pitch_yaw_rad!r} is not allowed: expected three '
                         'finite angles (roll, pitch, yaw), rad')
    return kinematics.check_attitude(kinematics.from_roll_pitch_yaw(*angles), owner)


def same_bits(a, b):
    """Tell whether two tuples of floats are equal bit for bit (``==`` and the signs of zeros)."""
    return a is b or (a == b and all(math.copysign(1.0, x) == math.copysign(1.0, y)
                                     for x, y in zip(a, b)))


class _Forecast:
    """The attitudes and forces of the samples after one, should its rate and acceleration hold."""

    __slots__ = ('rate', 'accel', 'times_ns', 'attitudes', 'forces')

    def __init__(self, rate, accel, times_ns, attitudes, forces):
        self.rate, self.accel, self.times_ns = rate, accel, times_ns
        self.attitudes, self.forces = attitudes, forces


class AttitudeState:
    """
    The attitude on the samples' time line and the specific force of each sample.

    Parameters
    ----------
    attitude_wxyz : array_like
        Attitude at the first sample, (w, x, y, z), unit.
    gravity_m_s2 : float
        Magnitude of gravity, (0, 100] m/s^2 (:func:`kinematics.check_gravity`).
    upcoming : callable or None
        ``upcoming(sample_ns, count)`` returns the next ``count`` sample
        instants after ``sample_ns``, ns, as the sample clock will hand them
        out if nothing changes; None: no forecasts (:meth:`forces` gives the
        current force only).

    """

    def __init__(self, attitude_wxyz, gravity_m_s2, upcoming=None):
        self.gravity_m_s2 = kinematics.check_gravity(gravity_m_s2, 'node')
        self._q = kinematics.check_attitude(attitude_wxyz, 'AttitudeState')
        self.attitude_wxyz = tuple(self._q.tolist())
        self._upcoming = upcoming
        self._last_ns = None
        self._last_rate = None
        self._moving = False
        self._force_key = None
        self._force = None
        self._accel = None
        self._forecast = None
        self._next = 0
        self._forecast_force = None

    def restart(self):
        """Forget the time line (a clock jump): the attitude stays, the next sample starts it."""
        self._last_ns = None
        self._last_rate = None
        self._forecast = None
        self._forecast_force = None

    def advance(self, sample_ns, rate_rad_s):
        """
        Return the attitude (w, x, y, z) at sample time ``sample_ns``, ns.

        ``rate_rad_s`` (x, y, z) is this sample's true body rate, held until the
        next sample. The first sample (and the first after :meth:`restart`)
        is at the attitude in force.
        """
        last_ns, last_rate = self._last_ns, self._last_rate
        self._last_ns, self._last_rate = sample_ns, rate_rad_s
        self._forecast_force = None
        forecast = self._forecast
        if forecast is not None:
            i = self._next
            if i < len(forecast.times_ns) and sample_ns == forecast.times_ns[i] \
                    and same_bits(last_rate, forecast.rate):
                self._next = i + 1
                self._moving = any(rate_rad_s)
                self._q = None
                self._forecast_force = forecast.forces[i]
                self.attitude_wxyz = forecast.attitudes[i]
                return self.attitude_wxyz
            self._forecast = None
        if last_ns is None or not self._moving or sample_ns <= last_ns:
            self._moving = any(rate_rad_s)
            return self.attitude_wxyz
        self._moving = any(rate_rad_s)
        q = self._q if self._q is not None else np.array(self.attitude_wxyz)
        q = kinematics.step(q, last_rate, (sample_ns - last_ns) / NS_PER_S)
        self._q = q
        self.attitude_wxyz = tuple(q.tolist())
        return self.attitude_wxyz

    def specific_force(self, linear_accel_m_s2):
        """
        Return the specific force (x, y, z), m/s^2, at the current attitude.

        ``linear_accel_m_s2`` is the applied linear acceleration, body frame.
        The same tuple comes back while the attitude and the acceleration hold.
        """
        self._accel = linear_accel_m_s2
        forecast = self._forecast_force
        if forecast is not None and same_bits(linear_accel_m_s2, self._forecast.accel):
            return forecast
        key = (self.attitude_wxyz, linear_accel_m_s2)
        if key != self._force_key:
            force = kinematics.specific_force_one(self.attitude_wxyz, linear_accel_m_s2,
                                                  self.gravity_m_s2)
            # the same tuple object while the force holds: the block stepper's key
            if force != self._force:
                self._force = force
            self._force_key = key
        return self._force

    @property
    def key(self):
        """Return the applied acceleration of the current sample (what a forecast holds)."""
        return self._accel

    def forces(self, count):
        """
        Return the specific forces of the current sample and the next ``count - 1``.

        They hold if the current rate and applied acceleration hold and the
        next samples come at the instants ``upcoming`` gives; the attitudes
        and forces of those samples are kept, and :meth:`advance` and
        :meth:`specific_force` hand them out while they hold. Call it after
        :meth:`specific_force` of the current sample.

        Returns
        -------
        list of tuple
            ``count`` forces (x, y, z), m/s^2, the first the current one.

        """
        current = self.specific_force(self._accel)
        if count < 2 or self._upcoming is None or self._last_ns is None:
            return [current]
        rate, accel = self._last_rate, self._accel
        times = self._upcoming(self._last_ns, count - 1)
        if any(rate):
            q = self._q if self._q is not None else np.array(self.attitude_wxyz)
            dt_s = np.diff(np.array([self._last_ns, *times], dtype=np.int64)) / NS_PER_S
            path = kinematics.steps_held(q, rate, dt_s)
            attitudes = list(map(tuple, path.tolist()))
            forces = list(map(tuple, kinematics.specific_force(
                path, accel, self.gravity_m_s2).tolist()))
        else:
            attitudes = [self.attitude_wxyz] * len(times)
            forces = [current] * len(times)
        self._forecast = _Forecast(rate, accel, times, attitudes, forces)
        self._next = 0
        return [current, *forces]
