"""
The accelerometer's two figures in a noise export: from the log, or given by the user.

Estimators take the accelerometer's white noise N_a (m/s^2/sqrt(Hz), the
velocity random walk) and bias random walk K_a (m/s^3/sqrt(Hz)) beside the
gyro's, continuous-time as Kalibr's ``accelerometer_noise_density`` and
``accelerometer_random_walk``; each writer converts them with the convention
it states for the gyro. :func:`accel_figures` decides where they come from:

* a log with an accelerometer (``accel_{x,y,z}_m_s2`` columns, an Imu's
  ``linear_acceleration``): its own IEEE Std 952 identification
  (:func:`gyro_emulator.analysis.calibrate.noise.calibrate_noise` with
  ``sense=ACCEL``), chosen as the gyro's are
  (:func:`~gyro_emulator.analysis.calibrate.noise.export_noise`: largest over
  the axes, a K_a the record does not resolve as its upper bound, times
  ``inflate``);
* the user's ``--accel-noise-density`` and ``--accel-random-walk``: written
  as given (not inflated), in place of the log's when it has them, and each
  file says so;
* neither: None, and each writer leaves the keys so that its consumer stops
  on them by name.
"""

from dataclasses import dataclass

from gyro_emulator.analysis.calibrate.noise import export_noise
from gyro_emulator.sensor.accel import accel_from_mapping, AccelTerms
from gyro_emulator.sensor.fields import YamlKey
from gyro_emulator.yaml_text import float_text
import numpy as np

#: The options that give the accelerometer figures (named in messages).
ACCEL_OPTIONS = '--accel-noise-density and --accel-random-walk'
#: Unit and short name of each figure.
_KEYS = {'noise_density': ('m/s^2/sqrt(Hz)', 'N_a', '--accel-noise-density'),
         'random_walk': ('m/s^3/sqrt(Hz)', 'K_a', '--accel-random-walk')}


@dataclass(frozen=True)
class AccelFigures:
    """
    The accelerometer's continuous-time N_a and K_a, and where they came from.

    ``given``: the user's (``--accel-noise-density``, ``--accel-random-walk``),
    written as given; else the log's. ``calibration`` is the log's
    accelerometer :class:`~gyro_emulator.analysis.calibrate.noise.NoiseCalibration`
    (None: the log has none) and ``log`` its
    :class:`~gyro_emulator.analysis.calibrate.noise.ExportedNoise` (the
    log's N_a and K_a, inflated): the provenance of every file, and what
    the user's figures replace.
    """

    noise_density_m_s2_sqrt_hz: float
    random_walk_m_s3_sqrt_hz: float
    given: bool = True
    calibration: object = None
    log: object = None

    def __post_init__(self):
        """Check that both figures are finite and positive."""
        for name in ('noise_density_m_s2_sqrt_hz', 'random_walk_m_s3_sqrt_hz'):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0.0):
                raise ValueError(f'{name} = {value!r} is out of range: allowed (0, inf)')

    @property
    def random_walk_is_bound(self):
        """Return whether K_a is an upper bound (the log's, not resolved)."""
        return not self.given and self.log.rrw_is_bound

    def value(self, key):
        """Return ``noise_density`` (N_a) or ``random_walk`` (K_a)."""
        return (self.noise_density_m_s2_sqrt_hz if key == 'noise_density'
                else self.random_walk_m_s3_sqrt_hz)

    def source(self, key):
        """Say where figure ``key`` came from, for the comment beside it."""
        _, name, option = _KEYS[key]
        if self.given:
            if self.log is None:
                return 'given by the user'
            logged = self.log.arw_rad_s_sqrt_hz if key == 'noise_density' else (
                self.log.rrw_rad_s_sqrt_s)
            return f"given by the user ({option}), in place of the log's {float_text(logged)}"
        return name + (' (upper bound)' if key == 'random_walk' and self.random_walk_is_bound
                       else '')

    def comment(self, key):
        """Return the comment of a figure: its unit and :meth:`source`."""
        unit = _KEYS[key][0]
        return f'{unit}; {self.source(key)}' if self.given else f'{unit}, {self.source(key)}'


def accel_figures(calibration=None, inflate=1.0, given=None):
    """
    Return the :class:`AccelFigures` of an export, or None (module docstring).

    ``calibration`` is the log's accelerometer calibration (or None),
    ``given`` the user's (N_a, K_a) or None.
    """
    log = None if calibration is None else export_noise(calibration, inflate)
    if given is not None:
        return AccelFigures(*given, given=True, calibration=calibration, log=log)
    if calibration is None:
        return None
    return AccelFigures(log.arw_rad_s_sqrt_hz, log.rrw_rad_s_sqrt_s, given=False,
                        calibration=calibration, log=log)


def require_accel(fmt, accel):
    """Refuse ``vins`` without the accelerometer figures: VINS-Fusion would not stop on them."""
    if fmt == 'vins' and accel is None:
        raise ValueError(f'--format vins needs {ACCEL_OPTIONS} when the log has no '
                         'accelerometer: VINS-Fusion reads a missing acc_n or acc_w as 0 and a '
                         'text one as 1.8e308, without an error (parameters.cpp), so no file '
                         'without them can stop it')


#: The two terms of an accelerometer given by hand for a gyro-only log's preset.
GIVEN_TERMS = ('electronics_noise', 'random_walk')


def given_accel_config(accel):
    """
    Return the preset's accelerometer from figures given for a log without one.

    White noise N_a and random walk K_a on every axis and nothing else:
    mechanical_noise off (N_a is the whole white noise, as the gyro twin's
    N), no bias, flicker, temperature or scale terms (the log measures none).
    """
    terms = {name: name in GIVEN_TERMS for name in AccelTerms.names()}
    return accel_from_mapping({
        'terms': terms,
        'electronics_noise_m_s2_sqrt_hz': [accel.noise_density_m_s2_sqrt_hz] * 3,
        'random_walk_m_s3_sqrt_hz': [accel.random_walk_m_s3_sqrt_hz] * 3},
        'the accelerometer given by the user')


def given_accel_layout():
    """Return the ``accelerometer:`` key of :func:`given_accel_config` for the sensor YAML."""
    return YamlKey('accelerometer', parts=(
        YamlKey('terms'), YamlKey('electronics_noise_m_s2_sqrt_hz', '.6g'),
        YamlKey('random_walk_m_s3_sqrt_hz', '.6g')))
