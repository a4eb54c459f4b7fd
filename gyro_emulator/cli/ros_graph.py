"""
``gyro-emulator ros param`` and ``ros topic``: ros2param and ros2topic on rclpy.

Each command is a short-lived node named ``_gyro_emulator_cli_<pid>`` (a
leading underscore hides it, as ros2cli's nodes are hidden). Ctrl-C is the
normal end of ``topic hz`` and ``topic echo``: they exit 0.
"""

import collections
import difflib
import importlib
import math
import os
import sys
import time

from gyro_emulator.resources import load_yaml_text
from gyro_emulator.validation import quote
from rcl_interfaces.msg import Parameter as ParameterMsg, ParameterType, ParameterValue
import rclpy
from rclpy.parameter import get_parameter_value, parameter_value_to_python
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
import yaml

#: How often the graph is looked at while waiting for a topic, s.
GRAPH_POLL_S = 0.1

#: The range of a ROS integer parameter (int64).
INT64_MIN, INT64_MAX = -2 ** 63, 2 ** 63 - 1


class _Session:
    """rclpy context and a hidden node; Ctrl-C ends it quietly."""

    def __enter__(self):
        rclpy.init()
        self.node = rclpy.create_node(f'_gyro_emulator_cli_{os.getpid()}')
        return self

    def __exit__(self, kind, value, traceback):
        self.node.destroy_node()
        rclpy.try_shutdown()
        return kind is KeyboardInterrupt

    def wait(self, future, timeout_s, what):
        """Spin until ``future`` is done; raise OSError naming ``what`` after timeout_s."""
        rclpy.spin_until_future_complete(self.node, future, timeout_sec=timeout_s)
        if not future.done():
            raise OSError(f'no answer from {what} within {timeout_s:g} s')
        return future.result()


def parameter_value(text):
    """
    Return the ParameterValue of ``text``, read as ``ros2 param set`` reads it.

    rclpy's ``get_parameter_value`` behind the one bounded YAML loader
    (``resources.load_yaml_text``): an alias bomb or a value nested too deep
    is refused in one line before anything expands it. Text that is not YAML,
    a mapping, or a scalar that is none of bool, int, float and string (a
    date) is sent as the string given (rclpy would put the parsed object into
    ``string_value`` and fail); an integer beyond int64 is refused.

    Raises
    ------
    ValueError
        One line quoting at most about 200 characters of ``text``.

    """
    try:
        doc = load_yaml_text(text, 'VALUE')
    except ValueError as exc:
        if ': malformed YAML: ' not in str(exc):
            raise
        doc = text
    items = doc if isinstance(doc, list) else [doc]
    if any(isinstance(v, int) and not isinstance(v, bool) and not INT64_MIN <= v <= INT64_MAX
           for v in items):
        raise ValueError(f'VALUE = {quote(text)}: an integer beyond the int64 range of a ROS '
                         f'parameter: allowed [{INT64_MIN}, {INT64_MAX}]')
    if doc is text or not isinstance(doc, (bool, int, float, str, list, type(None))):
        return ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=text)
    return get_parameter_value(text)


def param(action, node_name, name, value, timeout_s):
    """``param set NODE NAME VALUE`` or ``param get NODE NAME``; return the exit status."""
    new = parameter_value(value) if action == 'set' else None
    with _Session() as session:
        client = AsyncParameterClient(session.node, node_name)
        if not client.wait_for_services(timeout_sec=timeout_s):
            raise OSError(f'node {node_name} not found within {timeout_s:g} s '
                          '(same ROS_DOMAIN_ID and ROS_AUTOMATIC_DISCOVERY_RANGE?)')
        names = session.wait(client.list_parameters(), timeout_s, node_name).result.names
        if name not in names:
            raise ValueError(undeclared(name, node_name, names))
        current = session.wait(client.get_parameters([name]), timeout_s,
                               node_name).values[0]
        if action == 'get':
            if current.type == ParameterType.PARAMETER_NOT_SET:
                print(f'Parameter not set: {name}')
                return 1
            print(f'{name}: {parameter_value_to_python(current)!r}')
            return 0
        if (current.type == ParameterType.PARAMETER_DOUBLE
                and new.type == ParameterType.PARAMETER_INTEGER):
            new = ParameterValue(type=ParameterType.PARAMETER_DOUBLE,
                                 double_value=float(new.integer_value))
        result = session.wait(client.set_parameters([ParameterMsg(name=name, value=new)]),
                              timeout_s, node_name).results[0]
        if result.successful:
            print('Set parameter successful')
            return 0
        print(f'Setting parameter failed: {result.reason}', file=sys.stderr)
        return 1
    return 0


def undeclared(name, node_name, names):
    """Return the one line for a parameter ``name`` that ``node_name`` does not declare."""
    close = difflib.get_close_matches(name, names, n=3, cutoff=0.6)
    hint = ('close matches: ' + ', '.join(close)) if close else \
        f'no close match among its {len(names)} parameters'
    return f'parameter {name!r} is not declared by {node_name}; {hint}'


def topic_list(spin_time_s):
    """Print every topic and its types after ``spin_time_s`` of discovery."""
    with _Session() as session:
        end = time.monotonic() + spin_time_s
        while time.monotonic() < end:
            rclpy.spin_once(session.node, timeout_sec=GRAPH_POLL_S)
        for name, types in sorted(session.node.get_topic_names_and_types()):
            print(f'{name} [{", ".join(types)}]')
    return 0


def _resolve(node, topic):
    """Return the fully qualified topic name (``imu/data_raw`` -> ``/imu/data_raw``)."""
    return node.resolve_topic_name(topic)


def _message_class(type_name):
    """Return the class of ``pkg/msg/Type`` (or ``pkg/Type``)."""
    parts = type_name.split('/')
    if len(parts) not in (2, 3) or (len(parts) == 3 and parts[1] != 'msg'):
        raise ValueError(f'--type = {type_name!r}: expected a message type such as '
                         'sensor_msgs/msg/Imu')
    try:
        return getattr(importlib.import_module(f'{parts[0]}.msg'), parts[-1])
    except (ImportError, AttributeError):
        raise ValueError(f'--type = {type_name!r}: no such message type here') from None


def _wait_for_topic(session, topic, type_name):
    """Return (message class, QoS matching the publishers) once ``topic`` has one."""
    node = session.node
    said = False
    while True:
        publishers = node.get_publishers_info_by_topic(topic)
        if publishers:
            break
        if not said:
            print(f'waiting for a publisher of {topic}', file=sys.stderr)
            said = True
        rclpy.spin_once(node, timeout_sec=GRAPH_POLL_S)
    type_name = type_name or publishers[0].topic_type
    # As ros2topic does: best effort if any publisher is, transient local if all are.
    best_effort = any(p.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT
                      for p in publishers)
    latched = all(p.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
                  for p in publishers)
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT if best_effort
                     else ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL if latched
                     else DurabilityPolicy.VOLATILE)
    return _message_class(type_name), qos


def _spin_until(session, done):
    while not done():
        rclpy.spin_once(session.node, timeout_sec=GRAPH_POLL_S)


def rate_text(stamps_s):
    """
    Return ros2 topic hz's report of receive times ``stamps_s`` (s, increasing).

    Rate = 1 / mean period; min, max and standard deviation of the periods;
    window = the number of periods.
    """
    periods = [b - a for a, b in zip(stamps_s, list(stamps_s)[1:])]
    mean = sum(periods) / len(periods)
    std = math.sqrt(sum((p - mean) ** 2 for p in periods) / len(periods))
    return (f'average rate: {1.0 / mean:.3f}\n\tmin: {min(periods):.3f}s '
            f'max: {max(periods):.3f}s std dev: {std:.5f}s window: {len(periods)}')


def topic_hz(topic, type_name, window, count):
    """Print the receive rate each second (and at the end with ``count``)."""
    with _Session() as session:
        topic = _resolve(session.node, topic)
        cls, qos = _wait_for_topic(session, topic, type_name)
        stamps = collections.deque(maxlen=window)
        received = [0]

        def on_message(_raw):
            stamps.append(time.monotonic())
            received[0] += 1

        def report():
            if len(stamps) > 1:
                print(rate_text(stamps), flush=True)
            else:
                print('no new messages', flush=True)

        # Raw: the rate needs the arrival, not the content.
        session.node.create_subscription(cls, topic, on_message, qos, raw=True)
        session.node.create_timer(1.0, report)
        _spin_until(session, lambda: count is not None and received[0] >= count)
        report()
    return 0


def message_to_dict(msg):
    """Return a ROS message as nested dicts and lists of plain Python values."""
    if hasattr(msg, 'get_fields_and_field_types'):
        return {name: message_to_dict(getattr(msg, name))
                for name in msg.get_fields_and_field_types()}
    if hasattr(msg, 'tolist'):  # numpy arrays and scalars, array.array
        msg = msg.tolist()
    if isinstance(msg, (list, tuple)):
        return [message_to_dict(item) for item in msg]
    return list(msg) if isinstance(msg, bytes) else msg


def topic_echo(topic, type_name, count):
    """Print each message as YAML, ``---`` after each, until ``count`` or Ctrl-C."""
    with _Session() as session:
        topic = _resolve(session.node, topic)
        cls, qos = _wait_for_topic(session, topic, type_name)
        printed = [0]

        def on_message(msg):
            if count is not None and printed[0] >= count:
                return
            print(yaml.safe_dump(message_to_dict(msg), sort_keys=False,
                                 default_flow_style=False), end='---\n', flush=True)
            printed[0] += 1

        session.node.create_subscription(cls, topic, on_message, qos)
        _spin_until(session, lambda: count is not None and printed[0] >= count)
    return 0
