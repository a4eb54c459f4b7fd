"""
How commands get from the node's subscriptions to its driver.

The node subscribes through :meth:`Intake.subscribe`. A command's callback
only appends the message, still serialized, to the topic's inbox: a
``collections.deque`` with ``maxlen`` :data:`INBOX_DEPTH`, so under a flood
the newest messages stay and memory is bounded. When a sample needs its
inputs, the driver calls :meth:`Intake.take`, which decodes every inbox in
one vectorised call (:func:`gyro_emulator.recording.cdr.decode`; rclpy's
deserialiser for the types without a fixed layout, and as a fallback); the
driver then checks each command and queues it at its stamp
(:class:`gyro_emulator.emulation.driver.commands.Commands`). A zero stamp
means "on receipt": the sample that takes it.

Raw callbacks and one decode per sample keep a command flood from stalling
the output: about 1.5 us a message, not ~100 us (``bench/bench_node.py``).
A handful of messages (up to :data:`gyro_emulator.recording.cdr.SMALL_BATCH`)
is decoded message by message, the same columns at a few microseconds.
"""

from collections import deque

from gyro_emulator.recording import cdr, topics
from gyro_emulator.ros import codec
from gyro_emulator.units import NS_PER_S
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.qos import qos_profile_sensor_data, QoSProfile
from rclpy.qos_overriding_options import QoSOverridingOptions
from rclpy.serialization import deserialize_message

#: Messages each inbox keeps until the next sample (the newest stay).
INBOX_DEPTH = 100


def _appender(inbox):
    """Return a subscription callback that appends to ``inbox`` (rclpy inspects it)."""
    def append(msg):
        inbox.append(msg)
    return append


def _deserialized(topic, payloads):
    """Return (stamps ns, (N, 3) or (N,) values) of payloads through rclpy's deserialiser."""
    cls = codec.topic_class(topic)
    stamps, values = [], []
    for payload in payloads:
        msg = payload if isinstance(payload, cls) else deserialize_message(payload, cls)
        stamp = msg.header.stamp
        stamps.append(stamp.sec * NS_PER_S + stamp.nanosec)
        if topic is topics.TEMPERATURE_CMD:
            values.append(msg.temperature)
        else:
            vector = msg.twist.twist.angular if topic is topics.ODOM_CMD else msg.vector
            values.append((vector.x, vector.y, vector.z))
    return stamps, values


def decode(topic, payloads):
    """
    Return the stamps (ns) and values of a batch of command messages.

    Fixed-layout types are decoded together from their CDR bytes; anything
    else (``nav_msgs/Odometry``, or bytes that are not plain little-endian
    CDR) goes through rclpy's deserialiser. Values are (x, y, z) tuples, or
    temperatures in deg C.
    """
    if topic.type_name in cdr.LAYOUTS and all(isinstance(p, bytes) for p in payloads):
        try:
            decoded = cdr.decode(topic.type_name, payloads)
        except ValueError:
            return _deserialized(topic, payloads)
        if topic is topics.TEMPERATURE_CMD:
            values = decoded.field('temperature').tolist()
        else:
            values = [tuple(v) for v in decoded.field('vector').tolist()]
        return decoded.stamp_ns.tolist(), values
    return _deserialized(topic, payloads)


class Intake:
    """
    The node's command inboxes, fed from raw subscriptions; the driver's command source.

    Parameters
    ----------
    rate_topic : gyro_emulator.recording.topics.Topic or None
        The rate input (``cmd/angular_velocity`` or ``cmd/odom``); None: none
        (``input_source: imu``).

    Attributes
    ----------
    inboxes : dict
        ``{topic: deque of serialized messages}``, in the order they are taken.

    """

    def __init__(self, rate_topic):
        streams = {topics.TEMPERATURE_CMD: 'temperature',
                   topics.ACCEL_CMD: 'linear_acceleration'}
        if rate_topic is not None:
            streams[rate_topic] = 'rate'
        self._streams = streams
        self.inboxes = {topic: deque(maxlen=INBOX_DEPTH) for topic in streams}
        self.subscriptions = []

    def take(self):
        """Return and empty every inbox: ``(stream name, stamps ns, values)`` per topic."""
        batches = []
        for topic, inbox in self.inboxes.items():
            if not inbox:
                continue
            payloads = list(inbox)
            inbox.clear()
            stamps, values = decode(topic, payloads)
            batches.append((self._streams[topic], stamps, values))
        return batches

    def subscribe(self, node, on_imu=None):
        """
        Subscribe ``node`` to its inputs (its executor serves them).

        Commands go, still serialized, into the inboxes and are taken at the
        next sample; each takes effect at the first sample at or after its
        stamp, so the order in which the executor serves the timer and the
        subscriptions does not change the output. With ``on_imu``,
        ``imu/ideal`` is handled as it arrives: one output per message.
        """
        qos = QoSProfile(history=qos_profile_sensor_data.history, depth=INBOX_DEPTH,
                         reliability=qos_profile_sensor_data.reliability,
                         durability=qos_profile_sensor_data.durability)
        options = QoSOverridingOptions.with_default_policies
        # Default QoS event handlers would join every executor wake-up.
        quiet = SubscriptionEventCallbacks(use_default_callbacks=False)
        for topic, inbox in self.inboxes.items():
            raw = topic.type_name != topics.ODOMETRY
            self.subscriptions.append(node.create_subscription(
                codec.topic_class(topic), topic.name, _appender(inbox), qos, raw=raw,
                qos_overriding_options=options(), event_callbacks=quiet))
        if on_imu is not None:
            topic = topics.IMU_IDEAL_IN
            self.subscriptions.append(node.create_subscription(
                codec.topic_class(topic), topic.name, on_imu, qos,
                qos_overriding_options=options(), event_callbacks=quiet))
