"""
How commands get from the node's subscriptions into its command streams.

A subscription callback only appends the message, still serialized, to the
topic's inbox: a ``collections.deque`` with ``maxlen`` :data:`INBOX_DEPTH`, so
under a flood the newest messages stay and memory is bounded. At each sample
:meth:`Intake.take` decodes every inbox in one vectorised call
(:func:`gyro_emulator.recording.cdr.decode`; rclpy's deserialiser for the
types without a fixed layout, and as a fallback), validates each command
(:mod:`gyro_emulator.emulation.commands`) and queues it in its stamped
:class:`~gyro_emulator.emulation.commands.CommandStream`. A zero stamp means
"on receipt": the sample that takes it.

Raw callbacks and one decode per sample keep a command flood from stalling
the output: about 1.5 us a message, not ~100 us (``bench/bench_node.py``).
"""

from collections import deque

from gyro_emulator.emulation.commands import (check_acceleration, check_rate,
                                              check_temperature, CommandStream,
                                              InputRejected)
from gyro_emulator.recording import cdr, topics
from gyro_emulator.ros import codec
from gyro_emulator.units import NS_PER_S
from rclpy.serialization import deserialize_message

#: Messages each inbox keeps until the next sample (the newest stay).
INBOX_DEPTH = 100


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
    The node's command streams, fed from raw subscriptions through inboxes.

    Parameters
    ----------
    rate_topic : gyro_emulator.recording.topics.Topic or None
        The rate input (``cmd/angular_velocity`` or ``cmd/odom``); None: none
        (``input_source: imu``).
    initial_temperature_c : float
        Ambient temperature before the first command, deg C.
    initial_accel_m_s2 : tuple of float
        Specific force before the first command, m/s^2.
    capacity : int
        Commands per stream waiting for their stamp.
    reject : callable
        ``reject(InputRejected)``: count and log a refused command.
    clamp : callable
        ``clamp(raw_temp_c, temp_c)``: count and log a clamped temperature.

    """

    def __init__(self, rate_topic, initial_temperature_c, initial_accel_m_s2, capacity,
                 reject, clamp):
        self.rate = CommandStream('rate', (0.0, 0.0, 0.0), capacity)
        self.temperature = CommandStream('temperature', initial_temperature_c, capacity)
        self.accel = CommandStream('linear_acceleration', tuple(initial_accel_m_s2),
                                   capacity)
        self._reject, self._clamp = reject, clamp
        handlers = {topics.TEMPERATURE_CMD: (self.temperature, self._temperature),
                    topics.ACCEL_CMD: (self.accel, self._accel)}
        if rate_topic is not None:
            handlers[rate_topic] = (self.rate, self._rate)
        self._handlers = handlers
        self.inboxes = {topic: deque(maxlen=INBOX_DEPTH) for topic in handlers}

    @property
    def streams(self):
        """Return the rate, temperature and acceleration streams, in that order."""
        return (self.rate, self.temperature, self.accel)

    def take(self, now_ns, limits):
        """Validate and queue every command that arrived; ``now_ns`` is the node clock."""
        lead_ns = int(limits.max_stamp_lead_s * NS_PER_S)
        for topic, inbox in self.inboxes.items():
            if not inbox:
                continue
            payloads = list(inbox)
            inbox.clear()
            stream, check = self._handlers[topic]
            for stamp_ns, value in zip(*decode(topic, payloads)):
                try:
                    self._offer(stream, check(value, limits), stamp_ns, now_ns, lead_ns)
                except InputRejected as exc:
                    self._reject(exc)

    def _offer(self, stream, value, stamp_ns, now_ns, lead_ns):
        if stream.offer(value, stamp_ns, now_ns, lead_ns):
            self._reject(InputRejected('queue_overflow', f'{stream.name}: more than '
                                       f'{stream.capacity} commands wait for their '
                                       'stamp: the oldest was dropped'))

    @staticmethod
    def _rate(value, limits):
        return check_rate(value, limits)

    @staticmethod
    def _accel(value, limits):
        return check_acceleration(value, limits)

    def _temperature(self, value, limits):
        temp, clamped = check_temperature(value, limits)
        if clamped:
            self._clamp(value, temp)
        return temp

    def pending(self):
        """Return how many commands wait for their stamp, over all streams."""
        return sum(len(stream.pending) for stream in self.streams)

    def reset_clock(self):
        """Forget every stamp (the clock jumped back)."""
        for stream in self.streams:
            stream.reset_clock()
