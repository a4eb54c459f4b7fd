"""
Thermal exports: PX4 TC_G0_* and ArduPilot INS_TCAL1_* parameters, this emulator's bias terms.

* ``px4``: a QGroundControl parameter file (``1 1 NAME VALUE TYPE``, tab
  separated, as PX4's Tools/process_sensor_caldata.py writes it). PX4's
  sensors module subtracts X0 + X1 d + X2 d^2 + X3 d^3 with d = T - TREF and
  T held within [TMIN, TMAX]; TREF is the middle of the range; values in
  rad/s per K^k. TC_G0_ID must be the gyro's device id, which a log does
  not give: written from ``px4_gyro_id`` (an INT32 parameter, type 6, as
  process_sensor_caldata.py writes it); without it the row is left out, the
  file says so and the command warns (:data:`PX4_NO_ID`): PX4 applies
  TC_G0_* only to the gyro whose device id is TC_G0_ID.
* ``ardupilot``: ``NAME VALUE`` lines (as Tools/scripts/tempcal_IMU.py
  writes them). ArduPilot's AP_InertialSensor_tempcal.cpp subtracts
  p(T - 35) - p(T_cal - 35), p(d) = (GYR1 d + GYR2 d^2 + GYR3 d^3) 1e-6,
  T and T_cal held within [TMIN, TMAX]: a fixed reference of 35 C, no
  constant term (the ordinary gyro calibration at T_cal takes the offset),
  coefficients in rad/s per K^k times 1e6.
* ``preset``: this emulator's sensor YAML: ``turn_on_bias_deg_s`` (the
  polynomial at T_ref), ``bias_temp_coeff_deg_s_k`` and
  ``bias_temp_coeff2_deg_s_k2`` about T_ref (the device's
  ``calibration_temp_c``); the emulator's bias model is at most quadratic.

The accelerometer, when the log has one (its own
:class:`~gyro_emulator.analysis.calibrate.thermal.ThermalFit`, ``accel``):

* ``px4``: ``TC_A_ENABLE``, ``TC_A0_TMIN/TMAX/TREF`` and
  ``TC_A0_X{0..3}_{0,1,2}`` in m/s^2/K^k, the offset PX4 subtracts as for
  the gyro, less each axis's median (as process_sensor_caldata.py fits
  the accelerometer: the constant part, gravity and the offset at the
  median, is left to the accelerometer calibration, ``CAL_ACC*``);
  ``TC_A0_ID`` from ``px4_accel_id`` (:data:`PX4_NO_ACCEL_ID` without it);
* ``ardupilot``: ``INS_TCAL1_ACC{1,2,3}_{X,Y,Z}``, as the gyro's
  (AP_InertialSensor_tempcal.cpp ``correct_accel``: the same polynomial
  about 35 C without its constant, times 1e6, m/s^2/K^k), within the
  file's one TMIN..TMAX;
* ``preset``: the ``accelerometer:`` bias tempco ``bias_temp_coeff_m_s2_k``
  about the device's ``calibration_temp_c`` (the model is linear: a
  higher-order fit is refitted at order 1), its turn-on bias (the fit at
  T_ref less gravity along the mean direction), white noise and LSB.

Without one the file says the accelerometer part was not written, and why.
"""

from dataclasses import replace

from gyro_emulator import units
from gyro_emulator.analysis.calibrate.provenance import (accel_thermal_lines, as_comments,
                                                         thermal_lines)
from gyro_emulator.analysis.calibrate.thermal import polyfit_stats
from gyro_emulator.sensor.accel import accel_from_mapping, AccelTerms
from gyro_emulator.sensor.config import config_from_mapping, config_yaml, ErrorTerms, YamlKey
from gyro_emulator.units import AXES
from gyro_emulator.yaml_text import as_written, Figure
import numpy as np

FORMATS = ('px4', 'ardupilot', 'preset')
#: The warning of a PX4 file written without the gyro's device id.
PX4_NO_ID = ('TC_G0_ID is not in the PX4 file (no --px4-gyro-id): the thermal correction stays '
             "off until TC_G0_ID is set to the gyro's device id (param show CAL_GYRO0_ID)")
#: The warning of a PX4 file with the accelerometer but without its device id.
PX4_NO_ACCEL_ID = ('TC_A0_ID is not in the PX4 file (no --px4-accel-id): the accelerometer '
                   "correction stays off until TC_A0_ID is set to the accelerometer's device id "
                   '(param show CAL_ACC0_ID)')
#: Why a file has no accelerometer part, when the log has no accelerometer.
NO_ACCEL = 'not measured by this gyro log'
#: Largest PX4 INT32 parameter value.
_INT32_MAX = 2 ** 31 - 1
#: ArduPilot's fixed reference temperature (AP_InertialSensor_tempcal.cpp TEMP_REFERENCE), C.
ARDUPILOT_TREF_C = 35.0
#: ArduPilot stores its coefficients times this (SCALE_FACTOR).
ARDUPILOT_SCALE = 1.0e6


def _num(value):
    return f'{float(value):.9g}'


def _padded(coeffs):
    out = np.zeros(4)
    out[:len(coeffs)] = coeffs
    return out


def _require_three(fit, tool):
    missing = [a for a in AXES if a not in fit.coefficients]
    if missing:
        raise ValueError(f'--format {tool} needs all three gyro axes: the log has '
                         f'{", ".join(fit.coefficients)} (give x, y and z)')


def px4_params(fit):
    """Return the PX4 values {name: value}: TC_G0_TMIN/TMAX/TREF and TC_G0_X{k}_{axis}."""
    params = {'TC_G0_TMIN': fit.temp_min_c, 'TC_G0_TMAX': fit.temp_max_c,
              'TC_G0_TREF': fit.temp_ref_c}
    for i, axis in enumerate(AXES):
        coeffs = _padded(fit.coefficients[axis])
        for k in range(4):
            params[f'TC_G0_X{k}_{i}'] = float(coeffs[k])
    return params


def _check_gyro_id(gyro_id, name='px4_gyro_id', shown='CAL_GYRO0_ID'):
    if gyro_id is not None and not (isinstance(gyro_id, (int, np.integer))
                                    and 0 < gyro_id <= _INT32_MAX):
        raise ValueError(f'{name} = {gyro_id!r} is out of range: allowed 1 .. {_INT32_MAX} '
                         f'(the device id PX4 shows as {shown})')


def px4_accel_params(fit):
    """
    Return the accelerometer's PX4 values: TC_A0_TMIN/TMAX/TREF and TC_A0_X{k}_{axis}.

    X0 is the fit at TREF less the axis's median group mean (module docstring).
    """
    params = {'TC_A0_TMIN': fit.temp_min_c, 'TC_A0_TMAX': fit.temp_max_c,
              'TC_A0_TREF': fit.temp_ref_c}
    for i, axis in enumerate(AXES):
        coeffs = _padded(fit.coefficients[axis])
        coeffs[0] -= fit.median[axis]
        for k in range(4):
            params[f'TC_A0_X{k}_{i}'] = float(coeffs[k])
    return params


def _px4_accel(accel, accel_id, why):
    """Return (comment lines, parameter rows) of the accelerometer part of a PX4 file."""
    if accel is None:
        return [f'TC_A* (accelerometer): {why or NO_ACCEL}; this file leaves them unchanged.'], []
    _require_three(accel, 'px4')
    _check_gyro_id(accel_id, 'px4_accel_id', 'CAL_ACC0_ID')
    lines = accel_thermal_lines(accel, "TC_A0_*, m/s^2/K^k, less each axis's median group mean "
                                       'as PX4 process_sensor_caldata.py fits it')
    lines.append(f'TC_A0_ID = {accel_id}: the device id given (--px4-accel-id).' if accel_id
                 else 'Not written: TC_A0_ID (give --px4-accel-id, or set it after loading this '
                      'file). Until it is set PX4 applies no accelerometer correction.')
    rows = [('TC_A_ENABLE', 1, 6)] + ([('TC_A0_ID', accel_id, 6)] if accel_id else [])
    return lines, rows + [(n, v, 9) for n, v in sorted(px4_accel_params(accel).items())]


def px4(fit, gyro_id=None, accel=None, accel_id=None, accel_why=None):
    """
    Write the PX4 parameter file (module docstring); ``gyro_id`` becomes TC_G0_ID.

    ``accel`` is the accelerometer's fit (``accel_id`` its TC_A0_ID), or
    None and ``accel_why`` the reason it is not written.
    """
    _require_three(fit, 'px4')
    _check_gyro_id(gyro_id)
    accel_lines, accel_rows = _px4_accel(accel, accel_id, accel_why)
    convention = ('PX4 subtracts X0 + X1 d + X2 d^2 + X3 d^3, d = T - TC_G0_TREF with T held '
                  'within [TC_G0_TMIN, TC_G0_TMAX]; X_k in rad/s/K^k, temperatures in deg C '
                  '(TREF = middle of the range, as PX4 process_sensor_caldata.py sets it).')
    text = as_comments(thermal_lines(fit, 'px4', convention)
                       + ['Load with QGroundControl (Parameters > Tools > Load from file), then '
                          'reboot.',
                          (f'TC_G0_ID = {gyro_id}: the device id given (--px4-gyro-id); PX4 '
                           'applies TC_G0_* only to the gyro with that id.' if gyro_id else
                           'Not written: TC_G0_ID (a log does not give the device id: give '
                           '--px4-gyro-id, or set it after loading this file). Until it is set '
                           'PX4 applies no thermal correction: it corrects only the gyro whose '
                           'device id is TC_G0_ID.'),
                          *accel_lines,
                          '',
                          'Vehicle-Id Component-Id Name Value Type'])
    rows = [('TC_G_ENABLE', 1, 6)] + ([('TC_G0_ID', gyro_id, 6)] if gyro_id else [])
    rows += [(name, value, 9) for name, value in sorted(px4_params(fit).items())] + accel_rows
    return text + ''.join(f'1\t1\t{name}\t{_num(value) if kind == 9 else int(value)}\t{kind}\n'
                          for name, value, kind in rows)


def read_px4_params(text):
    """Parse a QGroundControl parameter file (the :func:`px4` layout) to {name: value}."""
    params = {}
    for number, line in enumerate(text.splitlines(), 1):
        if not line.strip() or line.lstrip().startswith('#'):
            continue
        cells = line.split('\t')
        if len(cells) != 5:
            raise ValueError(f'PX4 parameter file line {number}: {len(cells)} tab-separated '
                             'cells: expected 5 (vehicle, component, name, value, type)')
        try:
            params[cells[2]] = float(cells[3])
        except ValueError:
            raise ValueError(f'PX4 parameter file line {number}: {cells[2]} = {cells[3]!r} is '
                             'not a number') from None
    return params


def rebase(coeffs, old_ref_c, new_ref_c):
    """Re-expand a polynomial in (T - old_ref) as one in (T - new_ref), ascending powers."""
    poly = np.polynomial.Polynomial(coeffs)
    shifted = poly(np.polynomial.Polynomial([new_ref_c - old_ref_c, 1.0]))
    return _padded(shifted.coef[:4]) if len(shifted.coef) <= 4 else shifted.coef


def ardupilot(fit, accel=None, accel_why=None):
    """Write the ArduPilot parameter file (module docstring); ``accel`` as for :func:`px4`."""
    _require_three(fit, 'ardupilot')
    convention = ('ArduPilot subtracts p(T - 35) - p(T_cal - 35), p(d) = (GYR1 d + GYR2 d^2 '
                  '+ GYR3 d^3) 1e-6 rad/s, T held within [TMIN, TMAX]; the constant term is '
                  'not stored (the ordinary gyro calibration at T_cal takes it): GYRk are the '
                  f'fitted rad/s/K^k, re-expanded about {ARDUPILOT_TREF_C:g} C, times 1e6.')
    if accel is None:
        acc_lines = [f'INS_TCAL1_ACC* (accelerometer): {accel_why or NO_ACCEL}; left unset '
                     '(0 = no correction).']
    else:
        _require_three(accel, 'ardupilot')
        acc_lines = accel_thermal_lines(accel, 'INS_TCAL1_ACC*, the same convention in '
                                               'm/s^2/K^k, within the one TMIN..TMAX')
    lines = thermal_lines(fit, 'ardupilot', convention) + acc_lines + [
        'ArduPilot learns on board only over 10 K or more; these offline values have no such '
        'limit but hold only within TMIN..TMAX.']
    rows = [('INS_TCAL1_ENABLE', '1'), ('INS_TCAL1_TMIN', f'{fit.temp_min_c:.2f}'),
            ('INS_TCAL1_TMAX', f'{fit.temp_max_c:.2f}')]
    shifted = {a: rebase(fit.coefficients[a], fit.temp_ref_c, ARDUPILOT_TREF_C) for a in AXES}
    for k in (1, 2, 3):
        for axis in AXES:
            rows.append((f'INS_TCAL1_GYR{k}_{axis.upper()}',
                         _num(shifted[axis][k] * ARDUPILOT_SCALE)))
    if accel is not None:
        acc = {a: rebase(accel.coefficients[a], accel.temp_ref_c, ARDUPILOT_TREF_C) for a in AXES}
        rows += [(f'INS_TCAL1_ACC{k}_{a.upper()}', _num(acc[a][k] * ARDUPILOT_SCALE))
                 for k in (1, 2, 3) for a in AXES]
    return as_comments(lines) + ''.join(f'{name} {value}\n' for name, value in rows)


def _preset_axis_values(fit, axis):
    """(turn-on bias, c1, c2) about T_ref: the fit itself up to order 2, else an order-2 refit."""
    if fit.order <= 2:
        coeffs = _padded(fit.coefficients[axis])
        return coeffs[0], coeffs[1], coeffs[2]
    g = fit.groups[axis]
    coeffs, _, _ = polyfit_stats(g.temp_c - fit.temp_ref_c, g.rate_rad_s, 2)
    return coeffs[0], coeffs[1], coeffs[2]


def preset(fit, accel=None, accel_why=None):
    """
    Write this emulator's sensor YAML (module docstring), N and the LSB as the fit carries them.

    ``fit`` needs its white noise and LSB
    (:func:`gyro_emulator.analysis.calibrate.thermal.with_white_noise`), as
    does ``accel``, the accelerometer's fit (or None, ``accel_why`` saying
    why).
    """
    if fit.arw_rad_s_sqrt_hz is None or fit.lsb_rad_s is None:
        raise ValueError('--format preset needs the white noise and LSB of the log: '
                         'fit with thermal.with_white_noise first')
    convention = ('bias(T) = turn_on_bias + c1 (T - T_cal) + c2 (T - T_cal)^2 with T_cal = '
                  "device calibration_temp_c = the fit's T_ref; T is the die temperature "
                  "(thermal_lag off: the log's temperature is the die's).")
    values = {a: _preset_axis_values(fit, a) for a in fit.coefficients}
    lsb = fit.lsb_rad_s
    lines = thermal_lines(fit, 'preset', convention) + [
        'N (electronics_arw) from the same samples (IEEE Std 952 fit); bias instability and '
        'rate random walk: not measurable from this log, left at 0.']
    if fit.order > 2:
        lines.append("The emulator's bias model is quadratic: the cubic fit is refitted at "
                     'order 2 here.')
    if len(values) < 3:
        lines.append(f'Axes {", ".join(a for a in AXES if a not in values)} copy axis '
                     f'{next(iter(values))}.')
    if lsb > 0.0:
        lines.append(f'Samples lie on a grid of {lsb:.6g} rad/s (the LSB, or the precision the '
                     'log was written with): quantization on.')
    config, device = preset_config(fit, values)
    layout = _preset_layout(device, lsb)
    if accel is None:
        lines.append(f'Accelerometer: {accel_why or NO_ACCEL}; its terms are not written.')
    else:
        key, accel_config, accel_lines = _preset_accel(fit, accel)
        config, layout = replace(config, accelerometer=accel_config), layout + (key,)
        lines += accel_lines
    return config_yaml(config, layout, as_comments(lines))


#: The accelerometer's keys of ``--format preset`` (SI, 6-digit figures).
_ACCEL_FIGURES = ('electronics_noise_m_s2_sqrt_hz', 'turn_on_bias_m_s2', 'bias_temp_coeff_m_s2_k')


def _preset_accel(fit, accel):
    """
    Return (its YAML key, AccelConfig, comment lines) of the accelerometer of ``--format preset``.

    The bias is linear in (T - T_cal) with T_cal the gyro fit's T_ref (the
    device's ``calibration_temp_c``): the accelerometer's fit re-expanded
    there, refitted at order 1 when higher. The turn-on bias is its value at
    T_cal less gravity along the direction of the medians (as ``calibrate
    noise`` takes it); N and the LSB from the same samples.
    """
    if accel.arw_rad_s_sqrt_hz is None or accel.lsb_rad_s is None:
        raise ValueError("--format preset needs the accelerometer's white noise and LSB: fit "
                         'with thermal.with_white_noise first')
    lines = accel_thermal_lines(accel, 'accelerometer: bias_temp_coeff_m_s2_k about the '
                                       "device's calibration_temp_c, turn_on_bias_m_s2, "
                                       'electronics_noise_m_s2_sqrt_hz')
    median = np.array([accel.median[a] for a in AXES])
    gravity = median * (units.STANDARD_GRAVITY_M_S2 / np.linalg.norm(median))
    rows = {}
    for i, axis in enumerate(AXES):
        if accel.order > 1:
            g = accel.groups[axis]
            coeffs = polyfit_stats(g.temp_c - fit.temp_ref_c, g.rate_rad_s, 1)[0]
        else:
            coeffs = rebase(accel.coefficients[axis], accel.temp_ref_c, fit.temp_ref_c)
        rows[axis] = (accel.arw_rad_s_sqrt_hz[axis], coeffs[0] - gravity[i], coeffs[1])
    if accel.order > 1:
        lines.append("The emulator's accelerometer bias is linear in temperature: the fit is "
                     'refitted at order 1 here.')
    lines.append('turn_on_bias_m_s2 is the fit at calibration_temp_c less gravity, g = 9.80665 '
                 'm/s^2 along the direction of the medians (' + ', '.join(
                     f'{v:.5g}' for v in gravity) + ' m/s^2): a bias across gravity cannot be '
                 'told from a tilt at one attitude and is taken as none.')
    on = {'electronics_noise', 'turn_on_bias', 'bias_temperature'}
    mapping = {name: [as_written(rows[a][k]) for a in AXES]
               for k, name in enumerate(_ACCEL_FIGURES)}
    parts = (YamlKey('terms'),) + tuple(YamlKey(name, '.6g') for name in _ACCEL_FIGURES)
    if accel.lsb_rad_s > 0.0:
        on.add('quantization')
        mapping['lsb_m_s2'] = as_written(accel.lsb_rad_s)
        parts += (YamlKey('lsb_m_s2', '.6g', scalar=True),)
    mapping['terms'] = {name: name in on for name in AccelTerms.names()}
    return (YamlKey('accelerometer', parts=parts),
            accel_from_mapping(mapping, 'the accelerometer preset'), lines)


#: The bias and noise keys of ``--format preset``: 6-digit figures in datasheet units.
_PRESET_FIGURES = ('electronics_arw_deg_sqrt_h', 'turn_on_bias_deg_s', 'bias_temp_coeff_deg_s_k',
                   'bias_temp_coeff2_deg_s_k2')


def _preset_layout(device, lsb):
    """Return the keys ``--format preset`` writes; the device ``{preset, calibration_temp_c}``."""
    return ((YamlKey('device', given=device), YamlKey('terms'))
            + tuple(YamlKey(name, '.6g') for name in _PRESET_FIGURES)
            + ((YamlKey('lsb_deg_s', '.6g', scalar=True),) if lsb > 0.0 else ()))


def preset_config(fit, values):
    """
    Return (sensor configuration, its device entry) of ``--format preset`` (module docstring).

    ``values`` are (turn-on bias, c1, c2) per fitted axis (axes it lacks copy
    the first); every figure is the value the file holds: T_ref to 4
    decimals, the rest to 6 digits, so the configuration reads back from the
    text exactly.
    """
    lsb = fit.lsb_rad_s
    on = {'electronics_noise', 'turn_on_bias', 'bias_temperature'} | (
        {'quantization'} if lsb > 0.0 else set())
    rows = [values.get(a) or next(iter(values.values())) for a in AXES]
    noise = fit.arw_rad_s_sqrt_hz
    noise_rows = [noise.get(a) or next(iter(noise.values())) for a in AXES]
    device = {'preset': 'paper', 'calibration_temp_c': Figure(fit.temp_ref_c, '.4f')}
    figures = {'electronics_arw_deg_sqrt_h': [
        units.rad_s_sqrt_hz_to_arw_deg_sqrt_h(v) for v in noise_rows]}
    for k, name in enumerate(_PRESET_FIGURES[1:]):
        figures[name] = [units.rad_s_to_deg_s(v[k]) for v in rows]
    if lsb > 0.0:
        figures['lsb_deg_s'] = units.rad_s_to_deg_s(lsb)
    written = {name: np.vectorize(as_written)(v).tolist() for name, v in figures.items()}
    config = config_from_mapping({
        'device': {'preset': 'paper', 'calibration_temp_c': as_written(fit.temp_ref_c, '.4f')},
        'terms': {n: n in on for n in ErrorTerms.names()}, **written})
    return config, device


def write_thermal(fit, fmt, px4_gyro_id=None, accel=None, px4_accel_id=None, accel_why=None):
    """
    Return the text of format ``fmt`` (one of :data:`FORMATS`); ``preset`` needs N, LSB.

    ``px4_gyro_id`` (px4 only) is the gyro's device id, written as TC_G0_ID;
    ``accel`` the accelerometer's fit (or None, ``accel_why`` saying why),
    ``px4_accel_id`` its device id (TC_A0_ID).
    """
    for given, option in ((px4_gyro_id, '--px4-gyro-id'), (px4_accel_id, '--px4-accel-id')):
        if given is not None and fmt != 'px4':
            raise ValueError(f'{option} is for --format px4, not {fmt}')
    if fmt == 'px4':
        return px4(fit, px4_gyro_id, accel, px4_accel_id, accel_why)
    if fmt == 'ardupilot':
        return ardupilot(fit, accel, accel_why)
    if fmt == 'preset':
        return preset(fit, accel, accel_why)
    raise ValueError(f'format = {fmt!r} is not allowed: choose {", ".join(FORMATS)}')
