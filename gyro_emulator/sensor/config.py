"""
Configuration of the 3-axis gyro error model: a frozen, validated dataclass.

A :class:`SensorConfig` holds one physics device per axis (its scale factor,
temperature dependence, sense-mode dynamics and Brownian noise come from the
physics) and the error terms a datasheet specifies on top. Every term can be
switched off through :class:`ErrorTerms`; with all terms off the model's
output equals the true rate exactly.

All fields are SI (rad/s, s, deg C, m/s^2). Per-axis fields are length-3
tuples (x, y, z); a scalar is broadcast to the three axes. YAML files may use
datasheet units instead through the aliases in :data:`YAML_ALIASES`
(``bias_instability_deg_h``, ``electronics_arw_deg_sqrt_h``, ...), converted
by :mod:`gyro_emulator.units`, the one place for unit conversions.

The accelerometer of the part is :attr:`SensorConfig.accelerometer`, an
:class:`~gyro_emulator.sensor.accel.AccelConfig` (YAML key ``accelerometer``;
without it, the default: the proof mass's Brownian noise).

Presets live in ``config/sensor_<name>.yaml`` (:data:`PRESET_NAMES`); their
YAML comments cite the source of every figure.
"""

from dataclasses import asdict, dataclass, field, fields, replace
import os

from gyro_emulator import units
from gyro_emulator.physics.params import Device, from_mapping
from gyro_emulator.physics.presets import DEFAULT_PRESET, physics_preset, PHYSICS_PRESETS
from gyro_emulator.resources import config_dir, read_yaml
from gyro_emulator.sensor.accel import accel_from_mapping, accel_yaml_value, AccelConfig
from gyro_emulator.sensor.extensions import ExtendedTerms, MIN_TIME_CONSTANT_S
from gyro_emulator.sensor.fields import (check_lsb, check_zero_diagonal, checked, converter,
                                         spell, Switches, YamlKey)
from gyro_emulator.validation import quote
import numpy as np

#: Sensor presets shipped in ``config/sensor_<name>.yaml``.
PRESET_NAMES = ('paper', 'consumer', 'tactical')
DEFAULT_SENSOR_PRESET = 'paper'


@dataclass(frozen=True)
class ErrorTerms(Switches):
    """
    On/off switch of every term of the error model (all on by default).

    Physics terms: ``scale_factor_temperature`` (Young's modulus, gas damping
    and pressure, Eq 5-22), ``sense_dynamics`` (sense-mode envelope, unity DC
    gain), ``mechanical_noise`` (Brownian ARW of the sense mode) and
    ``thermal_lag`` (die temperature lags ambient). The others are the
    datasheet terms named by the matching :class:`SensorConfig` fields.
    """

    scale_factor_temperature: bool = True
    sense_dynamics: bool = True
    output_filter: bool = True
    thermal_lag: bool = True
    turn_on_bias: bool = True
    bias_temperature: bool = True
    mechanical_noise: bool = True
    electronics_noise: bool = True
    bias_instability: bool = True
    rate_random_walk: bool = True
    scale_factor_error: bool = True
    nonlinearity: bool = True
    misalignment: bool = True
    g_sensitivity: bool = True
    quantization: bool = True
    saturation: bool = True
    latency: bool = True
    timestamp_jitter: bool = True
    clock_drift: bool = True


#: Allowed values of the fields by kind ('axis': 3 numbers or one for all
#: axes, 'scalar', 'matrix': 3x3, 'pair': 2 numbers, 'optional': a number or
#: None): name -> (low, high, unit). Sanity limits for MEMS gyros, not design
#: rules; closed ranges, but for the low bounds in _OPEN_LOW.
_RANGES = {
    'axis': {
        'mode_split_hz': (0.0, 5000.0, 'Hz'),
        'turn_on_bias_rad_s': (-10.0, 10.0, 'rad/s'),
        'turn_on_bias_sigma_rad_s': (0.0, 10.0, 'rad/s'),
        'bias_temp_coeff_rad_s_k': (-0.1, 0.1, 'rad/s/K'),
        'bias_temp_coeff2_rad_s_k2': (-0.01, 0.01, 'rad/s/K^2'),
        'electronics_noise_rad_s_sqrt_hz': (0.0, 1.0, 'rad/s/sqrt(Hz)'),
        'bias_instability_rad_s': (0.0, 1.0, 'rad/s'),
        'rate_random_walk_rad_s_sqrt_s': (0.0, 1.0, 'rad/s/sqrt(s)'),
        'scale_factor_error': (-0.5, 0.5, ''),
        'nonlinearity_s_rad': (-1.0, 1.0, 's/rad'),
        'lsb_rad_s': (0.0, 1.0, 'rad/s (0 = none)'),
        'range_rad_s': (0.0, 1000.0, 'rad/s'),
    },
    'scalar': {
        'output_filter_hz': (0.0, 1e5, 'Hz (0 = none)'),
        'output_filter_order': (1, 4, ''),
        'thermal_time_constant_s': (0.0, 1e5, 's'),
        'self_heating_c': (-20.0, 50.0, 'C'),
        'bias_instability_per_decade': (0.5, 4.0, 'terms/decade'),
        'latency_s': (0.0, 1.0, 's'),
        'timestamp_jitter_s': (0.0, 0.1, 's'),
        'clock_drift_ppm': (-1e4, 1e4, 'ppm'),
    },
    'matrix': {
        'misalignment': (-0.2, 0.2, 'rad'),
        'g_sensitivity_rad_s_m_s2': (-0.1, 0.1, 'rad/s per m/s^2'),
    },
    'pair': {'bias_instability_band_s': (1e-3, 1e6, 's')},
    'optional': {'initial_die_temp_c': (-60.0, 200.0, 'C')},
}
_OPEN_LOW = frozenset({'range_rad_s'})


def field_ranges():
    """
    Return the documented range of every numeric :class:`SensorConfig` field.

    ``{name: (kind, low, high, unit, low_open)}``; ``kind`` is ``axis``,
    ``scalar``, ``matrix``, ``pair`` or ``optional`` (see ``_RANGES``). A
    value inside the range gives a working model or a one-line ValueError
    naming the field (e.g. a filter cut-off at or above Nyquist), nothing else.
    """
    return {name: (kind, low, high, unit, name in _OPEN_LOW)
            for kind, ranges in _RANGES.items() for name, (low, high, unit) in ranges.items()}


#: Smallest non-zero quantisation step, rad/s (0.2 mdeg/h: far below any real
#: part's LSB, and range / LSB stays an exact count in float64).
MIN_LSB_RAD_S = 1e-9


@dataclass(frozen=True)
class SensorConfig:
    """
    Parameters of the 3-axis gyro error model (SI units; per-axis = (x, y, z)).

    The output of axis i is (see :mod:`gyro_emulator.sensor.model`)::

        x     = (I + misalignment) omega
        s     = H_sense[ SF_i(T_die) (1 + scale_factor_error_i) s_x (x_i + nonlinearity_i x_i^2) ]
        bias  = turn_on + c1 dT + c2 dT^2 + G a + flicker(B) + random walk(K) + b_x
        y     = Q( sat( H_filter[ s + bias + white(N_mech(T_die), N_elec) ] ) )

    with dT = T_die - calibration temperature of the axis's device, and b_x,
    s_x the extended terms (0 and 1 unless ``extended`` sets some).

    Attributes
    ----------
    device : tuple of 3 gyro_emulator.physics.params.Device
        Physics device of each axis (also accepts one Device or a preset name).
    terms : ErrorTerms
        On/off switches.
    mode_split_hz : tuple
        Drive/sense frequency split for the sense dynamics, Hz.
    output_filter_hz, output_filter_order : float, int
        Digital Butterworth low-pass of the ASIC (0 Hz = none).
    thermal_time_constant_s, self_heating_c : float
        Die temperature lag behind ambient and its steady offset.
    turn_on_bias_rad_s, turn_on_bias_sigma_rad_s : tuple
        Fixed turn-on bias and the sigma of its run-to-run random part.
    bias_temp_coeff_rad_s_k, bias_temp_coeff2_rad_s_k2 : tuple
        Zero-rate bias temperature coefficients (linear, quadratic).
    electronics_noise_rad_s_sqrt_hz : tuple
        Electronics white rate noise, two-sided density (= its ARW N).
    bias_instability_rad_s, bias_instability_band_s, bias_instability_per_decade
        B (Allan floor 0.664 B), the correlation-time band of the flicker
        model and its Gauss-Markov terms per decade.
    rate_random_walk_rad_s_sqrt_s : tuple
        K, rad/s/sqrt(s).
    scale_factor_error, nonlinearity_s_rad : tuple
        Gain error (ratio) and quadratic nonlinearity (per rad/s).
    misalignment, g_sensitivity_rad_s_m_s2 : 3x3 tuples
        Cross-axis coupling (zero diagonal) and bias per m/s^2 of specific force.
    lsb_rad_s, range_rad_s : tuple
        Quantisation step (0 = none) and full-scale range.
    latency_s, timestamp_jitter_s, clock_drift_ppm : float
        Output delay, its Gaussian jitter (sigma; each draw clipped to +-0.45 of
        a sample period, so stamps stay strictly increasing) and the sensor
        clock error.
    initial_die_temp_c : float or None
        Die temperature at the first sample (None: in equilibrium with it).
    extended : ExtendedTerms
        The terms of the causes diagnose names beyond these (bias hysteresis,
        polynomials in time, steps, pressure drift, ...; all off by default:
        :mod:`gyro_emulator.sensor.extensions`). YAML key ``extended``.
    accelerometer : AccelConfig
        The part's accelerometer (:mod:`gyro_emulator.sensor.accel`; run by
        :class:`gyro_emulator.sensor.imu.ImuModel`). YAML key ``accelerometer``.

    """

    device: tuple = (PHYSICS_PRESETS[DEFAULT_PRESET],) * 3
    terms: ErrorTerms = field(default_factory=ErrorTerms)
    mode_split_hz: tuple = (0.0, 0.0, 0.0)
    output_filter_hz: float = 0.0
    output_filter_order: int = 2
    thermal_time_constant_s: float = 0.0
    self_heating_c: float = 0.0
    turn_on_bias_rad_s: tuple = (0.0, 0.0, 0.0)
    turn_on_bias_sigma_rad_s: tuple = (0.0, 0.0, 0.0)
    bias_temp_coeff_rad_s_k: tuple = (0.0, 0.0, 0.0)
    bias_temp_coeff2_rad_s_k2: tuple = (0.0, 0.0, 0.0)
    electronics_noise_rad_s_sqrt_hz: tuple = (0.0, 0.0, 0.0)
    bias_instability_rad_s: tuple = (0.0, 0.0, 0.0)
    bias_instability_band_s: tuple = (0.1, 1000.0)
    bias_instability_per_decade: float = 1.0
    rate_random_walk_rad_s_sqrt_s: tuple = (0.0, 0.0, 0.0)
    scale_factor_error: tuple = (0.0, 0.0, 0.0)
    nonlinearity_s_rad: tuple = (0.0, 0.0, 0.0)
    misalignment: tuple = ((0.0,) * 3,) * 3
    g_sensitivity_rad_s_m_s2: tuple = ((0.0,) * 3,) * 3
    lsb_rad_s: tuple = (0.0, 0.0, 0.0)
    range_rad_s: tuple = (34.9066, 34.9066, 34.9066)
    latency_s: float = 0.0
    timestamp_jitter_s: float = 0.0
    clock_drift_ppm: float = 0.0
    initial_die_temp_c: float = None
    extended: ExtendedTerms = field(default_factory=ExtendedTerms)
    accelerometer: AccelConfig = field(default_factory=AccelConfig)

    def __post_init__(self):
        """Normalise per-axis fields to tuples and validate every field."""
        object.__setattr__(self, 'device', _devices(self.device))
        if not isinstance(self.extended, ExtendedTerms):
            raise ValueError(
                f'SensorConfig.extended = {quote(self.extended)} is not allowed: expected '
                'an ExtendedTerms')
        if not isinstance(self.terms, ErrorTerms):
            raise ValueError(
                f'SensorConfig.terms = {quote(self.terms)} is not allowed: expected '
                'an ErrorTerms')
        if not isinstance(self.accelerometer, AccelConfig):
            raise ValueError(f'SensorConfig.accelerometer = {quote(self.accelerometer)} is not '
                             'allowed: expected an AccelConfig')
        for kind, ranges in _RANGES.items():
            for name, limits in ranges.items():
                object.__setattr__(self, name, checked('SensorConfig', name, getattr(self, name),
                                                       kind, limits, name in _OPEN_LOW))
        check_lsb('SensorConfig', 'lsb_rad_s', self.lsb_rad_s, MIN_LSB_RAD_S, 1, 'rad/s')
        tau = self.thermal_time_constant_s
        if 0.0 < tau < MIN_TIME_CONSTANT_S:
            raise ValueError(f'SensorConfig.thermal_time_constant_s = {tau!r} is out of range: '
                             f'allowed 0 (no lag) or [{MIN_TIME_CONSTANT_S:g}, 1e+05] s')
        if self.output_filter_order != int(self.output_filter_order):
            raise ValueError(
                f'SensorConfig.output_filter_order = {quote(self.output_filter_order)}'
                ' is not allowed: choose 1, 2, 3 or 4')
        object.__setattr__(self, 'output_filter_order', int(self.output_filter_order))
        band = self.bias_instability_band_s
        if band[0] > band[1]:
            raise ValueError(
                f'SensorConfig.bias_instability_band_s = {quote(band)} is not allowed:'
                ' the first (shortest) correlation time must not exceed the second')
        check_zero_diagonal('SensorConfig', self.misalignment)

    @classmethod
    def ideal(cls, device=None):
        """Return every error term off (the accelerometer's too): output = true input."""
        kwargs = {} if device is None else {'device': device}
        return cls(terms=ErrorTerms.none(), accelerometer=AccelConfig.ideal(), **kwargs)

    def with_terms(self, **switches):
        """Return a copy with some terms switched (``quantization=False``, ...)."""
        return replace(self, terms=replace(self.terms, **switches))

    def only(self, *names):
        """Return a copy with only the named terms on."""
        unknown = sorted(set(names) - set(ErrorTerms.names()))
        if unknown:
            raise ValueError(
                f'unknown error term(s) {", ".join(unknown)}; allowed: '
                f'{", ".join(ErrorTerms.names())}')
        return replace(self, terms=ErrorTerms(
            **{n: n in names for n in ErrorTerms.names()}))

    def axis_array(self, name):
        """Return a per-axis or matrix field as a float numpy array."""
        return np.array(getattr(self, name), dtype=float)


def _device_from_spec(spec, owner):
    if isinstance(spec, Device):
        return spec
    if isinstance(spec, str):
        try:
            return physics_preset(spec)
        except ValueError as exc:
            raise ValueError(f'{owner}: {exc}') from None
    if isinstance(spec, dict):
        spec = dict(spec)
        base = _device_from_spec(spec.pop('preset', DEFAULT_PRESET), owner)
        merged = asdict(base)
        for key, value in spec.items():
            if isinstance(value, dict) and isinstance(merged.get(key), dict):
                merged[key] = {**merged[key], **value}
            else:
                merged[key] = value
        return from_mapping(Device, merged, owner)
    raise ValueError(
        f'{owner} = {quote(spec)} is not allowed: give a physics preset name '
        f'({", ".join(sorted(PHYSICS_PRESETS))}), a mapping of device fields '
        '(optionally with "preset") or a list of three of those')


def device_from_spec(spec, owner):
    """
    Return a physics Device from a preset name, a Device or a mapping of fields.

    A mapping may name a ``preset`` to start from and override any field,
    nested by component (``gas: {pressure_pa: 100}``); errors name ``owner``.
    """
    return _device_from_spec(spec, owner)


def _devices(spec):
    owner = 'SensorConfig.device'
    if isinstance(spec, (list, tuple)):
        if len(spec) != 3:
            raise ValueError(f'{owner} has {len(spec)} entries: expected one '
                             'device or three (x, y, z)')
        return tuple(_device_from_spec(s, f'{owner}[{i}]') for i, s in enumerate(spec))
    device = _device_from_spec(spec, owner)
    return (device, device, device)


_PCT = converter(units.percent_to_ratio)


#: YAML keys in datasheet units: key -> (SensorConfig field, converter).
YAML_ALIASES = {
    'electronics_arw_deg_sqrt_h': (
        'electronics_noise_rad_s_sqrt_hz', converter(units.arw_deg_sqrt_h_to_rad_s_sqrt_hz)),
    'electronics_noise_deg_s_sqrt_hz': (
        'electronics_noise_rad_s_sqrt_hz', converter(units.deg_s_sqrt_hz_to_rad_s_sqrt_hz)),
    'bias_instability_deg_h': ('bias_instability_rad_s', converter(units.deg_h_to_rad_s)),
    'rate_random_walk_deg_h_sqrt_h': (
        'rate_random_walk_rad_s_sqrt_s', converter(units.rrw_deg_h_sqrt_h_to_rad_s_sqrt_s)),
    'turn_on_bias_deg_s': ('turn_on_bias_rad_s', converter(units.deg_s_to_rad_s)),
    'turn_on_bias_sigma_deg_s': ('turn_on_bias_sigma_rad_s', converter(units.deg_s_to_rad_s)),
    'bias_temp_coeff_deg_s_k': ('bias_temp_coeff_rad_s_k', converter(units.deg_s_to_rad_s)),
    'bias_temp_coeff2_deg_s_k2': ('bias_temp_coeff2_rad_s_k2', converter(units.deg_s_to_rad_s)),
    'scale_factor_error_ppm': ('scale_factor_error', converter(units.ppm_to_ratio)),
    'scale_factor_error_pct': ('scale_factor_error', _PCT),
    'misalignment_pct': ('misalignment', _PCT),
    'g_sensitivity_deg_s_g': (
        'g_sensitivity_rad_s_m_s2', converter(units.deg_s_per_g_to_rad_s_per_m_s2)),
    'lsb_deg_s': ('lsb_rad_s', converter(units.deg_s_to_rad_s)),
    'range_deg_s': ('range_rad_s', converter(units.deg_s_to_rad_s)),
}


def config_from_mapping(mapping, source=''):
    """
    Build a :class:`SensorConfig` from a mapping (parsed YAML).

    Keys are :class:`SensorConfig` field names or the datasheet-unit aliases
    of :data:`YAML_ALIASES`; ``terms`` is a mapping of :class:`ErrorTerms`
    switches. Unknown keys raise ``ValueError`` naming the key.
    """
    if mapping is None:
        mapping = {}
    if not isinstance(mapping, dict):
        raise ValueError(f'{source or "SensorConfig"}: expected a mapping of settings, '
                         f'got {quote(mapping)}')
    given, source = source, source or 'SensorConfig'
    field_names = [f.name for f in fields(SensorConfig)]
    kwargs = {}
    for key, value in mapping.items():
        if key in YAML_ALIASES:
            target, convert = YAML_ALIASES[key]
            if target in kwargs:
                raise ValueError(f'{source}: {key} and another key both set {target}')
            try:
                kwargs[target] = convert(value)
            except (TypeError, ValueError):
                raise ValueError(f'{source}: {key} = {quote(value)} is not a number or a '
                                 'list of numbers') from None
        elif key == 'terms':
            kwargs['terms'] = ErrorTerms.from_mapping(value, source)
        elif key == 'accelerometer':
            kwargs['accelerometer'] = accel_from_mapping(value, f'{source}: accelerometer')
        elif key == 'extended':
            try:
                kwargs['extended'] = ExtendedTerms.from_mapping(value or {}, 'extended')
            except (TypeError, ValueError) as exc:
                raise ValueError(f'{source}: {exc}') from None
        elif key in field_names:
            if key in kwargs:
                raise ValueError(f'{source}: {key} is set twice (directly and by an '
                                 'alias)')
            kwargs[key] = value
        else:
            allowed = sorted(set(field_names) | set(YAML_ALIASES))
            raise ValueError(f'{source}: unknown key {quote(key)}; allowed: '
                             f'{", ".join(allowed)}')
    try:
        return SensorConfig(**kwargs)
    except ValueError as exc:
        if not given:
            raise
        raise ValueError(f'{source}: {exc}') from None


def preset_path(name):
    """Return the YAML path of the named sensor preset."""
    return os.path.join(config_dir(), f'sensor_{name}.yaml')


def config_source(name_or_path):
    """
    Return the file a sensor config names: a preset's YAML, else the path as given.

    None gives None. Commands name it among their inputs, so that no output
    replaces the preset a run read (:func:`gyro_emulator.outputs.check`).
    """
    if name_or_path is None:
        return None
    name = str(name_or_path)
    return preset_path(name) if name in PRESET_NAMES else name


def load_sensor_config(name_or_path=None):
    """
    Load a sensor configuration by preset name or YAML path.

    Parameters
    ----------
    name_or_path : str or os.PathLike or None
        ``'paper'`` (default), ``'consumer'``, ``'tactical'`` or a YAML file.

    Returns
    -------
    SensorConfig

    Raises
    ------
    ValueError
        Unknown preset, unreadable or malformed YAML, unknown keys or values
        out of range (the message names the key, the value and the range).

    """
    name = DEFAULT_SENSOR_PRESET if name_or_path is None else str(name_or_path)
    path = config_source(name)
    if not os.path.isfile(path):
        raise ValueError(
            f'sensor config {quote(name)} is neither a preset '
            f'({", ".join(PRESET_NAMES)}) nor a readable file')
    return config_from_mapping(read_yaml(path), source=path)


# --- the inverse of config_from_mapping: a SensorConfig as sensor YAML text ----------

#: Each alias of :data:`YAML_ALIASES`: SI value -> the alias's unit (the inverse converters).
_FROM_SI = {
    'electronics_arw_deg_sqrt_h': units.rad_s_sqrt_hz_to_arw_deg_sqrt_h,
    'electronics_noise_deg_s_sqrt_hz': units.rad_s_sqrt_hz_to_deg_s_sqrt_hz,
    'bias_instability_deg_h': units.rad_s_to_deg_h,
    'rate_random_walk_deg_h_sqrt_h': units.rad_s_sqrt_s_to_rrw_deg_h_sqrt_h,
    'scale_factor_error_ppm': units.ratio_to_ppm,
    'scale_factor_error_pct': units.ratio_to_percent, 'misalignment_pct': units.ratio_to_percent,
    'g_sensitivity_deg_s_g': units.rad_s_per_m_s2_to_deg_s_per_g,
    **dict.fromkeys(('turn_on_bias_deg_s', 'turn_on_bias_sigma_deg_s', 'bias_temp_coeff_deg_s_k',
                     'bias_temp_coeff2_deg_s_k2', 'lsb_deg_s', 'range_deg_s'),
                    units.rad_s_to_deg_s)}


def default_layout(config):
    """Return the keys that spell every field of ``config`` (full precision, SI names)."""
    names = [f.name for f in fields(SensorConfig) if f.name not in ('extended', 'accelerometer')]
    return tuple(YamlKey(n) for n in names) + (YamlKey('extended', parts=tuple(
        YamlKey(t) for t in ('start_time_s',) + config.extended.active())),
        YamlKey('accelerometer'))


def config_yaml(config, layout=None, provenance='', comments=None, footer=''):
    """
    Return ``config`` as sensor YAML text: the inverse of :func:`config_from_mapping`.

    Parameters
    ----------
    config : SensorConfig
        What the file says.
    layout : sequence of YamlKey, optional
        The keys to write, in order, and how (default: :func:`default_layout`).
    provenance, footer : str
        Comment lines written above and below the data.
    comments : dict, optional
        Key -> comment written after the line of that key (any depth).

    Returns
    -------
    str
        Text that :func:`load_sensor_config` reads back as ``config``.

    Raises
    ------
    ValueError
        When the text would denote another configuration (a ``given`` value,
        or a figure written with fewer digits than ``config`` holds).

    """
    from gyro_emulator import yaml_text     # PyYAML waits for a file (see resources)

    mapping = {key.name: _exact(_value(config, key), yaml_text)
               for key in (default_layout(config) if layout is None else layout)}
    if config_from_mapping(mapping, source='the written config') != config:
        raise ValueError('the written config does not read back as the configuration: a '
                         'given value or a figure written with fewer digits differs from it')
    return provenance + yaml_text.dump(mapping, comments) + footer


def _exact(value, yaml_text):
    """Return ``value`` with every Figure replaced by the value its text reads back as."""
    if isinstance(value, yaml_text.Figure):
        return yaml_text.Figure(yaml_text.as_written(value, value.spec), value.spec)
    if isinstance(value, dict):
        return {k: _exact(v, yaml_text) for k, v in value.items()}
    if isinstance(value, list):
        return type(value)(_exact(v, yaml_text) for v in value)
    return value


def _value(config, key):
    """Return the YAML value of top-level ``key``: given, or spelt from ``config``."""
    if key.given is not None:
        return key.given
    if key.name == 'device':
        forms = [_device_value(d, key.spec) for d in config.device]
        return forms[0] if len(set(config.device)) == 1 else forms
    if key.name == 'terms':
        names = ErrorTerms.names() if key.parts is None else [p.name for p in key.parts]
        return {n: getattr(config.terms, n) for n in names}
    if key.name == 'extended':
        out = {p.name: _extended_value(config.extended, p) for p in key.parts or ()}
        return out or None
    if key.name == 'accelerometer':
        return accel_yaml_value(config.accelerometer, key.parts)
    if key.name in YAML_ALIASES:
        value = getattr(config, YAML_ALIASES[key.name][0])
        return spell(np.asarray(_FROM_SI[key.name](np.array(value))).tolist(), key)
    return spell(getattr(config, key.name), key)


def _extended_value(ext, part):
    """Return ``start_time_s`` or one term of ``extended`` (its fields in ``part.parts``)."""
    if part.given is not None:
        return part.given
    if part.name == 'start_time_s':
        return spell(ext.start_time_s, part)
    term = getattr(ext, part.name)
    names = [f.name for f in fields(term)] if part.parts is None else [p.name for p in part.parts]
    return {n: spell(getattr(term, n), part) for n in names}


def _device_value(device, spec):
    """Return the physics preset ``device`` is, or ``{preset: closest, <fields that differ>}``."""
    from gyro_emulator.yaml_text import Figure

    def differences(preset):
        out = {}
        for f in fields(Device):
            mine, theirs = getattr(device, f.name), getattr(preset, f.name)
            if f.name == 'calibration_temp_c' and mine != theirs:
                out[f.name] = Figure(mine, spec)
            elif f.name != 'calibration_temp_c' and mine != theirs:
                out[f.name] = {g.name: (getattr(mine, g.name) if isinstance(
                    getattr(mine, g.name), str) else Figure(getattr(mine, g.name), spec))
                    for g in fields(mine) if getattr(mine, g.name) != getattr(theirs, g.name)}
        return out

    name, diff = min(((n, differences(p)) for n, p in PHYSICS_PRESETS.items()),
                     key=lambda item: len(item[1]))
    return {'preset': name, **diff} if diff else name
