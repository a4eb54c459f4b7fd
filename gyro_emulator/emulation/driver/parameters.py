"""
The node's parameters as plain values: the table, the checks, the sensor mapping.

Two families of parameters (the ROS side, ``gyro_emulator.ros.params``,
declares them with descriptors and reads the defaults file):

* node parameters (:data:`NODE_PARAMS`): rate, frame, seed, input policies.
  Their defaults are read from ``config/gyro_emulator.yaml`` (a
  ``--params-file`` style file a user can copy and edit); the table here only
  holds type, unit, range, description and whether the parameter is
  structural (read-only after start).
* error-model parameters ``sensor.<field>`` and ``sensor.terms.<term>``: one
  per :class:`gyro_emulator.sensor.config.SensorConfig` field and
  :class:`~gyro_emulator.sensor.config.ErrorTerms` switch. Their defaults are
  the values of the configuration named by ``sensor_config`` (a preset or a
  YAML path), so choosing a preset never fights hard-coded numbers; a params
  file may override any of them. 3x3 matrices are 9 numbers, row-major;
  ``sensor.initial_die_temp_c`` = NaN means "in equilibrium". The extended
  terms (``SensorConfig.extended``, :mod:`gyro_emulator.sensor.extensions`)
  are structural: they come from the ``sensor_config`` YAML only and are not
  parameters (a changed ``sensor.*`` parameter keeps them).

:func:`check_value` gives the message format used everywhere (field, value,
allowed range or choices); :func:`fault_from`, :func:`effective_config` and
:func:`input_limits` turn values into what the driver runs on.
"""

import array
from dataclasses import dataclass, fields, replace
import math

from gyro_emulator.emulation.driver.commands import InputLimits, TEMPERATURE_POLICIES
from gyro_emulator.emulation.driver.imu_timeline import MAX_RATE_HZ
from gyro_emulator.emulation.driver.sample_clock import OVERRUN_POLICIES
from gyro_emulator.physics.kinematics import MAX_GRAVITY_M_S2
from gyro_emulator.recording import topics
from gyro_emulator.sensor import config as sensor_config
from gyro_emulator.sensor import faults
from gyro_emulator.sensor.imu import MAX_APPLIED_ACCEL_M_S2
from gyro_emulator.units import AXES
from gyro_emulator.validation import GYRO_LIMIT_RAD_S, MODEL_TEMP_RANGE_C

SENSOR_PREFIX = 'sensor.'
TERMS_PREFIX = 'sensor.terms.'
#: Error terms that ``noise_enabled = false`` switches off.
NOISE_TERMS = ('mechanical_noise', 'electronics_noise', 'bias_instability',
               'rate_random_walk', 'timestamp_jitter')
#: Accelerometer terms (sensor.accel.AccelTerms) that ``noise_enabled = false`` switches off.
ACCEL_NOISE_TERMS = ('mechanical_noise', 'electronics_noise', 'bias_instability', 'random_walk')
#: Values of ``rate_source``: the rate inputs of the topic table.
RATE_SOURCES = tuple(topics.RATE_INPUTS)
STALE_RATE_POLICIES = ('zero', 'hold')
#: Values of ``input_source``: timed commands, or one output per simulator Imu.
INPUT_SOURCES = ('command', 'imu')
INT64_MAX = 2 ** 63 - 1
#: Values of ``qos_reliability``.
QOS_RELIABILITIES = ('best_effort', 'reliable')
#: Largest |angle| of ``initial_attitude_rpy_rad``, rad (one turn).
MAX_ANGLE_RAD = 2.0 * math.pi
#: ``seed`` value meaning "derive the seed from the node's fully qualified name".
SEED_FROM_NAME = -1
#: The runtime fault parameters, in the order of :class:`gyro_emulator.sensor.faults.Fault`.
FAULT_PARAMS = ('fault.type', 'fault.axis', 'fault.magnitude', 'fault.start_s',
                'fault.duration_s')


@dataclass(frozen=True)
class ParamSpec:
    """
    One node parameter: type, range, description and mutability.

    Attributes
    ----------
    name : str
        Parameter name.
    kind : str
        ``double``, ``integer``, ``bool``, ``string`` or ``double_array``
        (three numbers, each in [low, high]).
    description : str
        One line for ``ros2 param describe``, with the unit.
    read_only : bool
        Structural: fixed after start (``ros2 param set`` is refused).
    low, high : float or None
        Inclusive range for numbers.
    choices : tuple of str
        Allowed values of a string parameter (empty: any).
    low_open : bool
        ``low`` itself is refused: the range is (low, high].
    frame : bool
        A tf2 frame name: not empty and not starting with ``/`` (tf2 refuses
        both in a transform lookup, so a consumer could not place the data).

    """

    name: str
    kind: str
    description: str
    read_only: bool = False
    low: float = None
    high: float = None
    choices: tuple = ()
    low_open: bool = False
    frame: bool = False


NODE_PARAMS = (
    ParamSpec('rate_hz', 'double', 'Output data rate, Hz (one model sample per tick; '
              'with input_source imu, the rate until the input stamps give one)',
              True, 1.0, MAX_RATE_HZ),
    ParamSpec('frame_id', 'string', 'header.frame_id of imu/data_raw (REP 145: the '
              'sensor frame; a tf2 frame name)', True, frame=True),
    ParamSpec('seed', 'integer', 'Seed of the numpy random generator of every noise '
              'term: same seed + same inputs = same output; -1 = derived from the '
              'fully qualified node name (a SeedSequence of it: independent per instance, '
              'the same on every run)', True, SEED_FROM_NAME, INT64_MAX),
    ParamSpec('sensor_config', 'string', 'Error model: a preset name (paper, consumer, '
              'tactical) or a sensor YAML path; the sensor.* defaults come from it', True),
    ParamSpec('input_source', 'string', 'command: a timer at rate_hz samples the '
              'cmd/* inputs; imu: one output per imu/ideal message (sensor_msgs/Imu from a '
              'simulator), stamped with its stamp plus the latency, dt from the stamps',
              True, choices=INPUT_SOURCES),
    ParamSpec('rate_source', 'string', 'Where the true rate comes from: '
              'angular_velocity (cmd/angular_velocity, Vector3Stamped) or odometry '
              '(cmd/odom, nav_msgs/Odometry twist.twist.angular)', True,
              choices=RATE_SOURCES),
    ParamSpec('initial_temperature_c', 'double', 'Ambient temperature before the first '
              'cmd/temperature, deg C', True, *MODEL_TEMP_RANGE_C),
    ParamSpec('command_timeout_s', 'double', 'A rate command older than this is stale: '
              'stale_rate_policy applies and diagnostics warn; 0 = never stale, s',
              False, 0.0, 3600.0),
    ParamSpec('stale_rate_policy', 'string', 'Rate used while the command is stale: zero '
              '(a resting gyro) or hold (last command)', False,
              choices=STALE_RATE_POLICIES),
    ParamSpec('temperature_policy', 'string', 'Ambient temperatures outside the model '
              'range are clamped to it or rejected', False,
              choices=TEMPERATURE_POLICIES),
    ParamSpec('max_abs_rate_rad_s', 'double', 'Commands with a larger |rate| component '
              'are rejected (the sensor range saturates below this), rad/s', False,
              1e-3, GYRO_LIMIT_RAD_S),
    ParamSpec('max_abs_accel_m_s2', 'double', 'Acceleration inputs with a larger |component| '
              '(cmd/linear_acceleration, the applied acceleration; imu/ideal, the specific '
              'force) are rejected, m/s^2', False, 1e-3, MAX_APPLIED_ACCEL_M_S2),
    ParamSpec('max_stamp_lead_s', 'double', 'Commands stamped further ahead of the node '
              'clock are rejected, s', False, 1e-3, 1e6),
    ParamSpec('command_queue_size', 'integer', 'Commands per stream waiting for their '
              'stamp; the oldest is dropped beyond', True, 1, 100000),
    ParamSpec('noise_enabled', 'bool', 'false switches off every noise term (white '
              'noise, bias instability, rate random walk, timestamp jitter)'),
    ParamSpec('temperature_override_enabled', 'bool', 'true: use temperature_override_c '
              'as the ambient temperature and ignore cmd/temperature'),
    ParamSpec('temperature_override_c', 'double', 'Ambient temperature while the '
              'override is enabled, deg C', False, *MODEL_TEMP_RANGE_C),
    ParamSpec('default_linear_acceleration_m_s2', 'double_array', 'Applied linear '
              'acceleration before the first cmd/linear_acceleration, m/s^2, body frame '
              '(gravity is added from the attitude: a level part at rest reads +g on z)', True,
              -MAX_APPLIED_ACCEL_M_S2, MAX_APPLIED_ACCEL_M_S2),
    ParamSpec('gravity_m_s2', 'double', 'Magnitude of gravity, m/s^2: the specific force is '
              'the applied acceleration minus gravity rotated into the sensor frame', True,
              0.0, MAX_GRAVITY_M_S2, low_open=True),
    ParamSpec('initial_attitude_rpy_rad', 'double_array', 'Attitude at the first sample: '
              'roll, pitch, yaw (REP 103 fixed axes x, y, z) of the sensor frame in the ENU '
              'world, rad; [0, 0, 0] = level, gravity +g on z', True, -MAX_ANGLE_RAD,
              MAX_ANGLE_RAD),
    ParamSpec('publish_linear_acceleration', 'bool', "Publish the accelerometer (the model's "
              'noisy linear_acceleration with its covariance) in imu/data_raw; false: absent '
              '(covariance[0] = -1), for gyro-only setups'),
    ParamSpec('qos_reliability', 'string', 'Reliability of imu/data_raw, imu/temperature and '
              '~/truth/*: best_effort (sensor data, the default) or reliable', True,
              choices=QOS_RELIABILITIES),
    ParamSpec('publish_truth', 'bool', 'Publish ~/truth/rate, ~/truth/bias, '
              '~/truth/scale_factor and ~/truth/imu (attitude) each sample'),
    ParamSpec('temperature_rate_hz', 'double', 'Rate of imu/temperature, Hz (at most '
              'rate_hz; the default is lowered to rate_hz when rate_hz is below it)', True,
              0.1, 5000.0),
    ParamSpec('overrun_policy', 'string', 'Samples that came due while the timer was late '
              '(CPU load, a coarse /clock): fifo publishes every one in a burst, each '
              'stamped with its own sample time; drop publishes the newest only and counts '
              'the rest', False, choices=OVERRUN_POLICIES),
    ParamSpec('max_burst_samples', 'integer', 'fifo: most samples published by one timer '
              'tick; the rest wait for the next tick', False, 1, 10000),
    ParamSpec('fifo_depth_samples', 'integer', 'fifo: most samples waiting to be '
              'published; beyond, the oldest are dropped and counted', False, 1, 1000000),
    ParamSpec('diagnostics_period_s', 'double', 'Period of /diagnostics (steady clock), '
              's', True, 0.05, 60.0),
    ParamSpec('block_samples', 'integer', 'Samples the model computes ahead per call '
              '(exact: rewound when an input changes; 1 = one call per sample)', True,
              1, 1000),
    ParamSpec('record_start_clock_s', 'double', 'Node-clock time of record time '
              'extended.start_time_s of the sensor_config (the time line of its '
              'extended terms), s; negative: the first sample', True, -1.0, 1e12),
    ParamSpec('startup_bias_calibration', 'double', 'Seconds at rest at the start over '
              'which the gyro bias is estimated (the mean) and then removed from imu/data_raw, '
              "as a driver's start-up calibration does; not applied if the commanded rate "
              'is not zero or the spread says motion (/diagnostics says which); the truth '
              'topics keep the true bias; 0 = off, s', True, 0.0, 3600.0),
    ParamSpec('record_dir', 'string', 'Record inputs, outputs and truth into an MCAP '
              'bag in this directory (gyro_emulator.ros.self_record); empty = off', True),
    ParamSpec('fault.type', 'string', 'Injected fault (sensor.faults): none, stuck, '
              'bias_step, drift, spike, dropout, saturate or noise_burst; shown on '
              '~/truth/fault and /diagnostics', False, choices=faults.FAULT_TYPES),
    ParamSpec('fault.axis', 'string', 'Axis of the fault: x, y, z or all', False,
              choices=faults.FAULT_AXES),
    ParamSpec('fault.magnitude', 'double', 'Size of the fault: rad/s (bias_step, spike, '
              'noise_burst sigma), rad/s per s (drift), sign (saturate)', False,
              -faults.MAX_ABS_MAGNITUDE, faults.MAX_ABS_MAGNITUDE),
    ParamSpec('fault.start_s', 'double', 'Start of the fault after the fault parameters '
              'are set, s (node clock)', False, 0.0, faults.MAX_TIME_S),
    ParamSpec('fault.duration_s', 'double', 'Length of the fault, s; 0 = until '
              'fault.type is set to none', False, 0.0, faults.MAX_TIME_S),
)

NODE_SPECS = {spec.name: spec for spec in NODE_PARAMS}

#: One line per SensorConfig field for the parameter descriptors.
SENSOR_DESCRIPTIONS = {
    'extended': 'Extended terms (sensor.extensions: the causes diagnose names); structural: '
                'set in the sensor_config YAML under extended:, not a runtime parameter',
    'accelerometer': 'The accelerometer (sensor.accel); structural: set in the sensor_config '
                     'YAML under accelerometer:, not a runtime parameter',
    'device': 'Physics device of every axis: a physics preset name (paper, '
              'paper_sutherland, paper_sealed); empty = the sensor_config one',
    'mode_split_hz': 'Drive/sense frequency split of the sense dynamics (x, y, z), Hz',
    'output_filter_hz': 'ASIC Butterworth low-pass cut-off, Hz (0 = none)',
    'output_filter_order': 'ASIC Butterworth low-pass order (1..4)',
    'thermal_time_constant_s': 'Die temperature lag behind ambient, s',
    'self_heating_c': 'Steady die temperature rise over ambient, deg C',
    'turn_on_bias_rad_s': 'Fixed turn-on bias (x, y, z), rad/s',
    'turn_on_bias_sigma_rad_s': 'Sigma of the run-to-run turn-on bias (x, y, z), rad/s',
    'bias_temp_coeff_rad_s_k': 'Linear bias temperature coefficient (x, y, z), rad/s/K',
    'bias_temp_coeff2_rad_s_k2': 'Quadratic bias temperature coefficient (x, y, z), '
                                 'rad/s/K^2',
    'electronics_noise_rad_s_sqrt_hz': 'Electronics white rate noise density (ARW) '
                                       '(x, y, z), rad/s/sqrt(Hz)',
    'bias_instability_rad_s': 'Bias instability B (x, y, z), rad/s',
    'bias_instability_band_s': 'Correlation-time band of the flicker model (short, '
                               'long), s',
    'bias_instability_per_decade': 'Gauss-Markov terms per decade of the flicker model',
    'rate_random_walk_rad_s_sqrt_s': 'Rate random walk K (x, y, z), rad/s/sqrt(s)',
    'scale_factor_error': 'Scale-factor error (x, y, z), ratio',
    'nonlinearity_s_rad': 'Quadratic scale-factor nonlinearity (x, y, z), s/rad',
    'misalignment': 'Cross-axis coupling, 3x3 row-major (9 numbers, zero diagonal), rad',
    'g_sensitivity_rad_s_m_s2': 'Bias per specific force, 3x3 row-major (9 numbers), '
                                'rad/s per m/s^2',
    'lsb_rad_s': 'Quantisation step (x, y, z), rad/s (0 = none)',
    'range_rad_s': 'Full-scale range (x, y, z), rad/s; beyond it the output saturates',
    'latency_s': 'Output delay added to the imu/data_raw stamp, s',
    'timestamp_jitter_s': 'Sigma of the Gaussian stamp jitter, s; each draw is clipped '
                          'to +-0.45 sample periods, so stamps stay strictly increasing',
    'clock_drift_ppm': 'Sensor clock error, ppm: sets the output data rate, not the stamps',
    'initial_die_temp_c': 'Die temperature at the first sample, deg C (NaN = in '
                          'equilibrium with ambient)',
    'terms': 'On/off switches of the error terms',
}


def _type_name(kind):
    return {'double': 'a number', 'integer': 'an integer', 'bool': 'true or false',
            'string': 'a string', 'double_array': 'three numbers'}[kind]


def check_value(spec, value):
    """
    Return ``value`` converted to the spec's type, or raise ValueError.

    The message names the parameter, the value and the allowed range or
    choices, like every validation error of the package.
    """
    kind = spec.kind
    if kind == 'bool':
        if not isinstance(value, bool):
            raise ValueError(f'{spec.name} = {value!r} is not allowed: choose true or false')
        return value
    if kind == 'string':
        if not isinstance(value, str):
            raise ValueError(f'{spec.name} = {value!r} is not {_type_name(kind)}')
        if spec.choices and value not in spec.choices:
            raise ValueError(f'{spec.name} = {value!r} is not allowed: choose one of '
                             f'{", ".join(spec.choices)}')
        if spec.frame and (not value or value.startswith('/')):
            raise ValueError(f'{spec.name} = {value!r} is not allowed: a tf2 frame name '
                             "(not empty, not starting with '/')")
        return value
    if kind == 'double_array':
        return _check_triple(spec, value)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f'{spec.name} = {value!r} is not {_type_name(kind)}')
    if kind == 'integer':
        if value != int(value):
            raise ValueError(f'{spec.name} = {value!r} is not {_type_name(kind)}')
        value = int(value)
    else:
        value = float(value)
    below = spec.low is not None and (value <= spec.low if spec.low_open else value < spec.low)
    if not math.isfinite(value) or below or (spec.high is not None and value > spec.high):
        raise ValueError(f'{spec.name} = {value!r} is out of range: allowed '
                         f'{"(" if spec.low_open else "["}{spec.low:g}, {spec.high:g}]')
    return value


def _check_triple(spec, value):
    """Return three finite numbers in [low, high] as a list of floats, or raise ValueError."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple, array.array)) \
            or len(value) != 3 or any(isinstance(v, (bool, str)) or not isinstance(
                v, (int, float)) for v in value):
        raise ValueError(f'{spec.name} = {value!r} is not {_type_name(spec.kind)}')
    out = [float(v) for v in value]
    for axis, v in zip(AXES, out):
        if not math.isfinite(v) or not spec.low <= v <= spec.high:
            raise ValueError(f'{spec.name}.{axis} = {v!r} is out of range: allowed '
                             f'[{spec.low:g}, {spec.high:g}]')
    return out


# --- the error model as parameters ------------------------------------------

def _config_fields():
    # ``extended`` (sensor.extensions) is structural: it comes from the
    # sensor_config YAML only and is not a runtime parameter; so, for now, is
    # the ``accelerometer`` (sensor.accel).
    return [f.name for f in fields(sensor_config.SensorConfig)
            if f.name not in ('terms', 'extended', 'accelerometer')]


def sensor_param_values(config):
    """
    Return ``{parameter name: ROS value}`` for a SensorConfig.

    Tuples become lists of floats (3x3 matrices flattened row-major), the
    device becomes ``''`` (keep the configuration's devices) and None becomes
    NaN; each ErrorTerms switch is a ``sensor.terms.<name>`` bool.
    """
    out = {}
    for name in _config_fields():
        value = getattr(config, name)
        if name == 'device':
            value = ''
        elif value is None:
            value = float('nan')
        elif isinstance(value, tuple) and value and isinstance(value[0], tuple):
            value = [float(v) for row in value for v in row]
        elif isinstance(value, tuple):
            value = [float(v) for v in value]
        elif isinstance(value, bool):
            pass
        elif isinstance(value, int):
            value = int(value)
        else:
            value = float(value)
        out[SENSOR_PREFIX + name] = value
    for term in sensor_config.ErrorTerms.names():
        out[TERMS_PREFIX + term] = bool(getattr(config.terms, term))
    return out


def _from_ros(field, value, base):
    if field == 'initial_die_temp_c':
        return None if isinstance(value, float) and math.isnan(value) else value
    if isinstance(value, (list, tuple, array.array)):
        # rclpy hands a double array parameter over as an array.array
        value = [float(v) if not isinstance(v, (bool, str)) else v for v in value]
        current = getattr(base, field)
        if isinstance(current, tuple) and current and isinstance(current[0], tuple) \
                and len(value) == 9:
            return tuple(tuple(value[3 * i:3 * i + 3]) for i in range(3))
        return tuple(value)
    return value


def apply_sensor_params(base, values):
    """
    Return ``base`` with ``sensor.*`` parameter values applied (validated).

    Parameters
    ----------
    base : SensorConfig
        The configuration the values modify.
    values : dict
        ``{parameter name: ROS value}``; other names are ignored.

    Returns
    -------
    SensorConfig
        A new, validated configuration. Raises ValueError naming the
        parameter, the value and the allowed range.

    """
    kwargs = {}
    switches = {}
    for name, value in values.items():
        if name.startswith(TERMS_PREFIX):
            term = name[len(TERMS_PREFIX):]
            if term not in sensor_config.ErrorTerms.names():
                raise ValueError(f'{name}: unknown error term; allowed: '
                                 f'{", ".join(sensor_config.ErrorTerms.names())}')
            switches[term] = value
        elif name.startswith(SENSOR_PREFIX):
            field = name[len(SENSOR_PREFIX):]
            if field not in _config_fields():
                raise ValueError(f'{name}: unknown error-model parameter; allowed: '
                                 f'{", ".join(_config_fields())}')
            if field == 'device':
                if value:
                    kwargs['device'] = value
                continue
            kwargs[field] = _from_ros(field, value, base)
    try:
        config = replace(base, **kwargs)
        if switches:
            config = config.with_terms(**switches)
    except (TypeError, ValueError) as exc:
        raise ValueError(f'sensor parameters: {exc}') from None
    return config


def without_noise(config):
    """Return ``config`` with every :data:`NOISE_TERMS` switch off, and the accelerometer's."""
    present = [t for t in NOISE_TERMS if t in sensor_config.ErrorTerms.names()]
    accel = config.accelerometer
    quiet = replace(accel, terms=replace(accel.terms, **dict.fromkeys(ACCEL_NOISE_TERMS, False)))
    return replace(config.with_terms(**dict.fromkeys(present, False)), accelerometer=quiet)


def fault_from(values):
    """Return the Fault of the ``fault.*`` parameter values (ValueError if invalid)."""
    kwargs = {name.split('.', 1)[1]: values[name] for name in FAULT_PARAMS}
    kwargs['kind'] = kwargs.pop('type')
    return faults.Fault(**kwargs)


def effective_config(config, noise_enabled):
    """Return ``config``, or :func:`without_noise` of it when ``noise_enabled`` is false."""
    return config if noise_enabled else without_noise(config)


def input_limits(values, config, temp_range_c):
    """
    Return the :class:`InputLimits` of the node parameter values.

    Parameters
    ----------
    values : dict
        Node parameter values (``max_abs_rate_rad_s``, ``temperature_policy``, ...).
    config : SensorConfig
        The error model in force: its self-heating narrows the ambient range.
    temp_range_c : tuple of float
        (low, high) die temperatures the model accepts, deg C.

    """
    low, high = temp_range_c
    heating = config.self_heating_c if config.terms.thermal_lag else 0.0
    return InputLimits(
        max_abs_rate_rad_s=values['max_abs_rate_rad_s'],
        max_abs_accel_m_s2=values['max_abs_accel_m_s2'],
        temp_range_c=(low - min(0.0, heating), high - max(0.0, heating)),
        temperature_policy=values['temperature_policy'],
        max_stamp_lead_s=values['max_stamp_lead_s'])
