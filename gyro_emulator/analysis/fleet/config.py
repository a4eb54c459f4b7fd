"""
The fleet YAML: a nominal device, its fabrication tolerances, a temperature grid, specs.

A fleet is a population of parts drawn from one design. Every parameter is
``group.field`` in SI units:

* ``geometry.*``, ``material.*``, ``gas.*``, ``drive.*``: the float fields of
  :mod:`gyro_emulator.physics.params` (every length, film thickness, gap,
  package pressure, drive voltages ...; counts such as ``hole_count`` are
  not toleranced);
* ``mismatch.sense_beam_width_m``: how much wider the beams are as the sense
  mode bends them than as the drive mode does (an x/y etch asymmetry, m;
  nominal 0): it sets the drive-sense split;
* ``electronics.*``: the rate-noise density, bias temperature coefficient,
  bias instability and rate random walk of the read-out (one axis, SI);
* ``extended.<term>.<param>``: a parameter of an extended term
  (:mod:`gyro_emulator.sensor.extensions`) the fleet's ``extended:`` mapping
  turns on, in the sensor YAML's format and units, with that module's ranges
  (one read-out axis: a per-axis amplitude is one number).

A tolerance is ``{normal: X}`` (X = sigma) or ``{uniform: X}`` (X = half
width), X absolute in the parameter's unit or ``"N%"`` of the nominal, with
an optional ``offset`` (same forms). A factor is one draw per device that
moves several parameters together (``field += coefficient * factor``, or
``field *= 1 + coefficient * factor`` for a factor given in %): a lateral
over-etch widens gaps and holes and thins beams and fingers at once.

``specs`` bound datasheet metrics of the part; ``model_checks`` bound the
metrics that say whether the first-order model holds for a part
(``exact_ratio``): those are reported apart and are not in the yield.

Every error is one line naming the key, the value and what is allowed.
"""

from dataclasses import dataclass, field, fields, replace
import math
import os

from gyro_emulator.physics import params as physics_params
from gyro_emulator.resources import read_yaml
from gyro_emulator.sensor.config import device_from_spec, field_ranges, load_sensor_config
from gyro_emulator.sensor.extensions import ExtendedTerms, TERM_TYPES
from gyro_emulator.validation import check_range, check_temperature_c, quote

#: Device parameter groups and the component of the Device each one names.
DEVICE_GROUPS = ('geometry', 'material', 'gas', 'drive')

#: Electronics terms of one read-out axis: fleet name -> SensorConfig field.
ELECTRONICS = {
    'noise_rad_s_sqrt_hz': 'electronics_noise_rad_s_sqrt_hz',
    'bias_temp_coeff_rad_s_k': 'bias_temp_coeff_rad_s_k',
    'bias_instability_rad_s': 'bias_instability_rad_s',
    'rate_random_walk_rad_s_sqrt_s': 'rate_random_walk_rad_s_sqrt_s',
}

#: The x/y suspension asymmetry parameter (see the module docstring).
MISMATCH = 'mismatch.sense_beam_width_m'

#: Prefix of the parameters of the extended terms: ``extended.<term>.<param>``.
EXTENDED = 'extended.'

#: Metrics a spec may bound (unit in the name); see analysis.fleet.evaluate.
METRICS = ('f_drive_hz', 'split_hz', 'q_drive', 'q_sense', 'sf_m_per_rad_s',
           'sf_error_pct', 'sf_tempco_ppm_k', 'sf_residual_pct', 'arw_deg_sqrt_h',
           'bias_tempco_deg_s_k', 'range_dps', 'exact_ratio', 'sf_error_exact_pct')

#: Metrics that exist only with ``exact: true``.
EXACT_METRICS = ('exact_ratio', 'sf_error_exact_pct')

#: Metrics that measure the first-order model's validity, not the part: a
#: bound on them goes under ``model_checks``, never ``specs`` (it is
#: reported apart and is not in the yield).
MODEL_CHECK_METRICS = ('exact_ratio',)

_TOP_KEYS = ('device', 'calibration_temp_c', 'temperatures_c', 'sense_limit_fraction',
             'mismatch', 'electronics', 'tolerances', 'factors', 'specs', 'invalid',
             'exact', 'sensor_runs', 'attribution_devices', 'model_checks', 'extended')


@dataclass(frozen=True)
class Parameter:
    """A parameter that can vary: its name, nominal value and allowed range."""

    name: str
    nominal: float
    low: float
    high: float
    unit: str
    low_open: bool


@dataclass(frozen=True)
class Tolerance:
    """Independent variation of one parameter: nominal + offset + scale z."""

    name: str
    dist: str
    scale: float
    offset: float


@dataclass(frozen=True)
class Factor:
    """A common draw moving several parameters (relative when given in %)."""

    name: str
    dist: str
    scale: float
    relative: bool
    moves: tuple


@dataclass(frozen=True)
class Spec:
    """Bounds on one metric: low <= metric <= high (|metric| when ``absolute``)."""

    metric: str
    low: float
    high: float
    absolute: bool


@dataclass(frozen=True)
class SensorRuns:
    """Short sensor-level runs for the first ``devices`` devices (Allan N, B, K)."""

    devices: int
    duration_s: float
    rate_hz: float
    config: object


@dataclass(frozen=True)
class FleetConfig:
    """A parsed, validated fleet YAML (see the module docstring)."""

    device: physics_params.Device
    parameters: dict
    tolerances: tuple
    factors: tuple
    temperatures_c: tuple
    calibration_temp_c: float
    sense_limit_fraction: float
    specs: tuple
    invalid: str
    exact: bool
    sensor_runs: SensorRuns
    attribution_devices: int
    source: str = ''
    model_checks: tuple = ()
    # Out of the repr (the run's fingerprint) so a fleet without it keeps its
    # fingerprint; analysis.fleet.state adds it when given.
    extended: ExtendedTerms = field(default=None, repr=False)
    varied: tuple = field(default=(), init=False)

    def __post_init__(self):
        """Record the parameters that vary (sorted), from tolerances and factors."""
        names = {t.name for t in self.tolerances}
        for factor in self.factors:
            names.update(name for name, _ in factor.moves)
        object.__setattr__(self, 'varied', tuple(sorted(names)))

    def sources(self):
        """Return the names of the variation sources: tolerances, then factors."""
        return tuple(t.name for t in self.tolerances) + tuple(
            'factor.' + f.name for f in self.factors)


def _fail(where, message):
    raise ValueError(f'{where}: {message}')


def _mapping(where, value, allowed=None):
    if not isinstance(value, dict):
        _fail(where, f'{quote(value)} is not allowed: expected a mapping')
    if allowed is not None:
        unknown = sorted(set(map(str, value)) - set(allowed))
        if unknown:
            _fail(where, f'unknown key(s) {", ".join(unknown)}; allowed: '
                         f'{", ".join(allowed)}')
    return value


def _number(where, value):
    """
    Return ``value`` as a finite float, or fail naming ``where``.

    A number YAML 1.1 leaves a string (``1e-8``, an exponent without a dot)
    is the number it spells, as in the device mapping and the sensor YAML.
    """
    if isinstance(value, str):
        value = _spelled_number(value)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(
            value):
        _fail(where, f'{quote(value)} is not a finite number')
    return float(value)


def _spelled_number(text):
    """Return the float a string spells (``'1e-8'``), else the string unchanged."""
    try:
        return float(text)
    except ValueError:
        return text


def amount(where, value):
    """
    Parse an amount: a number (absolute) or ``"N%"`` (relative).

    Returns
    -------
    (float, bool)
        The value (a fraction when relative) and whether it was relative.

    """
    if isinstance(value, str) and not value.strip().endswith('%'):
        if isinstance(_spelled_number(value), str):
            _fail(where, f'{quote(value)} is not a number or a percentage such as "2%"')
        return _number(where, value), False
    if isinstance(value, str):
        try:
            number = float(value.strip()[:-1])
        except ValueError:
            _fail(where, f'{quote(value)} is not a number or a percentage such as "2%"')
        if not math.isfinite(number):
            _fail(where, f'{quote(value)} is not finite')
        return number / 100.0, True
    return _number(where, value), False


def _parameters(device, mismatch, electronics):
    """Every parameter that can vary, with its nominal value and range."""
    out = {}
    for group in DEVICE_GROUPS:
        component = getattr(device, group)
        for spec in fields(component):
            if 'range' not in spec.metadata or spec.type is not float:
                continue
            low, high, unit, low_open = spec.metadata['range']
            out[f'{group}.{spec.name}'] = Parameter(
                f'{group}.{spec.name}', float(getattr(component, spec.name)), low, high, unit,
                low_open)
    width = min(device.geometry.beam1_width_m, device.geometry.beam2_width_m)
    out[MISMATCH] = Parameter(MISMATCH, mismatch, -width, 1e-4, 'm', True)
    ranges = field_ranges()
    for name, target in ELECTRONICS.items():
        _, low, high, unit, low_open = ranges[target]
        out['electronics.' + name] = Parameter('electronics.' + name, electronics[name], low,
                                               high, unit, low_open)
    return out


def _extended(raw):
    """Parse the fleet's ``extended:`` mapping (the sensor YAML's format); None if absent."""
    if raw is None:
        return None
    ext = ExtendedTerms.from_mapping(raw, 'extended')
    for name in ext.active():
        term = ext.get(name)
        for param, (kind, *_rest) in term.RANGES.items():
            value = getattr(term, param)
            if kind == 'axis' and len(set(value)) != 1:
                _fail(f'extended.{name}.{param}', f'{quote(list(value))} is not allowed: a fleet '
                                                  'part has one read-out axis: give one number')
    return ext


def extended_parameters(ext, calibration_temp_c):
    """
    Return the parameters of the active extended terms, ``extended.<term>.<param>``.

    Nominal: the term's value (one axis); range: the term's own ``RANGES``
    (:mod:`gyro_emulator.sensor.extensions`). ``ref_temp_c`` left unset is
    the calibration temperature, as in the sensor model.
    """
    out = {}
    for name in (() if ext is None else ext.active()):
        term = ext.get(name)
        for param, (kind, low, high, unit) in term.RANGES.items():
            value = getattr(term, param)
            if kind == 'axis':
                value = value[0]
            elif value is None:
                value = calibration_temp_c
            key = f'{EXTENDED}{name}.{param}'
            out[key] = Parameter(key, float(value), low, high, unit, kind == 'open')
    return out


def _counts(device):
    return sorted(f'{group}.{spec.name}' for group in DEVICE_GROUPS
                  for spec in fields(getattr(device, group)) if spec.type is int)


def _parameter(where, name, parameters, device):
    if name in parameters:
        return parameters[name]
    if name in _counts(device):
        _fail(where, f'{name} is a count: tolerances apply to lengths, thicknesses, gaps, '
                     'pressures, material constants and electronics terms')
    if name.startswith(EXTENDED):
        _extended_unknown(where, name, parameters)
    _fail(where, f'unknown parameter {quote(name)}; allowed: {", ".join(sorted(parameters))}')


def _extended_unknown(where, name, parameters):
    """Fail on an unknown ``extended.<term>.<param>``: name the term or its parameters."""
    term, _, param = name[len(EXTENDED):].partition('.')
    if term not in TERM_TYPES:
        _fail(where, f'unknown extended term {quote(term)}; allowed: {", ".join(TERM_TYPES)}')
    allowed = [k for k in parameters if k.startswith(f'{EXTENDED}{term}.')]
    if not allowed:
        _fail(where, f"extended.{term} is not on in the fleet's extended: mapping: give "
                     'the term and its nominal values there')
    _fail(where, f'unknown parameter {quote(param)} of extended.{term}; allowed: '
                 f'{", ".join(k.rsplit(".", 1)[1] for k in allowed)}')


def _distribution(where, value, allowed_extra=()):
    """Return (dist, amount, relative, the mapping) of ``{normal|uniform: X, ...}``."""
    _mapping(where, value, ('normal', 'uniform') + tuple(allowed_extra))
    kinds = [k for k in ('normal', 'uniform') if k in value]
    if len(kinds) != 1:
        _fail(where, f'{quote(value)} is not allowed: give exactly one of normal (sigma) or '
                     'uniform (half width)')
    scale, relative = amount(f'{where}.{kinds[0]}', value[kinds[0]])
    if scale < 0.0:
        _fail(f'{where}.{kinds[0]}', f'{quote(value[kinds[0]])} is out of range: allowed >= 0')
    return kinds[0], scale, relative


def _tolerances(raw, parameters, device):
    out = []
    for name, value in _mapping('tolerances', raw or {}).items():
        where = f'tolerances.{name}'
        param = _parameter(where, str(name), parameters, device)
        dist, scale, relative = _distribution(where, value, ('offset',))
        offset, offset_relative = amount(f'{where}.offset', value.get('offset', 0.0))
        for is_relative, key in ((relative, dist), (offset_relative, 'offset')):
            if is_relative and param.nominal == 0.0:
                _fail(f'{where}.{key}', f'a percentage of a zero nominal ({name} = 0) is '
                                        'not allowed: give an absolute value')
        scale *= abs(param.nominal) if relative else 1.0
        offset *= abs(param.nominal) if offset_relative else 1.0
        out.append(Tolerance(param.name, dist, scale, offset))
    return tuple(sorted(out, key=lambda t: t.name))


def _factors(raw, parameters, device):
    out = []
    for name, value in _mapping('factors', raw or {}).items():
        where = f'factors.{name}'
        dist, scale, relative = _distribution(where, value, ('moves',))
        moves = _mapping(f'{where}.moves', value.get('moves'))
        if not moves:
            _fail(f'{where}.moves', 'is empty: name the parameters the factor moves')
        pairs = []
        for target, coefficient in moves.items():
            param = _parameter(f'{where}.moves', str(target), parameters, device)
            pairs.append((param.name, _number(f'{where}.moves.{target}', coefficient)))
            if relative and param.nominal == 0.0:
                _fail(f'{where}.moves.{target}', 'a relative factor cannot move a zero '
                                                 'nominal: give the factor in absolute units')
        out.append(Factor(str(name), dist, scale, relative, tuple(sorted(pairs))))
    return tuple(sorted(out, key=lambda f: f.name))


def _specs(raw, exact, key='specs'):
    """Parse ``specs`` (datasheet metrics) or ``model_checks`` (model-validity metrics)."""
    out = []
    allowed = MODEL_CHECK_METRICS if key == 'model_checks' else tuple(
        m for m in METRICS if m not in MODEL_CHECK_METRICS)
    for metric, value in _mapping(key, raw or {}).items():
        where = f'{key}.{metric}'
        if key == 'specs' and metric in MODEL_CHECK_METRICS:
            _fail(where, 'is a check of the first-order model, not a part spec: put it '
                         'under model_checks (reported apart, not in the yield)')
        if metric not in allowed:
            _fail(key, f'unknown metric {quote(metric)}; allowed: {", ".join(allowed)}')
        if metric in EXACT_METRICS and not exact:
            _fail(where, 'needs the exact 2-DOF evaluation: set exact: true')
        bounds = _mapping(where, value, ('min', 'max', 'abs_max'))
        if not bounds:
            _fail(where, 'give min, max or abs_max')
        if 'abs_max' in bounds:
            if set(bounds) != {'abs_max'}:
                _fail(where, 'abs_max cannot be combined with min or max')
            high = _number(f'{where}.abs_max', bounds['abs_max'])
            if high < 0.0:
                _fail(f'{where}.abs_max', f'{quote(high)} is out of range: allowed >= 0')
            out.append(Spec(str(metric), 0.0, high, True))
            continue
        low = _number(f'{where}.min', bounds['min']) if 'min' in bounds else -math.inf
        high = _number(f'{where}.max', bounds['max']) if 'max' in bounds else math.inf
        if low > high:
            _fail(where, f'min {quote(low)} is above max {quote(high)}')
        out.append(Spec(str(metric), low, high, False))
    return tuple(out)


def _temperatures(raw, calibration_temp_c):
    if raw is None:
        raw = [-40.0, -20.0, 0.0, 25.0, 45.0, 65.0, 85.0]
    if not isinstance(raw, list) or not raw:
        _fail('temperatures_c', f'{quote(raw)} is not allowed: expected a list of temperatures, C')
    temps = tuple(_number(f'temperatures_c[{i}]', t) for i, t in enumerate(raw))
    check_temperature_c(temps, 'fleet', 'temperatures_c')
    if len(set(temps)) != len(temps) or len(temps) < 2:
        _fail('temperatures_c', f'{quote(list(temps))} is not allowed: give at least two '
                                'different temperatures')
    check_temperature_c(calibration_temp_c, 'fleet', 'calibration_temp_c')
    return tuple(sorted(temps))


def _sensor_runs(raw):
    if raw is None:
        return None
    where = 'sensor_runs'
    raw = _mapping(where, raw, ('devices', 'duration_s', 'rate_hz', 'config'))
    devices = raw.get('devices', 8)
    if isinstance(devices, bool) or not isinstance(devices, int):
        _fail(f'{where}.devices', f'{quote(devices)} is not a whole number')
    check_range(where, 'devices', devices, 1, 1024, '', low_open=False)
    duration = check_range(where, 'duration_s', _number(f'{where}.duration_s',
                                                        raw.get('duration_s', 600.0)),
                           10.0, 86400.0, 's', low_open=False)
    rate = check_range(where, 'rate_hz', _number(f'{where}.rate_hz', raw.get('rate_hz', 100.0)),
                       1.0, 10000.0, 'Hz', low_open=False)
    return SensorRuns(int(devices), duration, rate, load_sensor_config(raw.get('config')))


def _nominals(where, raw, allowed, defaults):
    values = dict(defaults)
    for key, value in _mapping(where, raw or {}, allowed).items():
        values[key] = _number(f'{where}.{key}', value)
    return values


def config_from_mapping(mapping, source=''):
    """
    Build a :class:`FleetConfig` from a parsed fleet YAML mapping.

    Raises
    ------
    ValueError
        One line naming the key, the value and what is allowed: unknown keys,
        unknown or non-tolerable parameters, impossible nominal geometry,
        bad distributions, specs or temperatures.

    """
    raw = _mapping(source or 'fleet YAML', mapping, _TOP_KEYS)
    device = device_from_spec(raw.get('device', 'paper'), 'device')
    cal = _number('calibration_temp_c', raw.get('calibration_temp_c',
                                                device.calibration_temp_c))
    temps = _temperatures(raw.get('temperatures_c'), cal)
    mismatch = _nominals('mismatch', raw.get('mismatch'), ('sense_beam_width_m',),
                         {'sense_beam_width_m': 0.0})['sense_beam_width_m']
    electronics = _nominals('electronics', raw.get('electronics'), tuple(ELECTRONICS),
                            dict.fromkeys(ELECTRONICS, 0.0))
    parameters = _parameters(device, mismatch, electronics)
    extended = _extended(raw.get('extended'))
    parameters.update(extended_parameters(extended, cal))
    for param in parameters.values():
        group, name = param.name.rsplit('.', 1)
        check_range(group, name, param.nominal, param.low, param.high, param.unit,
                    param.low_open)
    exact = raw.get('exact', False)
    if not isinstance(exact, bool):
        _fail('exact', f'{quote(exact)} is not allowed: choose true or false')
    invalid = raw.get('invalid', 'reject')
    if invalid not in ('reject', 'clip'):
        _fail('invalid', f'{quote(invalid)} is not allowed: choose reject or clip')
    attribution = raw.get('attribution_devices', 65536)
    if isinstance(attribution, bool) or not isinstance(attribution, int):
        _fail('attribution_devices', f'{quote(attribution)} is not a whole number')
    check_range('fleet', 'attribution_devices', attribution, 0, 1 << 16, '', low_open=False)
    fraction = check_range('fleet', 'sense_limit_fraction', _number(
        'sense_limit_fraction', raw.get('sense_limit_fraction', 0.1)), 0.0, 1.0, '')
    return FleetConfig(
        device=replace(device, calibration_temp_c=cal), parameters=parameters,
        tolerances=_tolerances(raw.get('tolerances'), parameters, device),
        factors=_factors(raw.get('factors'), parameters, device), temperatures_c=temps,
        calibration_temp_c=cal, sense_limit_fraction=fraction,
        specs=_specs(raw.get('specs'), exact), invalid=invalid, exact=exact,
        sensor_runs=_sensor_runs(raw.get('sensor_runs')), attribution_devices=attribution,
        source=source, model_checks=_specs(raw.get('model_checks'), exact, 'model_checks'),
        extended=extended)


def load_fleet_config(path):
    """Read and validate a fleet YAML file (see :func:`config_from_mapping`)."""
    if not os.path.isfile(str(path)):
        raise ValueError(f'fleet YAML {quote(str(path))} is not a readable file')
    return config_from_mapping(read_yaml(path), source=str(path))
