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
block stepper keeps its block).
"""

import math

from gyro_emulator.physics import kinematics
from gyro_emulator.units import NS_PER_S


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


class AttitudeState:
    """
    The attitude on the samples' time line and the specific force of each sample.

    Parameters
    ----------
    attitude_wxyz : array_like
        Attitude at the first sample, (w, x, y, z), unit.
    gravity_m_s2 : float
        Magnitude of gravity, (0, 100] m/s^2 (:func:`kinematics.check_gravity`).

    """

    def __init__(self, attitude_wxyz, gravity_m_s2):
        self.gravity_m_s2 = kinematics.check_gravity(gravity_m_s2, 'node')
        self._q = kinematics.check_attitude(attitude_wxyz, 'AttitudeState')
        self.attitude_wxyz = tuple(self._q.tolist())
        self._last_ns = None
        self._last_rate = None
        self._moving = False
        self._force_key = None
        self._force = None

    def restart(self):
        """Forget the time line (a clock jump): the attitude stays, the next sample starts it."""
        self._last_ns = None
        self._last_rate = None

    def advance(self, sample_ns, rate_rad_s):
        """
        Return the attitude (w, x, y, z) at sample time ``sample_ns``, ns.

        ``rate_rad_s`` (x, y, z) is this sample's true body rate, held until the
        next sample. The first sample (and the first after :meth:`restart`)
        is at the attitude in force.
        """
        last_ns, last_rate = self._last_ns, self._last_rate
        self._last_ns, self._last_rate = sample_ns, rate_rad_s
        if last_ns is None or not self._moving or sample_ns <= last_ns:
            self._moving = any(rate_rad_s)
            return self.attitude_wxyz
        self._moving = any(rate_rad_s)
        q = kinematics.step(self._q, last_rate, (sample_ns - last_ns) / NS_PER_S)
        self._q = q
        self.attitude_wxyz = tuple(q.tolist())
        return self.attitude_wxyz

    def specific_force(self, linear_accel_m_s2):
        """
        Return the specific force (x, y, z), m/s^2, at the current attitude.

        ``linear_accel_m_s2`` is the applied linear acceleration, body frame.
        The same tuple comes back while the attitude and the acceleration hold.
        """
        key = (self.attitude_wxyz, linear_accel_m_s2)
        if key != self._force_key:
            force = kinematics.specific_force_one(self.attitude_wxyz, linear_accel_m_s2,
                                                  self.gravity_m_s2)
            # the same tuple object while the force holds: the block stepper's key
            if force != self._force:
                self._force = force
            self._force_key = key
        return self._force
