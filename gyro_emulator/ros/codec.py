"""
ROS 2 message types, schemas and CDR serialisation for the bag layer.

The schema of a topic is the ``ros2msg`` text rosbag2 stores: the installed
``share/<pkg>/msg/<Name>.msg`` with its dependencies concatenated
(:func:`gyro_emulator.recording.bag.message_definition`, which only reads files so the
offline tools can use it without rclpy). Serialisation is rclpy's own
``serialize_message``/``deserialize_message`` (the rmw's CDR), so what we
record is byte-for-byte what a subscriber receives, up to padding bytes that
rclpy leaves uninitialised.
"""

import importlib
import re

from gyro_emulator.recording import bag
from gyro_emulator.units import NS_PER_S
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, qos_profile_sensor_data, QoSProfile,
                       ReliabilityPolicy)
from rclpy.serialization import deserialize_message
from rclpy.type_support import check_is_valid_msg_type, NoTypeSupportImportedException

_CLASSES = {}
#: A ROS 2 message type name: package (lower case, digits, _), 'msg', CamelCase name.
_TYPE_NAME = re.compile(r'[a-z][a-z0-9_]*/msg/[A-Z][A-Za-z0-9]*')


def message_class(type_name):
    """
    Return the Python class of a message type.

    Parameters
    ----------
    type_name : str
        ``package/msg/Name`` (``package/Name`` is accepted too).

    Raises
    ------
    ValueError
        If the package or the type is not installed.

    """
    cls = _CLASSES.get(type_name)
    if cls is not None:
        return cls
    parts = type_name.split('/') if isinstance(type_name, str) else []
    if len(parts) == 2:
        parts = [parts[0], 'msg', parts[1]]
    full = '/'.join(parts)
    if not _TYPE_NAME.fullmatch(full):
        raise ValueError(f'message type {type_name!r} is not understood: expected '
                         'package/msg/Name (lower_case package, CamelCase name)')
    # Type strings may come from untrusted bags: import only interfaces that
    # are installed as .msg files, and only if what is imported is a message.
    bag.message_definition(full)
    try:
        module = importlib.import_module(f'{parts[0]}.msg')
        cls = getattr(module, parts[2])
        check_is_valid_msg_type(cls)
    except (ImportError, AttributeError, TypeError, NoTypeSupportImportedException):
        raise ValueError(f'message type {type_name!r} is not installed') from None
    _CLASSES[type_name] = cls
    return cls


def topic_class(topic):
    """Return the message class of a topic-table entry (:mod:`gyro_emulator.recording.topics`)."""
    return message_class(topic.type_name)


def topic_qos(topic):
    """
    Return the rclpy ``QoSProfile`` of a topic-table entry's QoS kind.

    ``sensor_data`` is rclpy's ``qos_profile_sensor_data`` (best effort, keep
    last 5, volatile); ``reliable`` is reliable, keep last 10, volatile;
    ``latched`` is reliable, keep last 1, transient local.
    """
    if topic.qos == 'sensor_data':
        return qos_profile_sensor_data
    if topic.qos == 'latched':
        return QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    return QoSProfile(depth=10)


def type_name_of(message):
    """Return ``package/msg/Name`` of a message instance or class."""
    cls = message if isinstance(message, type) else type(message)
    package = cls.__module__.split('.')[0]
    namespace = cls.__module__.split('.')[1]
    return f'{package}/{namespace}/{cls.__name__}'


def schema_text(type_name):
    """Return the ros2msg schema of ``type_name`` as rosbag2 stores it."""
    return bag.message_definition(type_name)


def deserialize(data, type_name):
    """Return the message of type ``type_name`` decoded from CDR ``data``."""
    return deserialize_message(data, message_class(type_name))


def qos_to_profile(qos):
    """
    Return a rosbag2 v9 metadata mapping of an rclpy ``QoSProfile``.

    Parameters
    ----------
    qos : rclpy.qos.QoSProfile
        The profile offered by a publisher.

    """
    def enum_name(value, default):
        name = getattr(value, 'name', None)
        if not name or name in ('SYSTEM_DEFAULT', 'UNKNOWN'):
            return default
        return name.lower()

    profile = bag.qos_profile(
        reliability=enum_name(qos.reliability, 'reliable'),
        durability=enum_name(qos.durability, 'volatile'),
        history=enum_name(qos.history, 'keep_last'),
        depth=qos.depth,
        liveliness=enum_name(qos.liveliness, 'automatic'))
    for key, duration in (('deadline', qos.deadline), ('lifespan', qos.lifespan),
                          ('liveliness_lease_duration', qos.liveliness_lease_duration)):
        sec, nsec = divmod(int(duration.nanoseconds), NS_PER_S)
        if 0 < duration.nanoseconds and sec < 2**31 - 1:
            profile[key] = {'sec': int(sec), 'nsec': int(nsec)}
    return profile


def profile_to_qos(profile, depth=None):
    """
    Return an rclpy ``QoSProfile`` from a rosbag2 v9 metadata mapping.

    Parameters
    ----------
    profile : dict
        ``reliability``, ``durability``, ``history`` and ``depth`` are used.
    depth : int, optional
        Override the history depth.

    """
    def policy(enum, value, default):
        if isinstance(value, int):
            try:
                return enum(value)
            except ValueError:
                return default
        return getattr(enum, str(value).upper(), default)

    return QoSProfile(
        history=policy(HistoryPolicy, profile.get('history'), HistoryPolicy.KEEP_LAST),
        depth=int(depth if depth is not None else profile.get('depth') or 10),
        reliability=policy(ReliabilityPolicy, profile.get('reliability'),
                           ReliabilityPolicy.RELIABLE),
        durability=policy(DurabilityPolicy, profile.get('durability'),
                          DurabilityPolicy.VOLATILE))
