"""
What the node publishes per sample: Imu, die temperature, truth and fault truth.

:class:`OutputStage` owns the node's publishers and the serialized templates
(``ros/rawmsg.py``) of ``imu/data_raw``, ``imu/temperature`` and
``~/truth/{rate,bias,scale_factor,imu}``, and publishes one
:class:`~gyro_emulator.emulation.driver.records.Output` of the driver (the
fault in force has already acted on it, :mod:`gyro_emulator.sensor.faults`):

* ``imu/data_raw`` (REP 145/103): rad/s and m/s^2 in the sensor frame,
  ``angular_velocity_covariance`` and ``linear_acceleration_covariance`` =
  diag(sigma^2), orientation absent (``orientation_covariance[0] = -1``),
  linear acceleration absent (``[0] = -1``) when the driver says so
  (``publish_linear_acceleration``). A dropout publishes nothing; a stuck
  axis repeats the float64 of the last published value bit for bit.
* ``imu/temperature`` on the samples the driver marks (``temperature_rate_hz``).
* the truth of the same sample, stamped at the sample instant; ``~/truth/imu``
  carries the attitude (``orientation``, sensor frame to ENU world), the true
  rate and the true specific force. A truth topic that nobody subscribes
  to is not built (``Publisher.get_subscription_count``): its QoS is
  volatile, so nothing would be delivered nor kept for a later subscriber
  (a durable one would always be published).
* ``~/truth/fault`` (diagnostic_msgs/DiagnosticArray, latched) whenever the
  fault state changes; :func:`fault_message` gives its encoding.

A ``tap`` (the node's self-recording, :mod:`gyro_emulator.ros.self_record`)
receives every message as it is published, serialized: (publisher, bytes).
It sees each sample in the process that made it, so none is lost in flight
when the node stops; with a tap, every truth topic is built.
"""

import copy

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from gyro_emulator.recording import topics
from gyro_emulator.ros import codec
from gyro_emulator.ros.rawmsg import RawMessage
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
from rclpy.qos_overriding_options import QoSOverridingOptions
from rclpy.serialization import serialize_message
from rclpy.time import Time

_LEVELS = {0: DiagnosticStatus.OK, 1: DiagnosticStatus.WARN, 2: DiagnosticStatus.ERROR}


def fault_message(stamp, name, hardware_id, fault, state, level, since_ns):
    """
    Build the ``~/truth/fault`` message: one DiagnosticStatus in a DiagnosticArray.

    Encoding: ``header.stamp`` is the sample instant of the change; the
    status has ``level`` OK (no fault acting), WARN or ERROR (the fault's
    severity while it acts), ``name`` = ``<node>: fault``, ``message`` = the
    fault type, and the key/values ``type``, ``axis``, ``magnitude`` (in the
    type's unit), ``start_s``, ``duration_s`` (as set), ``state``
    (``none``, ``pending``, ``active`` or ``ended``) and ``since_ns`` (node
    clock of the change, integer ns).
    """
    msg = DiagnosticArray()
    msg.header.stamp = stamp
    status = DiagnosticStatus(level=_LEVELS[level], name=name, message=fault.kind,
                              hardware_id=hardware_id)
    status.values = [KeyValue(key=k, value=v) for k, v in (
        ('type', fault.kind), ('axis', fault.axis), ('magnitude', repr(fault.magnitude)),
        ('start_s', repr(fault.start_s)), ('duration_s', repr(fault.duration_s)),
        ('state', state), ('since_ns', str(int(since_ns))))]
    msg.status = [status]
    return msg


def _qos(topic, reliability):
    """Return the topic's QoS profile with ``reliability`` (``best_effort`` or ``reliable``)."""
    qos = codec.topic_qos(topic)
    if topic.qos != 'sensor_data':
        return qos
    qos = copy.copy(qos)
    qos.reliability = (ReliabilityPolicy.RELIABLE if reliability == 'reliable'
                       else ReliabilityPolicy.BEST_EFFORT)
    return qos


class OutputStage:
    """
    The node's publishers and message templates.

    Parameters
    ----------
    node : rclpy.node.Node
        The emulator node.
    frame_id : str
        ``header.frame_id`` of every message.
    reliability : str
        ``qos_reliability``: ``best_effort`` (sensor data) or ``reliable`` for
        ``imu/data_raw``, ``imu/temperature`` and ``~/truth/*`` (``qos_overrides``
        still apply on top).

    """

    def __init__(self, node, frame_id, reliability='best_effort'):
        # Each publisher's QoS event handlers (incompatible QoS / type warnings)
        # join every executor wake-up; only imu/data_raw, the output that
        # drivers' users subscribe to, keeps them.
        options = QoSOverridingOptions.with_default_policies
        quiet = PublisherEventCallbacks(use_default_callbacks=False)

        def publisher(topic, **kwargs):
            return node.create_publisher(codec.topic_class(topic), topic.name,
                                         _qos(topic, reliability), **kwargs)
        self.imu_pub = publisher(topics.IMU_OUT, qos_overriding_options=options())
        self.temp_pub = publisher(topics.DIE_TEMPERATURE_OUT, event_callbacks=quiet,
                                  qos_overriding_options=options())
        self.truth_pubs = [publisher(topic, qos_overriding_options=options(),
                                     event_callbacks=quiet)
                           for topic in topics.TRUTH_TOPICS.values()]
        self.truth_imu_pub = publisher(topics.TRUTH_IMU, qos_overriding_options=options(),
                                       event_callbacks=quiet)
        self.fault_pub = publisher(topics.TRUTH_FAULT, event_callbacks=quiet)
        self.diag_pub = publisher(topics.DIAGNOSTICS, event_callbacks=quiet)
        #: called with (publisher, serialized message) on each publish; None: no one
        self.tap = None
        imu = codec.topic_class(topics.IMU_OUT)()
        imu.header.frame_id = frame_id
        imu.orientation_covariance[0] = -1.0
        imu.linear_acceleration_covariance[0] = -1.0
        self.imu = RawMessage(imu, {
            'stamp': ('header.stamp', 'time'), 'rate': ('angular_velocity', 'vector3'),
            'cov': ('angular_velocity_covariance', ('array', 9)),
            'accel': ('linear_acceleration', 'vector3'),
            'accel_cov': ('linear_acceleration_covariance', ('array', 9))})
        self._accel_shown = False
        self._covariance_shown = None
        self._accel_covariance_shown = None
        temp = codec.topic_class(topics.DIE_TEMPERATURE_OUT)()
        temp.header.frame_id = frame_id
        self.temp_msg = RawMessage(temp, {'stamp': ('header.stamp', 'time'),
                                          'value': ('temperature', 'double')})
        self.truth_msgs = []
        for topic in topics.TRUTH_TOPICS.values():
            msg = codec.topic_class(topic)()
            msg.header.frame_id = frame_id
            self.truth_msgs.append(RawMessage(msg, {'stamp': ('header.stamp', 'time'),
                                                    'value': ('vector', 'vector3')}))
        truth_imu = codec.topic_class(topics.TRUTH_IMU)()
        truth_imu.header.frame_id = frame_id
        self._truth_kept = [pub.qos_profile.durability != DurabilityPolicy.VOLATILE
                            for pub in (*self.truth_pubs, self.truth_imu_pub)]
        self.truth_imu = RawMessage(truth_imu, {
            'stamp': ('header.stamp', 'time'), 'rate': ('angular_velocity', 'vector3'),
            'force': ('linear_acceleration', 'vector3'),
            **{'q' + c: ('orientation.' + c, 'double') for c in 'wxyz'}})

    def sample_publishers(self):
        """Return (publisher, topic) of every topic this stage publishes samples and faults on."""
        return ((self.imu_pub, topics.IMU_OUT), (self.temp_pub, topics.DIE_TEMPERATURE_OUT),
                *zip(self.truth_pubs, topics.TRUTH_TOPICS.values()),
                (self.truth_imu_pub, topics.TRUTH_IMU), (self.fault_pub, topics.TRUTH_FAULT))

    def _send(self, pub, payload):
        """Publish a serialized message and hand it to the tap."""
        pub.publish(payload)
        if self.tap is not None:
            self.tap(pub, payload)

    def _wanted(self, pub, kept):
        """Tell whether a truth topic is built: kept for late joiners, subscribed or tapped."""
        return kept or self.tap is not None or pub.get_subscription_count() > 0

    def set_covariance(self, covariance):
        """Show ``angular_velocity_covariance`` (9 numbers, rad^2/s^2) from now on."""
        if covariance is self._covariance_shown:
            return
        self.imu.put('cov', *covariance)
        self._covariance_shown = covariance

    def set_accel_covariance(self, covariance):
        """
        Show ``linear_acceleration_covariance`` (9 numbers, m^2/s^4) from now on.

        None: the accelerometer is absent (REP 145: element 0 = -1, the rest 0,
        and the acceleration 0).
        """
        if covariance is self._accel_covariance_shown:
            return
        if covariance is None:
            self.imu.put('accel', 0.0, 0.0, 0.0)
            self.imu.put('accel_cov', -1.0, *(0.0,) * 8)
        else:
            self.imu.put('accel_cov', *covariance)
        self._accel_covariance_shown = covariance

    def publish(self, output, truth=True):
        """
        Publish one sample.

        Parameters
        ----------
        output : gyro_emulator.emulation.driver.records.Output
            The driver's sample: stamps, the gyro and accelerometer channels
            (value, covariance, truth), the attitude, die temperature, what to show.
        truth : bool
            Publish ``~/truth/*``.

        """
        gyro, accel = output.gyro, output.accel
        if gyro.covariance is not self._covariance_shown:
            self.set_covariance(gyro.covariance)
        shown = accel.covariance if output.accel_shown else None
        if shown is not self._accel_covariance_shown:
            self.set_accel_covariance(shown)
        if output.published:
            imu = self.imu
            imu.set_stamp_ns('stamp', output.stamp_ns)
            imu.put('rate', *gyro.rate_rad_s)
            if shown is not None:
                imu.put('accel', *accel.accel_m_s2)
            self._send(self.imu_pub, imu.payload())
        if truth:
            self._publish_truth(output)
        if output.temperature_due:
            self.temp_msg.set_stamp_ns('stamp', output.sample_ns)
            self.temp_msg.put('value', output.die_temp_c)
            self._send(self.temp_pub, self.temp_msg.payload())

    def _publish_truth(self, output):
        """Publish ``~/truth/{rate,bias,scale_factor,imu}`` of one sample, at its instant."""
        gyro = output.gyro
        kept = self._truth_kept
        for pub, msg, vec, keep in zip(self.truth_pubs, self.truth_msgs,
                                       (gyro.true_rate_rad_s, gyro.bias_rad_s,
                                        gyro.scale_factor), kept):
            if self._wanted(pub, keep):
                msg.set_stamp_ns('stamp', output.sample_ns)
                msg.put('value', *vec.tolist())
                self._send(pub, msg.payload())
        if not self._wanted(self.truth_imu_pub, kept[-1]):
            return
        w, x, y, z = output.attitude_wxyz
        msg = self.truth_imu
        msg.set_stamp_ns('stamp', output.sample_ns)
        for name, value in (('qw', w), ('qx', x), ('qy', y), ('qz', z)):
            msg.put(name, value)
        msg.put('rate', *gyro.true_rate_rad_s.tolist())
        msg.put('force', *output.accel.true_specific_force_m_s2)
        self._send(self.truth_imu_pub, msg.payload())

    def publish_fault(self, report, name, hardware_id):
        """Publish a :class:`~gyro_emulator.emulation.driver.records.FaultReport` (a change)."""
        stamp = Time(nanoseconds=int(report.stamp_ns)).to_msg()
        msg = fault_message(stamp, name, hardware_id, report.fault, report.state, report.level,
                            report.since_ns)
        self._send(self.fault_pub, serialize_message(msg))
