"""
What a channel of a static log senses: the gyro's rate or the accelerometer's specific force.

The IEEE Std 952 identification (:mod:`gyro_emulator.analysis.allan`), the
outlier screening (:mod:`gyro_emulator.analysis.outliers`), the noise and
thermal calibrations and their exports are one implementation for both
channels; a :class:`Sense` is what differs: the unit of the samples, their
physical limits, and the datasheet units the terms are shown in. The fit
itself is unit-free: a :class:`~gyro_emulator.analysis.allan.NoiseFit` of
accelerometer samples holds N in m/s^2/sqrt(Hz) (velocity random walk), B in
m/s^2 and K in m/s^3/sqrt(Hz) (acceleration random walk) in the fields the
gyro's names give in rad/s units (``arw_rad_s_sqrt_hz``, ...); its
:meth:`~gyro_emulator.analysis.allan.NoiseFit.value` reads a term by name
without the unit.
"""

from dataclasses import dataclass

from gyro_emulator import units
from gyro_emulator.validation import GYRO_LIMIT_RAD_S
import numpy as np

#: Largest accelerometer reading a record may hold, m/s^2 (about 1000 g: the widest
#: range :class:`gyro_emulator.sensor.accel.AccelConfig` allows). Beyond it a reading
#: is a bad cell, not a specific force.
ACCEL_LIMIT_M_S2 = 10000.0


def _scaled(factor):
    return lambda value: np.asarray(value, dtype=float) * factor


@dataclass(frozen=True)
class Sense:
    """
    One sensed quantity: its name, SI unit, limits and how its noise terms are shown.

    Attributes
    ----------
    name : str
        ``gyro`` or ``accelerometer`` (said in messages).
    unit : str
        SI unit of a sample (``rad/s``, ``m/s^2``).
    limit : float
        Largest magnitude of a sample that is a reading, in ``unit``.
    si_units : dict
        Term (``arw``, ``bias_instability``, ``rrw``, ``quantization``,
        ``rate_ramp``) -> its SI unit.
    shown : dict
        Term -> (converter from SI, datasheet unit) for reports.
    labels : dict
        Term -> its name in reports (``N (ARW)``, ``N (VRW)``, ...).
    shift : tuple
        (converter from SI, unit) of a level step in a report.
    scale_option : str
        The option that rescales the logged samples.

    """

    name: str
    unit: str
    limit: float
    si_units: dict
    shown: dict
    labels: dict
    shift: tuple
    scale_option: str

    @property
    def limits(self):
        """Return (-limit, limit), the physical range of a sample."""
        return (-self.limit, self.limit)

    def show(self, term, value):
        """Return ``value`` (SI) of ``term`` in its datasheet unit, as a float."""
        return float(self.shown[term][0](value))


#: The gyro: rad/s, shown in deg/sqrt(h), deg/h, deg/h/sqrt(h).
GYRO = Sense(
    name='gyro', unit='rad/s', limit=GYRO_LIMIT_RAD_S,
    si_units={'quantization': 'rad', 'arw': 'rad/s/sqrt(Hz)', 'bias_instability': 'rad/s',
              'rrw': 'rad/s^2/sqrt(Hz)', 'rate_ramp': 'rad/s^2'},
    shown={'quantization': (_scaled(1e6), 'urad'),
           'arw': (units.rad_s_sqrt_hz_to_arw_deg_sqrt_h, 'deg/sqrt(h)'),
           'bias_instability': (units.rad_s_to_deg_h, 'deg/h'),
           'rrw': (units.rad_s_sqrt_s_to_rrw_deg_h_sqrt_h, 'deg/h/sqrt(h)'),
           'rate_ramp': (lambda v: units.rad_s_to_deg_h(v) * 3600.0, 'deg/h/h')},
    labels={'quantization': 'Q (quantisation)', 'arw': 'N (ARW)',
            'bias_instability': 'B (bias instability)', 'rrw': 'K (rate random walk)',
            'rate_ramp': 'R (rate ramp)'},
    shift=(units.rad_s_to_deg_s, 'deg/s'), scale_option='--gyro-scale')

#: The accelerometer: m/s^2, shown in ug/sqrt(Hz), mg and m/s^3/sqrt(Hz).
ACCEL = Sense(
    name='accelerometer', unit='m/s^2', limit=ACCEL_LIMIT_M_S2,
    si_units={'quantization': 'm/s', 'arw': 'm/s^2/sqrt(Hz)', 'bias_instability': 'm/s^2',
              'rrw': 'm/s^3/sqrt(Hz)', 'rate_ramp': 'm/s^3'},
    shown={'quantization': (_scaled(1e3), 'mm/s'),
           'arw': (units.m_s2_sqrt_hz_to_ug_sqrt_hz, 'ug/sqrt(Hz)'),
           'bias_instability': (units.m_s2_to_mg, 'mg'),
           'rrw': (_scaled(1.0), 'm/s^3/sqrt(Hz)'),
           'rate_ramp': (_scaled(1.0), 'm/s^3')},
    labels={'quantization': 'Q (quantisation)', 'arw': 'N (VRW)',
            'bias_instability': 'B (bias instability)', 'rrw': 'K (accel. random walk)',
            'rate_ramp': 'R (accel. ramp)'},
    shift=(units.m_s2_to_mg, 'mg'), scale_option='--accel-scale')
