"""
Short sensor-level runs of a few parts of a fleet, and their Allan N, B and K.

For each of the first ``sensor_runs.devices`` valid parts of block 0, the
3-axis error model (:class:`gyro_emulator.sensor.model.GyroModel`) runs the
part's own physics on every axis: its device, its drive-sense split (the
sense envelope of ``mode_split_hz``, magnitude) and its electronics terms,
on top of the non-physics terms of the ``sensor_runs.config`` preset, and
the fleet's extended terms (``extended:``, with the part's drawn
``extended.<term>.<param>`` on every axis), which then replace the preset's
own ``extended:``. The
record is the static profile
(:func:`gyro_emulator.emulation.profiles.static_profile`) at the calibration
temperature, run by the one chunk loop
(:func:`gyro_emulator.emulation.run_profile.run_over_profile`) without its
specific force (the run measures noise, not g-sensitivity); the x axis is
analysed
with :func:`gyro_emulator.analysis.allan.overlapping_adev` and
:func:`~gyro_emulator.analysis.allan.fit_noise_terms` (IEEE Std 952).

Part i's record draws from ``SeedSequence(seed, spawn_key=(0, i))``, a
child of block 0's sequence, so it is the same run whatever the scheduler.
"""

from dataclasses import replace

from gyro_emulator import units
from gyro_emulator.analysis import allan
from gyro_emulator.analysis.fleet import config as fleet_config
from gyro_emulator.emulation.profiles import static_profile
from gyro_emulator.emulation.run_profile import OnClock, run_over_profile
from gyro_emulator.sensor import noise
from gyro_emulator.sensor.model import GyroModel
import numpy as np

#: Largest split the sensor configuration accepts, Hz.
MAX_SPLIT_HZ = 5000.0

#: Allan terms reported as a value only when the run resolves them:
#: (fit term, key, unit, the part's model field, converter to the unit).
_BOUNDED_TERMS = (
    ('bias_instability', 'bias_instability', 'deg_h', 'bias_instability_rad_s',
     units.rad_s_to_deg_h),
    ('rrw', 'rrw', 'deg_h_sqrt_h', 'rate_random_walk_rad_s_sqrt_s',
     units.rad_s_sqrt_s_to_rrw_deg_h_sqrt_h))


def part_device(config, values, i):
    """Part i of a block of drawn values as a scalar Device."""
    changes = {}
    for group in fleet_config.DEVICE_GROUPS:
        prefix = group + '.'
        fields = {name[len(prefix):]: float(arr[i]) for name, arr in values.items()
                  if name.startswith(prefix)}
        if fields:
            changes[group] = replace(getattr(config.device, group), **fields)
    return replace(config.device, **changes)


def part_extended(config, values, i):
    """Part i's extended terms: the fleet's, with its drawn parameters on every axis."""
    ext = config.extended
    changes = {}
    for name in ext.active():
        term = ext.get(name)
        drawn = {}
        for param, (kind, *_) in term.RANGES.items():
            key = f'{fleet_config.EXTENDED}{name}.{param}'
            if key in values:
                value = float(values[key][i])
                drawn[param] = (value,) * 3 if kind == 'axis' else value
        if drawn:
            changes[name] = replace(term, **drawn)
    return replace(ext, **changes)


def _electronics(config, values, i):
    out = {}
    for name, target in fleet_config.ELECTRONICS.items():
        key = 'electronics.' + name
        out[target] = float(values[key][i]) if key in values else \
            config.parameters[key].nominal
    return out


def part_sensor_config(config, values, metrics, i):
    """Part i's sensor configuration (see the module docstring)."""
    split = float(min(abs(metrics['split_hz'][i]), MAX_SPLIT_HZ))
    device = part_device(config, values, i)
    sensor = replace(config.sensor_runs.config, device=(device,) * 3,
                     mode_split_hz=(split,) * 3, **{
                         key: (value,) * 3
                         for key, value in _electronics(config, values, i).items()})
    if config.extended is not None:
        sensor = replace(sensor, extended=part_extended(config, values, i))
    return sensor


def run_part(config, values, metrics, i, seed):
    """
    Run part i of block 0 for ``sensor_runs.duration_s`` and fit its Allan terms.

    Returns
    -------
    dict
        Device id, split, the predicted ARW (physics + electronics, at the
        calibration temperature) and the fitted N (deg/sqrt(h)); B (deg/h)
        and K (deg/h/sqrt(h)) each as the fitted value when the run resolves
        it (its lower 95 % bound above zero), else None, with the upper 95 %
        bound (``*_upper_*``) and the part's own model value (``*_model_*``).
        A 600 s run cannot resolve a K below tens of deg/h/sqrt(h): the
        fit's K there is the scatter of the longest taus, not a random walk.

    """
    runs = config.sensor_runs
    sensor = part_sensor_config(config, values, metrics, i)
    device = sensor.device[0]
    rng = np.random.Generator(np.random.SFC64(np.random.SeedSequence(seed, spawn_key=(0, i))))
    model = GyroModel(sensor, runs.rate_hz, rng)
    n = int(round(runs.duration_s * runs.rate_hz))
    static = OnClock(static_profile(runs.duration_s, config.calibration_temp_c), n,
                     model.sample_period_s)
    gyro_x = np.concatenate([chunk.batch.gyro_rad_s[:, 0] for chunk in run_over_profile(
        model, static, specific_force=False)])
    result = allan.overlapping_adev(gyro_x, runs.rate_hz)
    fit = allan.fit_noise_terms(result)
    elec = _electronics(config, values, i)['electronics_noise_rad_s_sqrt_hz']
    predicted = float(np.hypot(noise.brownian_arw_rad_s_sqrt_hz(
        device, config.calibration_temp_c), elec))
    out = {
        'device_id': int(i), 'split_hz': float(metrics['split_hz'][i]),
        'arw_predicted_deg_sqrt_h': float(units.rad_s_sqrt_hz_to_arw_deg_sqrt_h(predicted)),
        'arw_deg_sqrt_h': fit.arw_deg_sqrt_h,
    }
    own = _electronics(config, values, i)
    for term, name, unit, model_field, to_unit in _BOUNDED_TERMS:
        out[f'{name}_{unit}'] = float(to_unit(fit.value(term))) if fit.resolved(term) else None
        out[f'{name}_upper_{unit}'] = float(to_unit(fit.intervals[term].high))
        out[f'{name}_model_{unit}'] = float(to_unit(own[model_field]))
    return out


def run_parts(config, values, metrics, invalid, seed):
    """Sensor-level runs of the first ``sensor_runs.devices`` valid parts of block 0."""
    if config.sensor_runs is None:
        return []
    chosen = np.flatnonzero(~invalid)[:config.sensor_runs.devices]
    return [run_part(config, values, metrics, int(i), seed) for i in chosen]
