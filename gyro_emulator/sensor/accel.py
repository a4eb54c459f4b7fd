"""
Configuration of the 3-axis accelerometer error model: a frozen, validated dataclass.

An :class:`AccelConfig` is the ``accelerometer`` of a
:class:`~gyro_emulator.sensor.config.SensorConfig` (YAML key
``accelerometer:``). The accelerometer is a sense channel of its own on the
gyro's compiled kernel (:mod:`gyro_emulator.sensor.imu`); for axis i, with
the true specific force f (body frame, m/s^2) and the die temperature T of
the part (the gyro's, after its thermal lag)::

    x    = (I + misalignment) f
    g_i  = (1 + scale_factor_temp_coeff_i (T - T_cal)) (1 + scale_factor_error_i)
    b_i  = turn_on_i + bias_temp_coeff_i (T - T_cal) + flicker(B_i) + walk(K_i)
    y_i  = Q( sat( H_filter[ g_i x_i + b_i + white(N_mech(T), N_elec) ] ) )

T_cal is the calibration temperature of the axis's physics device. There is
no sense-mode envelope and no g-sensitivity. N_mech is the Brownian noise of
the device's proof mass (:func:`gyro_emulator.sensor.noise.brownian_vrw_m_s2_sqrt_hz`),
the physics part; N_elec the electronics part, in quadrature.

All fields are SI (m/s^2, m/s^2/sqrt(Hz), m/s^3/sqrt(Hz), 1/K); per-axis
fields are length-3 tuples (x, y, z), a scalar is broadcast. YAML files may
use datasheet units through :data:`YAML_ALIASES` (ug/sqrt(Hz), m/s/sqrt(h),
mg, mg/K, ppm/K, ppm, %, g), converted by :mod:`gyro_emulator.units`.
The default is the proof mass's Brownian noise and nothing else (the
``paper`` preset's accelerometer), with a 16 g range.
"""

from dataclasses import dataclass, field, fields

from gyro_emulator import units
from gyro_emulator.sensor.fields import (check_lsb, check_zero_diagonal, checked, converter,
                                         spell, Switches, YamlKey)
from gyro_emulator.validation import quote

#: The widest full-scale range of common MEMS IMUs, 16 g, m/s^2.
DEFAULT_RANGE_M_S2 = 16.0 * units.STANDARD_GRAVITY_M_S2
#: Smallest non-zero quantisation step, m/s^2 (0.1 ng: far below any part's LSB).
MIN_LSB_M_S2 = 1e-9


@dataclass(frozen=True)
class AccelTerms(Switches):
    """
    On/off switch of every term of the accelerometer model (all on by default).

    ``mechanical_noise`` is the physics (the proof mass's Brownian noise);
    the others are the datasheet terms named by the matching
    :class:`AccelConfig` fields (``random_walk``: the acceleration random walk).
    """

    scale_factor_temperature: bool = True
    output_filter: bool = True
    turn_on_bias: bool = True
    bias_temperature: bool = True
    mechanical_noise: bool = True
    electronics_noise: bool = True
    bias_instability: bool = True
    random_walk: bool = True
    scale_factor_error: bool = True
    misalignment: bool = True
    quantization: bool = True
    saturation: bool = True


#: Allowed values of the fields by kind (as SensorConfig's): name -> (low, high,
#: unit). Sanity limits for MEMS accelerometers, not design rules; closed
#: ranges, but for the low bounds in _OPEN_LOW.
_RANGES = {
    'axis': {
        'electronics_noise_m_s2_sqrt_hz': (0.0, 0.1, 'm/s^2/sqrt(Hz)'),
        'bias_instability_m_s2': (0.0, 1.0, 'm/s^2'),
        'random_walk_m_s3_sqrt_hz': (0.0, 1.0, 'm/s^3/sqrt(Hz)'),
        'turn_on_bias_m_s2': (-20.0, 20.0, 'm/s^2'),
        'turn_on_bias_sigma_m_s2': (0.0, 20.0, 'm/s^2'),
        'bias_temp_coeff_m_s2_k': (-0.1, 0.1, 'm/s^2/K'),
        'scale_factor_temp_coeff_per_k': (-0.01, 0.01, '1/K'),
        'scale_factor_error': (-0.5, 0.5, ''),
        'lsb_m_s2': (0.0, 10.0, 'm/s^2 (0 = none)'),
        'range_m_s2': (0.0, 10000.0, 'm/s^2'),
    },
    'scalar': {
        'output_filter_hz': (0.0, 1e5, 'Hz (0 = none)'),
        'output_filter_order': (1, 4, ''),
        'bias_instability_per_decade': (0.5, 4.0, 'terms/decade'),
    },
    'matrix': {'misalignment': (-0.2, 0.2, 'rad')},
    'pair': {'bias_instability_band_s': (1e-3, 1e6, 's')},
}
_OPEN_LOW = frozenset({'range_m_s2'})


def field_ranges():
    """
    Return the documented range of every numeric :class:`AccelConfig` field.

    ``{name: (kind, low, high, unit, low_open)}`` as
    :func:`gyro_emulator.sensor.config.field_ranges`.
    """
    return {name: (kind, low, high, unit, name in _OPEN_LOW)
            for kind, ranges in _RANGES.items() for name, (low, high, unit) in ranges.items()}


@dataclass(frozen=True)
class AccelConfig:
    """
    Parameters of the 3-axis accelerometer error model (SI units; module docstring).

    Attributes
    ----------
    terms : AccelTerms
        On/off switches.
    electronics_noise_m_s2_sqrt_hz : tuple
        Electronics white acceleration noise, two-sided density (its velocity
        random walk N), in quadrature with the physics part.
    bias_instability_m_s2, bias_instability_band_s, bias_instability_per_decade
        B (Allan floor 0.664 B), the correlation-time band of the flicker
        model and its Gauss-Markov terms per decade (as the gyro's).
    random_walk_m_s3_sqrt_hz : tuple
        Acceleration random walk K, m/s^3/sqrt(Hz) (= m/s^2/sqrt(s)).
    turn_on_bias_m_s2, turn_on_bias_sigma_m_s2 : tuple
        Fixed turn-on bias and the sigma of its run-to-run random part.
    bias_temp_coeff_m_s2_k : tuple
        Zero-g bias temperature coefficient, m/s^2/K.
    scale_factor_temp_coeff_per_k : tuple
        Sensitivity temperature coefficient, 1/K.
    scale_factor_error : tuple
        Sensitivity error (ratio).
    misalignment : 3x3 tuple
        Cross-axis coupling (zero diagonal), rad.
    lsb_m_s2, range_m_s2 : tuple
        Quantisation step (0 = none) and full-scale range, m/s^2.
    output_filter_hz, output_filter_order : float, int
        Digital Butterworth low-pass (0 Hz = none).

    """

    terms: AccelTerms = field(default_factory=AccelTerms)
    electronics_noise_m_s2_sqrt_hz: tuple = (0.0, 0.0, 0.0)
    bias_instability_m_s2: tuple = (0.0, 0.0, 0.0)
    bias_instability_band_s: tuple = (0.1, 1000.0)
    bias_instability_per_decade: float = 1.0
    random_walk_m_s3_sqrt_hz: tuple = (0.0, 0.0, 0.0)
    turn_on_bias_m_s2: tuple = (0.0, 0.0, 0.0)
    turn_on_bias_sigma_m_s2: tuple = (0.0, 0.0, 0.0)
    bias_temp_coeff_m_s2_k: tuple = (0.0, 0.0, 0.0)
    scale_factor_temp_coeff_per_k: tuple = (0.0, 0.0, 0.0)
    scale_factor_error: tuple = (0.0, 0.0, 0.0)
    misalignment: tuple = ((0.0,) * 3,) * 3
    lsb_m_s2: tuple = (0.0, 0.0, 0.0)
    range_m_s2: tuple = (DEFAULT_RANGE_M_S2,) * 3
    output_filter_hz: float = 0.0
    output_filter_order: int = 2

    def __post_init__(self):
        """Normalise per-axis fields to tuples and validate every field."""
        owner = 'AccelConfig'
        if not isinstance(self.terms, AccelTerms):
            raise ValueError(f'{owner}.terms = {quote(self.terms)} is not allowed: expected an '
                             'AccelTerms')
        for kind, ranges in _RANGES.items():
            for name, limits in ranges.items():
                object.__setattr__(self, name, checked(owner, name, getattr(self, name), kind,
                                                       limits, name in _OPEN_LOW))
        check_lsb(owner, 'lsb_m_s2', self.lsb_m_s2, MIN_LSB_M_S2, 10.0, 'm/s^2')
        if self.output_filter_order != int(self.output_filter_order):
            raise ValueError(f'{owner}.output_filter_order = {quote(self.output_filter_order)} is '
                             'not allowed: choose 1, 2, 3 or 4')
        object.__setattr__(self, 'output_filter_order', int(self.output_filter_order))
        band = self.bias_instability_band_s
        if band[0] > band[1]:
            raise ValueError(f'{owner}.bias_instability_band_s = {quote(band)} is not allowed: '
                             'the first (shortest) correlation time must not exceed the second')
        check_zero_diagonal(owner, self.misalignment)

    @classmethod
    def ideal(cls):
        """Return an accelerometer with every term off: output = true specific force."""
        return cls(terms=AccelTerms.none())


_MG = converter(units.mg_to_m_s2)

#: YAML keys in datasheet units: key -> (AccelConfig field, converter to SI).
YAML_ALIASES = {
    'electronics_noise_ug_sqrt_hz': ('electronics_noise_m_s2_sqrt_hz',
                                     converter(units.ug_sqrt_hz_to_m_s2_sqrt_hz)),
    'electronics_vrw_m_s_sqrt_h': ('electronics_noise_m_s2_sqrt_hz',
                                   converter(units.vrw_m_s_sqrt_h_to_m_s2_sqrt_hz)),
    'bias_instability_mg': ('bias_instability_m_s2', _MG),
    'turn_on_bias_mg': ('turn_on_bias_m_s2', _MG),
    'turn_on_bias_sigma_mg': ('turn_on_bias_sigma_m_s2', _MG),
    'bias_temp_coeff_mg_k': ('bias_temp_coeff_m_s2_k', _MG),
    'scale_factor_temp_coeff_ppm_k': ('scale_factor_temp_coeff_per_k',
                                      converter(units.ppm_to_ratio)),
    'scale_factor_error_ppm': ('scale_factor_error', converter(units.ppm_to_ratio)),
    'scale_factor_error_pct': ('scale_factor_error', converter(units.percent_to_ratio)),
    'misalignment_pct': ('misalignment', converter(units.percent_to_ratio)),
    'lsb_mg': ('lsb_m_s2', _MG),
    'range_g': ('range_m_s2', converter(units.g_to_m_s2)),
}

#: Each alias of :data:`YAML_ALIASES`: SI value -> the alias's unit (the inverse converters).
_FROM_SI = {
    'electronics_noise_ug_sqrt_hz': units.m_s2_sqrt_hz_to_ug_sqrt_hz,
    'electronics_vrw_m_s_sqrt_h': units.m_s2_sqrt_hz_to_vrw_m_s_sqrt_h,
    **dict.fromkeys(('bias_instability_mg', 'turn_on_bias_mg', 'turn_on_bias_sigma_mg',
                     'bias_temp_coeff_mg_k', 'lsb_mg'), units.m_s2_to_mg),
    'scale_factor_temp_coeff_ppm_k': units.ratio_to_ppm,
    'scale_factor_error_ppm': units.ratio_to_ppm,
    'scale_factor_error_pct': units.ratio_to_percent,
    'misalignment_pct': units.ratio_to_percent,
    'range_g': units.m_s2_to_g}


def accel_from_mapping(mapping, source='accelerometer'):
    """
    Build an :class:`AccelConfig` from a mapping (the parsed ``accelerometer:`` of a YAML).

    Keys are :class:`AccelConfig` field names, the datasheet-unit aliases of
    :data:`YAML_ALIASES` and ``terms`` (a mapping of :class:`AccelTerms`
    switches). Unknown keys, a field set twice and bad values raise a
    one-line ``ValueError`` naming ``source`` and the key.
    """
    if mapping is None:
        mapping = {}
    if not isinstance(mapping, dict):
        raise ValueError(f'{source}: expected a mapping of accelerometer settings, got '
                         f'{quote(mapping)}')
    names = [f.name for f in fields(AccelConfig)]
    kwargs = {}
    for key, value in mapping.items():
        if key == 'terms':
            kwargs['terms'] = AccelTerms.from_mapping(value, source)
            continue
        if key not in YAML_ALIASES and key not in names:
            raise ValueError(f'{source}: unknown key {quote(key)}; allowed: '
                             f'{", ".join(sorted(set(names) | set(YAML_ALIASES)))}')
        target = YAML_ALIASES[key][0] if key in YAML_ALIASES else key
        if target in kwargs:
            raise ValueError(f'{source}: {target} is set twice (directly or by an alias)')
        if key in YAML_ALIASES:
            try:
                value = YAML_ALIASES[key][1](value)
            except (TypeError, ValueError):
                raise ValueError(f'{source}: {key} = {quote(value)} is not a number or a list '
                                 'of numbers') from None
        kwargs[target] = value
    try:
        return AccelConfig(**kwargs)
    except ValueError as exc:
        raise ValueError(f'{source}: {exc}') from None


def accel_yaml_value(accel, parts):
    """
    Return the ``accelerometer:`` mapping of ``accel`` for the sensor YAML writer.

    ``parts`` are the :class:`~gyro_emulator.sensor.fields.YamlKey` s to
    write (fields, aliases or ``terms``; None: every field in SI and every
    switch). A key's ``given`` value is written as it is.
    """
    if parts is None:
        parts = [YamlKey(f.name) for f in fields(AccelConfig)]
    out = {}
    for key in parts:
        if key.given is not None:
            out[key.name] = key.given
        elif key.name == 'terms':
            names = AccelTerms.names() if key.parts is None else [p.name for p in key.parts]
            out['terms'] = {n: getattr(accel.terms, n) for n in names}
        elif key.name in YAML_ALIASES:
            value = getattr(accel, YAML_ALIASES[key.name][0])
            out[key.name] = spell(_FROM_SI[key.name](value).tolist(), key)
        else:
            out[key.name] = spell(getattr(accel, key.name), key)
    return out
