"""
A sensor configuration as diagnose's baseline: what the emulator really outputs.

``diagnose --config NAME|FILE`` replaces the paper's ``gyro = b0 + s0 R(T)
Omega`` by the output of the emulator itself, computed through the path
``simulate --config NAME|FILE --profile RECORD`` runs (the one chunk loop
:func:`gyro_emulator.emulation.run_profile.run_over_profile` over the record
on the model's grid, :func:`gyro_emulator.emulation.simulate.iter_simulation`,
with :class:`gyro_emulator.sensor.model.GyroModel`, the model the node runs)
with every noise term off, for the record's applied rate, temperature and
acceleration::

    gyro = b0 + s0 r(t) + o(t),   r(t) = y(t) - o(t)

* y(t): the emulator's output for the record's inputs (rate on the
  diagnosed axis; temperature, or the calibration temperature without one;
  specific force, or level without one, as ``simulate`` reads a record):
  sense dynamics, output filter, nonlinearity and saturation included, each
  sample at its own time;
* o(t): its output for the same inputs at zero rate (bias tempco,
  g-sensitivity, the extended bias terms);
* r(t): so the rate part of the output: the physics ratio, scale-factor
  error and extended scale-factor terms times the rate, through the rate
  dynamics.

The user's calibration of b0 and s0 stays as it is (:mod:`.baseline`). The
pipeline is not changed: the record is transformed instead. The measured
output loses o(t) and the applied rate becomes r(t)/R(T), R the baseline's
ratio of the configuration's device, so that the baseline's
``s0 R(T) Omega`` is ``s0 r(t)`` and every cause's columns are relative to
the emulator's output. The record's times are the sample instants, as
``simulate --profile`` writes them; ``extended.start_time_s`` is the
record's first time.

A configuration's latency and clock drift are run as ``simulate --profile``
runs them, so the baseline holds what they do to its output: a latency
delays the stamps of the node's messages, not the samples ``simulate
--profile`` writes at the record's times (it changes no value); a clock
drift changes the model's grid, whose samples at the record's samples are
published with the record's inputs and times (the part's filters run on
its own clock between them).
"""

from dataclasses import replace

from gyro_emulator.emulation.profiles import LEVEL_ACCEL_M_S2
from gyro_emulator.emulation.recorded_profile import RecordedProfile
from gyro_emulator.emulation.simulate import iter_simulation
from gyro_emulator.sensor.config import ErrorTerms, load_sensor_config
from gyro_emulator.units import AXES
import numpy as np

#: Noise terms switched off for the deterministic output.
NOISE_TERMS = ('mechanical_noise', 'electronics_noise', 'bias_instability',
               'rate_random_walk', 'turn_on_bias', 'quantization', 'timestamp_jitter')


def deterministic(config, start_time_s):
    """Return ``config`` with every noise term off (other switches kept) from ``start_time_s``."""
    on = {n: getattr(config.terms, n) and n not in NOISE_TERMS for n in ErrorTerms.names()}
    return replace(config, terms=ErrorTerms(**on),
                   extended=replace(config.extended, start_time_s=float(start_time_s)))


def record_profile(config, data, axis, with_rate=True):
    """
    Return the record's inputs as ``simulate --profile RECORD`` reads them (a RecordedProfile).

    The applied rate about ``axis`` (zero with ``with_rate`` False), the
    temperature (without one: the axis's calibration temperature) and the
    specific force (without one: level, z up), on the record's times.
    """
    t = np.asarray(data.time_s, dtype=float)
    i = AXES.index(axis)
    rate = np.zeros((len(t), 3))
    if with_rate:
        rate[:, i] = data.rate_cmd_rad_s
    temp = np.asarray(data.temp_c, dtype=float) if data.has_temp else np.full(
        len(t), config.device[i].calibration_temp_c)
    accel = np.asarray(data.accel_m_s2, dtype=float) if data.has_accel else np.tile(
        LEVEL_ACCEL_M_S2, (len(t), 1))
    return RecordedProfile(data.source or 'record', t, rate, temp, accel)


def emulated_output(config, data, axis, with_rate=True):
    """
    Return the emulator's deterministic output on the record's samples, rad/s (axis ``axis``).

    What ``simulate --config ... --profile RECORD`` writes for the record
    with every noise term off (:func:`deterministic`), one value per record
    sample, in order.
    """
    t = np.asarray(data.time_s, dtype=float)
    profile = record_profile(config, data, axis, with_rate)
    i = AXES.index(axis)
    chunks = iter_simulation(deterministic(config, t[0]), profile, profile.duration_s,
                             profile.rate_hz)
    return np.concatenate([c.batch.gyro_rad_s[c.published, i] for c in chunks])


def offset_and_rate(config, data, axis):
    """
    Return o(t) and r(t) on the record's samples (module docstring).

    Parameters
    ----------
    config : gyro_emulator.sensor.config.SensorConfig
        The starting configuration.
    data : gyro_emulator.analysis.diagnose.data.MeasuredData
        The record: its times (s), applied rate (rad/s), temperature (C) and
        acceleration (m/s^2).
    axis : str
        The diagnosed axis, 'x', 'y' or 'z'.

    """
    offset = emulated_output(config, data, axis, with_rate=False)
    return offset, emulated_output(config, data, axis) - offset


def load(config_name):
    """Return the sensor configuration ``config_name`` (a preset or a file)."""
    return load_sensor_config(config_name)


def transform(data, config, axis, phys_ratio):
    """
    Return the record relative to the configuration's output (module docstring).

    ``phys_ratio`` is the baseline's R(T) (``DevicePhysics.ratio``).
    """
    offset, rate = offset_and_rate(config, data, axis)
    ratio = phys_ratio(data.temp_c) if data.has_temp else 1.0
    return replace(data, gyro_rad_s=data.gyro_rad_s - offset, rate_cmd_rad_s=rate / ratio)
