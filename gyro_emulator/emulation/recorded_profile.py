"""
A measured record as a ``simulate`` profile: its inputs at its own sample times.

``simulate --profile LOG`` (a CSV, CSV.gz or rosbag2 bag that
:func:`gyro_emulator.recording.record.load_record` reads) drives the
emulator with what the part saw: a :class:`RecordedProfile` is the recorded
kind of the one profile protocol, a :class:`~.profiles.SampledProfile` on
the record's times (the model's temperature range):

* the applied rate: a vector channel as it is; a CSV's single
  ``rate_cmd_rad_s`` column about the sense axis ``axis``. A record with no
  applied rate is refused unless ``static`` says the part was at rest (zero
  rate), as ``diagnose --static`` does;
* the temperature, interpolated from its own times to the record's
  (without one: ``temp_c``, constant);
* the specific force likewise (a CSV's accelerometer columns; the
  acceleration commands of a bag written when they held it, with a note);
  without one, it is left to the motion: gravity turning with the applied
  rate from a level start (:mod:`~gyro_emulator.emulation.profiles`; a part
  at rest reads level, z up), plus a bag's applied linear acceleration
  (``cmd/linear_acceleration``, body frame, gravity excluded), as the node
  does.

The output is written at the record's sample times. The model runs on a
uniform grid at the record's median sample interval from its first sample
(the model is a sampled system: its noise and filters need one rate); each
record sample takes the grid sample nearest to it, moved on by one where two
would share one (:meth:`RecordedProfile.grid_index`), so every record
sample has its own output and time-dependent terms see the record's clock;
:meth:`RecordedProfile.on_model_grid` is that grid as a timeline of
:func:`gyro_emulator.emulation.run_profile.run_over_profile`.
"""

from dataclasses import dataclass
import os

from gyro_emulator.emulation.profiles import SampledProfile
from gyro_emulator.emulation.run_profile import MotionForce
from gyro_emulator.recording.record import is_bag, load_record
from gyro_emulator.units import AXES
from gyro_emulator.validation import check_record_values, MODEL_TEMP_RANGE_C
import numpy as np


def is_record_path(path):
    """Return whether ``path`` names a measured record: a CSV (``.csv``, ``.csv.gz``) or a bag."""
    text = str(path)
    return text.endswith(('.csv', '.csv.gz', '.mcap')) or (
        os.path.isdir(text) and is_bag(text))


@dataclass(frozen=True)
class RecordedProfile(SampledProfile):
    """
    A record's inputs on its own times (module docstring): the recorded kind.

    Attributes
    ----------
    name : str
        The record's path.
    time_s : numpy.ndarray
        Record sample times, s, non-decreasing (a repeated stamp, from a
        logger's clock resolution, is accepted), shape (N,).
    rate_rad_s, accel_m_s2 : numpy.ndarray
        Applied rate (rad/s) and specific force (m/s^2), shape (N, 3); a
        specific force of None is left to the motion.
    temp_c : numpy.ndarray
        Temperature, deg C, shape (N,).
    linear_accel_m_s2 : numpy.ndarray or None
        A bag's applied linear acceleration (body frame, gravity excluded),
        shape (N, 3), with a specific force left to the motion.
    notes : tuple of str
        How the record was read (``Record.recovery``): what a damaged bag
        lost, a bag's acceleration commands taken as the specific force
        (:func:`~gyro_emulator.recording.topics.old_accel_note`).

    """

    notes: tuple = ()

    def grid_index(self, period_s):
        """Return the model grid sample of each record sample: nearest, strictly increasing."""
        k = np.rint((self.time_s - self.time_s[0]) / period_s).astype(np.int64)
        n = np.arange(len(k))
        return np.maximum.accumulate(k - n) + n

    def on_model_grid(self, period_s):
        """Return the record on the model's grid of ``period_s`` (s), as a timeline."""
        return ModelGrid(self, float(period_s), self.grid_index(period_s))


@dataclass(frozen=True)
class ModelGrid:
    """
    A record on the model's uniform grid from its first sample (module docstring).

    Grid sample g is at ``time_s[0] + g period_s``, its inputs interpolated
    from the record's; the grid samples of the record's samples
    (``index``) take the record's own inputs and times and are published,
    the others withheld.
    """

    profile: RecordedProfile
    period_s: float
    index: np.ndarray

    @property
    def count(self):
        """Return the number of grid samples: up to the last record sample's."""
        return int(self.index[-1]) + 1

    def inputs(self, start, stop):
        """Return the times, inputs and published flags of grid samples start .. stop - 1."""
        record = self.profile
        grid = np.arange(start, stop)
        time_s = record.time_s[0] + grid * self.period_s
        lo, hi = np.searchsorted(self.index, [grid[0], grid[-1] + 1])
        at = self.index[lo:hi] - start
        samples = record.samples(time_s)
        samples.rate_rad_s[at] = record.rate_rad_s[lo:hi]
        samples.temp_c[at] = record.temp_c[lo:hi]
        if record.accel_m_s2 is not None:
            samples.accel_m_s2[at] = record.accel_m_s2[lo:hi]
        if record.linear_accel_m_s2 is not None:
            samples.linear_accel_m_s2[at] = record.linear_accel_m_s2[lo:hi]
        time_s[at] = record.time_s[lo:hi]
        published = np.zeros(len(grid), bool)
        published[at] = True
        return time_s, samples, published


def _on_record_times(channel, t, width):
    """Interpolate a channel's values from its own times to ``t``: shape (N,) or (N, width)."""
    values = np.asarray(channel.values, dtype=float)
    if len(channel.time_s) == len(t) and np.array_equal(channel.time_s, t):
        return values.copy()                # a CSV: the record's own times
    if values.ndim == 1:
        return np.interp(t, channel.time_s, values)
    return np.column_stack([np.interp(t, channel.time_s, values[:, k]) for k in range(width)])


def _rate(record, t, axis, static):
    rate = np.zeros((len(t), 3))
    if record.rate is None:
        if not static:
            raise ValueError(f'{record.path}: the record has no applied rate (rate_cmd_rad_s or '
                             'a rate topic): give --static if the part was at rest (zero rate)')
        return rate
    values = _on_record_times(record.rate, t, 3)
    if values.ndim == 1:
        rate[:, AXES.index(axis)] = values
    else:
        rate[:] = values
    return rate


def default_topics(gyro=None):
    """
    Return the bag roles of a recorded profile.

    ``gyro`` (None: the one Imu topic with messages) and the emulator's
    command topics where the bag has them (None: the defaults of
    :func:`~gyro_emulator.recording.record.load_record`).
    """
    return {'gyro': gyro, 'rate': None, 'temp': None, 'accel': None}


def recorded_profile(path, axis='z', static=False, temp_c=25.0, topics=None):
    """
    Read a measured record as a profile (module docstring).

    Parameters
    ----------
    path : str
        CSV (``.csv``, ``.csv.gz``) or rosbag2 bag (directory or ``.mcap``).
    axis : str
        Sense axis a CSV's single ``rate_cmd_rad_s`` column is about: x, y or z.
    static : bool
        The part was at rest: a record without an applied rate gets zero rate.
    temp_c : float
        Temperature of a record without one, deg C.
    topics : dict, optional
        Bag roles (gyro: the sample times; rate, temp, accel) -> topics, as
        for :func:`~gyro_emulator.recording.record.load_record` (default:
        :func:`default_topics`).

    Returns
    -------
    RecordedProfile

    """
    if axis not in AXES:
        raise ValueError(f'simulate.axis = {axis!r} is not allowed: choose x, y or z')
    roles = topics or default_topics()
    record = load_record(path, roles)
    for role, kind in (('rate', 'rate'), ('temp', 'temp')):     # the rule diagnose applies
        channel = getattr(record, role)
        if channel is not None:
            check_record_values(str(path), channel.source, channel.values, kind)
    t = np.asarray(record.time_s, dtype=float)
    if len(t) < 2 or np.any(np.diff(t) < 0.0) or t[-1] <= t[0]:
        raise ValueError(f'{path}: time_s must not go back and must span at least 2 samples '
                         f'to drive the model ({len(t)} samples)')
    temp = (np.full(len(t), float(temp_c)) if record.temp is None
            else _on_record_times(record.temp, t, 1))
    lo, hi = MODEL_TEMP_RANGE_C
    if not (np.all(np.isfinite(temp)) and lo <= temp.min() and temp.max() <= hi):
        raise ValueError(f'{path}: temp_c = {temp.min():.4g} .. {temp.max():.4g} C is out of '
                         f'range: allowed [{lo}, {hi}] C')
    accel = None if record.accel is None else _on_record_times(record.accel, t, 3)
    linear = None if record.linear_accel is None else \
        _on_record_times(record.linear_accel, t, 3)
    rate = _rate(record, t, axis, static)
    for name, values in (('rate', rate), ('accel', accel), ('linear_accel', linear)):
        if values is not None and not np.all(np.isfinite(values)):
            raise ValueError(f'{path}: the {name} channel has values that are not finite')
    return RecordedProfile(str(path), t, rate, temp, accel, linear_accel_m_s2=linear,
                           notes=tuple(record.recovery))


def commanded_specific_force(record, time_s):
    """
    Return the specific force (N, 3), m/s^2, of a bag record's applied acceleration at ``time_s``.

    The record's applied rate (a vector channel; zero without one) and its
    applied linear acceleration (:attr:`Record.linear_accel
    <gyro_emulator.recording.record.Record.linear_accel>`) are interpolated
    to ``time_s`` (s on the record's clock, non-decreasing); the attitude is
    integrated from a level start with the rate held from each time to the
    next and f = a_body - R(q)^T (0, 0, -g), through the one route
    (:class:`~gyro_emulator.emulation.run_profile.MotionForce`), as
    ``simulate --profile`` and the node do.
    """
    t = np.asarray(time_s, dtype=float)
    rate = np.zeros((len(t), 3))
    if record.rate is not None and np.ndim(record.rate.values) == 2:
        rate = _on_record_times(record.rate, t, 3)
    linear = _on_record_times(record.linear_accel, t, 3)
    profile = SampledProfile(f'{record.path}: commands', t, rate, np.zeros(len(t)), None,
                             linear_accel_m_s2=linear)
    return MotionForce(profile).complete(t, profile.own_samples(0, len(t)))[0].accel_m_s2
