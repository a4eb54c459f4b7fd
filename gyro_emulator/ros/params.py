"""
The node's parameters on the ROS side: descriptors, declaration, the defaults file.

The table, the checks and the ``sensor.*`` mapping are plain Python
(:mod:`gyro_emulator.emulation.driver.parameters`); here they become
``rcl_interfaces`` descriptors with ranges for rclpy to enforce
(:func:`descriptor`, :func:`sensor_descriptor`), parameters declared on the
node (:func:`declare_node_parameters`, :func:`declare_sensor_parameters`),
and the defaults come from ``config/gyro_emulator.yaml``, read by rclpy's own
``--params-file`` reader (:func:`node_defaults`).
"""

import array

from gyro_emulator.emulation.driver.parameters import (
    check_value, fault_from, NODE_PARAMS, NODE_SPECS, SENSOR_DESCRIPTIONS, sensor_param_values,
    SENSOR_PREFIX, TERMS_PREFIX)
from gyro_emulator.recording import topics
from gyro_emulator.resources import config_file, read_yaml
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                ParameterType)
from rclpy.parameter import (Parameter, parameter_dict_from_yaml_file,
                             parameter_value_to_python)
from rclpy.qos import HistoryPolicy, ReliabilityPolicy

NODE_NAME = topics.NODE_NAME
DEFAULTS_FILE = 'gyro_emulator.yaml'
#: Prefix of the QoS parameters (``QoSOverridingOptions``) of the node's topics.
QOS_PREFIX = 'qos_overrides.'
#: Largest history depth the middleware takes (a DDS 32-bit signed length).
MAX_QOS_DEPTH = 2 ** 31 - 1
#: The overridable QoS policies that are names, with the names rclpy takes.
QOS_POLICY_NAMES = {
    policy: tuple(m.name.lower() for m in enum if m.name != 'UNKNOWN')
    for policy, enum in (('history', HistoryPolicy), ('reliability', ReliabilityPolicy))}


def descriptor(spec):
    """Return the rcl_interfaces ParameterDescriptor of a node parameter."""
    kinds = {'double': ParameterType.PARAMETER_DOUBLE,
             'integer': ParameterType.PARAMETER_INTEGER,
             'bool': ParameterType.PARAMETER_BOOL,
             'string': ParameterType.PARAMETER_STRING,
             'double_array': ParameterType.PARAMETER_DOUBLE_ARRAY}
    desc = ParameterDescriptor(name=spec.name, type=kinds[spec.kind],
                               description=spec.description, read_only=spec.read_only)
    if spec.kind == 'double' and spec.low is not None:
        desc.floating_point_range = [FloatingPointRange(
            from_value=float(spec.low), to_value=float(spec.high), step=0.0)]
        desc.additional_constraints = f'[{spec.low:g}, {spec.high:g}]'
    elif spec.kind == 'integer' and spec.low is not None:
        desc.integer_range = [IntegerRange(
            from_value=int(spec.low), to_value=int(spec.high), step=0)]
        desc.additional_constraints = f'[{int(spec.low)}, {int(spec.high)}]'
    elif spec.kind == 'double_array':
        desc.additional_constraints = f'3 numbers, each in [{spec.low:g}, {spec.high:g}]'
    elif spec.choices:
        desc.additional_constraints = 'one of: ' + ', '.join(spec.choices)
    return desc


def default_params_path():
    """Return the path of ``config/gyro_emulator.yaml`` (see ``resources.config_dir``)."""
    return config_file(DEFAULTS_FILE)


def load_params_file(path, node_name=NODE_NAME):
    """
    Read a ``--params-file`` style YAML and return its parameters, flattened.

    The file is parsed by rclpy's own reader
    (``rclpy.parameter.parameter_dict_from_yaml_file``): the ``/**``
    wildcard section first, then the node's own section. YAML syntax errors
    are reported with their line and column first (:func:`read_yaml`).

    Parameters
    ----------
    path : str
        YAML file with ``/**:`` or ``<node name>:`` then ``ros__parameters:``.
    node_name : str
        Node whose section is read after the ``/**`` wildcard section.

    Returns
    -------
    dict
        ``{'rate_hz': 200.0, 'sensor.lsb_rad_s': [...], ...}``.

    """
    doc = read_yaml(path)
    if not isinstance(doc, dict):
        raise ValueError(f'{path}: expected "/**: {{ros__parameters: {{...}}}}"')
    sections = [key for key in ('/**', node_name, '/' + node_name) if key in doc]
    if not sections:
        raise ValueError(f'{path}: no "/**" or "{node_name}" section with '
                         'ros__parameters')
    for key in sections:
        section = doc[key]
        if not isinstance(section, dict) or not isinstance(
                section.get('ros__parameters'), dict):
            raise ValueError(f'{path}: section {key!r} has no ros__parameters mapping')
    try:
        messages = parameter_dict_from_yaml_file(path, use_wildcard=True,
                                                 target_nodes=sections)
    except (RuntimeError, TypeError, ValueError) as exc:
        raise ValueError(f'{path}: not a ROS 2 parameter file: {exc}') from None
    return {name: _python_value(msg.value) for name, msg in messages.items()}


def _python_value(value):
    """Return a ParameterValue message as a plain Python value (arrays as lists)."""
    out = parameter_value_to_python(value)
    return list(out) if isinstance(out, (tuple, array.array)) else out


def node_defaults(path=None):
    """
    Return the node parameters' defaults from ``config/gyro_emulator.yaml``.

    Every entry of :data:`NODE_PARAMS` must be present and valid; unknown
    keys other than ``sensor.*``, ``qos_overrides.*`` and ``use_sim_time``
    are refused, so a typo cannot pass silently.
    """
    path = default_params_path() if path is None else path
    raw = load_params_file(path)
    missing = [spec.name for spec in NODE_PARAMS if spec.name not in raw]
    if missing:
        raise ValueError(f'{path}: missing parameter(s) {", ".join(missing)}')
    unknown = sorted(name for name in raw if name not in NODE_SPECS and not name.startswith(
        (SENSOR_PREFIX, QOS_PREFIX)) and name != 'use_sim_time')
    if unknown:
        raise ValueError(f'{path}: unknown parameter(s) {", ".join(unknown)}; allowed: '
                         f'{", ".join(NODE_SPECS)}, sensor.*')
    return {spec.name: check_value(spec, raw[spec.name]) for spec in NODE_PARAMS}


def sensor_descriptor(name, value):
    """Return the descriptor of a ``sensor.*`` parameter (validated by SensorConfig)."""
    if name.startswith(TERMS_PREFIX):
        return ParameterDescriptor(
            name=name, type=ParameterType.PARAMETER_BOOL,
            description=f'Error term {name[len(TERMS_PREFIX):]} on or off')
    field = name[len(SENSOR_PREFIX):]
    text = SENSOR_DESCRIPTIONS.get(field, f'SensorConfig.{field}')
    if field == 'device':
        return ParameterDescriptor(name=name, type=ParameterType.PARAMETER_STRING,
                                   description=text, read_only=True)
    # Numbers and lists: accept ints for doubles and a scalar for a per-axis list;
    # SensorConfig checks shape and range and names the allowed range.
    return ParameterDescriptor(name=name, description=text, dynamic_typing=True,
                               additional_constraints='validated by SensorConfig')


def _as_double(name, value):
    """Return Parameter ``value`` of parameter ``name``, an integer of a double as a double."""
    spec = NODE_SPECS.get(name)
    if spec is None:
        return value
    if spec.kind == 'double' and value.type_ == Parameter.Type.INTEGER:
        return Parameter(name, Parameter.Type.DOUBLE, float(value.value))
    if spec.kind == 'double_array' and value.type_ == Parameter.Type.INTEGER_ARRAY:
        return Parameter(name, Parameter.Type.DOUBLE_ARRAY, [float(v) for v in value.value])
    return value


def _doubles_as_doubles(node):
    """Take an integer override of a double as a double (a params file may write 200)."""
    overrides = getattr(node, '_parameter_overrides', None)
    if not isinstance(overrides, dict):
        return
    for name, value in list(overrides.items()):
        overrides[name] = _as_double(name, value)


def integers_as_doubles(parameters):
    """
    Pre-set callback: an integer set at run time for a double is taken as a double.

    ``ros2 param set /gyro_emulator fault.magnitude 2`` sends an INTEGER,
    which rclpy would refuse for a DOUBLE parameter without naming it, as
    at start-up (:func:`declare_node_parameters`) it is taken as 2.0.
    """
    return [_as_double(p.name, p) for p in parameters]


def declare_node_parameters(node):
    """
    Declare every node parameter on ``node``; return their checked values.

    Raises ValueError for a value the table refuses (the message names the
    parameter, the value and the allowed range), for ``temperature_rate_hz``
    above ``rate_hz`` and for an invalid ``fault.*`` set.
    """
    _doubles_as_doubles(node)
    defaults = node_defaults()
    values = {}
    for spec in NODE_PARAMS:
        default = defaults[spec.name]
        if spec.name == 'temperature_rate_hz':
            # The shipped 10 Hz must not refuse a slower rate_hz (1 Hz is allowed).
            default = min(default, values['rate_hz'])
        value = node.declare_parameter(spec.name, default, descriptor(spec)).value
        values[spec.name] = check_value(spec, value)
    if values['temperature_rate_hz'] > values['rate_hz']:
        raise ValueError(f'temperature_rate_hz = {values["temperature_rate_hz"]!r} is '
                         f'out of range: allowed (0, rate_hz = {values["rate_hz"]:g}]')
    fault_from(values)
    return values


def declare_sensor_parameters(node, base):
    """Declare the ``sensor.*`` parameters of SensorConfig ``base``; return their values."""
    return {name: node.declare_parameter(name, default, sensor_descriptor(name, default)).value
            for name, default in sensor_param_values(base).items()}


def check_qos_overrides(node):
    """
    Refuse a ``qos_overrides.*`` value that rclpy or the middleware cannot take.

    Call before the node creates its publishers and subscriptions: rclpy
    turns a policy name it does not know into a RuntimeError and rcl a depth
    beyond the middleware's into an RCLError without the parameter's name.
    Raises ValueError naming the parameter, the value and what is allowed
    (``depth`` [0, 2^31 - 1]; ``history`` and ``reliability`` one of rclpy's
    policy names, in any case). A value of the wrong type is left to rclpy,
    which names the parameter and both types.
    """
    overrides = getattr(node, '_parameter_overrides', None) or {}
    for name in sorted(overrides):
        if not name.startswith(QOS_PREFIX):
            continue
        policy, value = name.rsplit('.', 1)[-1], overrides[name].value
        if policy == 'depth' and isinstance(value, int) and not isinstance(value, bool) \
                and not 0 <= value <= MAX_QOS_DEPTH:
            raise ValueError(f'{name} = {value!r} is out of range: allowed '
                             f'[0, {MAX_QOS_DEPTH}]')
        allowed = QOS_POLICY_NAMES.get(policy)
        if allowed and isinstance(value, str) and value.lower() not in allowed:
            raise ValueError(f'{name} = {value!r} is not allowed: choose one of '
                             f'{", ".join(allowed)}')


def unknown_overrides(node):
    """
    Return the names of parameter overrides that ``node`` does not declare, sorted.

    Once the node's publishers and subscriptions exist, a ``qos_overrides.*``
    name it did not declare is unknown too: a policy its topics do not let
    change (durability) or a topic it does not have.
    """
    overrides = getattr(node, '_parameter_overrides', None) or {}
    return [name for name in sorted(overrides) if not node.has_parameter(name)]
