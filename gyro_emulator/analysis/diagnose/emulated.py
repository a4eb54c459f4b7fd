"""
A sensor configuration as diagnose's baseline: the emulator's own deterministic output.

``diagnose --config NAME|FILE`` replaces the paper's ``gyro = b0 + s0 R(T)
Omega`` by the output of :class:`gyro_emulator.sensor.model.GyroModel` (the
code path the node runs) with every noise term off, for the record's
temperature and acceleration::

    gyro = b0 + s0 g(t) Omega + o(t)

* o(t): the model's output at zero rate (bias tempco, g-sensitivity, the
  extended bias terms);
* g(t): its gain, (y(c) - o)/c for a constant rate c = :data:`PROBE_RAD_S`
  on the diagnosed axis (physics ratio, scale-factor error, the extended
  scale-factor terms).

The user's calibration of b0 and s0 stays as it is (:mod:`.baseline`). The
pipeline is not changed: the record is transformed instead. The measured
output loses o(t) and the applied rate becomes Omega g(t)/R(T), R the
baseline's ratio of the configuration's device, so that the baseline's
``s0 R(T) Omega`` is ``s0 g(t) Omega`` and every cause's columns are
relative to the emulator's output. The model runs on a uniform grid at the
record's median sample interval from the record's first sample
(``extended.start_time_s`` = its record time) and is interpolated to the
record's times.
"""

from dataclasses import replace

from gyro_emulator.sensor.config import ErrorTerms, load_sensor_config
from gyro_emulator.sensor.model import GyroModel
from gyro_emulator.units import AXES
import numpy as np

#: Noise terms switched off for the deterministic output.
NOISE_TERMS = ('mechanical_noise', 'electronics_noise', 'bias_instability',
               'rate_random_walk', 'turn_on_bias', 'quantization', 'timestamp_jitter')
#: Constant rate of the gain probe, rad/s.
PROBE_RAD_S = 0.1
#: Terms the baseline cannot carry (it has no rate dynamics and no time shift): the reason.
UNSUPPORTED = {
    'latency_s': 'a delay of the output',
    'clock_drift_ppm': 'a drift of the sample clock',
    'output_filter_hz': 'an output filter (rate dynamics)',
    'nonlinearity_s_rad': 'a gain that depends on the rate',
}


def check_config(config, path):
    """Raise a one-line ValueError naming the first term diagnose's baseline cannot carry."""
    for name, what in UNSUPPORTED.items():
        if np.any(np.asarray(getattr(config, name), dtype=float) != 0.0):
            raise ValueError(f'{path}: {name} = {getattr(config, name)!r} is {what}, which '
                             "diagnose's baseline cannot carry: set it to 0 to diagnose "
                             'against this configuration')


def deterministic(config, start_time_s):
    """Return ``config`` with every noise term off and the record's start time."""
    on = {n: n not in NOISE_TERMS for n in ErrorTerms.names()}
    return replace(config, terms=ErrorTerms(**on),
                   extended=replace(config.extended, start_time_s=float(start_time_s)))


def offset_and_gain(config, data, axis):
    """
    Return o(t) and g(t) on the record's times (module docstring).

    Parameters
    ----------
    config : gyro_emulator.sensor.config.SensorConfig
        The starting configuration.
    data : gyro_emulator.analysis.diagnose.data.MeasuredData
        The record: its times (s), temperature (C) and acceleration (m/s^2).
    axis : str
        The diagnosed axis, 'x', 'y' or 'z'.

    """
    t = np.asarray(data.time_s, dtype=float)
    dt = float(np.median(np.diff(t)))
    grid = t[0] + dt * np.arange(int(np.floor((t[-1] - t[0]) / dt + 1e-9)) + 2)
    temp = np.interp(grid, t, data.temp_c) if data.has_temp else np.full(
        len(grid), config.device[AXES.index(axis)].calibration_temp_c)
    accel = None if not data.has_accel else np.column_stack(
        [np.interp(grid, t, data.accel_m_s2[:, k]) for k in range(3)])
    cfg = deterministic(config, t[0])
    i = AXES.index(axis)
    out = []
    for c in (0.0, PROBE_RAD_S):
        rate = np.zeros((len(grid), 3))
        rate[:, i] = c
        model = GyroModel(cfg, 1.0 / dt, np.random.default_rng(0))
        out.append(model.run(rate, temp, accel).gyro_rad_s[:, i])
    offset = np.interp(t, grid, out[0])
    gain = np.interp(t, grid, (out[1] - out[0]) / PROBE_RAD_S)
    return offset, gain


def load(config_name):
    """Return the sensor configuration ``config_name`` (a preset or a file), checked."""
    config = load_sensor_config(config_name)
    check_config(config, config_name)
    return config


def transform(data, config, axis, phys_ratio):
    """
    Return the record relative to the configuration's output (module docstring).

    ``phys_ratio`` is the baseline's R(T) (``DevicePhysics.ratio``).
    """
    offset, gain = offset_and_gain(config, data, axis)
    ratio = phys_ratio(data.temp_c) if data.has_temp else 1.0
    return replace(data, gyro_rad_s=data.gyro_rad_s - offset,
                   rate_cmd_rad_s=data.rate_cmd_rad_s * gain / ratio)
