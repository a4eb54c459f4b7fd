"""
The topic table: every topic the emulator reads or writes, defined once.

Names are relative (resolved in the node's namespace) unless they start with
``/``; ``~/`` names live under the node's own name, as in ROS 2. Message types
are ``pkg/msg/Type`` strings, the form rosbag2 metadata uses. QoS is a plain
description (no rclpy here); :mod:`gyro_emulator.ros` turns it into a
``QoSProfile``:

* ``sensor_data``: best effort, keep last 5, volatile (rclpy's
  ``qos_profile_sensor_data``, REP 2003 for sensor drivers);
* ``reliable``: reliable, keep last 10, volatile (the rclpy default);
* ``latched``: reliable, keep last 1, transient local (a late subscriber
  gets the current state at once).

The node, scenario, recorder, replay and the offline readers all look topics
up here, so a name is spelled in one place.
"""

from dataclasses import dataclass
from types import MappingProxyType

VECTOR3_STAMPED = 'geometry_msgs/msg/Vector3Stamped'
IMU = 'sensor_msgs/msg/Imu'
TEMPERATURE = 'sensor_msgs/msg/Temperature'
ODOMETRY = 'nav_msgs/msg/Odometry'
DIAGNOSTIC_ARRAY = 'diagnostic_msgs/msg/DiagnosticArray'
CLOCK = 'rosgraph_msgs/msg/Clock'

#: QoS kinds a topic may have (see the module docstring).
QOS_KINDS = ('sensor_data', 'reliable', 'latched')


@dataclass(frozen=True)
class Topic:
    """
    One topic of the emulator's interface.

    Attributes
    ----------
    name : str
        ROS name: relative, absolute (``/``) or private (``~/``).
    type_name : str
        Message type, ``pkg/msg/Type``.
    qos : str
        One of :data:`QOS_KINDS`.
    direction : str
        ``in`` (the node subscribes) or ``out`` (the node publishes).
    description : str
        What it carries, with units.

    """

    name: str
    type_name: str
    qos: str
    direction: str
    description: str

    def __post_init__(self):
        if self.qos not in QOS_KINDS:
            raise ValueError(f'Topic.qos = {self.qos!r} is not allowed: choose one of '
                             f'{", ".join(QOS_KINDS)}')
        if self.direction not in ('in', 'out'):
            raise ValueError(f'Topic.direction = {self.direction!r} is not allowed: '
                             "choose 'in' or 'out'")

    @property
    def bag_name(self):
        """Return the name as a bag recorded at the root namespace stores it."""
        return self.name if self.name.startswith('/') else '/' + self.name


#: The table: one row per topic (name, type, QoS kind, direction, content).
RATE_CMD, ODOM_CMD, TEMPERATURE_CMD, ACCEL_CMD = (Topic(*row) for row in (
    ('cmd/angular_velocity', VECTOR3_STAMPED, 'reliable', 'in', 'true body rate, rad/s'),
    ('cmd/odom', ODOMETRY, 'reliable', 'in', 'twist.twist.angular as the true rate'),
    ('cmd/temperature', TEMPERATURE, 'reliable', 'in', 'ambient temperature, deg C'),
    ('cmd/linear_acceleration', VECTOR3_STAMPED, 'reliable', 'in',
     'applied linear acceleration, body frame, m/s^2 (gravity is added from the attitude)'),
))
#: The rosbag2 ``custom_data`` entry every bag the emulator writes carries: its
#: ``cmd/linear_acceleration`` is the applied linear acceleration (body frame,
#: gravity excluded), as the node takes it. A bag without it was written when
#: that topic held the specific force (gravity included):
#: :func:`accel_commands_applied`.
ACCEL_CMD_MEANING = MappingProxyType({'cmd_linear_acceleration': 'applied'})


def accel_commands_applied(custom_data):
    """Return whether a bag's ``custom_data`` marks its acceleration commands applied."""
    return all((custom_data or {}).get(k) == v for k, v in ACCEL_CMD_MEANING.items())


def old_accel_note(topic):
    """Return the note of acceleration commands read as the specific force (an older bag)."""
    meaning = ', '.join(f'{k}: {v}' for k, v in ACCEL_CMD_MEANING.items())
    return (f'{topic} read as the specific force (gravity included): the bag has no '
            f'custom_data {meaning}, so it was written when that topic held the specific '
            'force; the node takes the applied acceleration (gravity excluded)')


#: The ideal IMU of a simulator (``input_source: imu``), e.g. through ros_gz_bridge.
IMU_IDEAL_IN = Topic('imu/ideal', IMU, 'sensor_data', 'in',
                     'ideal IMU from a simulator: angular velocity rad/s, specific force m/s^2')
IMU_OUT, DIE_TEMPERATURE_OUT, DIAGNOSTICS = (Topic(*row) for row in (
    ('imu/data_raw', IMU, 'sensor_data', 'out',
     'gyro (rad/s) and accelerometer (m/s^2) output (REP 145)'),
    ('imu/temperature', TEMPERATURE, 'sensor_data', 'out', 'die temperature, deg C'),
    ('/diagnostics', DIAGNOSTIC_ARRAY, 'reliable', 'out', 'driver status'),
))
TRUTH_RATE, TRUTH_BIAS, TRUTH_SCALE_FACTOR = (
    Topic(f'~/truth/{what}', VECTOR3_STAMPED, 'sensor_data', 'out', f'true {what} per sample')
    for what in ('rate', 'bias', 'scale_factor'))
TRUTH_IMU = Topic('~/truth/imu', IMU, 'sensor_data', 'out',
                  'true attitude (orientation, sensor to ENU world), rate and specific force '
                  'per sample')
TRUTH_FAULT = Topic('~/truth/fault', DIAGNOSTIC_ARRAY, 'latched', 'out',
                    'the injected fault and its state, on each change')

#: The node's default name; its private (``~/``) topics live under ``/<name>/``.
NODE_NAME = 'gyro_emulator'
#: Where the truth topics of a node with the default name are, in a bag.
TRUTH_NAMESPACE = f'/{NODE_NAME}/truth'


def is_truth(name):
    """Return whether a bag topic is a node's truth (``.../truth/<what>``), not a measurement."""
    parts = str(name).rstrip('/').split('/')
    return len(parts) >= 3 and parts[-2] == 'truth'


#: What ``replay`` adds to its output bag (offline; not topics of the node).
REPLAY_MEASURED, REPLAY_RESIDUAL = (Topic(*row) for row in (
    ('/replay/measured', VECTOR3_STAMPED, 'reliable', 'out', 'measured gyro output, rad/s'),
    ('/replay/residual', VECTOR3_STAMPED, 'reliable', 'out', 'measured - emulated, rad/s'),
))

#: Truth topics by the short name the node publishes them under.
TRUTH_TOPICS = MappingProxyType({'rate': TRUTH_RATE, 'bias': TRUTH_BIAS,
                                 'scale_factor': TRUTH_SCALE_FACTOR})

#: Every topic of the node's interface, in the order of the README's table.
NODE_TOPICS = (RATE_CMD, ODOM_CMD, TEMPERATURE_CMD, ACCEL_CMD, IMU_IDEAL_IN, IMU_OUT,
               DIE_TEMPERATURE_OUT, TRUTH_RATE, TRUTH_BIAS, TRUTH_SCALE_FACTOR, TRUTH_IMU,
               TRUTH_FAULT, DIAGNOSTICS)

#: What the recorder takes by default: the emulator's inputs and outputs.
RECORDED_BY_DEFAULT = (RATE_CMD, TEMPERATURE_CMD, ACCEL_CMD, IMU_OUT,
                       DIE_TEMPERATURE_OUT, DIAGNOSTICS)

#: Rate inputs by ``rate_source`` parameter value.
RATE_INPUTS = MappingProxyType({'angular_velocity': RATE_CMD, 'odometry': ODOM_CMD})


def by_name(name):
    """Return the :class:`Topic` called ``name`` (with or without a leading ``/``)."""
    key = name.lstrip('/')
    for topic in NODE_TOPICS:
        if topic.name.lstrip('/') == key:
            return topic
    raise ValueError(f'topic {name!r} is not in the topic table: known '
                     f'{", ".join(t.name for t in NODE_TOPICS)}')
